"""Scenarios: the data that describes one run.

* :mod:`.model`: :class:`Scenario`, its checks across tables, and how a document becomes one
  (:func:`parse_scenario`, :func:`apply_overrides`);
* :mod:`.tables`: the hand-written tables (the world, ``[planner]``, ``[safety]``, ``[metrics]``,
  ``[recording]``); :mod:`.generated`: the tables generated from the simulator's dataclasses
  (``[radio]``, ``[[faults]]``, ``[planner.dacmp]``, ``[planner.apf]``); :mod:`.fields`: the
  building blocks of both, and the generator;
* :mod:`.loading`: built-in scenarios and TOML files; :mod:`.overrides`: dotted keys (``--set``);
* :mod:`.translation` and :mod:`.positions`: errors that name the key, what was found and what
  was expected, the first in document order;
* :mod:`.trust`: which ``module:Class`` planners may be imported; :mod:`.warnings`: values that
  run but look unintended; ``builtin/``: the built-in scenario files.
"""

from swarm.scenario.generated import FAULT_KINDS, ApfSettings, DacmpSettings, Fault, JoinFault, RadioSettings, fault_table
from swarm.scenario.loading import builtin_scenarios, load_scenario, scenario_from_toml
from swarm.scenario.model import Scenario, apply_overrides, parse_scenario
from swarm.scenario.overrides import parse_assignment
from swarm.scenario.tables import (
    DEFAULT_UAV_TYPES,
    Area,
    FleetSpec,
    GreedySettings,
    MapSettings,
    MetricsSettings,
    PlacedTarget,
    PlannerSettings,
    RecordingSettings,
    SafetySettings,
    TargetSettings,
    ThreatSpec,
    UavSpec,
    UavTypeSpec,
)
from swarm.scenario.warnings import scenario_warnings

__all__ = [
    "ApfSettings",
    "Area",
    "DEFAULT_UAV_TYPES",
    "DacmpSettings",
    "FAULT_KINDS",
    "fault_table",
    "Fault",
    "FleetSpec",
    "GreedySettings",
    "JoinFault",
    "MapSettings",
    "MetricsSettings",
    "RecordingSettings",
    "PlacedTarget",
    "PlannerSettings",
    "RadioSettings",
    "SafetySettings",
    "Scenario",
    "TargetSettings",
    "ThreatSpec",
    "UavSpec",
    "UavTypeSpec",
    "apply_overrides",
    "builtin_scenarios",
    "load_scenario",
    "parse_assignment",
    "parse_scenario",
    "scenario_from_toml",
    "scenario_warnings",
]


def __getattr__(name: str) -> type:
    """A fault kind's ``[[faults]]`` table by name (``DropFault``...: :func:`fault_table` by kind)."""
    from swarm.scenario import generated

    return generated.__getattr__(name)
