"""Run folders are artifacts to trust: ``scenario.json`` reads back as the scenario that ran,
``swarm rerun`` re-runs a folder to the same event-log hash (or says where and why not), the
versions that ran are recorded, and a folder that cannot be re-run gets one ``error:`` line and
is left as it was. (Every built-in through every path that reads a run: test_every_builtin.py.)
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings

from swarm import Simulation, load_scenario, rerun
from swarm.cli import main
from swarm.events import log_sha256, read_events, split_provenance, with_provenance
from swarm.outputs import write_run
from swarm.provenance import versions
from swarm.scenario import builtin_scenarios, parse_scenario
from swarm.testing import scenarios
from swarm.testing.invariants import load_run_log


def _written(scenario) -> dict:
    """``scenario.json`` as a run writes it and a reader gets it back."""
    return json.loads(json.dumps(scenario.to_dict()))


# --- scenario.json round-trips ------------------------------------------------------------------------


@pytest.mark.parametrize("name", builtin_scenarios())
def test_every_builtin_round_trips_through_its_written_document(name):
    sc = load_scenario(name)
    assert parse_scenario(_written(sc), f"{name}/scenario.json", truncated=True) == sc
    assert parse_scenario(sc.to_document(), name) == sc


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sc=scenarios())
def test_generated_scenarios_round_trip(sc):
    assert parse_scenario(_written(sc), "scenario.json", truncated=True) == sc
    assert parse_scenario(sc.to_document(), "generated") == sc


def test_generated_missions_round_trip():
    """Geographic areas (lon/lat polygons), polygon no-fly zones, wind and endurance with a base
    (each drawn or not per example): the written document reads back as the scenario, as does
    its input document; and the examples did include every one of those tables."""
    drawn: Counter[str] = Counter()

    @settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow], database=None,
              derandomize=True)
    @given(sc=scenarios(geo=True, max_no_fly=2, wind=True, endurance=True, max_uavs=3))
    def round_trip(sc):
        drawn.update(k for k in ("geo", "no_fly", "wind", "endurance") if getattr(sc, k))
        assert parse_scenario(_written(sc), "scenario.json", truncated=True) == sc
        assert parse_scenario(sc.to_document(), "generated") == sc

    round_trip()
    assert set(drawn) == {"geo", "no_fly", "wind", "endurance"}, drawn


def test_a_geographic_size_that_contradicts_its_polygon_is_still_refused():
    doc = _written(load_scenario("geo-coast"))
    doc["area"]["width_m"] += 1000.0
    with pytest.raises(Exception, match=r"area\.width_m.*left out with \[geo\] area"):
        parse_scenario(doc, "scenario.json")


# --- swarm rerun ------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def case1_folder(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("case1")
    assert main(["run", "paper-case1", "--duration", "20", "--seed", "3", "--set", "radio.loss_base=0.1",
                 "--out", str(out), "--quiet", "--no-figures"]) == 0
    return out


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_rerun_of_a_run_folder_gives_the_same_hash(case1_folder, tmp_path, capsys):
    before = _snapshot(case1_folder)
    assert main(["rerun", str(case1_folder), "--out", str(tmp_path / "again"), "--quiet"]) == 0
    lines = capsys.readouterr().out.splitlines()
    recorded = json.loads((case1_folder / "metrics.json").read_text())["event_log_sha256"]
    assert lines[0].split()[:2] == ["original", recorded] and lines[1].split()[:2] == ["re-run", recorded]
    assert "equal" in lines[2]
    again = json.loads((tmp_path / "again" / "metrics.json").read_text())
    assert again["event_log_sha256"] == recorded and again["seed"] == 3
    assert _snapshot(case1_folder) == before  # the folder re-run is only read


def test_rerun_from_python_names_its_temporary_folder(case1_folder):
    res = rerun(case1_folder)
    assert res.equal and res.first_difference_s is None and not res.version_differences
    assert res.out.is_dir() and res.out != case1_folder
    assert (res.out / "events.msgpack").is_file() and (res.out / "scenario.json").is_file()


def test_a_changed_scenario_reruns_to_another_hash_and_says_where(case1_folder, tmp_path, capsys):
    folder = tmp_path / "changed"
    folder.mkdir()
    for name, data in _snapshot(case1_folder).items():
        (folder / name).write_bytes(data)
    doc = json.loads((folder / "scenario.json").read_text())
    doc["uavs"][0]["x_m"] += 50.0  # the first UAV starts elsewhere: its first pose differs
    (folder / "scenario.json").write_text(json.dumps(doc))
    assert main(["rerun", str(folder), "--out", str(tmp_path / "again"), "--quiet"]) == 1
    out = capsys.readouterr().out
    assert "DIFFERENT: the first tick whose events differ is t = 0 s" in out
    assert "versions: the same as the original's" in out
    res = rerun(folder, tmp_path / "again2")
    assert not res.equal and res.first_difference_s == 0.0


def test_versions_are_recorded_and_compared(case1_folder, tmp_path, capsys):
    now = versions()
    assert set(now) >= {"simulator", "python", "numpy"}
    assert json.loads((case1_folder / "metrics.json").read_text())["versions"] == now
    data = (case1_folder / "events.msgpack").read_bytes()
    provenance, events = split_provenance(data)
    assert provenance == now
    # Not hashed: the hash is of the events, the same with or without the record.
    assert log_sha256(data) == log_sha256(events) == json.loads((case1_folder / "metrics.json").read_text())["event_log_sha256"]
    assert list(read_events(data)) == list(read_events(events))
    # A folder written by other versions: the same hash, and the differences said.
    folder = tmp_path / "older"
    folder.mkdir()
    for name, blob in _snapshot(case1_folder).items():
        (folder / name).write_bytes(blob)
    (folder / "events.msgpack").write_bytes(with_provenance(events, {**now, "numpy": "1.26.0"}))
    assert main(["rerun", str(folder), "--out", str(tmp_path / "again"), "--quiet"]) == 0
    assert f"versions differ: numpy 1.26.0 -> {now['numpy']}" in capsys.readouterr().out


def test_an_embedded_run_stopped_early_reruns_to_where_it_stopped(tmp_path):
    with Simulation(load_scenario("paper-case1"), seed=5) as sim:
        sim.step(12)
        result = sim.result()
        write_run(result, tmp_path / "embedded", sim.scenario.to_dict())
    res = rerun(tmp_path / "embedded", tmp_path / "again")
    assert res.equal, res
    assert json.loads((tmp_path / "again" / "metrics.json").read_text())["sim_seconds"] == result.metrics["sim_seconds"]


def test_a_sweep_run_folder_and_a_geographic_one_rerun(tmp_path):
    out = tmp_path / "sweep"
    assert main(["sweep", "geo-coast", "--seeds", "1", "--planner", "dacmp,greedy", "--duration", "20", "--workers", "1",
                 "--out", str(out), "--quiet"]) == 0
    folders = sorted(p.parent for p in out.glob("runs/*/*/seed-*/metrics.json"))
    assert len(folders) == 2
    for folder in folders:
        sc, events = load_run_log(folder)
        assert sc.geo is not None and events[0].kind == "start"
        assert rerun(folder, tmp_path / folder.parent.parent.name).equal


def test_swarm_run_takes_a_scenario_json_and_points_a_run_folder_to_rerun(case1_folder, tmp_path, capsys):
    assert main(["run", str(case1_folder / "scenario.json"), "--seed", "3", "--out", str(tmp_path / "r"),
                 "--quiet", "--no-figures"]) == 0
    again = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert again["event_log_sha256"] == json.loads((case1_folder / "metrics.json").read_text())["event_log_sha256"]
    assert main(["run", str(case1_folder), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and f"swarm rerun {case1_folder}" in err[0]


def _damaged(case1_folder: Path, tmp_path: Path, how: str) -> Path:
    folder = tmp_path / how
    folder.mkdir()
    for name, blob in _snapshot(case1_folder).items():
        (folder / name).write_bytes(blob)
    if how == "no-scenario":
        (folder / "scenario.json").unlink()
    elif how == "no-events":
        (folder / "events.msgpack").unlink()
    elif how == "truncated-log":
        data = (folder / "events.msgpack").read_bytes()
        (folder / "events.msgpack").write_bytes(data[: len(data) // 2])
    elif how == "damaged-scenario":
        (folder / "scenario.json").write_text('{"seed": 3, "area": ')
    elif how == "wrong-scenario":
        (folder / "scenario.json").write_text(json.dumps({**json.loads((folder / "scenario.json").read_text()),
                                                          "dt_s": -1.0}))
    elif how == "no-events-at-all":
        (folder / "events.msgpack").write_bytes(b"")
    return folder


@pytest.mark.parametrize("how", ["no-scenario", "no-events", "truncated-log", "damaged-scenario", "wrong-scenario",
                                 "no-events-at-all"])
def test_a_folder_that_cannot_be_rerun_gets_one_error_line_and_is_left_alone(case1_folder, tmp_path, capsys, how):
    folder = _damaged(case1_folder, tmp_path, how)
    before = _snapshot(folder)
    assert main(["rerun", str(folder), "--out", str(tmp_path / "again")]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), captured.err
    assert str(folder) in err[0]
    assert _snapshot(folder) == before
    assert not (tmp_path / "again").exists()


def test_rerun_refuses_to_write_into_the_folder_it_reruns(case1_folder, capsys):
    before = _snapshot(case1_folder)
    assert main(["rerun", str(case1_folder), "--out", str(case1_folder)]) == 2
    assert "another folder" in capsys.readouterr().err
    assert _snapshot(case1_folder) == before


@pytest.mark.slow
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(sc=scenarios(max_uavs=3, max_duration_s=30))
def test_a_generated_scenario_written_by_reproduction_reruns_from_its_run_folder(sc, tmp_path_factory):
    """The toolkit's reproduction files (what ``reproducible()`` writes for a failing example)
    run with ``swarm run`` into a folder that ``swarm rerun`` reproduces."""
    from swarm.testing.strategies import reproduction

    tmp = tmp_path_factory.mktemp("repro")
    path, command = reproduction(sc, tmp)
    assert command.startswith(f"swarm run {path} --seed {sc.seed}")
    assert main(["run", str(path), "--seed", str(sc.seed), "--out", str(tmp / "run"), "--quiet", "--no-figures"]) == 0
    res = rerun(tmp / "run", tmp / "again")
    assert res.equal, (res.first_difference_s, path.read_text())
