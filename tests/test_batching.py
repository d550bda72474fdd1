"""Batched planning (agents.planners.batching, DacmpPlanner.plan_many) gives the one-by-one results.

The simulator serves every UAV that replans in a tick with one planner call. That is only a
speed-up if each UAV still decides exactly as it would alone: these tests compare event-log
hashes of whole runs, and plans of generated multi-UAV situations, bit for bit.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.knowledge import Knowledge
from agents.maps.grid import Grid
from agents.maps.umap import UncertaintyMap
from agents.planners.base import PlanView
from agents.planners.dacmp.dubins import dubins_length
from agents.planners.dacmp.planner import DacmpPlanner
from agents.types import UavType
from swarm import Simulation


def _run(scenario, batch: bool, **kw):
    with Simulation(scenario, batch_planning=batch, **kw) as sim:
        result = sim.run()
        batcher = sim._fleet.batcher
        return result.metrics["event_log_sha256"], (batcher.batches, batcher.plans) if batcher else None


@pytest.mark.slow  # four whole runs; the faults test below is the quick loop's
@pytest.mark.parametrize("scenario, duration", [
    ("paper-fig11", 300.0),  # six UAVs replanning on the same ticks, search only
    ("paper-case2", 400.0),  # two UAV types, targets (surveillance, competing repulsion), threats
])
def test_batched_run_has_the_one_by_one_event_log(scenario, duration):
    one_by_one, _ = _run(scenario, False, duration_s=duration)
    batched, (batches, plans) = _run(scenario, True, duration_s=duration)
    assert batches < plans  # plans really were served several at a time
    assert batched == one_by_one


def test_batched_run_with_faults_has_the_one_by_one_event_log(small_scenario_path):
    # Crashes, a late joiner and a partition change who replans when.
    assert _run(small_scenario_path, True, planner="dacmp", duration_s=120.0)[0] == \
        _run(small_scenario_path, False, planner="dacmp", duration_s=120.0)[0]


_FAST = UavType("B", 20.0, 40.0, 3.0, math.radians(30), 1500.0, 5.0, 5.1, 10_000.0)
_SLOW = UavType("A", 10.0, 20.0, 2.0, math.radians(30), 2000.0, 2.0, 2.1, 4_000.0)


def _uav_situation(draw, grid: Grid, t: float, uav: int) -> PlanView:
    kind = draw(st.sampled_from([_FAST, _SLOW]))
    x = draw(st.floats(0.0, grid.width_m))
    y = draw(st.floats(0.0, grid.height_m))
    umap = UncertaintyMap(grid, 1.0 / 400.0)
    for _ in range(draw(st.integers(0, 6))):  # some scans it made or heard
        umap.scan(draw(st.floats(0.0, grid.width_m)), draw(st.floats(0.0, grid.height_m)),
                  draw(st.floats(200.0, 3000.0)), draw(st.floats(0.0, t)))
    k = Knowledge()
    for tid in range(draw(st.integers(0, 3))):
        k.see_target(tid, draw(st.floats(0.0, grid.width_m)), draw(st.floats(0.0, grid.height_m)),
                     draw(st.floats(-15.0, 15.0)), draw(st.floats(-15.0, 15.0)), t - draw(st.floats(0.0, 30.0)), 1.0)
    for th in range(draw(st.integers(0, 2))):
        r = draw(st.floats(500.0, 3000.0))
        k.add_threat(th, draw(st.floats(0.0, grid.width_m)), draw(st.floats(0.0, grid.height_m)), r, r + 3000.0)
    for other in range(draw(st.integers(0, 3))):
        p = k.peer(100 + other)
        p.type, p.x, p.y, p.t_pose = "A", x + 1000.0, y, t - 1.0
        p.wx, p.wy, p.t_intent = draw(st.floats(0.0, grid.width_m)), draw(st.floats(0.0, grid.height_m)), t - 2.0
    v = draw(st.floats(kind.speed_min, kind.speed_max))
    theta = draw(st.floats(-math.pi, math.pi))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    return PlanView(t, uav, kind, x, y, v, theta, umap, k, rng, grid, 10.0, draw(st.booleans()), None)


@st.composite
def situations(draw):
    grid = Grid(20_000.0, 16_000.0, 100.0)
    t = draw(st.floats(10.0, 2000.0))
    return [_uav_situation(draw, grid, t, uav) for uav in range(draw(st.integers(2, 5)))]


@settings(max_examples=examples(25), deadline=None)
@given(situations())
def test_plan_many_is_plan_for_each(views):
    planner = DacmpPlanner(particles=12, iterations=6, levels=5)
    alone = [planner.plan(_with_rng_copy(v)) for v in views]
    together = planner.plan_many([_with_rng_copy(v) for v in views])
    assert together == alone


def _with_rng_copy(v: PlanView) -> PlanView:
    w = copy.copy(v)
    w.rng = copy.deepcopy(v.rng)
    return w


@settings(max_examples=examples(50), deadline=None)
@given(st.lists(st.tuples(st.floats(-5e3, 5e3), st.floats(-5e3, 5e3), st.floats(-4.0, 4.0), st.floats(0.0, 900.0)),
                min_size=1, max_size=4),
       st.lists(st.tuples(st.floats(-8e3, 8e3), st.floats(-8e3, 8e3)), min_size=1, max_size=8))
def test_dubins_several_poses_equal_one_pose_at_a_time(poses, points):
    px = np.array([[p[0] for p in points]] * len(poses))
    py = np.array([[p[1] for p in points]] * len(poses))
    x0, y0, th, r = (np.array(col) for col in zip(*poses))
    # Hypothesis also draws subnormal radii, whose 1/r overflows (to inf, then NaN) in both
    # paths alike: the comparison holds, numpy's warnings about it are noise here.
    with np.errstate(over="ignore", invalid="ignore"):
        many = dubins_length(x0[:, None], y0[:, None], th, px, py, r[:, None])
        for i, (a, b, h, rr) in enumerate(poses):
            assert np.array_equal(many[i], dubins_length(a, b, h, px[i], py[i], rr), equal_nan=True)


@pytest.mark.slow  # two whole runs
def test_shared_surveillance_prepares_the_watchers_pyramids_together_without_changing_the_log(monkeypatch):
    # Greedy with the shared surveillance logic: each UAV has its own planner instance (no
    # plan_many), but SharedSurveillance.prepare_many updates the map pyramids of the UAVs that
    # weigh a target in one MaintainedPyramid.update_many. The log must be the one-by-one log.
    from agents.planners.dacmp.maintained import MaintainedPyramid

    sizes: list[int] = []
    update_many = MaintainedPyramid.update_many

    def spy(pyramids, ts):
        sizes.append(len(pyramids))
        return update_many(pyramids, ts)

    monkeypatch.setattr(MaintainedPyramid, "update_many", staticmethod(spy))
    one_by_one, _ = _run("paper-case2", False, planner="greedy", duration_s=400.0)
    assert max(sizes) == 1
    sizes.clear()
    batched, _ = _run("paper-case2", True, planner="greedy", duration_s=400.0)
    assert max(sizes) > 1  # several watchers' pyramids were brought up to date in one call
    assert batched == one_by_one


def test_prepare_many_runs_once_per_flush_before_the_plans_and_its_error_reaches_every_plan():
    import asyncio
    from types import SimpleNamespace

    from agents.planners.base import Plan
    from agents.planners.batching import PlanBatcher

    calls: list[str] = []

    class Prepared:  # each UAV its own instance: planned one by one, prepared together
        fail = False

        @staticmethod
        def prepare_many(requests):
            calls.append(f"prepare {[v for _, v in requests]}")
            if Prepared.fail:
                raise RuntimeError("prepare broke")

        def plan(self, view):
            calls.append(f"plan {view}")
            return Plan(0.0, 0.0)

    async def serve():
        batcher = PlanBatcher()
        futures = [batcher.request(SimpleNamespace(uid=uid, planner=Prepared()), f"view{uid}") for uid in (2, 1)]
        batcher.flush()
        return [f.exception() or f.result() for f in futures]

    assert all(isinstance(r, Plan) for r in asyncio.run(serve()))
    assert calls == ["prepare ['view1', 'view2']", "plan view1", "plan view2"]  # in UAV-id order
    Prepared.fail = True
    calls.clear()
    errors = asyncio.run(serve())
    assert [str(e) for e in errors] == ["prepare broke"] * 2 and calls == ["prepare ['view1', 'view2']"]
