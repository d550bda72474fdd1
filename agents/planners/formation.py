"""Formation sweep: the UAVs of a type fly side by side as one wide front, band by band.

The textbook line-abreast search (a parallel sweep by several units abreast, as in the IAMSAR
Manual, Vol. II): lanes side by side, the front sweeps a band of the area, turns, sweeps the
next band, and when the area is done sweeps it again.

* **Lanes.** The UAVs of one type form one front (types fly at different speeds, so each type
  has its own front, and every front sweeps the whole area). The UAV of rank ``i`` among its
  type (``context.type_index`` of ``context.type_count``) flies lane ``i``; lane ``0`` is the one
  nearest ``y = 0`` (``x = 0`` when the area is taller than wide: the front then moves along
  ``y``). Lanes are at most ``2 R_s (1 - overlap)`` apart (``R_s`` = the detection radius),
  spread so the bands tile the area: ``bands = ceil(H / (n 2 R_s (1 - overlap)))`` bands of
  ``n`` lanes ``H / (bands n)`` apart (``H`` the area's side across the front).
* **Bands.** The front sweeps a band from one edge of the area to the other, then all its UAVs
  make the same turn (a parallel shift: each UAV's path is its neighbour's translated by one
  lane, so UAVs that are abreast stay exactly one lane apart through the turn) onto the next
  band, flown the other way. Order: the starting band, the bands on its side with fewer bands,
  the rest, then back and forth over all bands.
* **Keeping together without communication.** Nothing is heard or negotiated. Each UAV derives
  the front from its own start and its lane alone: the front starts where this UAV is, as if it
  were already in its lane (the band whose lane ``i`` is nearest its start, the direction along
  the front's axis nearest its heading, east or north on a tie, the start's position along that
  axis) and advances at the type's full speed from the UAV's first plan on. UAVs that start in a
  line abreast in lane order, such as paper-fig11's six UAVs, therefore all compute the same
  front from the time alone; each flies to its lane (if it starts more than about a replanning
  step off it, by the Dubins path that leaves it least behind its slot) and then keeps pace
  with its slot, the point of its lane where the front is now: its waypoint is a lookahead
  past the later of its slot and its own progress, so a UAV that fell behind (its join,
  collision or threat avoidance) cuts the inside of the next turns until it is back in its
  slot. A UAV cannot slow down (search flies at full speed), so one that is ahead stays ahead.
  UAVs that start elsewhere (paper-case2: on opposite edges, heading towards each other) derive
  different fronts and each sweeps its own; collision avoidance is the APF's, as for every
  planner.

It only searches (``surveils = "shared"``): with ``planner.surveillance = true`` the registry
wraps it in the shared surveillance logic (:mod:`agents.planners.surveillance`), which decides
when the UAV watches a target. Known threats: see :mod:`.reference`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

from agents.planners.base import Plan, PlanView
from agents.planners.lawnmower import turn_cost
from agents.planners.reference import (
    Follower,
    Pose,
    Track,
    lookahead_m,
    planning_radius,
    push_out_of_threats,
    threat_rings,
)

if TYPE_CHECKING:
    from agents.planners.base import PlannerContext

__all__ = ["FormationPlanner", "Front", "band_order", "front_geometry"]


@dataclass(frozen=True)
class Front:
    """The front's geometry in the frame whose ``u`` axis runs along the front's motion and
    ``w`` across it (``swap``: the world's ``(x, y)`` is ``(w, u)``)."""

    swap: bool
    lanes: int
    bands: int
    spacing: float  # between lanes
    u_lo: float  # passes run between these (the detection circle reaches the area's corners)
    u_hi: float

    def lane_w(self, band: int, lane: int) -> float:
        return (band * self.lanes + lane + 0.5) * self.spacing


def front_geometry(area_m: tuple[float, float], lanes: int, detect_radius: float, overlap: float = 0.0) -> Front:
    width, height = area_m
    swap = height > width
    along, across = (height, width) if swap else (width, height)
    bands = max(1, math.ceil(across / (lanes * 2.0 * detect_radius * (1.0 - overlap)) - 1e-9))
    spacing = across / (bands * lanes)
    inset = math.sqrt(max(detect_radius ** 2 - (spacing / 2.0) ** 2, 0.0))
    return Front(swap, lanes, bands, spacing, min(inset, along / 2.0), max(along - inset, along / 2.0))


def band_order(bands: int, first: int) -> Iterator[int]:
    """The bands in the order the front sweeps them, for ever: ``first``, the side of it with
    fewer bands (outwards), the other side, then back and forth over all bands."""
    up, down = list(range(first + 1, bands)), list(range(first - 1, -1, -1))
    sides = (down, up) if len(down) < len(up) else (up, down)
    yield first
    yield from sides[0]
    yield from sides[1]
    last = (sides[1] or sides[0] or [first])[-1]
    if bands == 1:
        while True:
            yield 0
    step = -1 if last == bands - 1 else 1
    b = last
    while True:
        if not 0 <= b + step < bands:
            step = -step
        b += step
        yield b


class FormationPlanner:
    name = "formation"
    surveils = "shared"  # it searches; the shared logic watches (agents.planners.surveillance)

    def __init__(self, lane: int = 0, lanes: int = 1, area_m: tuple[float, float] | None = None,
                 overlap: float = 0.0):
        if not 0 <= lane < lanes:
            raise ValueError(f"lane must be in [0, lanes): got lane {lane}, lanes {lanes}")
        if not 0.0 <= overlap < 1.0:
            raise ValueError(f"overlap must be in [0, 1): got {overlap}")
        self.lane, self.lanes, self.area_m, self.overlap = lane, lanes, area_m, overlap
        self.front: Front | None = None
        self.follower: Follower | None = None
        self.bands_flown: list[int] = []  # (for inspection and tests)

    @classmethod
    def from_context(cls, context: PlannerContext, overlap: float = 0.0) -> FormationPlanner:
        """Lane ``context.type_index`` of a front of ``context.type_count`` lanes over ``context.area_m``."""
        return cls(context.type_index, context.type_count, context.area_m, overlap)

    def _local(self, x: float, y: float, heading: float) -> Pose:
        assert self.front is not None
        return (y, x, math.pi / 2 - heading) if self.front.swap else (x, y, heading)

    def _world(self, u: float, w: float) -> tuple[float, float]:
        assert self.front is not None
        return (w, u) if self.front.swap else (u, w)

    def _start(self, view: PlanView) -> None:
        area = self.area_m or (view.grid.width_m, view.grid.height_m)
        self.front = fr = front_geometry(area, self.lanes, view.kind.detect_radius, self.overlap)
        self._r = planning_radius(view)
        self._v = view.kind.speed_max
        self._t0 = view.t
        u, w, heading = self._local(view.x, view.y, view.theta)
        along = area[1] if fr.swap else area[0]
        band = min(range(fr.bands), key=lambda b: (abs(w - fr.lane_w(b, self.lane)), b))
        self._dir = 1.0 if math.cos(heading) > -1e-6 else -1.0
        self._order = band_order(fr.bands, band)
        self._band = next(self._order)
        self.bands_flown = [self._band]
        u0 = min(max(u, 0.0), along)
        track = Track(u0, fr.lane_w(self._band, self.lane), 0.0 if self._dir > 0 else math.pi)
        track.line((fr.u_hi - u0) if self._dir > 0 else (u0 - fr.u_lo))
        look = lookahead_m(view, self._r)
        self.follower = Follower(track, self._extend, self._r, look, rejoin_m=max(look, 0.5 * view.kind.detect_radius),
                                 join_window_m=min(fr.u_hi - fr.u_lo, 6 * self._r))

    def _extend(self, track: Track) -> None:
        """The front's turn onto its next band, and that band's pass."""
        fr = self.front
        assert fr is not None
        nxt = next(self._order)
        self.bands_flown.append(nxt)
        d = self._dir
        dw = fr.lane_w(nxt, 0) - fr.lane_w(self._band, 0)  # the same for every lane
        _, delta = turn_cost(abs(dw), self._r)
        u_end = fr.u_hi if d > 0 else fr.u_lo
        track.dubins_to((u_end + d * delta, fr.lane_w(nxt, self.lane), math.pi if d > 0 else 0.0), self._r)
        track.line(fr.u_hi - fr.u_lo + delta)
        self._band, self._dir = nxt, -d

    def slot(self, t: float) -> int:
        """The track point where the front is at time ``t`` (this UAV's slot)."""
        assert self.follower is not None
        return int(self._v * (t - self._t0) / self.follower.track.ds)

    def plan(self, view: PlanView) -> Plan:
        if self.follower is None:
            self._start(view)
        f, fr = self.follower, self.front
        assert f is not None and fr is not None
        threats = list(view.knowledge.threats.values())
        u, w = f.waypoint(self._local(view.x, view.y, view.theta), view.t, self._v, sync_k=self.slot(view.t),
                          rings=threat_rings(threats, fr.swap))
        x, y = self._world(u, w)
        if threats:
            x, y = push_out_of_threats(x, y, threats, (view.x, view.y))
        return Plan(x, y)
