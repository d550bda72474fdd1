"""Issue 27: a scenario file is data. A planner it names as module:Class is imported only when
the user allowed it (typed --planner / planner=, a sweep's planners, --allow-planner-imports,
SWARM_ALLOW_PLANNER_IMPORTS=1; built-in and entry-point names always), and whatever is
imported is checked to be a planner class before anything in it is called. Issue 23 point 3:
options follow the planner that runs.

Every refusal is checked by its effect: a sentinel file that the refused code would create is
never created, and a module that would announce its import is not in sys.modules."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from agents.planners import PlannerContext, PlannerError, build_planner
from swarm import Simulation
from swarm.cli import main
from swarm.errors import ScenarioError
from swarm.experiments.sweep import execute, plan_runs
from swarm.scenario import apply_overrides, load_scenario
from swarm.scenario.trust import ALLOW_ENV
from swarm.testing.invariants import load_run_log
from swarm.testing.strategies import reproduction

ROOT = Path(__file__).resolve().parent.parent
SMALL = ROOT / "tests" / "data" / "faults-small.toml"
EXAMPLE = "random_waypoint:RandomWaypoint"  # examples/ on the path

# A module whose import creates SENTINEL and prints (it would be a valid planner otherwise),
# and a class without plan() whose constructor creates SENTINEL.
ON_IMPORT = '''
import pathlib
print("IMPORTED sentinel_on_import")
pathlib.Path({sentinel!r}).write_text("imported")
from agents.planners import Plan


class Planner:
    def plan(self, view):
        return Plan(view.x, view.y)
'''
NO_PLAN = '''
import pathlib


class NoPlan:
    def __init__(self, **options):
        pathlib.Path({sentinel!r}).write_text("called")
'''


@pytest.fixture(autouse=True)
def _no_env_opt_in(monkeypatch):
    monkeypatch.delenv(ALLOW_ENV, raising=False)


@pytest.fixture
def world(tmp_path, monkeypatch):
    """tmp_path with the two modules on sys.path (and examples/), the sentinel path, and a
    ``scenario(name, options)`` writing the small scenario with that planner."""
    sentinel = tmp_path / "PWNED"
    (tmp_path / "sentinel_on_import.py").write_text(ON_IMPORT.format(sentinel=str(sentinel)))
    (tmp_path / "no_plan_planner.py").write_text(NO_PLAN.format(sentinel=str(sentinel)))
    for p in (str(ROOT / "examples"), str(tmp_path)):
        monkeypatch.syspath_prepend(p)
    for mod in ("sentinel_on_import", "no_plan_planner"):
        monkeypatch.delitem(sys.modules, mod, raising=False)

    def scenario(name: str, options: dict | None = None, file: str = "evil.toml") -> Path:
        text = SMALL.read_text().replace('name = "greedy"', f"name = {json.dumps(name)}")
        if options:
            text += "\n[planner.options]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in options.items())
        path = tmp_path / file
        path.write_text(text)
        return path

    return sentinel, scenario


def evil_cases(sentinel: Path) -> list[tuple[str, dict]]:
    """The issue's file and its variants: each would create ``sentinel`` if called or imported."""
    return [
        ("subprocess:Popen", {"args": ["touch", str(sentinel)]}),
        ("os:system", {"command": f"touch {sentinel}"}),
        ("builtins:eval", {"source": f"open({str(sentinel)!r}, 'w')"}),
        ("sentinel_on_import:Planner", {}),
        ("no_plan_planner:NoPlan", {"x": 1}),
    ]


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


def test_a_file_naming_module_class_is_refused_by_validate_and_run_with_nothing_executed(world, capsys):
    sentinel, scenario = world
    for name, options in evil_cases(sentinel):
        path = scenario(name, options)
        for args in (["validate", str(path)], ["run", str(path), "--duration", "5", "--quiet"]):
            assert main(args) == 2, (name, args)
            line = _one_error_line(capsys)
            assert f"planner.name: found {name!r}" in line and "--allow-planner-imports" in line, line
            assert f"--planner {name}" in line and ALLOW_ENV in line
        with pytest.raises(ScenarioError) as err:
            Simulation(path)
        assert err.value.key == "planner.name"
        assert not sentinel.exists(), name
    assert "sentinel_on_import" not in sys.modules and "no_plan_planner" not in sys.modules
    assert "IMPORTED" not in capsys.readouterr().out


def test_what_is_allowed_is_checked_to_be_a_planner_class_before_anything_is_called(world, capsys):
    sentinel, scenario = world
    expected = {"subprocess:Popen": "Popen is not a planner (it has no plan(view) method)",
                "os:system": "'system' is a function, not a class",
                "builtins:eval": "'eval' is a function, not a class",
                "no_plan_planner:NoPlan": "NoPlan is not a planner"}
    for name, options in evil_cases(sentinel):
        if name not in expected:
            continue
        path = scenario(name, options)
        # the opt-in for files, and the same planner typed by the user: imported, checked, refused
        for args in (["run", str(path), "--duration", "5", "--quiet", "--allow-planner-imports"],
                     ["validate", str(path), "--allow-planner-imports"],
                     ["run", str(SMALL), "--planner", name, "--duration", "5", "--quiet",
                      *[f"--set=planner.options.{k}={json.dumps(v)}" for k, v in options.items()]]):
            assert main(args) == 2, (name, args)
            assert expected[name] in _one_error_line(capsys)
        with pytest.raises(ScenarioError, match="not a"):
            Simulation(SMALL, planner=name, planner_options=options)
        assert not sentinel.exists(), name


def test_missing_modules_and_names_are_one_error_line(world, capsys):
    _, scenario = world
    for name, words in (("nowhere_at_all:Planner", "cannot import module 'nowhere_at_all'"),
                        ("random_waypoint:Nope", "module 'random_waypoint' has no 'Nope'"),
                        ("random_waypoint:np", "'np' is a module, not a class"),
                        ("not a module:X", "expected package.module:Class")):
        assert main(["validate", str(scenario(name)), "--allow-planner-imports"]) == 2
        assert words in _one_error_line(capsys), name


def test_build_planner_checks_options_before_calling_the_class(world):
    sentinel, _ = world
    ctx = PlannerContext(uav=0, name="A1", type="A", type_index=0, type_count=1, area_m=(1e4, 1e4), cell_m=100.0,
                         levels=3, speed_max_by_type={"A": 50.0}, detect_radius_by_type={"A": 1500.0})
    with pytest.raises(PlannerError, match="not a planner"):
        build_planner("no_plan_planner:NoPlan", {}, ctx)
    with pytest.raises(PlannerError, match="unknown option 'bogus'"):
        build_planner(EXAMPLE, {"bogus": 1}, ctx)
    assert build_planner(EXAMPLE, {"tries": 2}, ctx).tries == 2
    assert not sentinel.exists()


def test_allowed_paths_run(world, capsys, monkeypatch, tmp_path):
    sentinel, scenario = world
    mine = scenario(EXAMPLE, {"tries": 2}, file="mine.toml")
    assert main(["run", str(mine), "--duration", "10", "--quiet"]) == 2  # a file alone: refused
    _one_error_line(capsys)
    # typed on the command line (the file's options are the typed planner's: same name)
    assert main(["run", str(mine), "--planner", EXAMPLE, "--duration", "10", "--quiet"]) == 0
    # the opt-in flag, and the environment variable
    assert main(["run", str(mine), "--duration", "10", "--quiet", "--allow-planner-imports"]) == 0
    assert main(["validate", str(mine), "--allow-planner-imports"]) == 0
    monkeypatch.setenv(ALLOW_ENV, "1")
    assert main(["validate", str(mine)]) == 0
    with Simulation(mine, duration_s=10.0) as sim:
        assert sim.actors[0].planner.tries == 2
    monkeypatch.delenv(ALLOW_ENV)
    # the Python call: by name (the file is then never asked), by class, or the opt-in
    with Simulation(mine, planner=EXAMPLE, duration_s=10.0) as sim:
        assert sim.actors[0].planner.tries == 2
    with Simulation(mine, duration_s=10.0, allow_planner_imports=True) as sim:
        assert sim.actors[0].planner.tries == 2
    # an opted-in module does run its import: the opt-in is real
    assert main(["run", str(scenario("sentinel_on_import:Planner")), "--duration", "5", "--quiet",
                 "--allow-planner-imports"]) == 0
    assert sentinel.exists()


def test_an_entry_point_name_in_a_file_needs_no_opt_in(world, tmp_path, monkeypatch, capsys):
    _, scenario = world
    dist = tmp_path / "my_planners-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: my-planners\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[swarm.planners]\nwaypoints = {EXAMPLE}\n")
    path = scenario("waypoints", {"tries": 3})
    assert main(["validate", str(path)]) == 0
    with Simulation(path, duration_s=10.0) as sim:
        assert sim.actors[0].planner.tries == 3


def test_a_file_whose_planner_is_replaced_is_never_asked_to_import(world, capsys):
    sentinel, scenario = world
    path = scenario("sentinel_on_import:Planner", {"x": 1})
    assert main(["run", str(path), "--planner", "greedy", "--duration", "5", "--quiet"]) == 0
    assert not sentinel.exists() and "sentinel_on_import" not in sys.modules


def test_sweep_workers_honour_the_decision_carried_by_the_run_spec(world):
    sentinel, scenario = world
    sc = load_scenario(SMALL)
    runs = plan_runs(sc, seeds=[0], planners=["greedy", "sentinel_on_import:Planner"], duration_s=5.0)
    assert sentinel.exists()  # the user named it: plan_runs validated (imported) it
    sentinel.unlink()
    del sys.modules["sentinel_on_import"]
    spec = next(s for s in runs if s.planner != "greedy")
    assert spec.allow_planner_imports == ("greedy", "sentinel_on_import:Planner")
    # A worker given a spec without the decision refuses it without importing anything.
    refused = execute(replace(spec, allow_planner_imports=()))
    assert "planner.name" in refused["error"] and "--allow-planner-imports" in refused["error"]
    assert not sentinel.exists() and "sentinel_on_import" not in sys.modules
    assert "files" in execute(spec) and sentinel.exists()  # given the decision, it imports and runs it
    sentinel.unlink()
    # A file's planner in the sweep's base scenario: refused unless opted in, then carried as True.
    with pytest.raises(ScenarioError, match="planner.name"):
        plan_runs(load_scenario(scenario(EXAMPLE), planner=EXAMPLE), seeds=[0], planners=["greedy"],
                  grid={"planner.name": ["no_plan_planner:NoPlan"]})
    assert not sentinel.exists()
    runs = plan_runs(sc, seeds=[0], planners=["greedy"], allow_planner_imports=True)
    assert runs[0].allow_planner_imports is True


def test_run_folders_and_repro_files_of_builtin_planners_replay_and_user_ones_need_allowing(world, tmp_path):
    out = tmp_path / "run"
    # (120 s: the small scenario's late joiner joins at 100 s, so the repro file loads back)
    assert main(["run", str(SMALL), "--duration", "120", "--out", str(out), "--quiet", "--no-figures"]) == 0
    scenario, events = load_run_log(out)
    assert scenario.planner.name == "greedy" and events
    path, command = reproduction(scenario, tmp_path / "repro")
    assert command == f"swarm run {path} --seed {scenario.seed}" and load_scenario(path) == scenario

    out = tmp_path / "mine"
    assert main(["run", str(SMALL), "--planner", EXAMPLE, "--duration", "120", "--out", str(out), "--quiet",
                 "--no-figures"]) == 0
    with pytest.raises(ScenarioError, match="planner.name"):
        load_run_log(out)
    scenario, _ = load_run_log(out, allow_planner_imports=[EXAMPLE])
    path, command = reproduction(scenario, tmp_path / "repro")
    assert command.endswith(f"--planner {EXAMPLE}")  # a repro file alone may not import it
    assert load_scenario(path, planner=EXAMPLE) == scenario


# --- issue 23 point 3: options follow the planner ---------------------------------------------

def test_run_checks_options_against_the_planner_that_runs(world, capsys):
    # paper-fig11's planner is dacmp, which takes no options: they are the typed planner's.
    assert main(["run", "paper-fig11", "--planner", EXAMPLE, "--set", "planner.options.tries=3",
                 "--duration", "10", "--quiet"]) == 0
    assert main(["run", "paper-fig11", "--planner", EXAMPLE, "--set", "planner.options.trys=3",
                 "--duration", "10", "--quiet"]) == 2
    line = _one_error_line(capsys)
    assert "planner.options.trys" in line and EXAMPLE in line and "did you mean 'tries'" in line


def test_options_written_for_one_planner_stay_with_it_when_another_runs(tmp_path):
    text = SMALL.read_text().replace('name = "greedy"', 'name = "lawnmower"\n[planner.options]\noverlap = 0.2')
    (tmp_path / "lawn.toml").write_text(text)
    with Simulation(tmp_path / "lawn.toml", planner="greedy", duration_s=5.0) as sim:
        sc = sim.scenario
    assert sc.planner.name == "greedy" and sc.planner.options_of() == {}
    assert sc.planner.options_for == {"lawnmower": {"overlap": 0.2}}
    back = apply_overrides(sc, {"planner.name": "lawnmower"}, truncated=True)
    assert back.planner.options_of() == {"overlap": 0.2}


def test_the_python_api_takes_options_beside_the_planner(world):
    import random_waypoint

    for planner in (EXAMPLE, random_waypoint.RandomWaypoint):
        with Simulation("paper-case1", planner=planner, planner_options={"tries": 3}, duration_s=10.0) as sim:
            assert sim.actors[0].planner.tries == 3
    with Simulation("paper-case1", planner="levy", planner_options={"mu": 1.5}, duration_s=10.0) as sim:
        assert sim.actors[0].planner.mu == 1.5
    with pytest.raises(ScenarioError) as err:
        Simulation("paper-case1", planner="levy", planner_options={"tries": 3})
    assert err.value.key == "planner.options.tries" and "planner.options_for.NAME.KEY" in str(err.value)


def test_a_sweep_takes_options_per_planner(world):
    sc = load_scenario("paper-case1")
    key = f"planner.options_for.{EXAMPLE}.tries"
    runs = plan_runs(sc, seeds=[0], planners=["greedy", EXAMPLE], grid={key: [2]}, duration_s=10.0)
    options = {s.planner: (s.scenario["planner"]["name"], s.scenario["planner"]["options_for"]) for s in runs}
    assert options == {"greedy": ("greedy", {EXAMPLE: {"tries": 2}}), EXAMPLE: (EXAMPLE, {EXAMPLE: {"tries": 2}})}
    for spec in runs:
        result = execute(spec)
        assert "files" in result, result
    # the same option for every planner: greedy takes none, and the error says how to aim it
    with pytest.raises(ScenarioError) as err:
        plan_runs(sc, seeds=[0], planners=["greedy", EXAMPLE], grid={"planner.options.tries": [2]})
    assert err.value.key == "planner.options.tries" and "'greedy'" in str(err.value)
    assert "planner.options_for.NAME.KEY" in str(err.value)
    # a dotted module path is quoted in a key, and errors name it the same way
    dotted = 'planner.options_for."examples.random_waypoint:RandomWaypoint".trys'
    with pytest.raises(ScenarioError) as err:
        plan_runs(sc, seeds=[0], planners=["greedy", "examples.random_waypoint:RandomWaypoint"], grid={dotted: [2]})
    assert err.value.key == dotted and "did you mean 'tries'" in str(err.value)


@pytest.mark.slow  # `python -m swarm` subprocesses (the issue's own check), one with a process pool
def test_cli_the_issues_file_and_a_per_planner_sweep(tmp_path):
    evil = tmp_path / "evil.toml"
    evil.write_text(SMALL.read_text().replace('name = "greedy"', 'name = "subprocess:Popen"')
                    + '\n[planner.options]\nargs = ["touch", "PWNED"]\n')
    env = {k: v for k, v in os.environ.items() if k != ALLOW_ENV}

    def swarm(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "swarm", *args], capture_output=True, text=True, cwd=tmp_path,
                              env={**env, "PYTHONPATH": str(ROOT)}, timeout=600)

    for command in ("validate", "run"):
        r = swarm(command, str(evil))
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: "), r.stderr
        assert "--allow-planner-imports" in lines[0]
    assert not (tmp_path / "PWNED").exists()
    real = "examples.random_waypoint:RandomWaypoint"
    r = swarm("run", str(evil), "--planner", real, "--duration", "10", "--quiet")
    assert r.returncode == 0, r.stderr
    out = tmp_path / "sweep"
    r = swarm("sweep", "paper-fig11", "--planner", f"greedy,{real}", "--set",
              f'planner.options_for."{real}".tries=2', "--seeds", "2", "--duration", "30", "--workers", "2",
              "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    seen = {}
    for path in out.glob("runs/**/scenario.json"):
        planner = json.loads(path.read_text())["planner"]
        seen.setdefault(planner["name"], planner["options_for"])
    assert seen == {"greedy": {real: {"tries": 2}}, real: {real: {"tries": 2}}}
    assert len(list(out.glob("runs/**/metrics.json"))) == 4


def test_sweep_fingerprints_of_runs_without_per_planner_options_are_what_they_were():
    # Folders of sweeps run before planner.options_for existed must resume (sweep.json).
    import hashlib

    from swarm.experiments.sweep import _dumps, fingerprint

    spec = plan_runs(load_scenario("paper-case1"), seeds=[3], planners=["greedy"], duration_s=10.0)[0]
    assert spec.scenario["planner"]["options_for"] == {}
    old_doc = {**spec.scenario, "planner": {k: v for k, v in spec.scenario["planner"].items() if k != "options_for"}}
    old = hashlib.sha256(_dumps([old_doc, "greedy", 3, 10.0], sort_keys=True, default=str).encode()).hexdigest()
    assert fingerprint(spec) == old
    with_options = plan_runs(load_scenario("paper-case1"), seeds=[3], planners=["greedy"], duration_s=10.0,
                             grid={"planner.options_for.levy.mu": [1.5]})[0]
    assert fingerprint(with_options) != old


def test_run_takes_the_planner_once(capsys):
    assert main(["run", "paper-case1", "--planner", "greedy", "--set", "planner.name=levy"]) == 2
    assert "give the planner once, with --planner" in _one_error_line(capsys)
    # as a --set value, a module:Class is a scenario setting: it needs the opt-in
    assert main(["run", "paper-case1", "--set", f"planner.name={EXAMPLE}", "--duration", "5", "--quiet"]) == 2
    assert "--allow-planner-imports" in _one_error_line(capsys)


def test_the_issues_file_verbatim_is_one_error_line(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "evil.toml").write_text('[planner]\nname = "subprocess:Popen"\n[planner.options]\n'
                                        'args = ["touch", "PWNED"]\n')
    for command in ("validate", "run"):
        assert main([command, "evil.toml"]) == 2
        line = _one_error_line(capsys)
        assert line.startswith("error: evil.toml: planner.name: found 'subprocess:Popen'") and "--allow-planner" in line
    assert not (tmp_path / "PWNED").exists()
