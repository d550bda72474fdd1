"""`swarm resilience`: each axis writes its figures, tables and JSON from its runs, finished runs
are skipped when run again, a failing run is recorded, and bad input is one error line.

Tiny versions only (paper-fig11 for 60 s, 1-2 seeds, 2-3 values per axis): the plumbing and the
direction of the numbers, not the experiment."""

from __future__ import annotations

import json
import math
from concurrent.futures import ThreadPoolExecutor

import pytest

from swarm.cli import main
from swarm.errors import UsageError
from swarm.experiments.resilience import PLANNERS, burst_fault, crash_candidates, parse_values, run_axis
from swarm.scenario import load_scenario

PNG = b"\x89PNG\r\n\x1a\n"
TINY = ["--duration", "60", "--workers", "2", "--quiet"]


def _png(path) -> None:
    assert path.is_file(), path
    data = path.read_bytes()
    assert data[:8] == PNG and len(data) > 5000, path


def _results(out, axis) -> dict:
    return json.loads((out / axis / "results.json").read_text())


def _point(res: dict, label: str) -> dict:
    return next(p for p in res["points"] if p["label"] == label)


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    """One results folder, filled axis by axis by the tests below (in file order)."""
    return tmp_path_factory.mktemp("resilience")


def test_loss_axis_writes_figures_tables_and_json_from_its_runs(out, capsys):
    assert main(["resilience", "loss", "--values", "0,0.3,0.9", "--seeds", "2", "--out", str(out), *TINY]) == 0
    err = capsys.readouterr().err
    assert "12 runs: 0 already finished, 12 ran, 0 failed" in err
    assert "of its loss-free coverage at 0.3 loss" in err
    for name in ("loss.png", "loss_kept.png"):
        _png(out / "loss" / name)
    res = _results(out, "loss")
    assert res["scenario"] == "paper-fig11" and res["duration_s"] == 60 and res["seeds"] == [0, 1]
    assert [p["label"] for p in res["points"]] == ["0", "0.3", "0.9"]
    assert res["runs_finished"] == 12 and res["runs_failed"] == 0 and not res["surveillance"]
    # The numbers come from the runs: the radio delivers what the loss rate lets through.
    for p in PLANNERS:
        delivered = [_point(res, v)["planners"][p]["delivered_fraction"]["mean"] for v in ("0", "0.3", "0.9")]
        assert delivered[0] > 0.95 and abs(delivered[1] - 0.7) < 0.05 and abs(delivered[2] - 0.1) < 0.05
        assert delivered[0] > delivered[1] > delivered[2]
        base = _point(res, "0")["planners"][p]
        assert base["kept_coverage"]["mean"] == 1.0 and base["runs"] == 2
        m = json.loads((out / "loss/runs" / p / "radio.loss_base=0.9/seed-001/metrics.json").read_text())
        assert m["sim_seconds"] == 60 and m["radio"]["dropped_by_cause"]["loss"] > 0
        assert math.isclose(_point(res, "0.9")["planners"][p]["coverage"]["mean"],
                            _mean_coverage(out / "loss/runs" / p / "radio.loss_base=0.9"))
    # the paired DACMP - greedy difference comes from the sweep's summary
    diff = _point(res, "0.3")["difference"]
    assert diff["paired_seeds"] == 2 and math.isfinite(diff["coverage"]["mean"])
    t = res["target"]
    assert t["available"] and t["loss"] == 0.3 and t["kept_at_least"] == 0.9 and isinstance(t["met"], bool)
    assert math.isclose(t["dacmp"]["kept_coverage"]["mean"], _point(res, "0.3")["planners"]["dacmp"]["kept_coverage"]["mean"])
    md = (out / "loss" / "table.md").read_text()
    assert "Target (issue 4)" in md and "coverage kept vs 0, DACMP" in md and "| 0.9 |" in md
    csv_lines = (out / "loss" / "table.csv").read_text().splitlines()
    assert csv_lines[0] == "axis,setting,value,planner,quantity,n,mean,sd,ci95_low,ci95_high"
    assert any(r.startswith("loss,radio.loss_base,0.9,dacmp,delivered_fraction,2,") for r in csv_lines)
    top = (out / "table.md").read_text()
    assert "## loss" in top and "## crash: UAVs crashed\n\nnot run" in top
    assert json.loads((out / "loss" / "summary.json").read_text())["runs_finished"] == 12


def _mean_coverage(folder) -> float:
    vals = [json.loads(p.read_text())["coverage"] for p in sorted(folder.glob("seed-*/metrics.json"))]
    return sum(vals) / len(vals)


def test_rerun_skips_finished_runs_and_redraws(out, capsys):
    metrics = sorted(out.glob("loss/runs/*/*/*/metrics.json"))
    assert len(metrics) == 12
    before = {p: p.stat().st_mtime_ns for p in metrics}
    (out / "loss" / "loss.png").unlink()
    assert main(["resilience", "loss", "--values", "0,0.3,0.9", "--seeds", "2", "--out", str(out), *TINY]) == 0
    assert "12 runs: 12 already finished, 0 ran, 0 failed" in capsys.readouterr().err
    assert {p: p.stat().st_mtime_ns for p in metrics} == before
    _png(out / "loss" / "loss.png")


@pytest.mark.parametrize("extra, expected", [
    (["--duration", "50"], "holds a finished run of 60.0 s, but this asks for 50 s"),
    (["--duration", "60", "--scenario", "paper-case1"], "holds a finished run of scenario 'paper-fig11'"),
])
def test_other_runs_in_the_same_folder_are_refused(out, capsys, extra, expected):
    assert main(["resilience", "loss", "--values", "0", "--seeds", "1", "--out", str(out), "--quiet", *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and expected in err and "Traceback" not in err


@pytest.mark.slow  # 12 runs; the loss axis above is the quick loop's
def test_burst_range_and_crash_axes(out, capsys):
    for args in (["burst", "--values", "3,100"], ["range", "--values", "2,inf"],
                 ["crash", "--values", "0,2", "--crash-at", "20"]):
        assert main(["resilience", *args, "--seeds", "1", "--out", str(out), *TINY]) == 0
        assert "4 runs: 0 already finished, 4 ran, 0 failed" in capsys.readouterr().err
        _png(out / args[0] / f"{args[0]}.png")
    burst = _results(out, "burst")
    assert burst["burst_mean_loss"] == 0.3 and [p["label"] for p in burst["points"]] == ["3", "100"]
    m = json.loads((out / "burst/runs/dacmp/burst.mean_frames=3.0,burst.mean_loss=0.3/seed-000/metrics.json").read_text())
    assert m["faults_applied"]["burst"] > 0
    assert 0.6 < _point(burst, "3")["planners"]["dacmp"]["delivered_fraction"]["mean"] < 0.8
    rng = _results(out, "range")
    assert [p["label"] for p in rng["points"]] == ["2 km", "unlimited"] and rng["baseline"] is None
    assert _point(rng, "unlimited")["planners"]["greedy"]["kept_coverage"]["mean"] == 1.0
    crash = _results(out, "crash")
    assert crash["crash_order"][:2] == ["B1", "B2"] and crash["crash_at_s"] == 20
    m = json.loads((out / "crash/runs/greedy/crashed_uavs=2,crash_at_s=20.0/seed-000/metrics.json").read_text())
    assert m["faults_applied"]["crash"] == 2
    for p in PLANNERS:  # two UAVs down from 20 s: less coverage than all six for 60 s
        assert _point(crash, "2")["planners"][p]["coverage"]["mean"] < _point(crash, "0")["planners"][p]["coverage"]["mean"]
    top = (out / "table.md").read_text()
    for a in ("loss", "burst", "range", "crash"):
        assert f"## {a}:" in top and top.split(f"## {a}:")[1].split("##")[0].count("not run") == 0, a


def test_a_failing_run_is_recorded_and_not_fatal(tmp_path, seed1_fails):
    with ThreadPoolExecutor(1) as ex:
        rep = run_axis("loss", tmp_path, values=[0.0], seeds=2, duration_s=30, executor=ex)
    assert len(rep.failed) == 2 and all("planted failure" in f["error"] for f in rep.failed)
    assert rep.results["runs_finished"] == 2 and rep.results["runs_failed"] == 2
    assert _point(rep.results, "0")["planners"]["dacmp"]["failed"] == 1
    assert (tmp_path / "loss/runs/dacmp/radio.loss_base=0.0/seed-001/error.json").is_file()
    _png(tmp_path / "loss" / "loss.png")
    assert "1 / 1, 2 failed" in (tmp_path / "loss" / "table.md").read_text()


def test_burst_chain_has_the_asked_mean_loss_and_burst_length():
    for length, loss in ((3.0, 0.3), (300.0, 0.3), (10.0, 0.5)):
        f = burst_fault(length, loss)
        assert math.isclose(f["p_enter_bad"] / (f["p_enter_bad"] + f["p_exit_bad"]), loss)
        assert math.isclose(1 / f["p_exit_bad"], length) and f["loss_bad"] == 1 and f["loss_good"] == 0
    with pytest.raises(UsageError, match="mean burst length must be >= 9"):
        burst_fault(2.0, 0.9)


def test_crash_order_skips_joiners_and_uavs_the_scenario_crashes(small_scenario_path):
    assert crash_candidates(load_scenario(small_scenario_path)) == ["B1", "A1"]
    assert crash_candidates(load_scenario("paper-fig11")) == ["B1", "B2", "B3", "B4", "B5", "B6"]
    assert parse_values("range", "2, 5,inf") == [2.0, 5.0, None]
    assert parse_values("crash", "0,3") == [0, 3]


@pytest.mark.parametrize("args, expected", [
    (["all", "--values", "0.1"], "--values needs one axis"),
    (["loss", "--values", "0,1.5"], "loss value 1.5: expected a loss rate from 0 to 1"),
    (["loss", "--values", "0,x"], "'x' is not a number"),
    (["loss", "--values", "0,0"], "a value is repeated"),
    (["burst", "--values", "0.5"], "expected a mean burst length >= 1 frame"),
    (["burst", "--burst-loss", "1"], "--burst-loss 1"),
    (["range", "--values", "-2"], "expected a range in km > 0"),
    (["crash", "--values", "7"], "paper-fig11 has 6 UAVs that fly from the start and do not crash (B1, B2, B3, B4, B5, B6)"),
    (["crash", "--crash-at", "5000"], "--crash-at 5000: expected a time from 0 to before the end of the run (2000 s)"),
    (["all", "--duration", "100"], "--crash-at 300: expected a time from 0 to before the end of the run (100 s)"),
    (["loss", "--seeds", "0"], "--seeds: found '0'"),
    (["loss", "--duration", "-5"], "--duration -5"),
    (["loss", "--workers", "0"], "--workers 0"),
    (["loss", "--scenario", "nope"], "nope: found no such file"),
])
def test_bad_input_is_one_error_line_and_runs_nothing(tmp_path, capsys, args, expected):
    assert main(["resilience", *args, "--out", str(tmp_path / "r"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and expected in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not any((tmp_path / "r").glob("*/runs"))


def test_unknown_axis_is_an_argparse_error(capsys):
    assert main(["resilience", "wind"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "invalid choice: 'wind'" in err and len(err.strip().splitlines()) == 1


@pytest.mark.slow  # the same CLI path as test_sweep.py's, which is in the quick loop
def test_unreachable_scheduler_is_one_error_line(tmp_path, capsys):
    assert main(["resilience", "loss", "--seeds", "1", "--out", str(tmp_path), "--quiet",
                 "--scheduler", "tcp://127.0.0.1:9", "--connect-timeout", "0.5"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "cannot reach a Dask scheduler" in err and "Traceback" not in err


# --- the fault axes (issue 16) -------------------------------------------------------------------

@pytest.mark.parametrize("axis, value, kind, count", [
    ("pause", 60.0, "pause", 3), ("restart", 2, "restart", 2), ("skew", 10.0, "clock_skew", 3),
    ("detect", 0.5, "sensor", 1), ("jammer", 10.0, "jammer", 1), ("liar", 2, "liar", 2),
])
def test_each_fault_axis_plans_its_faults(axis, value, kind, count):
    from swarm.experiments.resilience import BASELINE, plan_axis

    sc = load_scenario("paper-fig11")
    runs = plan_axis(axis, sc, values=[BASELINE[axis], value], seeds=[0], duration_s=600)
    assert len(runs) == 2 * len(PLANNERS)
    base, degraded = runs[0], runs[-1]
    assert [f for f in base.scenario["faults"] if f["kind"] == kind] == []  # the baseline has none
    made = [f for f in degraded.scenario["faults"] if f["kind"] == kind]
    assert len(made) == count
    names = crash_candidates(sc)
    if axis in ("pause", "restart", "skew", "liar"):
        assert [f["uav"] for f in made] == names[:count]
    if axis == "jammer":
        assert made[0]["radius_m"] == 10_000.0 and (made[0]["x_m"], made[0]["y_m"]) == (25_000.0, 25_000.0)
    if axis == "pause":
        assert (made[0]["start_s"], made[0]["end_s"]) == (300.0, 360.0)


@pytest.mark.parametrize("axis, text, expected", [
    ("detect", "1.5", r"expected a probability of detection in \[0, 1\]"),  # (the bounds of faults.Sensor.p_detect)
    ("skew", "2e6", r"expected a clock offset in s in \[-1000000, 1000000\]"),  # (faults.ClockSkew.offset_s)
    ("liar", "1.5", "is not a number; the liar axis takes whole numbers"),
    ("jammer", "-1", "expected a jammer radius in km >= 0"),
    ("pause", "inf", "expected a pause length in s >= 0"),
])
def test_fault_axis_values_are_checked(axis, text, expected):
    with pytest.raises(UsageError, match=expected):
        parse_values(axis, text)


@pytest.mark.slow  # 24 short runs
def test_fault_axes_run_and_their_faults_fire(out, capsys):
    """Each new axis runs, its faults fire in the degraded runs, and the figure and tables exist."""
    from swarm.experiments.resilience import BASELINE, plan_axis

    kinds = {"pause": "pause", "restart": "restart", "skew": "clock_skew", "detect": "sensor", "jammer": "jammer",
             "liar": "liar"}
    values = {"pause": "0,30", "restart": "0,2", "skew": "0,60", "detect": "1,0.3", "jammer": "0,30", "liar": "0,2"}
    for axis, kind in kinds.items():
        # 90 s: a restart at 10 s is down for 60 s, then flies again
        args = ["resilience", axis, "--values", values[axis], "--seeds", "1", "--crash-at", "10", "--out", str(out),
                "--duration", "90", "--workers", "2", "--quiet"]
        assert main(args) == 0
        assert "4 runs: 0 already finished, 4 ran, 0 failed" in capsys.readouterr().err
        _png(out / axis / f"{axis}.png")
        res = _results(out, axis)
        degraded = res["points"][-1]["label"]
        assert res["points"][0]["label"] != degraded
        runs = plan_axis(axis, load_scenario("paper-fig11"), values=parse_values(axis, values[axis]), seeds=[0],
                         duration_s=90, crash_at_s=10.0)
        fired = {spec.settings[0][1] == BASELINE[axis]: [] for spec in runs}
        for spec in runs:
            m = json.loads((out / axis / spec.folder / "metrics.json").read_text())
            fired[spec.settings[0][1] == BASELINE[axis]].append(m["faults_applied"].get(kind, 0))
        assert fired[True] == [0, 0] and len(fired[False]) == 2 and all(n > 0 for n in fired[False]), (axis, fired)
    top = (out / "table.md").read_text()
    assert all(f"## {a}:" in top for a in kinds)


@pytest.mark.slow
def test_an_axis_is_one_record(tmp_path, monkeypatch):
    """A new axis is one Axis record in swarm.experiments.resilience.axes.AXES: the command line,
    the runs, the figure and the tables take it from there (here a mean-wind axis)."""
    from swarm.experiments.resilience.axes import AXES, Axis

    gusts = Axis("gusts", "mean wind speed", "wind.speed_mps", (0.0, 8.0), "a wind speed in m/s from 0 to 99",
                 lambda v: v is not None and 0.0 <= v < 100.0,
                 lambda sc, v, ctx: ((("wind.speed_mps", v),), {"wind": {"speed_mps": v}} if v else {}),
                 "gusts (mean wind 0..8 m/s)", baseline=0.0, label=lambda v: f"{v:g} m/s")
    monkeypatch.setitem(AXES, "gusts", gusts)
    out = tmp_path / "r"
    assert main(["resilience", "gusts", "--seeds", "1", "--duration", "30", "--workers", "1", "--out", str(out),
                 "--quiet"]) == 0
    res = _results(out, "gusts")
    assert res["setting"] == "wind.speed_mps" and res["title"] == "mean wind speed"
    assert [p["label"] for p in res["points"]] == ["0 m/s", "8 m/s"] and res["has_baseline"]
    assert all(p["planners"][q]["runs"] == 1 for p in res["points"] for q in PLANNERS)
    _png(out / "gusts" / "gusts.png")
    assert "## gusts: mean wind speed" in (out / "table.md").read_text()
    assert main(["resilience", "gusts", "--values", "120", "--out", str(out), "--quiet"]) == 2
