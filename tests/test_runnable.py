"""Nothing a user can type kills a run without an error: line: values that validate one by one
but cannot run are refused with their key path, and a run too big for the machine is refused
before anything is allocated, naming the settings that drive its size."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from swarm import Simulation
from swarm.errors import ScenarioError
from swarm.kernel.memory import MemoryLimitError, estimate_memory
from swarm.scenario import apply_overrides, load_scenario

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("override, key", [
    ({"dt_s": 1e-6}, "dt_s"),
    ({"map.tau": 1e-300}, "map.tau"),
    ({"map.tau": 1e300}, "map.tau"),
    ({"map.prior_target_speed": 1e-300}, "map.prior_target_speed"),
    ({"uavs[0].join_s": 600.0}, "uavs[0].join_s"),
    ({"faults": [{"kind": "join", "uav": "A1", "at_s": 900.0}]}, "faults[0].at_s"),
])
def test_values_that_cannot_run_are_refused_with_their_key(override, key):
    with pytest.raises(ScenarioError) as err:
        apply_overrides(load_scenario("paper-case1"), override)
    assert err.value.key == key


@pytest.mark.parametrize("override", [{"area.cell_m": 1.0}, {"area.cell_m": 0.01},
                                      {"area.width_m": 5e8, "area.height_m": 5e8}])
def test_a_run_too_big_for_the_memory_limit_is_refused_before_allocating(override):
    sc = apply_overrides(load_scenario("paper-case1"), override)
    with pytest.raises(MemoryLimitError) as err:
        Simulation(sc, memory_limit_gb=8.0)
    message = str(err.value)
    assert "area.cell_m" in message and "area.width_m" in message and "--memory-limit" in message


def test_the_limit_can_be_raised_and_small_runs_pass():
    sc = apply_overrides(load_scenario("paper-case1"), {"area.cell_m": 25.0, "duration_s": 5.0})
    need = estimate_memory(sc).total / 1024**3
    with pytest.raises(MemoryLimitError):
        Simulation(sc, memory_limit_gb=need / 2)
    with Simulation(sc, memory_limit_gb=need * 2) as sim:
        sim.step()


def test_built_in_scenarios_fit_the_default_limit_of_a_24_gb_machine():
    for name in ("paper-fig11", "paper-case2", "bench-100", "bench-1000", "bench-dense-300"):
        assert estimate_memory(load_scenario(name)).total < 12 * 1024**3, name


# A `python -m swarm` subprocess each: the --set ones are slow (test_values_that_cannot_run_... checks
# the same refusals in process); the --memory-limit one, a CLI option, is the quick loop's.
@pytest.mark.parametrize("args, expected", [
    pytest.param(["--set", "area.cell_m=0.01"], "area.cell_m", marks=pytest.mark.slow),
    pytest.param(["--set", "map.tau=1e-300"], "map.tau", marks=pytest.mark.slow),
    pytest.param(["--set", "dt_s=1e-7"], "dt_s", marks=pytest.mark.slow),
    pytest.param(["--set", "uavs[2].join_s=1e6"], "uavs[2].join_s", marks=pytest.mark.slow),
    (["--set", "area.cell_m=1", "--memory-limit", "4"], "--memory-limit"),
])
def test_cli_absurd_inputs_are_one_error_line_exit_2(args, expected):
    r = subprocess.run([sys.executable, "-m", "swarm", "run", "paper-case1", "--duration", "5", *args],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    assert expected in lines[0]
