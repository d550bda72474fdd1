"""Lawnmower (boustrophedon) search: one strip of the area per UAV of a type, swept in passes.

The textbook coverage pattern (Choset's boustrophedon decomposition, in its simplest form: an
empty rectangle split into strips). The assignment is a priori, from what the planner knows
before the run (:class:`~agents.planners.base.PlannerContext`): the area
(``context.area_m``) and the UAV's rank among the UAVs of its type (``context.type_index`` of
``context.type_count``). Nothing is negotiated and nothing heard is used; a UAV whose
neighbour crashed does not take over its strip.

* **Strips.** The area is cut across its shorter side into ``type_count`` equal strips; the UAV
  of rank ``k`` owns strip ``k`` (rank 0 the strip at ``y = 0``, or ``x = 0`` when the area is
  taller than wide). Passes run along the longer side (fewer turns).
* **Passes.** The fewest passes at most ``2 R_s (1 - overlap)`` apart (``R_s`` = the UAV's
  detection radius) whose swaths tile the strip, evenly spaced (:func:`strip_passes`). A pass
  starts and ends where the detection circle still reaches the strip's corners, so no time is
  spent flying along the area's edge.
* **Turns.** Passes are joined by the shortest Dubins path at the planning radius (the turn
  radius at full speed, times 1.15); passes closer than two turn radii need a loop turn, so
  the next pass is chosen greedily by turn length among those not swept yet (for three passes
  2.8 km apart at a 2.6 km radius: 0, 2, 1 instead of 0, 1, 2). When every pass is swept, the
  sweep starts again from where the UAV is (re-sweeping the strip, in the same greedy order).
  Turns lie beyond the area's ends, and a loop turn bulges across by up to about half a turn
  radius beyond its pass (1.2 km in paper-fig11, inside the strip's 1.4 km margin there); the
  APF keeps UAVs of neighbouring strips apart where they meet.
* **Getting there.** At its first plan the UAV picks the pass, the direction and the entry
  point (within six turn radii of the pass's start) that it reaches by the shortest Dubins path
  (plus the turns its sweep will need from there), and flies that path; its transit may cross
  other strips.

It only searches (``surveils = "shared"``): with ``planner.surveillance = true`` the registry
wraps it in the shared surveillance logic (:mod:`agents.planners.surveillance`), which decides
when the UAV watches a target. Known threats: see :mod:`.reference` (the UAV follows a
threat's ring round it; no waypoint lies inside a ``d_max``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from agents.planners.base import Plan, PlanView
from agents.planners.reference import (
    Follower,
    Pose,
    Track,
    dubins_length,
    lookahead_m,
    planning_radius,
    push_out_of_threats,
    spread_offsets,
    threat_rings,
)

if TYPE_CHECKING:
    from agents.planners.base import PlannerContext

__all__ = ["LawnmowerPlanner", "Strip", "strip_passes", "turn_cost"]


@dataclass(frozen=True)
class Strip:
    """One UAV's strip, in the frame whose ``u`` axis runs along the passes and ``w`` across.

    ``swap``: the world's ``(x, y)`` is ``(w, u)`` (passes along ``y``; the area is taller than
    wide), else ``(u, w)``. The strip is ``[lo, hi]`` across; the passes are at ``passes``
    (``w``), flown from ``u_lo`` to ``u_hi`` or back."""

    swap: bool
    lo: float
    hi: float
    passes: tuple[float, ...]
    u_lo: float
    u_hi: float


def strip_passes(area_m: tuple[float, float], count: int, index: int, detect_radius: float,
                 overlap: float = 0.0) -> Strip:
    """Strip ``index`` of ``count`` and its passes (a pure function of its arguments)."""
    if not 0 <= index < count:
        raise ValueError(f"strip index {index} not in [0, {count})")
    width, height = area_m
    swap = height > width
    along, across = (height, width) if swap else (width, height)
    h = across / count
    lo, hi = index * h, (index + 1) * h if index < count - 1 else across
    passes = spread_offsets(lo, hi, 2.0 * detect_radius * (1.0 - overlap))
    spacing = (hi - lo) / len(passes)
    # The detection circle reaches a swath's corners from this far inside the area's edge.
    inset = math.sqrt(max(detect_radius ** 2 - (spacing / 2.0) ** 2, 0.0))
    u_lo, u_hi = min(inset, along / 2.0), max(along - inset, along / 2.0)
    return Strip(swap, lo, hi, tuple(passes), u_lo, u_hi)


def turn_cost(dw: float, r: float) -> tuple[float, float]:
    """The shortest way from the end of one pass to a pass ``dw`` across, flown back: Dubins
    from ``(0, 0, east)`` to ``(delta, dw, west)`` for the ``delta >= 0`` (how far past the
    end the next pass starts) minimising its length plus ``delta``. Returns (cost, delta)."""
    best = (math.inf, 0.0)
    for i in range(61):
        delta = 0.05 * i * r
        cost = dubins_length((0.0, 0.0, 0.0), (delta, dw, math.pi), r) + delta
        if cost < best[0] - 1e-6:
            best = (cost, delta)
    return best


class LawnmowerPlanner:
    name = "lawnmower"
    surveils = "shared"  # it searches; the shared logic watches (agents.planners.surveillance)

    def __init__(self, index: int = 0, count: int = 1, area_m: tuple[float, float] | None = None,
                 overlap: float = 0.0):
        if not 0 <= index < count:
            raise ValueError(f"index must be in [0, count): got index {index}, count {count}")
        if not 0.0 <= overlap < 1.0:
            raise ValueError(f"overlap must be in [0, 1): got {overlap}")
        self.index, self.count, self.area_m, self.overlap = index, count, area_m, overlap
        self.strip: Strip | None = None
        self.follower: Follower | None = None
        self.sequence: list[int] = []  # passes in the order flown (for inspection and tests)

    @classmethod
    def from_context(cls, context: PlannerContext, overlap: float = 0.0) -> LawnmowerPlanner:
        """Strip ``context.type_index`` of ``context.type_count`` of ``context.area_m``."""
        return cls(context.type_index, context.type_count, context.area_m, overlap)

    # --- frames -----------------------------------------------------------------------------

    def _local(self, x: float, y: float, heading: float) -> Pose:
        assert self.strip is not None
        return (y, x, math.pi / 2 - heading) if self.strip.swap else (x, y, heading)

    def _world(self, u: float, w: float) -> tuple[float, float]:
        assert self.strip is not None
        return (w, u) if self.strip.swap else (u, w)

    # --- the pattern ------------------------------------------------------------------------

    def _start(self, view: PlanView) -> None:
        area = self.area_m or (view.grid.width_m, view.grid.height_m)
        self.strip = st = strip_passes(area, self.count, self.index, view.kind.detect_radius, self.overlap)
        r = self._r = planning_radius(view)
        self._n_passes = len(st.passes)
        spacing = (st.hi - st.lo) / len(st.passes)
        self._turns = {j: turn_cost(j * spacing, r) for j in range(1, len(st.passes))}
        self._turns[0] = turn_cost(0.0, r)
        pose = self._local(view.x, view.y, view.theta)
        # The entry: pass, direction and point reached by the shortest Dubins path, counting the
        # turns of the sweep that follows from that pass.
        best: tuple[float, int, float] | None = None
        for j in range(len(st.passes)):
            order_cost = self._sweep_cost(j)
            for direction in (1.0, -1.0):
                u0 = st.u_lo if direction > 0 else st.u_hi
                length = st.u_hi - st.u_lo
                for i in range(0, int(min(length, 6 * r) // 250.0) + 1):
                    q = (u0 + direction * 250.0 * i, st.passes[j], 0.0 if direction > 0 else math.pi)
                    cost = dubins_length(pose, q, r) + order_cost
                    if best is None or cost < best[0] - 1e-6:
                        best = (cost, j, direction)
        assert best is not None
        _, j0, d0 = best
        track = Track(st.u_lo if d0 > 0 else st.u_hi, st.passes[j0], 0.0 if d0 > 0 else math.pi)
        self._pass, self._dir = j0, d0
        self._swept = {j0}
        self.sequence = [j0]
        track.line(st.u_hi - st.u_lo)
        look = lookahead_m(view, r)
        self.follower = Follower(track, self._extend, r, look, rejoin_m=max(look, 0.5 * view.kind.detect_radius),
                                 join_window_m=min(st.u_hi - st.u_lo, 6 * r))
        self.follower.join(pose, 0)

    def _next_pass(self, j: int, swept: set[int]) -> int:
        n = self._n_passes
        left = [i for i in range(n) if i not in swept] or [i for i in range(n) if i != j] or [j]
        return min(left, key=lambda i: (self._turns[abs(i - j)][0], abs(i - j), i))

    def _sweep_cost(self, j: int) -> float:
        swept, cost = {j}, 0.0
        while len(swept) < self._n_passes:
            i = self._next_pass(j, swept)
            cost += self._turns[abs(i - j)][0]
            swept.add(i)
            j = i
        return cost

    def _extend(self, track: Track) -> None:
        """The turn to the next pass and that pass."""
        st = self.strip
        assert st is not None
        n = len(st.passes)
        if len(self._swept) >= n:
            self._swept = {self._pass}  # the strip is done: sweep it again, from here
        nxt = self._next_pass(self._pass, self._swept)
        self._swept.add(nxt)
        self.sequence.append(nxt)
        d = self._dir
        _, delta = self._turns[abs(nxt - self._pass)]
        u_end = st.u_hi if d > 0 else st.u_lo
        start_u = u_end + d * delta
        track.dubins_to((start_u, st.passes[nxt], math.pi if d > 0 else 0.0), self._r)
        track.line(st.u_hi - st.u_lo + delta)
        self._pass, self._dir = nxt, -d

    # --- planning ---------------------------------------------------------------------------

    def plan(self, view: PlanView) -> Plan:
        if self.follower is None:
            self._start(view)
        f, st = self.follower, self.strip
        assert f is not None and st is not None
        threats = list(view.knowledge.threats.values())
        u, w = f.waypoint(self._local(view.x, view.y, view.theta), view.t, view.kind.speed_max,
                          rings=threat_rings(threats, st.swap))
        x, y = self._world(u, w)
        if threats:
            x, y = push_out_of_threats(x, y, threats, (view.x, view.y))
        return Plan(x, y)
