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
