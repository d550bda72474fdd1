"""The public test toolkit (needs the ``testing`` extra, which brings Hypothesis):

* :mod:`.strategies`: small valid scenarios, fleets, targets, threats, radio tables;
* :mod:`.fault_strategies`: every fault kind, whole fault schedules, link models;
* :mod:`.invariants`: checkers of safety, radio, map and assignment properties over event
  logs or live runs (these need no Hypothesis);
* :mod:`.stateful`: :class:`SwarmMachine`, a Hypothesis state machine driving one simulation;
* :mod:`.settings`: :data:`simulation_settings`, the Hypothesis settings a property over whole
  runs needs (no deadline, the ``too_slow`` health check suppressed, 50 examples).

Nothing outside this package imports Hypothesis: ``import swarm`` never needs it.
"""

try:
    import hypothesis  # noqa: F401
except ImportError as exc:  # pragma: no cover - depends on the environment
    raise ImportError(
        "swarm.testing needs Hypothesis: install the testing extra, pip install 'uav-swarm-sim[testing]'"
    ) from exc

from swarm.testing.fault_strategies import fault_schedules, faults, link_models
from swarm.testing.invariants import InvariantViolation, Monitor, Violation
from swarm.testing.settings import simulation_settings
from swarm.testing.stateful import SwarmMachine
from swarm.testing.strategies import scenario_documents, scenarios

__all__ = [
    "InvariantViolation",
    "Monitor",
    "SwarmMachine",
    "Violation",
    "fault_schedules",
    "faults",
    "link_models",
    "scenario_documents",
    "scenarios",
    "simulation_settings",
]
