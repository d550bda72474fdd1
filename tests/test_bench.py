"""``swarm bench``: one JSON line per case, with every field; ``--quick`` is the CI subset."""

from __future__ import annotations

import io
import json
import math

import pytest

from swarm.experiments import bench
from swarm.scenario import load_scenario

FIELDS = {"case", "scenario", "planner", "uavs", "sim_seconds", "wall_seconds", "realtime_factor", "cpu_seconds",
          "peak_rss_mb", "shares", "coverage", "event_log_sha256"}
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
    assert rows[1]["shares"]["planning"] > rows[0]["shares"]["planning"]  # DACMP plans, greedy barely


def test_bench_only_runs_the_named_case():
    out = io.StringIO()
    bench.main(only=["paper-fig11-greedy"], out=out, duration_s=5.0)
    (line,) = out.getvalue().splitlines()
    assert json.loads(line)["case"] == "paper-fig11-greedy"


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
    from swarm.metrics import Metrics
    from swarm.simulation import Simulation

    tick = Simulation._tick
    assert bench.classify(chain(tick, UavActor.step, GreedyPlanner.plan, UncertaintyMap.q_at)) == "planning"
    assert bench.classify(chain(tick, UavActor.step, UavActor._drain_inbox, UncertaintyMap.stamp)) == "map"
    assert bench.classify(chain(tick, UavActor.step, UavActor._drain_inbox)) == "actors"
    assert bench.classify(chain(tick, Metrics.scan, UncertaintyMap.cover)) == "world"
    assert bench.classify(chain(tick, Radio.broadcast)) == "radio"
    assert bench.classify(chain(tick, Grid.prefetch_disks)) == "map"
    assert bench.classify(sys._getframe()) == "world"
