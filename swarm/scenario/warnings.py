"""Warnings about a valid scenario: settings that are legal but under which a documented rule
no longer holds. ``swarm validate`` and ``swarm run`` print each as one ``warning:`` line; the
run goes ahead."""

from __future__ import annotations

from agents.assignment import rule_breaks
from swarm.scenario.model import Scenario

__all__ = ["scenario_warnings"]


def scenario_warnings(scenario: Scenario) -> list[str]:
    """One line per problem, without the ``warning:`` prefix."""
    out: list[str] = []
    if scenario.planner.surveillance:
        flown = sorted({u.type for u in scenario.uavs})
        kinds = [s.uav_type(n) for n, s in sorted(scenario.uav_types.items()) if n in flown]
        out += [f"uav_types: {m}; the assignment rules (docs/modelling.md, \"Assignment rules\") do not cover "
                f"these types and the checkers do not judge them"
                for m in rule_breaks(kinds, scenario.planner.dacmp.field_unit_m)]
    return out
