"""Planners behind one interface (:mod:`agents.planners.base`); pick one by name."""

from __future__ import annotations

from typing import TYPE_CHECKING

from agents.planners.base import Plan, Planner, PlannerError, PlanView
from agents.planners.greedy import GreedyPlanner

if TYPE_CHECKING:
    from swarm.scenario.model import PlannerSettings

PLANNER_NAMES = ("greedy", "dacmp")


def make_planner(settings: PlannerSettings, *, levels: int = 7, speed_max_by_type: dict[str, float] | None = None,
                 detect_radius_by_type: dict[str, float] | None = None) -> Planner:
    """Build the planner named by a scenario's ``[planner]`` table (one instance per UAV)."""
    name = settings.name
    if name == "greedy":
        return GreedyPlanner(headings=settings.greedy.headings)
    if name == "dacmp":
        from agents.planners.dacmp.planner import DacmpPlanner

        return DacmpPlanner.from_settings(settings, levels, speed_max_by_type, detect_radius_by_type)
    raise ValueError(f"unknown planner {name!r}; expected one of {', '.join(PLANNER_NAMES)}")


__all__ = ["PLANNER_NAMES", "GreedyPlanner", "Plan", "PlanView", "Planner", "PlannerError", "make_planner"]
