"""The public test toolkit (needs the ``testing`` extra, which brings Hypothesis):

* :mod:`.strategies`: small valid scenarios, fleets, targets, threats, radio tables;
* :mod:`.fault_strategies`: every fault kind, whole fault schedules, link models;
* :mod:`.invariants`: checkers of safety, radio, map and assignment properties over event
  logs or live runs (these need no Hypothesis: ``swarm paper`` uses them);
* :mod:`.stateful`: :class:`SwarmMachine`, a Hypothesis state machine driving one simulation;
* :mod:`.oracle`: the tick plane against the per-actor code it replaces, two simulations in
  lockstep compared every tick (needs no Hypothesis either);
* :mod:`.settings`: :data:`simulation_settings`, the Hypothesis settings a property over whole
  runs needs (no deadline, the ``too_slow`` health check suppressed, 50 examples).

Nothing outside this package imports Hypothesis: ``import swarm`` never needs it, nor do the
checkers; the strategies and the state machine say so when it is missing.
"""

from swarm.testing.invariants import InvariantViolation, Monitor, Violation

try:
    import hypothesis  # noqa: F401
except ImportError:  # the checkers above work without it; the rest says what it needs when used
    def __getattr__(name: str) -> object:
        if name in __all__:
            import swarm.testing._hypothesis  # noqa: F401  (raises the ImportError naming the extra)
        raise AttributeError(name)
else:
    from swarm.testing.fault_strategies import fault_schedules, faults, link_models
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
