"""The command line as a new user meets it: did-you-mean for subcommands, an aligned `swarm
list`, --set and --duration validated together, warnings for values that run but look
unintended (swarm.scenario.warnings), memory figures in readable units, `swarm report` on a sweep
folder."""

from __future__ import annotations

import json
import re

import pytest

from swarm.cli import main
from swarm.kernel.memory import MemoryLimitError, check_memory, format_bytes
from swarm.scenario import load_scenario, parse_scenario, scenario_warnings


def _one_error(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("error: ") and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("argv, suggestion", [
    (["rn", "paper-case1"], "did you mean 'run'?"),
    (["sweeep", "paper-case1"], "did you mean 'sweep'?"),
    (["paper", "fig1"], "did you mean 'fig11'?"),
    (["resilience", "crsh"], "did you mean 'crash'?"),
])
def test_a_mistyped_choice_gets_did_you_mean(argv, suggestion, capsys):
    assert main(argv) == 2
    assert suggestion in _one_error(capsys)


def test_no_suggestion_when_nothing_is_close(capsys):
    assert main(["zzzzzz"]) == 2
    err = _one_error(capsys)
    assert "did you mean" not in err and "choose from run, validate" in err


@pytest.mark.parametrize("extra", [[], ["--planners"]])
def test_list_is_aligned_whatever_the_name_lengths(extra, capsys):
    assert main(["list", *extra]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = [line.split()[0] for line in lines]
    assert any(len(n) > 14 for n in names) or extra  # demo-all-faults, bench-dense-300
    starts = {re.search(r"\S+\s+(?=\S)", line).end() for line in lines}
    assert len(starts) == 1, lines  # the second column starts at one place


def test_set_is_validated_with_the_duration_given(tmp_path, capsys):
    """dt_s=5e-5 is too fine for paper-case1's 600 s (over 10^7 ticks) but fine for a short run."""
    assert main(["run", "paper-case1", "--set", "dt_s=5e-5", "--duration", "0.05", "--json"]) == 0
    metrics = json.loads(capsys.readouterr().out)
    assert metrics["sim_seconds"] == pytest.approx(0.05)
    assert main(["run", "paper-case1", "--set", "dt_s=5e-5", "--quiet"]) == 2
    assert "dt_s" in _one_error(capsys)


def test_with_duration_a_set_join_is_still_judged_against_the_scenarios_end(capsys):
    assert main(["run", "paper-case1", "--duration", "5", "--set", "uavs[2].join_s=1e6", "--quiet"]) == 2
    err = _one_error(capsys)
    assert "uavs[2].join_s" in err and "(600: it would join after the end)" in err
    assert main(["run", "paper-case3", "--duration", "20", "--quiet"]) == 0  # its joiner at 300 s is cut, not refused
    assert "uavs[10] (B6 joining at 300 s) never happens" in capsys.readouterr().err


def test_set_edits_one_field_of_a_built_in_type(capsys):
    """docs/scenarios.md: --set edits the scenario merged with Table 1's types, so one field of B
    changes that field (it does not make a table of one field, which would be an error)."""
    assert main(["run", "paper-case1", "--set", "uav_types.B.speed_max=100", "--set", "uav_types.A.daa_range_m=0",
                 "--duration", "5", "--json"]) == 0
    capsys.readouterr()
    sc = load_scenario("paper-case1", overrides={"uav_types.B.speed_max": 100.0})
    assert sc.uav_types["B"].speed_max == 100.0 and sc.uav_types["B"].w_t == 2.0 and sc.uav_types["A"].w_t == 5.0


def test_set_and_duration_disagreeing_on_the_duration_is_one_error(capsys):
    assert main(["run", "paper-case1", "--set", "duration_s=5", "--duration", "1", "--quiet"]) == 2
    assert "give the duration once" in _one_error(capsys)


def test_a_sweep_validates_set_with_its_duration(tmp_path):
    from swarm.experiments.sweep import plan_runs

    sc = load_scenario("paper-case1")
    (spec,) = plan_runs(sc, seeds=[0], planners=["greedy"], grid={"dt_s": [1e-5]}, duration_s=1.0)
    assert spec.scenario["duration_s"] == sc.duration_s  # the document (and its fingerprint) as before
    with pytest.raises(Exception, match="dt_s"):
        plan_runs(sc, seeds=[0], planners=["greedy"], grid={"dt_s": [1e-5]})


_WARNED = """
name = "warned"
duration_s = 600
[planner]
surveillance = false  # (with it, type C's turn, wider than its sensor, breaks rule 5: one more warning)
[area]
width_m = 10000
height_m = 10000
[uav_types.C]
speed_min = 20
speed_max = 40
accel_max = 0.5
bank_max_deg = 0.44
detect_radius_m = 1000
w_t = 1
w_r = 1.1
influence_radius_m = 3000
[[uavs]]
type = "C"
x_m = 1000
y_m = 1000
[[uavs]]
type = "B"
x_m = 2000
y_m = 1000
join_s = 300
[[faults]]
kind = "crash"
uav = "C1"
at_s = 900
[[faults]]
kind = "drop"
rate = 0.3
start_s = 100
"""


def test_warnings_for_faults_and_joins_after_the_end_and_angles_like_radians():
    from swarm.scenario import scenario_from_toml

    sc = scenario_from_toml(_WARNED, "warned.toml")
    own = scenario_warnings(sc)
    assert len(own) == 2
    assert own[0].startswith("faults[0] (crash) happens at 900 s, at or after the end of the run (600 s)")
    assert own[1].startswith("uav_types.C.bank_max_deg = 0.44 looks like radians (0.44 rad = 25.2 degrees)")
    short = scenario_warnings(sc, duration_s=200.0)  # as --duration 200 runs it
    assert short[1] == ("the run ends at 200 s, before the scenario's end (600 s): uavs[1] (B1 joining at 300 s) "
                        "never happens")
    assert not any("faults[1]" in w for w in short)  # the drop starts at 100 s: it fires
    assert len(scenario_warnings(sc, duration_s=50.0)[1].split("faults[1] (drop at 100 s), uavs[1]")) == 2
    assert scenario_warnings(load_scenario("paper-case1")) == []
    fine = parse_scenario({**sc.to_dict(), "faults": [], "uav_types": {"C": {**sc.to_dict()["uav_types"]["C"],
                                                                           "bank_max_deg": 25.0}}})
    assert scenario_warnings(fine) == []


def test_the_cli_prints_warnings_and_runs(tmp_path, capsys):
    path = tmp_path / "warned.toml"
    path.write_text(_WARNED)
    assert main(["validate", str(path)]) == 0
    captured = capsys.readouterr()
    assert captured.out.startswith("ok: ")
    warnings = captured.err.strip().splitlines()
    assert len(warnings) == 2 and all(w.startswith(f"warning: {path}: ") for w in warnings)
    assert main(["run", str(path), "--duration", "20", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "warning: " in err and "error" not in err
    assert "the run ends at 20 s, before the scenario's end (600 s): faults[1] (drop at 100 s), uavs[1] (B1" in err
    assert main(["validate", str(path), "--json"]) == 0
    (record,) = json.loads(capsys.readouterr().out)
    assert len(record["warnings"]) == 2


@pytest.mark.parametrize("n, text", [(0, "0 B"), (512, "512 B"), (0.01 * 2**30, "10.2 MB"), (1.5 * 2**30, "1.5 GB"),
                                     (3 * 2**40, "3 TB"), (3.7e300, "3.37e+288 TB")])
def test_sizes_read_well(n, text):
    assert format_bytes(n) == text


def test_memory_refusals_use_readable_units(capsys):
    huge = load_scenario("paper-case1").with_overrides(**{"area.width_m": 1e300})
    with pytest.raises(MemoryLimitError) as info:
        check_memory(huge)
    message = str(info.value)
    assert len(message) < 600 and not re.search(r"\d{16}", message), message
    assert main(["run", "paper-fig11", "--memory-limit", "0.01", "--quiet"]) == 2
    err = _one_error(capsys)
    assert "above the limit of 10.2 MB" in err and "0.0 GB" not in err
    assert main(["run", "paper-fig11", "--memory-limit", "0", "--quiet"]) == 2
    assert "--memory-limit 0: expected a positive number of GB" in _one_error(capsys)


def test_report_on_a_sweep_folder_points_to_the_sweep_report(tmp_path, capsys):
    sweep = tmp_path / "sweep"
    (sweep / "runs" / "greedy" / "default" / "seed-000").mkdir(parents=True)
    (sweep / "runs" / "greedy" / "default" / "seed-000" / "events.msgpack").write_bytes(b"")
    (sweep / "sweep.json").write_text('{"runs": {}}')
    assert main(["report", str(sweep)]) == 2
    err = _one_error(capsys)
    assert "is a sweep folder, not a run folder" in err and "swarm sweep" in err
    assert str(sweep / "runs" / "greedy" / "default" / "seed-000") in err
    (sweep / "report.html").write_text("<html></html>")
    assert main(["report", str(sweep)]) == 2
    assert f"the sweep's report is {sweep / 'report.html'}" in _one_error(capsys)
