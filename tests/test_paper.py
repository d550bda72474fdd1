"""`swarm paper`: each experiment writes its figures and results, the table puts the paper's
quoted numbers next to ours (or "not run"), and finished runs are skipped when run again.

Tiny versions only (2 seeds, 60 s of simulated time) to check the plumbing, not the numbers.
The experiments that fill one results folder (``paper_out``) run in file order, each on the
ones before it, and are all marked ``slow``; the table and argument checks are quick."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from swarm.cli import main
from swarm.experiments.paper import EXPERIMENTS, FIG11_PLANNERS, fig11_planners, stays_above_from, write_table

PNG = b"\x89PNG\r\n\x1a\n"
TINY = ["--duration", "60", "--workers", "2", "--quiet"]
MEASURED = re.compile(r"\d+\.\d+ \[[-+]?\d+\.\d+, [-+]?\d+\.\d+\], 2 seeds")


def _png(path) -> None:
    assert path.is_file(), path
    data = path.read_bytes()
    assert data[:8] == PNG and len(data) > 5000, path


def _rows(out, experiment_prefix: str) -> list[list[str]]:
    lines = (out / "table.md").read_text().splitlines()
    return [[c.strip() for c in line.strip("|").split("|")] for line in lines
            if line.startswith(f"| {experiment_prefix}")]


@pytest.fixture(scope="module")
def paper_out(tmp_path_factory):
    """One results folder, filled experiment by experiment by the tests below (in file order)."""
    return tmp_path_factory.mktemp("paper")


def test_empty_folder_table_is_all_not_run(tmp_path):
    md, csv_path, rows = write_table(tmp_path)
    text = md.read_text()
    assert "paper (quoted)" in text and "ours (measured, N seeds, mean [95% CI])" in text
    assert rows and all(r["ours_measured"] == "not run" for r in rows)
    assert "0.712" in text and "0.763" in text and "12.1" in text and "13.7" in text
    assert csv_path.read_text().splitlines()[0].startswith("experiment,quantity,paper_quoted,ours_measured,n,mean")


@pytest.mark.slow  # fills paper_out: each test needs the ones before it
def test_fig11_writes_figures_and_table_then_skips_finished_runs(paper_out, capsys):
    out = paper_out
    planners = fig11_planners()  # the paper's pair, then the reference planners
    assert planners[:2] == FIG11_PLANNERS
    n = 2 * len(planners)
    assert main(["paper", "fig11", "--seeds", "2", "--out", str(out), *TINY]) == 0
    err = capsys.readouterr().err
    assert f"{n} runs: 0 already finished, {n} ran, 0 failed" in err
    for name in ("fig11_over_time.png", "fig11_final.png"):
        _png(out / "fig11" / name)
    s = json.loads((out / "fig11" / "summary.json").read_text())
    assert s["runs_finished"] == n
    rows = _rows(out, "Fig. 11")
    assert len(rows) == 2 * len(planners) + 2
    for _, quantity, paper, ours, note in rows:
        assert paper and ours != "not run", quantity
        assert "60 s" in note
    assert any("0.712" in r[2] for r in rows) and any("13.7" in r[2] for r in rows)
    assert sum(bool(MEASURED.search(r[3])) for r in rows) == 2 * len(planners)
    assert sum("reference planner, not in the paper" in r[2] for r in rows) == 2 * (len(planners) - 2)
    assert all("paired seeds" in r[3] for r in rows if "DACMP − greedy" in r[1])
    assert all(r[3] == "not run" for r in _rows(out, "Case"))  # the other experiments
    text = (out / "table.md").read_text()
    assert "paper (quoted)" in text and "ours (measured" in text

    metrics = sorted(out.glob("fig11/runs/*/*/*/metrics.json"))
    assert len(metrics) == n
    before = {p: p.stat().st_mtime_ns for p in metrics}
    assert main(["paper", "fig11", "--seeds", "2", "--out", str(out), *TINY]) == 0
    assert f"{n} runs: {n} already finished, 0 ran, 0 failed" in capsys.readouterr().err
    assert {p: p.stat().st_mtime_ns for p in metrics} == before


@pytest.mark.slow  # fills paper_out: each test needs the ones before it
def test_other_duration_on_finished_runs_is_one_error_line(paper_out, capsys):
    assert main(["paper", "fig11", "--seeds", "2", "--out", str(paper_out), "--duration", "30", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "60.0 s" in err[0] and "--out" in err[0]


@pytest.mark.slow  # fills paper_out: each test needs the ones before it
def test_case1_single_run_with_full_outputs(paper_out, capsys):
    out = paper_out
    assert main(["paper", "case1", "--out", str(out), *TINY]) == 0
    run = out / "case1" / "run"
    for name in ("metrics.json", "timeseries.csv", "events.msgpack", "scenario.json", "trajectories.png"):
        assert (run / name).stat().st_size > 0, name
    _png(out / "case1" / "case1_distance.png")
    _png(out / "case1" / "case1_trajectories.png")
    res = json.loads((out / "case1" / "results.json").read_text())
    assert res["duration_s"] == 60.0 and set(res["watchers_end"]) == {"1", "2"}
    rows = _rows(out, "Case 1")
    assert rows and all(r[3] not in ("", "not run") for r in rows)
    assert _rows(out, "Fig. 11")[0][3] != "not run"  # the table keeps fig11's results
    assert "already finished" not in capsys.readouterr().err


@pytest.mark.slow  # fills paper_out: each test needs the ones before it
def test_case2_with_seeds_then_case3_shares_the_case2_runs(paper_out, capsys):
    out = paper_out
    assert main(["paper", "case2", "--seeds", "2", "--out", str(out), *TINY]) == 0
    capsys.readouterr()
    for name in ("case2_trajectories.png", "case2_task_loads.png", "case2_coverage.png"):
        _png(out / "case2" / name)
    res = json.loads((out / "case2" / "results.json").read_text())
    assert res["run"]["targets_total"] == 6 and res["seeds"]["seeds"] == [0, 1]
    rows = _rows(out, "Case 2")
    assert any("over seeds 0..1" in r[1] and MEASURED.search(r[3]) for r in rows)
    assert any(r[2].startswith("4") and "handovers" in r[1] for r in rows)

    assert main(["paper", "case3", "--seeds", "2", "--out", str(out), *TINY]) == 0
    err = capsys.readouterr().err
    assert "case2/seeds: 2 runs: 2 already finished, 0 ran" in err
    assert "case3/seeds: 2 runs: 0 already finished, 2 ran" in err
    _png(out / "case3" / "case3_coverage.png")
    res = json.loads((out / "case3" / "results.json").read_text())
    assert res["seeds"] == [0, 1] and res["join_s"] == 300.0 and res["joiner"] == "B6"
    rows = _rows(out, "Case 3")
    assert any("n/a: runs end at 60 s" in r[3] for r in rows)
    assert any("paired seeds" in r[3] for r in rows)


@pytest.mark.slow  # fills paper_out: each test needs the ones before it
def test_all_reuses_everything_and_leaves_nothing_not_run(paper_out, capsys):
    out = paper_out
    assert main(["paper", "all", "--seeds", "2", "--out", str(out), *TINY]) == 0
    err = capsys.readouterr().err
    assert " ran," not in err.replace("0 ran,", "")  # every sweep run already finished
    assert "case1/run: already finished, kept" in err and "case2/run: already finished, kept" in err
    text = (out / "table.md").read_text()
    assert "not run" not in text
    assert len(list(out.glob("*/*.png"))) == 2 + 2 + 3 + 1
    for name in EXPERIMENTS:
        assert (out / name / "results.json").is_file()


def test_unreadable_results_are_flagged_not_fatal(tmp_path):
    (tmp_path / "case1").mkdir()
    (tmp_path / "case1" / "results.json").write_text(json.dumps({"experiment": "case1", "found": []}))
    _, _, rows = write_table(tmp_path)
    case1 = [r for r in rows if r["experiment"].startswith("Case 1")]
    assert case1 and all("unreadable case1/results.json" in r["ours_measured"] for r in case1)


def teststays_above_from():
    t = np.array([100.0, 200.0, 300.0, 400.0, 500.0])
    assert stays_above_from(t, np.array([0, 1, 0, 2, 2.0]), np.zeros(5), 250.0) == 400.0
    assert stays_above_from(t, np.array([1, 1, 1, 1, 1.0]), np.zeros(5), 250.0) == 250.0
    assert stays_above_from(t, np.array([1, 1, 1, 1, 0.0]), np.zeros(5), 250.0) is None


def test_bad_seeds_is_a_usage_error(tmp_path, capsys):
    assert main(["paper", "fig11", "--seeds", "0", "--out", str(tmp_path), "--quiet"]) == 2
    assert "--seeds: found '0'" in capsys.readouterr().err


@pytest.mark.slow  # the same CLI path as test_sweep.py's, which is in the quick loop
def test_unreachable_scheduler_is_one_error_line(tmp_path, capsys):
    assert main(["paper", "fig11", "--seeds", "1", "--out", str(tmp_path), "--quiet",
                 "--scheduler", "tcp://127.0.0.1:9", "--connect-timeout", "0.5"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "cannot reach a Dask scheduler" in err and "Traceback" not in err
