"""Hypothesis settings for properties whose examples are whole simulations.

Hypothesis's defaults suit fast, pure functions: a 200 ms deadline per example, a health check
that fails a test whose data take long to generate, and 100 examples. An example of a
simulation-backed property is a whole run (a generated scenario validated by the project's
model, then tens of simulated seconds with faults): it may take longer than 200 ms on a busy
machine, and Hypothesis then reports ``DeadlineExceeded`` or a ``FlakyFailure`` that says nothing
about the property. Use :data:`simulation_settings` instead::

    from hypothesis import given
    from swarm.testing.settings import simulation_settings
    from swarm.testing.strategies import scenarios

    @simulation_settings
    @given(scenarios(max_uavs=3))
    def test_my_property(scenario):
        ...

    TestMyMachine = MyMachine.TestCase            # a SwarmMachine subclass
    TestMyMachine.settings = simulation_settings

or load the registered profile once, e.g. in your ``conftest.py``:
``settings.load_profile("swarm-simulation")`` (:data:`PROFILE`).

What they are:

* ``deadline=None``: no per-example time limit (a run is not a microbenchmark);
* ``suppress_health_check``: :data:`SIMULATION_HEALTH_CHECKS`, the health checks such tests
  trip by design: ``too_slow`` (generating and validating a scenario with its fault schedule
  is slow next to Hypothesis's budget for data generation);
* ``max_examples=50``: half Hypothesis's default, a budget of about 5-25 s on one core for
  the documented property (runs of 20-60 simulated seconds with up to 4 UAVs). Raise it for
  a deeper search: ``settings(simulation_settings, max_examples=500)``.

Everything else comes from Hypothesis's built-in ``default`` profile (random examples, failures
kept in ``.hypothesis/``), whatever profile is loaded when this module is imported.
This project's own test profiles (``tests/conftest.py``) are built on these settings.
"""

from __future__ import annotations

import swarm.testing._hypothesis  # noqa: F401  (first: a clear error without Hypothesis)

# isort: split

from hypothesis import HealthCheck, settings

__all__ = ["PROFILE", "SIMULATION_HEALTH_CHECKS", "simulation_settings"]

#: The health checks a property over whole simulation runs trips by design.
SIMULATION_HEALTH_CHECKS: tuple[HealthCheck, ...] = (HealthCheck.too_slow,)

#: Settings for a property (or a state machine) whose examples are simulation runs.
simulation_settings = settings(settings.get_profile("default"), deadline=None,
                               suppress_health_check=SIMULATION_HEALTH_CHECKS, max_examples=50)

#: The name :data:`simulation_settings` is registered under (``settings.load_profile(PROFILE)``).
PROFILE = "swarm-simulation"
settings.register_profile(PROFILE, simulation_settings)
