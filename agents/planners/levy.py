"""Lévy walk search: straight steps of power-law lengths in uniformly random directions.

The classic random search of foraging theory (Viswanathan et al., 1999): a step's length
``l`` has the density ``p(l) ~ l^-mu`` for ``l >= l_min`` (a Pareto law; ``mu`` about 2 is the
optimum for sparse targets that can be revisited), its direction is uniform. Here ``l_min`` is
the UAV's detection radius ``R_s`` and steps are capped at the area's longer side (a longer
draw is cut to it). It knows nothing of the map: this is the lower reference, what blind search
achieves with the same airframes.

* **Draws** come only from the UAV's own random stream (``view.rng``): per step, first the
  length (:func:`pareto_step`), then the heading; the lengths drawn are kept in ``steps``.
* **Turns.** A fixed-wing UAV cannot turn on the spot: a step starts with a turn onto its
  heading at the planning radius (the turn radius at full speed, times 1.15, the shorter way
  round), then flies straight. Step lengths count the straight part only.
* **The area.** A step that would leave the area is reflected at a line ``R_s / 2`` inside the
  edge, like a billiard ball (the heading's component across that edge is reversed, by a turn
  at the planning radius), for the rest of its length.
* **Threats.** A heading whose first 10 km pass within a known threat's ``d_max`` (as greedy
  rejects such headings) is drawn again, up to 16 times (the length is kept, so lengths stay a
  pure power law); waypoints are moved out of ``d_max`` (:mod:`.reference`).

It only searches (``surveils = "shared"``): with ``planner.surveillance = true`` the registry
wraps it in the shared surveillance logic (:mod:`agents.planners.surveillance`), which decides
when the UAV watches a target.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from agents.knowledge import KnownThreat
from agents.planners.base import Plan, PlanView
from agents.planners.reference import (
    Follower,
    Track,
    inside_threat,
    lookahead_m,
    planning_radius,
    push_out_of_threats,
    threat_rings,
)

if TYPE_CHECKING:
    from agents.planners.base import PlannerContext

__all__ = ["LevyPlanner", "pareto_step"]

_HEADING_TRIES = 16
_THREAT_LOOK_M = 10_000.0


def pareto_step(rng: np.random.Generator, mu: float, minimum: float, cap: float) -> float:
    """One step length: Pareto with density ``~ l^-mu`` above ``minimum`` (survival
    ``(l / minimum)^-(mu - 1)``), cut to ``cap``. One draw from ``rng``."""
    u = float(rng.random())
    return min(minimum * math.pow(1.0 - u, -1.0 / (mu - 1.0)), cap)  # (1 - u > 0: the same C pow as **)


class LevyPlanner:
    name = "levy"
    surveils = "shared"  # it searches; the shared logic watches (agents.planners.surveillance)

    def __init__(self, mu: float = 2.0, area_m: tuple[float, float] | None = None):
        if not 1.0 < mu <= 3.0:
            raise ValueError(f"mu must be in (1, 3] (l^-mu is a density only for mu > 1; beyond 3 the "
                             f"walk is Brownian): got {mu}")
        self.mu, self.area_m = mu, area_m
        self.follower: Follower | None = None
        self.steps: list[float] = []  # lengths drawn, in order
        self._threats: list[KnownThreat] = []

    @classmethod
    def from_context(cls, context: PlannerContext, mu: float = 2.0) -> LevyPlanner:
        return cls(mu, context.area_m)

    def _start(self, view: PlanView) -> None:
        self._area = self.area_m or (view.grid.width_m, view.grid.height_m)
        self._r = planning_radius(view)
        self._rs = view.kind.detect_radius
        self._rng = view.rng
        margin = 0.5 * self._rs
        w, h = self._area
        self._box = (margin, w - margin, margin, h - margin) if min(w, h) > 2 * margin else (0.0, w, 0.0, h)
        look = lookahead_m(view, self._r)
        track = Track(view.x, view.y, view.theta)
        self.follower = Follower(track, self._extend, self._r, look, rejoin_m=max(look, 0.5 * self._rs),
                                 join_window_m=6 * self._r)

    def _heading_ok(self, x: float, y: float, heading: float, length: float) -> bool:
        c, s = math.cos(heading), math.sin(heading)
        n = max(1, int(min(length, _THREAT_LOOK_M) // 500.0))
        return not any(inside_threat(x + 500.0 * i * c, y + 500.0 * i * s, self._threats) for i in range(1, n + 1))

    def _extend(self, track: Track) -> None:
        """Draw the next step and append it: a turn onto its heading, then the straight."""
        rng = self._rng
        length = pareto_step(rng, self.mu, self._rs, max(self._area))
        self.steps.append(length)
        x, y, _ = track.pen
        heading = float(rng.uniform(-math.pi, math.pi))
        for _ in range(_HEADING_TRIES - 1):
            if not self._threats or self._heading_ok(x, y, heading, length):
                break
            heading = float(rng.uniform(-math.pi, math.pi))
        track.turn_to(heading, self._r)
        lo_x, hi_x, lo_y, hi_y = self._box
        left = length
        for _ in range(64):  # straight, reflected at the box's sides
            px, py, ph = track.pen
            c, s = math.cos(ph), math.sin(ph)
            hit, axis = math.inf, ""
            if abs(c) > 1e-12:
                d = ((hi_x if c > 0 else lo_x) - px) / c
                hit, axis = d, "x"
            if abs(s) > 1e-12:
                d = ((hi_y if s > 0 else lo_y) - py) / s
                if d < hit:
                    hit, axis = d, "y"
            go = min(left, max(hit, 0.0))
            track.line(go)
            left -= go
            if left <= 1e-6:
                break
            track.turn_to(math.remainder(math.pi - ph if axis == "x" else -ph, 2 * math.pi), self._r)

    def plan(self, view: PlanView) -> Plan:
        if self.follower is None:
            self._start(view)
        f = self.follower
        assert f is not None
        self._rng = view.rng
        self._threats = threats = list(view.knowledge.threats.values())
        x, y = f.waypoint((view.x, view.y, view.theta), view.t, view.kind.speed_max,
                          rings=threat_rings(threats))
        if threats:
            x, y = push_out_of_threats(x, y, threats, (view.x, view.y))
        return Plan(x, y)
