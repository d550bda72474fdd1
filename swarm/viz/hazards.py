"""What a map of a run draws besides the UAVs and targets: every hazard and fixed place of the
scenario (issue 33). One drawing for ``trajectories.png``, the report's figures and the
animation:

* the area polygon of a ``[geo]`` scenario: its outline, and the part of the bounding box
  outside it shaded (nothing to search there);
* the no-fly zones: ``[[threats]]`` circles and ``[[no_fly]]`` polygons, filled red, with their
  influence (where the repulsion acts) dotted;
* the ``[endurance]`` base: a black square.

Everything is read from the scenario as ``scenario.json`` holds it (local metres, or the
``[geo]`` polygons converted with the run's own frame: :mod:`swarm.geo`), so a run folder draws
the same as the run that wrote it.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from matplotlib.artist import Artist
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, PathPatch
from matplotlib.path import Path as MplPath

__all__ = ["Hazards", "draw_hazards", "hazards_of"]

ZONE_COLOUR = "red"
ZONE_ALPHA = 0.3
OUTSIDE_FILL = "#efe9d9"  # a pale land colour, hatched: unlike any scan map
OUTSIDE_HATCH = "////"
BASE_MARKER = "s"


@dataclass
class Hazards:
    """A scenario's hazards and fixed places in local metres (see the module docstring)."""

    circles: list[tuple[float, float, float, float]] = field(default_factory=list)  # x, y, radius, influence
    polygons: list[tuple[str, np.ndarray, float]] = field(default_factory=list)  # name, ring, influence_m
    area: np.ndarray | None = None  # the area polygon's ring, or None (the rectangle)
    size: tuple[float, float] = (0.0, 0.0)  # the area's bounding box (width, height)
    base: tuple[float, float] | None = None

    @property
    def zones(self) -> int:
        """How many no-fly zones (circles and polygons)."""
        return len(self.circles) + len(self.polygons)


def hazards_of(scenario: dict[str, Any], threats: Sequence[Any] = ()) -> Hazards:
    """The hazards of a scenario dict (``scenario.json``); ``threats`` are the run's circular
    threats (objects with ``x``, ``y``, ``radius``, ``d_max``: the world's or the replay's)."""
    area = scenario.get("area") or {}
    hz = Hazards(circles=[(float(t.x), float(t.y), float(t.radius), float(t.d_max)) for t in threats],
                 size=(float(area.get("width_m", 0.0)), float(area.get("height_m", 0.0))))
    geo, no_fly = scenario.get("geo"), scenario.get("no_fly") or []
    frame = None
    if geo or no_fly:
        from swarm.geo.frame import GeoProblem, frame_for
        from swarm.geo.geography import local_ring

        try:
            if geo and geo.get("area"):
                frame = frame_for(geo.get("crs", "EPSG:4326"), geo["area"], float(area.get("cell_m", 100.0)))
                hz.area = np.asarray(frame.area, dtype=np.float64)
            for z in no_fly:
                hz.polygons.append((str(z.get("name") or ""), local_ring(frame, z["polygon"], ("polygon",)),
                                    float(z.get("influence_m") or 0.0)))
        except (GeoProblem, KeyError, TypeError, ValueError) as exc:
            # (a scenario.json validated when it ran; a hand-edited one draws what it can, and says what not)
            warnings.warn(f"the area polygon or no-fly zones are not drawn: {exc}", stacklevel=2)
    e = scenario.get("endurance")
    if isinstance(e, dict) and e.get("x_m") is not None and e.get("y_m") is not None:
        hz.base = (float(e["x_m"]), float(e["y_m"]))
    return hz


def _outside_path(ring: np.ndarray, w: float, h: float, scale: float) -> MplPath:
    """The bounding box minus the polygon: a box and the ring turned the other way."""
    box = np.array([[0, 0], [w, 0], [w, h], [0, h], [0, 0]], dtype=np.float64)
    r = np.asarray(ring, dtype=np.float64)
    x, y = r[:, 0], r[:, 1]
    ccw = float(np.sum(x[:-1] * y[1:] - x[1:] * y[:-1])) > 0
    if ccw:
        r = r[::-1]
    verts = np.vstack([box, r]) * scale
    codes = ([MplPath.MOVETO] + [MplPath.LINETO] * 3 + [MplPath.CLOSEPOLY]
             + [MplPath.MOVETO] + [MplPath.LINETO] * (len(r) - 2) + [MplPath.CLOSEPOLY])
    return MplPath(verts, codes)


def draw_hazards(ax: Any, hz: Hazards, scale: float = 1.0, zorder: float = 1.0) -> tuple[list[Artist], list[Artist]]:
    """Draw ``hz`` on ``ax`` (coordinates times ``scale``: 1 for metres, 1e-3 for km). Returns
    the artists drawn and the legend handles for them."""
    artists: list[Artist] = []
    handles: list[Artist] = []
    if hz.area is not None:
        w, h = hz.size
        artists.append(ax.add_patch(PathPatch(_outside_path(hz.area, w, h, scale), fc=OUTSIDE_FILL, ec="0.72",
                                              hatch=OUTSIDE_HATCH, lw=0, zorder=zorder)))
        artists += ax.plot(hz.area[:, 0] * scale, hz.area[:, 1] * scale, "-", color="0.15", lw=1.1, zorder=zorder + 0.1)
        handles.append(Patch(fc=OUTSIDE_FILL, ec="0.72", hatch=OUTSIDE_HATCH, lw=0, label="outside the area polygon"))
    for x, y, r, d_max in hz.circles:
        artists.append(ax.add_patch(Circle((x * scale, y * scale), r * scale, color=ZONE_COLOUR, alpha=ZONE_ALPHA,
                                           lw=0, zorder=zorder)))
        artists.append(ax.add_patch(Circle((x * scale, y * scale), d_max * scale, fill=False, color=ZONE_COLOUR,
                                           ls=":", lw=0.7, zorder=zorder)))
    for _name, ring, influence in hz.polygons:
        artists += ax.fill(ring[:, 0] * scale, ring[:, 1] * scale, color=ZONE_COLOUR, alpha=ZONE_ALPHA, lw=0,
                           zorder=zorder)
        artists += ax.plot(ring[:, 0] * scale, ring[:, 1] * scale, "-", color=ZONE_COLOUR, lw=0.8, zorder=zorder)
        if influence > 0:
            import shapely

            edge = shapely.Polygon(ring).buffer(influence).exterior
            ex, ey = np.asarray(edge.xy)
            artists += ax.plot(ex * scale, ey * scale, ":", color=ZONE_COLOUR, lw=0.7, zorder=zorder)
    if hz.circles:
        handles.append(Patch(color=ZONE_COLOUR, alpha=0.35, label=f"threat ({len(hz.circles)})"))
    if hz.polygons:
        handles.append(Patch(color=ZONE_COLOUR, alpha=0.35, ec=ZONE_COLOUR, label=f"no-fly polygon ({len(hz.polygons)})"))
    if hz.base is not None:
        artists += ax.plot(hz.base[0] * scale, hz.base[1] * scale, BASE_MARKER, ms=8, mfc="black", mec="white",
                           mew=1.0, zorder=zorder + 3.5)
        handles.append(Line2D([], [], ls="", marker=BASE_MARKER, ms=8, mfc="black", mec="white", label="base"))
    return artists, handles
