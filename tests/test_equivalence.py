"""Setting changes paired by seed, and the equivalence verdict a model change's study reads."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from swarm.cli import main
from swarm.experiments.equivalence import (
    DETECTION_TIME,
    MARGINS,
    axis_pairs,
    censored_detection_time,
    compare_folders,
    equivalence,
)
from swarm.experiments.sweep import _settings_key, describe, plan_runs, summarize, sweep
from swarm.scenario import load_scenario
from swarm.viz.report.sweep_report import write_sweep_report


def test_detection_time_counts_an_undetected_target_as_the_whole_run():
    m = {"sim_seconds": 2000.0, "time_to_first_detection_s": {"0": 100.0, "1": None, "2": 0.0, "3": 300.0}}
    assert censored_detection_time(m) == (100.0 + 2000.0 + 0.0 + 300.0) / 4
    assert censored_detection_time({"sim_seconds": 10.0, "time_to_first_detection_s": {}}) is None
    assert censored_detection_time({"time_to_first_detection_s": {"0": 1.0}}) is None


def _d(mean: float, lo: float, hi: float, n: int = 30) -> dict:
    return {"n": n, "mean": mean, "sd": 1.0, "ci95": [lo, hi]}


def test_equivalent_only_when_the_whole_interval_is_within_the_margin():
    old = {"coverage": _d(0.85, 0.84, 0.86), "targets_found": _d(12.0, 11.5, 12.5),
           DETECTION_TIME: _d(500.0, 450.0, 550.0)}
    inside = equivalence({"coverage": _d(0.01, -0.005, 0.0199), "targets_found": _d(0.0, -1.0, 1.0),
                          DETECTION_TIME: _d(0.0, -49.0, 49.0)}, old)
    assert all(e["equivalent"] for e in inside.values()) and set(inside) == {"coverage", "targets_found", DETECTION_TIME}
    assert inside[DETECTION_TIME]["margin"] == pytest.approx(50.0)  # 10% of the old mean
    straddles = equivalence({"coverage": _d(0.0, -0.021, 0.01), "targets_found": _d(0.5, -0.2, 1.2),
                             DETECTION_TIME: _d(0.0, -51.0, 10.0)}, old)
    assert not any(e["equivalent"] for e in straddles.values())
    # one seed has no interval: no verdict rather than a false "yes"
    assert equivalence({"coverage": _d(0.0, 0.0, 0.0, n=1)}, old) == {}


@given(st.lists(st.floats(-0.05, 0.05, allow_nan=False), min_size=2, max_size=40))
def test_the_verdict_is_the_interval_inside_the_margin(diffs):
    d = describe(diffs)
    e = equivalence({"coverage": d}, {"coverage": describe([0.8] * len(diffs))})["coverage"]
    m = MARGINS["coverage"].absolute
    assert e["equivalent"] == (-m <= d["ci95"][0] and d["ci95"][1] <= m)


def test_axis_pairs_hold_the_other_settings_fixed():
    combos = [[("a", x), ("b", y)] for x in (1, 2, 3) for y in ("p", "q")]
    pairs = axis_pairs(combos, _settings_key)
    got = {(k, v, tuple(old), tuple(new)) for k, v, old, new in pairs}
    assert (("a", 2, (("a", 1), ("b", "q")), (("a", 2), ("b", "q")))) in got
    assert (("b", "q", (("a", 3), ("b", "p")), (("a", 3), ("b", "q")))) in got
    assert len(pairs) == 2 * 2 + 3 * 1  # a: 2 later values x 2 b's; b: 1 later value x 3 a's
    assert all(k != "a" or dict(old)["a"] == 1 for k, _, old, _ in pairs)


def test_summary_pairs_a_setting_change_seed_by_seed(small_scenario_path, tmp_path):
    small = load_scenario(small_scenario_path)
    runs = plan_runs(small, seeds=[0, 1, 2], planners=["greedy"], grid={"radio.loss_base": [0.0, 0.5]})
    covs = {}
    for spec in runs:  # made-up finished runs: the summary only reads metrics.json
        loss = dict(spec.settings)["radio.loss_base"]
        cov = 0.5 + 0.01 * spec.seed - 0.1 * loss
        covs[(loss, spec.seed)] = cov
        folder = tmp_path / spec.folder
        folder.mkdir(parents=True)
        (folder / "metrics.json").write_text(json.dumps({
            "seed": spec.seed, "sim_seconds": 100.0, "coverage": cov, "certainty": 0.2, "targets_found": 3,
            "targets_total": 4, "time_to_first_detection_s": {"0": 10.0 * spec.seed, "1": None}}))
    s = summarize(tmp_path, runs)
    (c,) = s["setting_comparisons"]
    assert (c["planner"], c["key"], c["old"], c["new"], c["paired_seeds"]) == ("greedy", "radio.loss_base", 0.0, 0.5, 3)
    assert c["difference"]["coverage"]["mean"] == pytest.approx(-0.05)
    assert c["difference"]["coverage"]["sd"] == pytest.approx(0.0, abs=1e-12)
    e = c["equivalence"]
    assert e["coverage"]["equivalent"] is False  # -0.05 is well outside ±0.02
    assert e["certainty"]["equivalent"] and e["targets_found"]["equivalent"] and e[DETECTION_TIME]["equivalent"]
    report = write_sweep_report(tmp_path, s)
    html = report.read_text()
    assert "Setting changes: equivalent?" in html and "radio.loss_base 0 \u2192 0.5" in html


@pytest.mark.slow
def test_cli_sweep_prints_the_equivalence_table(small_scenario_path, tmp_path, capsys):
    out = tmp_path / "sw"
    rc = main(["sweep", str(small_scenario_path), "--seeds", "2", "--planner", "greedy", "--duration", "20",
               "--set", "radio.tracks_every_s=5,7", "--workers", "1", "--out", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "radio.tracks_every_s: 5 -> 7" in text and "equivalent" in text
    s = json.loads((out / "summary.json").read_text())
    (c,) = s["setting_comparisons"]
    assert c["paired_seeds"] == 2 and math.isfinite(c["difference"]["coverage"]["mean"])


def test_a_sweep_without_set_axes_has_no_setting_comparisons(small_scenario_path, tmp_path):
    small = load_scenario(small_scenario_path)
    res = sweep(small, tmp_path, seeds=1, planners=["greedy"], duration_s=5.0, workers=1)
    assert res.summary["setting_comparisons"] == []
    assert Path(tmp_path / "summary.json").is_file()


def _fake_sweep(root: Path, coverage: dict[tuple[str, int], float], sha: str = "same") -> Path:
    for (planner, seed), cov in coverage.items():
        d = root / "runs" / planner / "default" / f"seed-{seed:03d}"
        d.mkdir(parents=True)
        (d / "metrics.json").write_text(json.dumps({
            "seed": seed, "sim_seconds": 100.0, "coverage": cov, "certainty": 0.3, "targets_found": 2,
            "targets_total": 3, "time_to_first_detection_s": {"0": 5.0, "1": None, "2": 7.0},
            "event_log_sha256": f"{sha}-{planner}-{seed}" if sha else f"x-{cov}"}))
    return root


def test_compare_folders_pairs_runs_and_judges_each_group(tmp_path):
    old = _fake_sweep(tmp_path / "old", {(p, s): 0.5 + 0.01 * s for p in ("dacmp", "greedy") for s in range(4)})
    _fake_sweep(tmp_path / "new" / "fig11", {**{("dacmp", s): 0.5 + 0.01 * s for s in range(4)},
                                                   **{("greedy", s): 0.45 + 0.01 * s for s in range(3)}},
                      sha="")
    c = compare_folders(old, tmp_path / "new")  # a folder holding one sweep is read as that sweep
    assert (c.paired, c.only_old, c.only_new) == (7, 1, 0)
    by = {g["planner"]: g for g in c.groups}
    assert by["dacmp"]["equivalence"]["coverage"]["equivalent"] and by["dacmp"]["paired_seeds"] == 4
    assert by["greedy"]["difference"]["coverage"]["mean"] == pytest.approx(-0.05)
    assert not by["greedy"]["equivalence"]["coverage"]["equivalent"] and not c.equivalent
    assert c.identical == 0  # the new runs' event logs differ (a model change)
    same = compare_folders(old, old)
    assert same.equivalent and same.identical == same.paired == 8


def test_cli_compare_exit_codes_and_errors(tmp_path, capsys):
    old = _fake_sweep(tmp_path / "a", {("greedy", s): 0.5 + 0.01 * s for s in range(3)})
    far = _fake_sweep(tmp_path / "b", {("greedy", s): 0.3 + 0.01 * s for s in range(3)}, sha="")
    assert main(["compare", str(old), str(old)]) == 0
    assert main(["compare", str(old), str(far)]) == 1
    assert "NOT equivalent" in capsys.readouterr().err
    assert main(["compare", str(old), str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: {tmp_path / 'missing'}: no such folder"]
    assert main(["compare", "--json", str(old), str(old)]) == 0
    assert json.loads(capsys.readouterr().out)["identical"] == 3
