"""Bring your own planner: a class outside the package, by module:Class, through swarm run,
swarm sweep (process pool) and the embedding API; wrong options and raising planners give one
error: line; metrics.json names the planner as given."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from swarm import Simulation, SimulationError
from swarm.errors import ScenarioError
from swarm.scenario import apply_overrides, load_scenario

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
EXAMPLE = "random_waypoint:RandomWaypoint"

BROKEN = '''
from agents.planners import Plan


class Raises:
    def plan(self, view):
        raise ValueError("no idea where to go")


class NotAPlan:
    def plan(self, view):
        return (1.0, 2.0)
'''


def _swarm(*args: str, extra_path: Path | None = None) -> subprocess.CompletedProcess:
    paths = [str(EXAMPLES)] + ([str(extra_path)] if extra_path else [])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(paths + [os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "swarm", *args], capture_output=True, text=True, env=env,
                          cwd=ROOT, timeout=600)


@pytest.fixture
def on_path(monkeypatch, tmp_path):
    (tmp_path / "broken_planners.py").write_text(BROKEN)
    for p in (str(EXAMPLES), str(tmp_path)):
        monkeypatch.syspath_prepend(p)
    return tmp_path


def test_embedding_api_runs_a_user_planner_by_name_and_by_class(on_path):
    with Simulation("paper-case1", planner=EXAMPLE, duration_s=60.0) as sim:
        metrics = sim.run().metrics
    assert metrics["planner"] == EXAMPLE and metrics["coverage"] > 0
    import random_waypoint

    with Simulation("paper-case1", planner=random_waypoint.RandomWaypoint, duration_s=60.0) as sim:
        again = sim.run().metrics
    assert again["event_log_sha256"] == metrics["event_log_sha256"]


def test_planner_options_reach_the_constructor_and_wrong_ones_name_the_key(on_path):
    # A module:Class set through overrides is a scenario setting: imported only when allowed.
    sc = apply_overrides(load_scenario("paper-case1"), {"planner.name": EXAMPLE, "planner.options": {"tries": 2}},
                         allow_planner_imports=[EXAMPLE])
    with Simulation(sc, duration_s=20.0) as sim:
        assert sim.actors[0].planner.tries == 2
    with pytest.raises(ScenarioError) as err:
        apply_overrides(load_scenario("paper-case1"), {"planner.name": EXAMPLE, "planner.options": {"trys": 2}},
                        allow_planner_imports=True)
    assert err.value.key == "planner.options.trys" and "did you mean 'tries'" in str(err.value)
    with pytest.raises(ScenarioError, match="planner.options.headings"):
        apply_overrides(load_scenario("paper-case1"), {"planner.name": "greedy", "planner.options": {"headings": 3}})


def test_a_raising_planner_stops_the_run_naming_planner_and_uav(on_path):
    with Simulation("paper-case1", planner="broken_planners:Raises", duration_s=20.0) as sim:
        with pytest.raises(SimulationError, match=r"UAV [AB]\d: planner broken_planners:Raises raised ValueError: no idea"):
            sim.run()
    with Simulation("paper-case1", planner="broken_planners:NotAPlan", duration_s=20.0) as sim:
        with pytest.raises(SimulationError, match="returned tuple, not a Plan"):
            sim.run()


@pytest.mark.slow  # `python -m swarm` subprocesses, one with a process pool
def test_cli_run_and_sweep_with_a_user_planner(tmp_path):
    out = tmp_path / "run"
    r = _swarm("run", "paper-case1", "--planner", EXAMPLE, "--duration", "60", "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    assert json.loads((out / "metrics.json").read_text())["planner"] == EXAMPLE
    sweep_dir = tmp_path / "sweep"
    r = _swarm("sweep", "paper-case1", "--planner", f"greedy,{EXAMPLE}", "--seeds", "2", "--duration", "30",
               "--workers", "2", "--out", str(sweep_dir), "--quiet")
    assert r.returncode == 0, r.stderr
    planners = {json.loads(p.read_text())["planner"] for p in sweep_dir.glob("runs/**/metrics.json")}
    assert planners == {"greedy", EXAMPLE}


@pytest.mark.slow  # four `python -m swarm` subprocesses (the in-process tests above are quick)
def test_cli_bad_planners_are_one_error_line_exit_2(tmp_path):
    (tmp_path / "broken_planners.py").write_text(BROKEN)
    cases = [
        (["run", "paper-case1", "--planner", "broken_planners:Raises", "--duration", "20"], "planner broken_planners:Raises"),
        (["run", "paper-case1", "--planner", "nowhere:Planner", "--duration", "20"], "cannot import module 'nowhere'"),
        (["run", "paper-case1", "--planner", "dacmq"], "did you mean 'dacmp'"),
        (["run", "paper-case1", "--planner", EXAMPLE, "--set", "planner.options.trys=3"], "planner.options.trys"),
    ]
    for args, expected in cases:
        r = _swarm(*args, extra_path=tmp_path)
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: "), (args, r.stderr)
        assert expected in lines[0] and "Traceback" not in r.stderr


def test_list_planners_shows_the_built_ins():
    r = _swarm("list", "--planners")
    assert r.returncode == 0 and "dacmp" in r.stdout and "greedy" in r.stdout


@pytest.mark.slow  # two `python -m swarm` subprocesses
def test_a_planner_registered_as_an_entry_point_is_found_by_name(tmp_path):
    # What `pip install` of a distribution declaring [project.entry-points."swarm.planners"] leaves.
    dist = tmp_path / "my_planners-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: my-planners\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[swarm.planners]\nwaypoints = {EXAMPLE}\n")
    r = _swarm("list", "--planners", extra_path=tmp_path)
    assert r.returncode == 0 and "waypoints" in r.stdout and "entry point" in r.stdout
    r = _swarm("run", "paper-case1", "--planner", "waypoints", "--duration", "20", "--json", extra_path=tmp_path)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["planner"] == "waypoints"
