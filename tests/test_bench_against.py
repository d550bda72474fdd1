"""`swarm bench --against`: each case and the yardstick alternately, one process each."""

from __future__ import annotations

import json
import sys

import pytest

from swarm.cli import main
from swarm.experiments.against import REFERENCE_CASE, table
from swarm.experiments.bench import CASES

FAKE = """\
import json, os, sys
print("a line that is not JSON")
args = sys.argv[1:]
print(json.dumps({"uav_steps_per_cpu_s": 1000.0, "args": args, "builtin": os.environ["SWARM_BUILTIN"]}))
with open(os.environ["FAKE_LOG"], "a") as f:
    f.write(json.dumps(args) + "\\n")
"""


def test_every_case_but_the_refused_ones_has_a_reference_case():
    paired = [c.name for c in CASES if c.scenario in REFERENCE_CASE]
    assert "paper-fig11-greedy" in paired and "bench-1000-greedy" in paired
    assert set(REFERENCE_CASE.values()) == {"fig11", "b100", "b1000"}


@pytest.mark.slow
def test_pairs_alternate_and_the_ratio_is_the_rates_quotient(tmp_path, capsys, monkeypatch):
    ref = tmp_path / "ref.py"
    ref.write_text(FAKE)
    log = tmp_path / "calls.jsonl"
    monkeypatch.setenv("FAKE_LOG", str(log))
    assert main(["bench", "--against", str(ref), "--pairs", "2", "--case", "paper-fig11-greedy"]) == 0
    out, err = capsys.readouterr()
    row = json.loads(out.strip().splitlines()[-1])
    assert row["case"] == "paper-fig11-greedy" and len(row["pairs"]) == 2
    for p in row["pairs"]:
        assert p["reference_uav_steps_per_cpu_s"] == 1000.0
        assert p["ratio"] == pytest.approx(p["uav_steps_per_cpu_s"] / 1000.0, abs=1e-3)
        assert p["event_log_sha256"].startswith("436c5faf")  # the case ran as `swarm bench` runs it
    calls = [json.loads(ln) for ln in log.read_text().splitlines()]
    assert calls == [["--case", "fig11", "--duration", "2000.0"]] * 2
    assert "| paper-fig11-greedy |" in err and row["machine"]["cpus"] >= 1


def test_a_case_without_a_reference_is_one_error_line_and_nothing_runs(tmp_path, capsys):
    ref = tmp_path / "ref.py"
    ref.write_text("raise SystemExit('must not run')")
    assert main(["bench", "--against", str(ref), "--case", "paper-case2-dacmp"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: no reference case for paper-case2-dacmp")


def test_a_missing_reference_or_no_pairs_is_one_error_line(tmp_path, capsys):
    assert main(["bench", "--against", str(tmp_path / "none.py"), "--case", "paper-fig11-greedy"]) == 2
    assert capsys.readouterr().err.startswith("error: --against")
    ref = tmp_path / "ref.py"
    ref.write_text("")
    assert main(["bench", "--against", str(ref), "--pairs", "0", "--case", "paper-fig11-greedy"]) == 2
    assert capsys.readouterr().err.startswith("error: --pairs 0")


def test_a_failing_reference_names_its_exit_and_last_stderr_line(tmp_path):
    from swarm.errors import UsageError
    from swarm.experiments.against import _json_line

    ref = tmp_path / "ref.py"
    ref.write_text("import sys; print('{}'); sys.exit('boom')")
    with pytest.raises(UsageError, match=r"failed \(exit 1\): boom"):
        _json_line([sys.executable, str(ref)])


def test_table_has_a_row_per_case():
    runs = [{"uav_steps_per_cpu_s": 10.0, "reference_uav_steps_per_cpu_s": 20.0, "ratio": 0.5, "load_avg": [1.0, 2.0]}]
    text = table([{"case": "c", "pairs": runs, "ratio_median": 0.5, "flatness_median": 0.9}])
    assert "| c | 10 | 20 | 0.50 (0.50) | 0.90 | 1.0-2.0 |" in text


def test_examples_per_cpu_minute_is_what_the_loop_measured():
    from swarm.experiments.examples import measure

    r = measure(2, duration_s=10.0)
    assert r["examples"] == 2 and len(r["cpu_ms_each"]) == 2
    assert r["examples_per_cpu_minute"] == pytest.approx(60.0 * 2 / r["cpu_seconds"], rel=2e-3)


def test_cli_bench_examples_refuses_a_count_below_one(capsys):
    assert main(["bench", "--examples", "0"]) == 2
    assert capsys.readouterr().err.strip() == "error: --examples 0: expected a whole number >= 1"
