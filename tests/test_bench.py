"""``swarm bench``: one JSON line per case, with every field; ``--quick`` is the CI subset."""

from __future__ import annotations

import io
import json
import math

import pytest

from swarm import cli
from swarm.events import read_events
from swarm.experiments import bench
from swarm.kernel.simulation import Simulation
from swarm.scenario import RadioSettings, load_scenario

FIELDS = {"case", "scenario", "planner", "uavs", "sim_seconds", "wall_seconds", "realtime_factor", "cpu_seconds",
          "peak_rss_mb", "shares", "coverage", "event_log_sha256", "anti_entropy", "uav_steps_per_cpu_s",
          "uav_steps_per_cpu_s_by_tenth", "flatness",
          "radio_bytes_per_uav_s", "event_log_bytes_per_uav_s", "sync_horizon_m", "digest_bytes_mean",
          "anti_entropy_bytes_per_uav_s", "scan_log_max", "scan_log_mean", "map_mb_max", "map_mb_mean"}
SHARES = {"planning", "map", "radio", "actors", "world"}


def test_quick_is_the_paper_fig11_pair():
    assert [c.name for c in bench.CASES if c.quick] == ["paper-fig11-greedy", "paper-fig11-dacmp"]


def test_every_case_names_a_loadable_scenario_and_a_planner():
    names = [c.name for c in bench.CASES]
    assert len(set(names)) == len(names)
    sizes = {}
    for c in bench.CASES:
        sc = load_scenario(c.scenario)
        assert c.planner in ("greedy", "dacmp") and c.planner in c.name
        sizes[c.scenario] = len(sc.uavs)
    assert sizes["bench-100"] == 100 and sizes["bench-1000"] == 1000 and sizes["bench-dense-300"] == 300
    assert {u.type for u in load_scenario("bench-100").uavs} == {"A", "B"}


def test_scale_cases_run_their_scenarios_with_anti_entropy_a_horizon_and_summary_logs():
    scale = {"bench-100", "bench-1000", "bench-dense-300"}
    for c in bench.CASES:
        sc = bench.case_scenario(c)
        assert sc == load_scenario(c.scenario)  # no per-case overrides
        if c.scenario in scale:
            r = sc.radio
            assert r.sync_every_s == RadioSettings().sync_every_s > 0, c.name
            assert math.isfinite(r.horizon_m) and r.horizon_m == r.range_m, c.name
            assert sc.recording.level == "summary", c.name
        else:  # the paper scenarios: as they always were
            assert math.isinf(sc.radio.horizon_m) and sc.recording.level == "frames"
    by_name = {c.name: c for c in bench.CASES}
    assert by_name["bench-100-dacmp"].duration_s is None  # the full 2000 s
    assert load_scenario("bench-100").duration_s == 2000.0
    one = by_name["bench-1000-dacmp"]
    assert (one.scenario, one.planner, one.duration_s, one.quick) == ("bench-1000", "dacmp", None, False)
    assert load_scenario("bench-1000").duration_s == 200.0


@pytest.mark.slow  # whole runs or a subprocess: the full run has it, the quick loop need not
def test_uav_ticks_counts_the_uavs_alive_in_each_tick():
    # paper-case3: 10 UAVs from 0 s, an 11th joins at 300 s.
    with Simulation("paper-case3", duration_s=305.0) as sim:
        result = sim.run()
    poses = sum(1 for _ in read_events(result.events, {"pose"}))
    assert bench.uav_ticks(result) == poses
    assert 10 * 305 < poses < 11 * 305


def test_bench_quick_emits_one_valid_json_line_per_case():
    out = io.StringIO()
    assert bench.main(quick=True, out=out, duration_s=60.0) == 0
    lines = out.getvalue().splitlines()
    assert len(lines) == 2
    rows = [json.loads(line) for line in lines]
    assert [r["case"] for r in rows] == ["paper-fig11-greedy", "paper-fig11-dacmp"]
    for r in rows:
        assert set(r) == FIELDS
        assert set(r["shares"]) == SHARES
        assert r["uavs"] == 6 and r["sim_seconds"] == 60.0 and r["scenario"] == "paper-fig11"
        assert r["planner"] in r["case"]
        assert r["wall_seconds"] > 0 and r["cpu_seconds"] > 0 and r["peak_rss_mb"] > 0
        assert r["realtime_factor"] == pytest.approx(60.0 / r["wall_seconds"], rel=0.05)  # wall rounded to ms
        assert all(0.0 <= v <= 1.0 for v in r["shares"].values())
        assert math.isclose(sum(r["shares"].values()), 1.0, abs_tol=0.01)
        assert len(r["event_log_sha256"]) == 64 and 0.0 < r["coverage"] <= 1.0
        assert r["anti_entropy"] is True  # paper-fig11 has the model's default
        # 6 UAVs alive in every one of the 60 ticks (cpu_seconds is rounded to ms).
        assert r["uav_steps_per_cpu_s"] == pytest.approx(6 * 60 / r["cpu_seconds"], rel=0.01)
        # Each tenth holds 6 UAVs x 6 ticks, in a tenth of the CPU time more or less: the
        # rates are of the same order as the whole run's, and the whole run's lies among them.
        tenths = r["uav_steps_per_cpu_s_by_tenth"]
        assert len(tenths) == 10 and all(v > 0 for v in tenths)
        assert min(tenths) <= r["uav_steps_per_cpu_s"] * 1.01 and max(tenths) >= r["uav_steps_per_cpu_s"] * 0.99
        assert r["flatness"] == pytest.approx(r["uav_steps_per_cpu_s"] / tenths[0], rel=0.01)
        assert r["radio_bytes_per_uav_s"] > 0 and r["event_log_bytes_per_uav_s"] > 0
        assert r["sync_horizon_m"] is None and r["digest_bytes_mean"] > 0 and r["scan_log_max"] > 0
        assert 0 < r["anti_entropy_bytes_per_uav_s"] < r["radio_bytes_per_uav_s"]
        assert r["map_mb_max"] is None  # paper-fig11's maps share storage (MapGroup)
    assert rows[1]["shares"]["planning"] > rows[0]["shares"]["planning"]  # DACMP plans, greedy barely


def test_bench_only_runs_the_named_case():
    out = io.StringIO()
    bench.main(only=["paper-fig11-greedy"], out=out, duration_s=5.0)
    (line,) = out.getvalue().splitlines()
    row = json.loads(line)
    assert row["case"] == "paper-fig11-greedy"
    # The per-UAV-second rates are the run's totals over 6 UAVs x 5 s.
    with Simulation("paper-fig11", planner="greedy", duration_s=5.0) as sim:
        result = sim.run()
    assert row["event_log_sha256"] == result.metrics["event_log_sha256"]
    assert row["radio_bytes_per_uav_s"] == round(result.metrics["radio"]["bytes_sent"] / 30.0, 1)
    assert row["event_log_bytes_per_uav_s"] == round(len(result.events) / 30.0, 1)


def test_bench_unknown_case_is_one_error_line_naming_the_cases(capsys):
    assert cli.main(["bench", "--case", "paper-fig11-greedy", "--case", "no-such-case"]) == 2
    out, err = capsys.readouterr()
    assert out == ""  # nothing ran
    (line,) = err.splitlines()
    assert line.startswith("error: ") and "no-such-case" in line
    assert all(c.name in line for c in bench.CASES)


def test_samples_are_filed_under_the_innermost_phase():
    import sys

    from agents.maps.grid import Grid
    from agents.maps.umap import UncertaintyMap

    class Probe:  # a frame-like chain built from real code objects
        def __init__(self, code, back=None):
            self.f_code, self.f_back = code, back

    def chain(*funcs):
        frame = None
        for f in funcs:
            frame = Probe(f.__code__, frame)
        return frame

    from agents.actor import UavActor
    from agents.planners.greedy import GreedyPlanner
    from comms.radio import Radio
    from swarm.kernel.metrics import Metrics
    from swarm.kernel.simulation import Simulation

    tick = Simulation._tick
    assert bench.classify(chain(tick, UavActor.step, GreedyPlanner.plan, UncertaintyMap.q_at)) == "planning"
    assert bench.classify(chain(tick, UavActor.step, UavActor._drain_inbox, UncertaintyMap.stamp)) == "map"
    assert bench.classify(chain(tick, UavActor.step, UavActor._drain_inbox)) == "actors"
    assert bench.classify(chain(tick, Metrics.scan, UncertaintyMap.cover)) == "world"
    assert bench.classify(chain(tick, Radio.broadcast)) == "radio"
    assert bench.classify(chain(tick, Grid.prefetch_disks)) == "map"
    assert bench.classify(sys._getframe()) == "world"
