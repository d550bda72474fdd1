"""Sweeps: combinations, statistics, errors recorded, resume after interruption, Dask, CLI."""

from __future__ import annotations

import json
import math
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from swarm.cli import main
from swarm.errors import ScenarioError
from swarm.experiments.sweep import describe, plan_runs, run_sweep, split_values, sweep
from swarm.scenario import load_scenario

DUR = 20.0


@pytest.fixture
def small(small_scenario_path):
    return load_scenario(small_scenario_path)


def _hashes(out: Path) -> dict[str, str]:
    return {str(p.parent.relative_to(out)): json.loads(p.read_text())["event_log_sha256"]
            for p in sorted(out.glob("runs/**/metrics.json"))}


def test_plan_runs_covers_every_combination(small):
    runs = plan_runs(small, seeds=[3, 4], planners=["dacmp", "greedy"],
                     grid={"radio.loss_base": [0.0, 0.3], "radio.latency_s": [0.0, 1.0]})
    assert len(runs) == 2 * 2 * 2 * 2
    assert len({r.folder for r in runs}) == len(runs)
    r = runs[-1]
    assert (r.planner, r.seed, r.settings) == ("greedy", 4, (("radio.loss_base", 0.3), ("radio.latency_s", 1.0)))
    assert r.scenario["planner"]["name"] == "greedy" and r.scenario["radio"]["loss_base"] == 0.3
    assert r.folder == "runs/greedy/radio.loss_base=0.3,radio.latency_s=1.0/seed-004"


def test_bad_setting_fails_before_running_and_names_the_key(small):
    with pytest.raises(ScenarioError) as e:
        plan_runs(small, seeds=[0], planners=["greedy"], grid={"radio.loss_base": [0.2, 1.5]})
    assert e.value.key == "radio.loss_base"


def test_describe_matches_student_t():
    d = describe([1.0, 2.0, 3.0, 4.0, 5.0])
    assert d["n"] == 5 and d["mean"] == 3.0
    assert math.isclose(d["sd"], math.sqrt(2.5))
    half = 2.7764451051977987 * math.sqrt(2.5) / math.sqrt(5)  # t(0.975, 4)
    assert math.isclose(d["ci95"][0], 3.0 - half) and math.isclose(d["ci95"][1], 3.0 + half)
    assert describe([7.0])["ci95"] == [7.0, 7.0]


def test_describe_clips_the_interval_to_the_metrics_range():
    from swarm.experiments.sweep import difference_bounds, metric_bounds

    # Two seeds: t(0.975, 1) = 12.7, so the raw interval of 3 targets found out of 14 leaves [0, 14].
    raw = describe([2.0, 4.0])
    assert raw["ci95"][0] < 0 and raw["ci95"][1] > 14 and "bounds" not in raw
    d = describe([2.0, 4.0], metric_bounds("targets_found", 14))
    assert d["ci95"] == [0.0, 14.0] and d["bounds"] == [0.0, 14.0]
    assert (d["mean"], d["sd"]) == (raw["mean"], raw["sd"])  # only the interval changes
    # A fraction: inside [0, 1]; an end that stays inside is the t interval's own.
    d = describe([0.97, 0.99], metric_bounds("surveillance_ratio_mean"))
    assert d["ci95"][1] == 1.0 and d["ci95"][0] == pytest.approx(raw_lo := 0.98 - 12.706204736174694 * 0.01)
    assert raw_lo < 0.97
    # Counters from 0; unknown metrics unbounded; a difference of two values in [a, b] in [a-b, b-a].
    assert metric_bounds("radio.sent") == (0.0, math.inf) and metric_bounds("violations.separation")[0] == 0.0
    assert metric_bounds("handovers") == (0.0, math.inf) and metric_bounds("some_planner_metric") == (-math.inf, math.inf)
    assert difference_bounds(metric_bounds("coverage")) == (-1.0, 1.0)
    assert difference_bounds(metric_bounds("radio.sent")) == (-math.inf, math.inf)
    # A value outside the range is shown, not clipped off: the range widens to keep it.
    assert describe([7.0, 9.0], (0.0, 8.0))["ci95"] == [0.0, 9.0]


def test_split_values_keeps_brackets_together():
    assert split_values("0,0.3, 0.5") == ["0", "0.3", "0.5"]
    assert split_values("[1,2],[3,4]") == ["[1,2]", "[3,4]"]
    assert split_values('"a,b",c') == ['"a,b"', "c"]


def test_sweep_summary_and_paired_comparison(small, tmp_path):
    with ThreadPoolExecutor(2) as ex:
        res = sweep(small, tmp_path, seeds=2, planners=["dacmp", "greedy"], duration_s=DUR, executor=ex)
    assert (res.total, res.skipped, res.ran, res.failed) == (4, 0, 4, [])
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["runs_finished"] == 4 and s["runs_failed"] == 0
    by = {g["planner"]: g for g in s["groups"]}
    assert by["dacmp"]["runs"] == 2 and by["greedy"]["runs"] == 2
    for g in by.values():
        cov = g["metrics"]["coverage"]
        assert cov["n"] == 2 and cov["ci95"][0] <= cov["mean"] <= cov["ci95"][1]
    per_run = {p.parent.parent.parent.name + "/" + p.parent.name: json.loads(p.read_text())["coverage"]
               for p in tmp_path.glob("runs/*/*/*/metrics.json")}
    assert math.isclose(by["greedy"]["metrics"]["coverage"]["mean"],
                        (per_run["greedy/seed-000"] + per_run["greedy/seed-001"]) / 2)
    (cmp,) = s["comparisons"]
    assert (cmp["baseline"], cmp["planner"], cmp["paired_seeds"]) == ("dacmp", "greedy", 2)
    diff = cmp["difference"]["coverage"]["mean"]
    assert math.isclose(diff, by["greedy"]["metrics"]["coverage"]["mean"] - by["dacmp"]["metrics"]["coverage"]["mean"])
    # Two seeds: every interval stays within its metric's range (issue 23), and the summary says how.
    assert "clipped" in s["interval"]
    total = json.loads(next(tmp_path.glob("runs/*/*/*/metrics.json")).read_text())["targets_total"]
    for stats, (lo, hi) in [(d, (0.0, 1.0)) for g in s["groups"] for m, d in g["metrics"].items()
                            if m in ("coverage", "certainty", "surveillance_ratio_mean")] \
            + [(g["metrics"]["targets_found"], (0.0, total)) for g in s["groups"]] \
            + [(d, (0.0, math.inf)) for g in s["groups"] for m, d in g["metrics"].items()
               if m.startswith(("radio.", "violations.")) or m.startswith("handovers")] \
            + [(cmp["difference"]["coverage"], (-1.0, 1.0))]:
        assert lo <= stats["ci95"][0] <= stats["mean"] <= stats["ci95"][1] <= hi, stats
    csv_lines = (tmp_path / "summary.csv").read_text().splitlines()
    assert csv_lines[0].startswith("planner,metric,runs,mean,sd,ci95_low,ci95_high")
    assert any(line.startswith("greedy,coverage,2,") for line in csv_lines)


def test_a_failing_run_is_recorded_and_does_not_stop_the_sweep(small, tmp_path, monkeypatch, seed1_fails):
    with ThreadPoolExecutor(1) as ex:
        res = sweep(small, tmp_path, seeds=3, planners=["greedy"], duration_s=DUR, executor=ex)
    assert res.ran == 3 and len(res.failed) == 1
    assert "planted failure" in res.failed[0]["error"]
    err = json.loads((tmp_path / "runs/greedy/default/seed-001/error.json").read_text())
    assert "RuntimeError: planted failure" in err["error"] and "Traceback" in err["traceback"]
    assert res.summary["runs_finished"] == 2 and res.summary["runs_failed"] == 1
    # Fixed: the next invocation retries only the failed run, and the error file goes away.
    monkeypatch.undo()  # the real Simulation.run again
    with ThreadPoolExecutor(1) as ex:
        again = sweep(small, tmp_path, seeds=3, planners=["greedy"], duration_s=DUR, executor=ex)
    assert (again.skipped, again.ran, again.failed) == (2, 1, [])
    assert not (tmp_path / "runs/greedy/default/seed-001/error.json").exists()


def test_interrupted_sweep_keeps_finished_runs_and_resumes(small, tmp_path):
    runs = plan_runs(small, seeds=range(4), planners=["greedy"], duration_s=DUR)
    finished = []

    def stop_after_two(done, total, spec, status):
        finished.append(spec.folder)
        if len(finished) == 2:
            raise KeyboardInterrupt

    with ThreadPoolExecutor(1) as ex, pytest.raises(KeyboardInterrupt):
        run_sweep(runs, tmp_path, executor=ex, progress=stop_after_two)
    kept = {p: (tmp_path / p / "metrics.json").stat().st_mtime_ns for p in finished}
    assert len(kept) == 2
    partial = json.loads((tmp_path / "summary.json").read_text())
    assert partial["runs_finished"] >= 2  # the summary of what finished was written on the way out

    seen = []
    with ThreadPoolExecutor(1) as ex:
        res = run_sweep(runs, tmp_path, executor=ex, progress=lambda d, t, s, st: seen.append((s.folder, st)))
    ran = [f for f, st in seen if st == "ok"]
    assert res.skipped == partial["runs_finished"] and res.ran == 4 - res.skipped
    assert not set(ran) & set(kept)  # nothing finished was redone
    for p, mtime in kept.items():
        assert (tmp_path / p / "metrics.json").stat().st_mtime_ns == mtime
    assert res.summary["runs_finished"] == 4


@pytest.mark.slow  # starts a Dask cluster and a process pool
def test_sweep_through_a_dask_local_cluster_gives_the_process_pool_results(small, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        res = sweep(small, tmp_path / "dask", seeds=2, planners=["greedy", "dacmp"], duration_s=DUR,
                    executor=client.get_executor())
    assert res.ran == 4 and not res.failed
    local = sweep(small, tmp_path / "local", seeds=2, planners=["greedy", "dacmp"], duration_s=DUR, workers=2)
    assert local.ran == 4
    assert _hashes(tmp_path / "dask") == _hashes(tmp_path / "local")


@pytest.mark.slow  # a process pool, twice; the in-process sweeps above are the quick loop's
def test_cli_sweep_and_resume(small_scenario_path, tmp_path, capsys):
    args = ["sweep", str(small_scenario_path), "--seeds", "2", "--planner", "greedy", "--duration", str(DUR),
            "--set", "radio.loss_base=0,0.5", "--workers", "2", "--out", str(tmp_path), "--quiet"]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "4 runs: 0 already finished, 4 ran, 0 failed" in err
    rows = (tmp_path / "summary.csv").read_text().splitlines()
    assert rows[0] == "planner,radio.loss_base,metric,runs,mean,sd,ci95_low,ci95_high"
    assert any(r.startswith("greedy,0.5,coverage,2,") for r in rows)
    assert (tmp_path / "report.html").read_text().count("<img") >= 1  # the sweep's report page
    assert main(args) == 0
    assert "4 runs: 4 already finished, 0 ran" in capsys.readouterr().err
    # The same folder asked for another duration: refused, naming a run folder, nothing lost.
    longer = [a if a != str(DUR) else str(2 * DUR) for a in args]
    assert main(longer) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "seed-000 holds a finished run of a different configuration" in err
    assert len(list(tmp_path.glob("runs/**/metrics.json"))) == 4


@pytest.mark.parametrize("bad, expected", [
    (["--planner", "astar"], "--planner 'astar'"),
    (["--set", "radio.loss_base"], "expected KEY=VALUE"),
    (["--set", "radio.loss_bse=0.1"], "radio.loss_bse"),
    (["--seeds", "0"], "--seeds: found '0'"),
])
def test_cli_sweep_bad_input_is_one_error_line(small_scenario_path, tmp_path, capsys, bad, expected):
    assert main(["sweep", str(small_scenario_path), "--out", str(tmp_path), "--quiet", *bad]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and expected in err and "Traceback" not in err


def test_cli_sweep_unreachable_scheduler(small_scenario_path, tmp_path, capsys):
    assert main(["sweep", str(small_scenario_path), "--out", str(tmp_path), "--quiet", "--seeds", "1",
                 "--scheduler", "tcp://127.0.0.1:9", "--connect-timeout", "0.5"]) == 2
    assert "cannot reach a Dask scheduler" in capsys.readouterr().err


# --- Ctrl-C: the first stops well, the second at once ---------------------------------------------


def _sweep_process(out: Path, seeds: int, duration: float):
    """`swarm sweep` in a process group of its own, as a terminal runs it: a Ctrl-C there
    reaches every process of the group (the sweep and its two workers), as os.killpg does."""
    import subprocess
    import sys

    args = [sys.executable, "-m", "swarm", "sweep", "paper-fig11", "--planner", "greedy", "--seeds", str(seeds),
            "--duration", str(duration), "--workers", "2", "--out", str(out), "--quiet"]
    return args, subprocess.Popen(args, stderr=subprocess.PIPE, text=True, start_new_session=True)


def _wait_for(predicate, timeout_s: float = 120.0) -> None:
    import time

    end = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.02)


def _finished(out: Path) -> set[str]:
    return {str(p.parent.relative_to(out)) for p in out.glob("runs/**/metrics.json")}


@pytest.mark.slow  # subprocesses and a process pool
def test_first_ctrl_c_keeps_the_runs_in_progress_and_the_sweep_resumes(tmp_path):
    import os
    import signal

    from swarm import Simulation

    out = tmp_path / "sweep"
    args, proc = _sweep_process(out, seeds=6, duration=300.0)
    _wait_for(lambda: len(_finished(out)) >= 1 or proc.poll() is not None)
    before = _finished(out)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    after = _finished(out)
    assert proc.returncode == 130, err
    assert "starting no new run, finishing the runs in progress" in err
    assert "stopped after the runs in progress finished" in err and "run the same command again to resume" in err
    # The runs in progress at the signal (at most one per worker) finished and are kept; no new one started.
    assert before < after and len(after - before) <= 2 and len(after) < 6, (before, after)
    assert f"{len(after)} of 6 runs are finished" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs_finished"] == len(after)
    # Those kept runs are whole: their hashes are what an undisturbed run gives.
    hashes = _hashes(out)
    for folder in after - before:
        seed = int(folder.rsplit("-", 1)[1])
        with Simulation("paper-fig11", seed=seed, planner="greedy", duration_s=300.0) as sim:
            assert sim.run().metrics["event_log_sha256"] == hashes[folder]
    # Resuming runs only what is missing and keeps what finished, byte for byte.
    assert main(args[3:]) == 0
    assert _finished(out) == {f"runs/greedy/default/seed-{s:03d}" for s in range(6)}
    assert {k: v for k, v in _hashes(out).items() if k in after} == hashes


@pytest.mark.slow  # subprocesses and a process pool
def test_second_ctrl_c_stops_at_once_keeping_what_finished(tmp_path):
    import os
    import signal
    import time

    out = tmp_path / "sweep"
    _, proc = _sweep_process(out, seeds=2, duration=4000.0)  # two runs of over 10 s each
    _wait_for(lambda: (out / "sweep.json").is_file() or proc.poll() is not None)  # the handler is in place
    time.sleep(1.0)  # the workers are running
    os.killpg(proc.pid, signal.SIGINT)
    time.sleep(0.3)
    os.killpg(proc.pid, signal.SIGINT)
    t0 = time.monotonic()
    _, err = proc.communicate(timeout=300)
    waited = time.monotonic() - t0
    assert proc.returncode == 130, err
    assert "stopped at once; the runs in progress were abandoned" in err and "resume" in err
    assert _finished(out) == set() and "0 of 2 runs are finished" in err
    assert json.loads((out / "summary.json").read_text())["runs_finished"] == 0
    assert waited < 5.0, f"took {waited:.1f} s to stop"  # a run takes longer than that
