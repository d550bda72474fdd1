"""The greedy baseline of the paper (section 4.2): myopic, level-0 only.

Among ``headings`` headings reachable within one replanning step (the current heading plus or
minus the largest turn the airframe can make in ``replan_s``), pick the one whose *next cell*
has the largest uncertainty ``q`` on the level-0 map. The next cell is where the leading edge of
the sensor footprint will be after one replanning step at the current speed, i.e. at distance
``v * replan_s + R_s`` along the heading: closer cells are inside the footprint and already
``q = 0``, so they cannot rank headings. No pyramid, no global guide, no Dubins weighting.
Ties (e.g. all cells unseen) are broken towards the straightest heading, then by the UAV's own
random stream. Headings whose next cell is outside the area or inside a known threat are
infeasible; if none is feasible the UAV turns towards the area centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from agents.planners.base import Plan, PlanView

if TYPE_CHECKING:
    from agents.planners.base import PlannerContext

# Tie-breaking weights, far below any real difference in q.
_STRAIGHT_BONUS = 1e-4
_JITTER = 1e-7


@dataclass
class GreedyPlanner:
    headings: int = 15
    name: str = "greedy"
    # It searches (the paper's section 4.2 compares search only). With planner.surveillance =
    # true the registry wraps it in the shared surveillance logic, DACMP's decision
    # (agents.planners.surveillance), so comparisons under surveillance are like for like.
    surveils = "shared"

    @classmethod
    def from_context(cls, context: PlannerContext) -> GreedyPlanner:
        """The planner of a scenario: its settings are the ``[planner.greedy]`` table."""
        return cls(headings=context.settings.greedy.headings)

    def plan(self, view: PlanView) -> Plan:
        k = view.kind
        turn = min(math.pi, k.turn_rate_max(view.v) * view.replan_s)
        offsets = np.linspace(-turn, turn, self.headings)
        ang = view.theta + offsets
        reach = view.v * view.replan_s + k.detect_radius
        px = view.x + reach * np.cos(ang)
        py = view.y + reach * np.sin(ang)
        g = view.grid
        feasible = (px >= 0) & (px <= g.width_m) & (py >= 0) & (py <= g.height_m)
        for th in view.knowledge.threats.values():
            feasible &= np.hypot(px - th.x, py - th.y) > th.d_max
        if not feasible.any():
            cx, cy = g.width_m / 2, g.height_m / 2
            d = math.hypot(cx - view.x, cy - view.y) or 1.0
            return Plan(view.x + reach * (cx - view.x) / d, view.y + reach * (cy - view.y) / d)
        ix, iy = g.cells_of(px, py)
        score = view.umap.q_at(ix, iy, view.t)
        score = score - _STRAIGHT_BONUS * np.abs(offsets) / (turn or 1.0)
        score = score + _JITTER * view.rng.random(self.headings)
        score[~feasible] = -np.inf
        best = int(np.argmax(score))
        return Plan(float(px[best]), float(py[best]))
