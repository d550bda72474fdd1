"""Sweeps take every value `run` takes (numbers, inf, strings, arrays, tables), name their
folders safely, write strict JSON and a one-row-per-run table."""

from __future__ import annotations

import csv
import json
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from swarm.cli import main
from swarm.experiments.sweep import load_runs, slug, strict_json
from swarm.viz.report import fmt


def _strict(path):
    def refuse(constant):
        raise ValueError(f"{path}: non-strict JSON constant {constant}")

    return json.loads(path.read_text(), parse_constant=refuse)


@pytest.mark.slow  # `swarm sweep` with its process pool, twice
def test_sweep_over_inf_and_tables_writes_strict_json_and_runs_csv(small_scenario_path, tmp_path, capsys):
    out = tmp_path / "sw"
    args = ["sweep", str(small_scenario_path), "--seeds", "2", "--planner", "greedy", "--duration", "10",
            "--set", "radio.range_m=5000,inf", "--set", 'faults=[{kind="drop",rate=0.5,start_s=0.0}]',
            "--out", str(out), "--quiet"]
    assert main(args) == 0
    summary = _strict(out / "summary.json")
    assert summary["runs_finished"] == 4 and summary["runs_failed"] == 0
    assert {g["settings"]["radio.range_m"] for g in summary["groups"]} == {5000, "inf"}
    assert (out / "report.html").is_file()
    with (out / "runs.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 4
    assert {r["radio.range_m"] for r in rows} == {"5000", "inf"}
    assert all(r["status"] == "ok" and r["planner"] == "greedy" and "coverage" in r for r in rows)
    assert json.loads(rows[0]["faults"]) == [{"kind": "drop", "rate": 0.5, "start_s": 0.0}]
    for metrics_path in out.glob("runs/**/metrics.json"):
        settings = _strict(metrics_path)["settings"]
        assert set(settings) == {"radio.range_m", "faults"}
    records = load_runs(out)
    assert len(records) == 4
    # re-running resumes: nothing runs again, nothing crashes
    assert main(args) == 0
    assert "4 already finished, 0 ran" in capsys.readouterr().err


def test_slugs_are_safe_and_distinct():
    a = slug([("faults", [{"kind": "drop", "rate": 0.5}])])
    b = slug([("faults", [{"kind": "drop", "rate": 0.25}])])
    assert a != b and "/" not in a and '"' not in a and len(a) < 100
    assert slug([("radio.range_m", math.inf)]) == "radio.range_m=inf"
    assert slug([("radio.loss_base", 0.3)]) == "radio.loss_base=0.3"


values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=8),
    lambda children: st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=4), children, max_size=3),
    max_leaves=8,
)


@given(values)
def test_every_value_formats_and_encodes(value):
    assert isinstance(fmt(value), str)
    json.dumps(strict_json(value), allow_nan=False)
    assert isinstance(slug([("k", value)]), str)


# --- the tables carry every number of metrics.json (issue 32) ------------------------------------

RW = "examples.random_waypoint:RandomWaypoint"
# An energy budget and radio drops, so that the endurance block and faults_applied are there.
ENDURANCE = {"x_m": 20000.0, "y_m": 22000.0, "types": {"B": {"capacity_wh": 600.0, "power_min_w": 3000.0},
                                                        "A": {"capacity_wh": 600.0, "power_min_w": 1000.0}}}
DROPS = [{"kind": "drop", "rate": 0.3, "start_s": 0.0}]


def _numeric_leaves(table, prefix=""):
    """Every number of a metrics.json under its dotted path (this test's own walk of the file,
    not the sweep's): nested tables' keys joined with dots; arrays, strings, booleans and
    nulls are not numbers."""
    for k, v in table.items():
        if isinstance(v, dict):
            yield from _numeric_leaves(v, f"{prefix}{k}.")
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            yield f"{prefix}{k}", v


@pytest.fixture(scope="module")
def tiny_sweep(tmp_path_factory):
    """paper-case1 for 30 s, 2 seeds, dacmp and the example planner (a module:Class name),
    paired differences against the example planner."""
    from concurrent.futures import ThreadPoolExecutor

    from swarm.experiments.sweep import sweep
    from swarm.scenario import load_scenario

    out = tmp_path_factory.mktemp("tables") / "sw"
    with ThreadPoolExecutor(2) as ex:
        res = sweep(load_scenario("paper-case1"), out, seeds=2, planners=["dacmp", RW], duration_s=30.0,
                    grid={"endurance": [ENDURANCE], "faults": [DROPS]}, executor=ex, baseline=RW)
    assert res.ran == 4 and not res.failed
    return out


def test_runs_csv_has_every_number_of_every_runs_metrics_json(tiny_sweep):
    with (tiny_sweep / "runs.csv").open(newline="") as fh:
        rows = {r["folder"]: r for r in csv.DictReader(fh)}
    assert len(rows) == 4
    for path in sorted(tiny_sweep.glob("runs/*/*/seed-*/metrics.json")):
        metrics = json.loads(path.read_text())
        row = rows[path.parent.relative_to(tiny_sweep).as_posix()]
        assert json.loads(row["endurance"]) == ENDURANCE == metrics["settings"]["endurance"]  # a setting's column
        leaves = {k: v for k, v in _numeric_leaves(metrics) if not k.startswith("settings.")}  # (not metrics)
        # The ones the issue names, so this test cannot pass on a thinner metrics.json.
        assert {"faults_applied.drop", "endurance.sorties", "endurance.time_on_station_s", "endurance.lost_to_energy",
                "uav_time_share.watching", "uav_time_share.searching", "watched_share_mean",
                "time_to_first_detection_s.0", "per_uav.B1.plans", "radio.dropped_by_cause.drop"} <= set(leaves)
        for name, value in leaves.items():
            assert name in row, name
            assert float(row[name]) == value, name
        assert not any(c.startswith("settings.") for c in row)
        assert row["planner"] == metrics["planner"] and int(row["seed"]) == metrics["seed"]


def test_summary_json_summarises_every_metric_and_bounds_the_shares(tiny_sweep):
    from swarm.experiments.sweep import metric_bounds

    summary = json.loads((tiny_sweep / "summary.json").read_text())
    not_summarised = {"seed", "sim_seconds", "wall_seconds", "events", "targets_total"}  # how a run ran
    for group in summary["groups"]:
        folders = sorted(tiny_sweep.glob(f"runs/{group['planner'].replace(':', '_')}*/*/seed-*/metrics.json"))
        assert len(folders) == 2, group["planner"]
        per_run = [{k: v for k, v in _numeric_leaves(json.loads(p.read_text())) if not k.startswith("settings.")}
                   for p in folders]
        assert not any(m.startswith("settings.") for m in group["metrics"])
        names = set().union(*per_run) - not_summarised
        assert names <= set(group["metrics"]), names - set(group["metrics"])
        for name in names:
            values = [r[name] for r in per_run if name in r]
            assert group["metrics"][name]["mean"] == pytest.approx(sum(values) / len(values)), name
    # Every share and ratio lies in [0, 1], its interval too (2 seeds: t = 12.7, wide).
    shares = [m for m in summary["groups"][0]["metrics"]
              if any(p.endswith(("share", "ratio", "share_mean", "ratio_mean")) for p in m.split("."))]
    assert {"watched_share_mean", "uav_time_share.watching", "per_uav.A1.time_share.searching",
            "surveillance_ratio.0"} <= set(shares)
    for group in summary["groups"]:
        for name in shares:
            d = group["metrics"][name]
            assert d["bounds"] == [0.0, 1.0] and 0.0 <= d["ci95"][0] <= d["ci95"][1] <= 1.0, name
    assert metric_bounds("watched_share_mean") == (0.0, 1.0) and metric_bounds("endurance.sorties")[0] == 0.0
    assert metric_bounds("endurance.per_uav.B1.energy_left_wh") == (-math.inf, math.inf)  # may end below 0
    assert {"per_uav", "time_to_first_detection_s", "watched_share", "surveillance_ratio",
            "endurance.per_uav"} <= set(summary["breakdowns"])


def test_paired_differences_are_taken_against_the_baseline(tiny_sweep):
    summary = json.loads((tiny_sweep / "summary.json").read_text())
    assert summary["baseline"] == RW
    (cmp,) = summary["comparisons"]
    assert (cmp["planner"], cmp["baseline"], cmp["paired_seeds"]) == ("dacmp", RW, 2)
    by = {g["planner"]: g["metrics"] for g in summary["groups"]}
    for name in ("coverage", "radio.sent", "endurance.time_on_station_s"):
        assert cmp["difference"][name]["mean"] == pytest.approx(by["dacmp"][name]["mean"] - by[RW][name]["mean"])


def test_a_module_class_planners_folders_are_portable_and_keep_its_name(tiny_sweep):
    from swarm.experiments.sweep import planner_folder

    folders = [p.relative_to(tiny_sweep).as_posix() for p in tiny_sweep.glob("runs/*/*/seed-*")]
    assert len(folders) == 4 and not any(c in f for f in folders for c in ':*?"<>|\\')
    ours = planner_folder(RW)
    assert ours.startswith("examples.random_waypoint_RandomWaypoint-") and planner_folder("dacmp") == "dacmp"
    assert planner_folder("a:b") != planner_folder("a_b")  # distinct names stay distinct
    for path in tiny_sweep.glob(f"runs/{ours}/*/seed-*"):
        assert json.loads((path / "scenario.json").read_text())["planner"]["name"] == RW
        assert json.loads((path / "metrics.json").read_text())["planner"] == RW
    with (tiny_sweep / "runs.csv").open(newline="") as fh:
        assert {r["planner"] for r in csv.DictReader(fh)} == {"dacmp", RW}


def test_the_sweep_report_shows_the_swarms_metrics_and_names_the_breakdowns(tiny_sweep, tmp_path):
    import re

    from swarm.viz.report import write_sweep_report

    summary = json.loads((tiny_sweep / "summary.json").read_text())
    html = write_sweep_report(tiny_sweep, summary, tmp_path / "report.html").read_text()
    heads = re.findall(r"<th>([^<]*)</th>", html)
    assert any(h.startswith("coverage") for h in heads) and not any(h.startswith("per_uav.") for h in heads)
    assert "Not shown, per UAV or per target" in html and "per_uav.* (" in html
    assert f"{RW} {chr(0x2212)} dacmp" in html  # the baseline first


def test_cli_sweep_baseline_that_is_not_a_planner_is_one_error_line(tmp_path, capsys):
    out = tmp_path / "sw"
    assert main(["sweep", "paper-case1", "--planner", "dacmp,greedy", "--baseline", "levy", "--seeds", "1",
                 "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0] == "error: --baseline 'levy': not a planner of this sweep (its planners: dacmp, greedy)"
    assert not out.exists()


def test_cli_sweep_baseline(tmp_path, capsys):
    out = tmp_path / "sw"
    assert main(["sweep", "paper-case1", "--planner", "dacmp,greedy", "--baseline", "greedy", "--seeds", "2",
                 "--duration", "10", "--workers", "2", "--out", str(out), "--quiet"]) == 0
    (cmp,) = json.loads((out / "summary.json").read_text())["comparisons"]
    assert (cmp["planner"], cmp["baseline"]) == ("dacmp", "greedy")
