"""The `swarm` command: outputs of a run, and readable errors with exit status 2."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from swarm.cli import main


def _swarm(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "swarm", *args], capture_output=True, text=True, cwd=cwd)


def test_run_writes_every_output(tmp_path, small_scenario_path):
    out = tmp_path / "run"
    assert main(["run", str(small_scenario_path), "--duration", "60", "--out", str(out), "--quiet"]) == 0
    for name in ("metrics.json", "timeseries.csv", "events.msgpack", "trajectories.png", "scenario.json"):
        assert (out / name).stat().st_size > 0, name
    m = json.loads((out / "metrics.json").read_text())
    assert m["sim_seconds"] == 60.0 and m["scenario"] == "faults-small"
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert {"t", "coverage", "certainty", "targets_found", "sent", "mode_B1", "mode_A2"} <= set(header)
    assert (out / "trajectories.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_damaged_scenario_gives_one_line_exit_2_no_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[area]\nwidth_m = "wide"\n')
    r = _swarm("validate", str(bad))
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    # every problem of the file, one error: line each, the first one a reader meets first
    assert len(lines) == 2 and all(line.startswith("error: ") for line in lines)
    assert str(bad) in lines[0] and "area.width_m" in lines[0] and "'wide'" in lines[0]
    assert "uavs" in lines[1]


@pytest.mark.slow  # `python -m swarm` subprocesses; the damaged-scenario one above is the quick loop's
def test_unknown_key_suggests_the_closest(tmp_path):
    bad = tmp_path / "typo.toml"
    bad.write_text('[[uavs]]\ntype = "B"\nx_m = 0.0\ny_m = 0.0\nheding_deg = 90.0\n')
    r = _swarm("run", str(bad))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "uavs[0].heding_deg" in r.stderr and "heading_deg" in r.stderr


@pytest.mark.slow  # `python -m swarm` subprocesses; the damaged-scenario one above is the quick loop's
def test_broken_toml_and_missing_file(tmp_path):
    broken = tmp_path / "broken.toml"
    broken.write_text("[area\nwidth_m = 1\n")
    r = _swarm("validate", str(broken))
    assert r.returncode == 2 and "invalid TOML" in r.stderr and "Traceback" not in r.stderr
    r = _swarm("run", "no-such-scenario")
    assert r.returncode == 2 and "paper-fig11" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.slow  # `python -m swarm` subprocesses; the damaged-scenario one above is the quick loop's
def test_bad_override_names_the_key(small_scenario_path):
    r = _swarm("run", str(small_scenario_path), "--set", "radio.loss_base=1.5", "--quiet")
    assert r.returncode == 2 and "radio.loss_base" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("name", ["paper-fig11", "paper-case1", "paper-case2", "paper-case3"])
def test_builtins_validate(name, capsys):
    assert main(["validate", name]) == 0
    assert capsys.readouterr().out.startswith(f"ok: {name}")


def test_validate_prints_at_most_20_problems_then_how_many_more(tmp_path, capsys):
    """Issue 33: one scenario with many mistakes printed every one (26,588 lines)."""
    uavs = "".join(f'[[uavs]]\ntype = "B"\nx_m = {-100 - k}\ny_m = 100\n' for k in range(25))
    bad = tmp_path / "many.toml"
    bad.write_text(uavs)
    assert main(["validate", str(bad)]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 21 and all(line.startswith("error: ") for line in lines)
    assert "uavs[19].x_m" in lines[19] and "... and 5 more problems" in lines[20]
    assert main(["validate", "--json", str(bad)]) == 2
    assert len(json.loads(capsys.readouterr().out)[0]["problems"]) == 25


def test_validate_applies_the_memory_guard_of_run(tmp_path, capsys):
    """Issue 33: validate said ok to a scenario that run refuses for memory."""
    big = tmp_path / "big.toml"
    big.write_text('[area]\nwidth_m = 500000\nheight_m = 500000\ncell_m = 1\n[[uavs]]\ntype = "B"\nx_m = 10\ny_m = 10\n')
    assert main(["validate", str(big), "--memory-limit", "8"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {big}: scenario 'big' would need about") and "area.cell_m" in err[0]
    assert main(["validate", "paper-case1", "--memory-limit", "8"]) == 0


def test_validate_counts_no_fly_polygons_as_hazards(capsys):
    assert main(["validate", "geo-coast", "paper-case2"]) == 0
    out = capsys.readouterr().out
    assert "1 no-fly zone (polygon)" in out and "4 no-fly zones (threat circles)" in out and "threats" not in out
