"""The world's and observer's tick-plane paths (issue 36) against the per-UAV code they replace:
the UAVs flown as arrays (``World.fly`` with ``vector_physics``) move exactly as one
``World.apply`` each, dynamics violations included; a short run gives the same event log and
time series either way."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.maps.grid import Grid
from agents.types import UavType
from swarm.kernel.world import _FLY_VECTOR_MIN, PENDING, TargetMotion, Targets, UavBody, World
from tests.budget import examples

_finite = st.floats(-1e4, 1e4, allow_nan=False)
_command = st.one_of(_finite, st.floats(-1e-7, 1e-7), st.sampled_from([math.inf, -math.inf, math.nan, 0.0, -0.0]))


@st.composite
def _types(draw):
    vmin = draw(st.floats(0.0, 60.0))
    return UavType(draw(st.sampled_from(["A", "B", "C"])), vmin, vmin + draw(st.floats(0.0, 80.0)),
                   draw(st.floats(0.01, 20.0)), draw(st.floats(0.01, 1.5)), 2000.0, 1.0, 1.0, 1000.0)


@st.composite
def _swarms(draw):
    types = draw(st.lists(_types(), min_size=1, max_size=3))
    n = draw(st.integers(_FLY_VECTOR_MIN, _FLY_VECTOR_MIN + 40))
    uavs = []
    for _ in range(n):
        kind = draw(st.sampled_from(types))
        # speeds inside, at the edges of and outside the type's range; any heading
        v = draw(st.one_of(st.floats(kind.speed_min, kind.speed_max), st.floats(0.0, 200.0),
                           st.sampled_from([kind.speed_min, kind.speed_max, 0.0])))
        uavs.append((kind, draw(_finite), draw(_finite), v, draw(st.floats(-10.0, 10.0)), draw(_command), draw(_command)))
    wind = draw(st.none() | st.tuples(st.floats(-30.0, 30.0), st.floats(-30.0, 30.0)))
    return uavs, draw(st.sampled_from([1.0, 0.5, 0.1, 2.0])), wind, draw(st.integers(1, 3))


def _world(uavs, wind, vector):
    w = World(Grid(1000.0, 1000.0, 100.0), Targets(TargetMotion()), [], vector_physics=vector)
    for uid, (kind, x, y, v, th, _, _) in enumerate(uavs):
        w.add_uav(UavBody(uid, f"U{uid}", kind, x, y, v, th, PENDING))
    w.wind = wind
    return w


@given(_swarms())
@settings(max_examples=examples(200))
def test_flying_as_arrays_moves_every_uav_as_apply_does(swarm):
    uavs, dt, wind, steps = swarm
    one, many = _world(uavs, wind, False), _world(uavs, wind, True)
    ids = list(range(len(uavs)))
    commands = [(a, om) for *_, a, om in uavs]
    for k in range(steps):
        for uid, (a, om) in zip(ids, commands):
            one.apply(uid, a, om, dt, float(k))
        many.fly(ids, commands, dt, float(k))
    for uid in ids:
        b1, b2 = one.uavs[uid], many.uavs[uid]
        # bit for bit (NaN never arises: commands are made finite first)
        assert (b1.x, b1.y, b1.v, b1.theta) == (b2.x, b2.y, b2.v, b2.theta), uid
    assert one.violations == many.violations
    assert one.dynamics_by_uav == many.dynamics_by_uav


def test_the_vector_path_is_taken_and_counts_a_violation():
    """Not vacuous: fly() with vector_physics does not call apply(), and a violation it finds
    is counted (a UAV faster than its type's top speed cannot brake back in one tick)."""
    kind = UavType("B", 25.0, 50.0, 2.0, math.radians(45.0), 500.0, 1.0, 1.0, 1000.0)
    uavs = [(kind, 10.0 * i, 0.0, 30.0, 0.0, 1.0, 0.01) for i in range(_FLY_VECTOR_MIN)]
    uavs[3] = (kind, 30.0, 0.0, 90.0, 0.0, 0.0, 0.0)  # 40 m/s over speed_max, brakes 2 m/s^2
    w = _world(uavs, None, True)
    w.apply = None  # type: ignore[method-assign,assignment]  (any per-UAV call would fail)
    w.fly(list(range(len(uavs))), [(1.0, 0.01)] * len(uavs), 1.0, 5.0)
    assert w.violations["dynamics"] == 1 and w.dynamics_by_uav == {3: [1, 5.0, 5.0]}
    assert w.uavs[3].v == 88.0 and w.uavs[0].v == 31.0


def test_rx_many_writes_what_rx_writes_frame_by_frame():
    from swarm import events as ev

    received = [(3, 120, True), (0, 77, False), (5, 1 << 20, True)]
    assert ev.rx_many(t=4.0, dst=2, received=received) == [
        ev.rx(t=4.0, src=s, dst=2, bytes=n, accepted=ok) for s, n, ok in received]
    assert ev.rx_many(t=4.0, dst=2, received=[]) == []


def test_runs_give_the_same_log_and_time_series_with_and_without_the_tick_plane():
    from swarm import Simulation

    out = []
    for tick_plane in (False, True):
        with Simulation("bench-100", planner="greedy", duration_s=12.0, seed=2, tick_plane=tick_plane) as sim:
            r = sim.run()
            out.append((r.metrics["event_log_sha256"], r.timeseries, r.metrics["coverage"], r.metrics["certainty"]))
    assert out[0] == out[1]
    assert np.isfinite(out[0][3])


def _step_with_dynamics(tg: Targets, dt: float, grid: Grid, nas: list[float], nws: list[float]) -> None:
    """Targets._step_each as it was written with agents.dynamics' clamp, integrate and wrap_angle
    (the reference its written-out loop must equal)."""
    from agents.dynamics import clamp, integrate, wrap_angle

    m = tg.motion
    sq = math.sqrt(dt)
    keep = math.exp(-dt / m.turn_reversion_s)
    w, h = grid.width_m, grid.height_m
    for i in range(len(tg)):
        a = clamp(float(tg.a[i]) + m.accel_sigma * sq * nas[i], -m.accel_max, m.accel_max)
        om = clamp(float(tg.omega[i]) * keep + m.turn_sigma * sq * nws[i], -m.turn_rate_max, m.turn_rate_max)
        v = float(tg.v[i])
        a = clamp(a, -v / dt, (m.speed_max - v) / dt)
        x, y, v, th = integrate(float(tg.x[i]), float(tg.y[i]), v, float(tg.theta[i]), a, om, dt)
        if x < 0.0:
            x, th = -x, math.pi - th
        elif x > w:
            x, th = 2 * w - x, math.pi - th
        if y < 0.0:
            y, th = -y, -th
        elif y > h:
            y, th = 2 * h - y, -th
        tg.x[i], tg.y[i], tg.v[i], tg.theta[i], tg.a[i], tg.omega[i] = x, y, v, wrap_angle(th), a, om


@given(st.integers(0, 2**32 - 1), st.integers(1, 12), st.sampled_from([1.0, 0.5, 3.0]))
@settings(max_examples=examples(50))
def test_targets_one_by_one_move_as_the_dynamics_functions_move_them(seed, n, dt):
    """(issue 36) The per-target loop has clamp(), integrate() and wrap_angle() written out: it
    moves targets exactly as those functions do, reflections at the border included."""
    rng = np.random.default_rng(seed)
    grid = Grid(2000.0, 1500.0, 100.0)
    motion = TargetMotion(speed_max=40.0, accel_max=2.0, accel_sigma=3.0, turn_sigma=0.5, turn_rate_max=0.3)
    loop, ref = Targets(motion), Targets(motion)
    for i in range(n):
        x, y, th, v = rng.uniform(0, 2000), rng.uniform(0, 1500), rng.uniform(-4, 4), rng.uniform(0, 40)
        loop.add(x, y, th, v, 1.0, np.random.default_rng([seed, i]))
        ref.add(x, y, th, v, 1.0, np.random.default_rng([seed, i]))
    for _ in range(60):
        na, nw = ref._draw_pairs()
        _step_with_dynamics(ref, dt, grid, na.tolist(), nw.tolist())
        loop._step_each(dt, grid)
        assert np.array_equal(loop._s[:6, :n], ref._s[:6, :n])


@given(st.integers(0, 2**32 - 1), st.integers(1, 8), st.integers(1, 8))
@settings(max_examples=examples(100))
def test_a_few_uavs_sense_targets_as_the_numpy_test_senses_them(seed, n_uavs, n_targets):
    """sense_many's scalar path for a few (UAV, target) pairs gives the readings of its numpy
    path (the same targets, order and values), targets on and near the detection circle included."""
    rng = np.random.default_rng(seed)
    w = World(Grid(10_000.0, 10_000.0, 100.0), Targets(TargetMotion()), [])
    kinds = [UavType(n, 20.0, 60.0, 2.0, 0.5, r, 1.0, 1.0, 1000.0) for n, r in (("A", 1500.0), ("B", 2000.0))]
    for uid in range(n_uavs):
        w.add_uav(UavBody(uid, f"U{uid}", kinds[uid % 2], *rng.uniform(0.0, 10_000.0, 2), 30.0, 0.0, "alive"))
    for i in range(n_targets):
        b = w.uavs[int(rng.integers(n_uavs))]
        ang = rng.uniform(0, 2 * math.pi)
        d = b.kind.detect_radius * float(rng.choice([0.5, 1.0, 1.0 + 1e-12, 1.5]))  # (on the circle too)
        w.targets.add(b.x + d * math.cos(ang), b.y + d * math.sin(ang), 0.3, 5.0, 1.0, np.random.default_rng(i))
    ids = list(range(n_uavs))
    xy = w.positions(ids)
    few: list[list] = [[] for _ in ids]
    many: list[list] = [[] for _ in ids]
    w._sense_few([w.uavs[u] for u in ids], xy, few)
    w._sense_many_targets([w.uavs[u] for u in ids], xy, many)
    assert few == many


@given(st.integers(0, 2**32 - 1), st.integers(2, 10), st.booleans())
@settings(max_examples=examples(100))
def test_a_few_detect_and_avoid_pairs_give_the_numpy_readings(seed, n_uavs, tick_pairs):
    """_detect_and_avoid's Python assembly for a few pairs (_sensed_few) gives the readings of its
    numpy path: the same UAVs, order and values, ranges of 0 and pairs on the range included,
    with the tick's shared pair query and without it."""
    import swarm.kernel.world as world_module
    from swarm.pairs import TickPairs

    rng = np.random.default_rng(seed)
    w = World(Grid(10_000.0, 10_000.0, 100.0), Targets(TargetMotion()), [],
              pairs=TickPairs(20_000.0) if tick_pairs else None)
    kinds = [UavType(n, 20.0, 60.0, 2.0, 0.5, 2000.0, 1.0, 1.0, 1000.0, daa_range=r)
             for n, r in (("A", 1500.0), ("B", 3000.0), ("C", 0.0))]
    for uid in range(n_uavs):
        if uid and rng.random() < 0.4:  # on another's range exactly, or a hair inside or out
            o = w.uavs[int(rng.integers(uid))]
            d = float(rng.choice([1500.0, 3000.0])) * float(rng.choice([1.0, 1.0 - 1e-15, 1.0 + 1e-15]))
            x, y = o.x + d, o.y
        else:
            x, y = rng.uniform(0.0, 6_000.0, 2)
        w.add_uav(UavBody(uid, f"U{uid}", kinds[int(rng.integers(3))], float(x), float(y),
                          float(rng.uniform(20, 60)), float(rng.uniform(-math.pi, math.pi)), "alive"))
    ids = w.alive_ids()
    xy = w.positions(ids)
    bodies = [w.uavs[u] for u in ids]
    saved = world_module._DAA_FEW_PAIRS
    try:
        world_module._DAA_FEW_PAIRS = 10**6
        few = w._detect_and_avoid(ids, bodies, xy)
        world_module._DAA_FEW_PAIRS = 0
        many = w._detect_and_avoid(ids, bodies, xy)
    finally:
        world_module._DAA_FEW_PAIRS = saved
    assert few == many
