"""A deterministic, asyncio actor-based multi-UAV swarm simulator with fault injection.

Embedding::

    from swarm import Simulation, load_scenario
    sim = Simulation(load_scenario("paper-case1"), seed=1)
    sim.step()                  # or: await sim.run_until(100.0) in your own event loop
    print(sim.snapshot().coverage)
"""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _package_version

from swarm.errors import APIMisuseError, ScenarioError, SimulationError, SwarmError, UsageError
from swarm.kernel.results import RunResult
from swarm.kernel.simulation import Simulation, Snapshot
from swarm.reproduce import RerunResult, rerun
from swarm.scenario import Scenario, builtin_scenarios, load_scenario

try:
    # One version source: pyproject.toml's, as installed.
    __version__ = _package_version("uav-swarm-sim")
except PackageNotFoundError:  # imported from a source tree that was never installed
    __version__ = "0+unknown"

__all__ = [
    "APIMisuseError",
    "RerunResult",
    "RunResult",
    "Scenario",
    "ScenarioError",
    "Simulation",
    "SimulationError",
    "Snapshot",
    "SwarmError",
    "UsageError",
    "builtin_scenarios",
    "load_scenario",
    "rerun",
]
