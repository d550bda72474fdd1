"""The public planner API: what a planner sees and returns, and how one is chosen.

* :mod:`.base`: :class:`Plan` (next waypoint, mode, watched target), :class:`PlanView` (what a
  planner sees of its UAV: pose, type, own map, own knowledge, own random stream), the
  :class:`Planner` protocol (``plan(view) -> Plan``, optionally ``plan_many(views)`` to plan
  many UAVs in one call, as DACMP does: see :mod:`.batching`) and :class:`PlannerContext`,
  what a planner may know before the run;
* :mod:`.registry`: built-in names, ``package.module:Class`` and the ``swarm.planners``
  entry-point group;
* the planners: :mod:`.greedy` (the paper's baseline), :mod:`.dacmp` (the paper's planner),
  and the reference planners :mod:`.lawnmower`, :mod:`.formation` and :mod:`.levy` (they search,
  like greedy; with surveillance on, :mod:`.surveillance` adds the shared surveillance logic to
  them: docs/planners.md).

The deprecation policy of this API is in docs/embedding.md.
"""

from __future__ import annotations

from agents.planners.base import Plan, Planner, PlannerContext, PlannerError, PlanView
from agents.planners.formation import FormationPlanner
from agents.planners.greedy import GreedyPlanner
from agents.planners.lawnmower import LawnmowerPlanner
from agents.planners.levy import LevyPlanner
from agents.planners.registry import (
    BUILTIN,
    ENTRY_POINT_GROUP,
    available_planners,
    build_planner,
    resolve_planner,
)

__all__ = [
    "BUILTIN",
    "ENTRY_POINT_GROUP",
    "FormationPlanner",
    "GreedyPlanner",
    "LawnmowerPlanner",
    "LevyPlanner",
    "Plan",
    "PlanView",
    "Planner",
    "PlannerContext",
    "PlannerError",
    "available_planners",
    "build_planner",
    "resolve_planner",
]
