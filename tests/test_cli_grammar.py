"""One CLI grammar: no abbreviations, --seed is one seed and --seeds a set, --version, --json,
"did you mean", and validate reporting every problem of every file."""

from __future__ import annotations

import json

import pytest

from swarm import __version__
from swarm.cli import main, parse_seeds


@pytest.mark.parametrize("text, seeds", [("3", [0, 1, 2]), ("4-6", [4, 5, 6]), ("7", list(range(7))),
                                         ("2,5,9", [2, 5, 9]), ("0-0", [0])])
def test_seed_sets(text, seeds):
    assert parse_seeds(text) == seeds


@pytest.mark.parametrize("text", ["0", "x", "5-3", "-1", "1,-2", ""])
def test_bad_seed_sets_are_refused(text):
    with pytest.raises(Exception, match="expected"):
        parse_seeds(text)


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"swarm {__version__}"


def test_seed_is_not_an_abbreviation_of_seeds(tmp_path, capsys):
    assert main(["sweep", "paper-case1", "--seed", "3", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "--seed" in err and "did you mean --seeds?" in err
    assert len(err.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())  # nothing ran


def test_mistyped_option_gets_did_you_mean(capsys):
    assert main(["run", "paper-case1", "--plannr", "greedy"]) == 2
    assert "did you mean --planner?" in capsys.readouterr().err


def test_validate_reports_every_problem_in_every_file(tmp_path, capsys):
    a = tmp_path / "a.toml"
    a.write_text('[area]\nwidth_m = -1.0\nhieght_m = 3.0\n[[uavs]]\ntype = "B"\nx_m = 1.0\ny_m = 1.0\n')
    b = tmp_path / "b.toml"
    b.write_text('seed = "x"\n')
    assert main(["validate", str(a), "paper-case1", str(b)]) == 2
    captured = capsys.readouterr()
    errors = captured.err.strip().splitlines()
    assert all(line.startswith("error: ") for line in errors)
    assert any("a.toml: area.width_m" in e for e in errors) and any("a.toml: area.hieght_m" in e for e in errors)
    assert any("b.toml: seed" in e for e in errors)
    assert "ok: paper-case1" in captured.out


def test_validate_json(capsys):
    assert main(["validate", "paper-case1", "--json"]) == 0
    records = json.loads(capsys.readouterr().out)
    assert records[0]["ok"] and records[0]["name"] == "paper-case1" and records[0]["uavs"] == 3


def test_run_json_prints_the_metrics(capsys):
    assert main(["run", "paper-case1", "--duration", "20", "--json"]) == 0
    metrics = json.loads(capsys.readouterr().out)
    assert metrics["scenario"] == "paper-case1" and metrics["sim_seconds"] == 20.0
    assert len(metrics["event_log_sha256"]) == 64
