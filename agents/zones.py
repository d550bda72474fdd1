"""Polygon keep-out zones as a UAV's planner sees them: no-fly polygons and the search area's
boundary (issue 26).

A circular threat (:class:`agents.knowledge.KnownThreat`) gives the APF three things at a point:
its clearance from the edge, the outward normal, and how far its field reaches. A
:class:`Keepout` gives the same three for any simple polygon, concave or not, so the APF
(:mod:`agents.apf`), the threat guard and the loiter stand-off treat polygons and circles alike
(circles keep their own exact code path: runs without polygons are unchanged).

* a **no-fly polygon** (``inverted=False``): the clearance is the distance to the polygon,
  positive outside, negative inside (minus the distance to its boundary); the normal points
  away from the polygon;
* the **area boundary** (``inverted=True``): the region to keep out of is everything *outside*
  the search area polygon: the clearance is positive inside the area (distance to its
  boundary), negative outside; the normal points into the area.

The geometry is plain numpy over the polygon's edges (a few tens of vertices): the distance to
every edge at once, the nearest one's foot point, and an even-odd crossing test for inside.
No shapely here: the agents stay importable without the ``geo`` dependencies, and these are
the same numbers on every machine (IEEE arithmetic in a fixed order). Zones are known before
take-off (published airspace, the mission's area), so they are never sent over the radio.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["Keepout"]


class Keepout:
    """A polygon to keep out of (or, ``inverted``, to keep inside of), with its repulsion reach.

    ``ring``: the polygon's vertices in local metres, ``(n, 2)``, closed or not (a closing
    vertex equal to the first is dropped). ``reach_m``: the distance from the edge within which
    the APF's eq. 30 repulsion acts (``d_max - R_T`` of a circle). ``zone``: its id (threat ids
    continue after the circles', so events and invariants name it like a threat)."""

    __slots__ = ("zone", "reach_m", "inverted", "ax", "ay", "dx", "dy", "len2", "bbox", "_xy")

    def __init__(self, zone: int, ring: Sequence[Sequence[float]] | np.ndarray, reach_m: float, inverted: bool = False):
        xy = np.asarray(ring, dtype=np.float64).reshape(-1, 2)
        if len(xy) > 1 and np.array_equal(xy[0], xy[-1]):
            xy = xy[:-1]
        if len(xy) < 3:
            raise ValueError(f"a polygon needs at least 3 distinct vertices, got {len(xy)}")
        self.zone = zone
        self.reach_m = float(reach_m)
        self.inverted = inverted
        self._xy = xy
        b = np.roll(xy, -1, axis=0)
        self.ax, self.ay = xy[:, 0].copy(), xy[:, 1].copy()
        self.dx, self.dy = b[:, 0] - xy[:, 0], b[:, 1] - xy[:, 1]
        self.len2 = np.maximum(self.dx * self.dx + self.dy * self.dy, 1e-300)
        self.bbox = (float(xy[:, 0].min()), float(xy[:, 1].min()), float(xy[:, 0].max()), float(xy[:, 1].max()))

    @property
    def vertices(self) -> np.ndarray:
        """The ring's distinct vertices, ``(n, 2)`` (not closed)."""
        return self._xy

    def contains_many(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Whether each point is inside the polygon (even-odd rule; boundary points may go
        either way), vectorised over points: ``(m,)`` bools."""
        x = np.asarray(x, dtype=np.float64)[:, None]
        y = np.asarray(y, dtype=np.float64)[:, None]
        ay, by = self.ay[None, :], (self.ay + self.dy)[None, :]
        crosses = (ay > y) != (by > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xi = self.ax[None, :] + (y - ay) * self.dx[None, :] / np.where(self.dy == 0.0, 1.0, self.dy)[None, :]
        inside: np.ndarray = np.count_nonzero(crosses & (x < xi), axis=1) % 2 == 1
        return inside

    def contains(self, x: float, y: float) -> bool:
        return bool(self.contains_many(np.array([x]), np.array([y]))[0])

    def boundary_distance(self, x: float, y: float) -> tuple[float, float, float]:
        """``(d, fx, fy)``: the distance from ``(x, y)`` to the polygon's boundary and the
        nearest boundary point (the first edge's, of equally near ones)."""
        px, py = x - self.ax, y - self.ay
        u = np.clip((px * self.dx + py * self.dy) / self.len2, 0.0, 1.0)
        ex, ey = px - u * self.dx, py - u * self.dy
        d2 = ex * ex + ey * ey
        k = int(np.argmin(d2))
        return math.sqrt(float(d2[k])), float(self.ax[k] + u[k] * self.dx[k]), float(self.ay[k] + u[k] * self.dy[k])

    def clearance(self, x: float, y: float) -> tuple[float, float, float]:
        """``(rho, ux, uy)``: the signed clearance from the region to keep out of (positive on
        the allowed side) and the unit normal pointing away from it, at ``(x, y)``."""
        d, fx, fy = self.boundary_distance(x, y)
        inside = self.contains(x, y)
        ex, ey = x - fx, y - fy
        n = math.hypot(ex, ey)
        if n <= 1e-9:  # on the boundary: the nearest edge's normal, away from the region to keep out of
            px, py = fx - self.ax, fy - self.ay
            u = np.clip((px * self.dx + py * self.dy) / self.len2, 0.0, 1.0)
            k = int(np.argmin(np.hypot(px - u * self.dx, py - u * self.dy)))
            ln = math.sqrt(float(self.len2[k]))
            ux, uy = float(self.dy[k]) / ln, float(-self.dx[k]) / ln  # outward for a counter-clockwise ring
            if (self._signed_area() < 0) != self.inverted:
                ux, uy = -ux, -uy
            return 0.0, ux, uy
        ux, uy = ex / n, ey / n
        # A point in the region to keep out of: the normal from it towards the nearest
        # boundary point points *out* of that region (away from the foot point's other side).
        bad = inside != self.inverted  # (no-fly: inside is bad; area: outside is bad)
        if bad:
            return -d, -ux, -uy
        return d, ux, uy

    def clearance_many(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Signed clearances of many points (positive on the allowed side), vectorised."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        px, py = x[:, None] - self.ax[None, :], y[:, None] - self.ay[None, :]
        u = np.clip((px * self.dx + py * self.dy) / self.len2, 0.0, 1.0)
        ex, ey = px - u * self.dx, py - u * self.dy
        d = np.sqrt((ex * ex + ey * ey).min(axis=1))
        bad = self.contains_many(x, y) != self.inverted
        signed: np.ndarray = np.where(bad, -d, d)
        return signed

    def _signed_area(self) -> float:
        x, y = self.ax, self.ay
        return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
