"""The fast paths added for speed give exactly what the code they stand in for gives.

* :func:`agents.dynamics.clamp` is ``min(max(v, lo), hi)`` for every float, NaN and signed
  zeros included;
* :meth:`swarm.kernel.world.World.sense_many` gives each UAV the reading the one-UAV formula gives;
* ``comms.codec._nums`` converts and rejects exactly as ``_num`` value by value;
* ``swarm.kernel.world._all_far_apart`` never hides a pair the k-d tree would report;
* :meth:`swarm.kernel.recorder.EventLog.flush` (one pack call per tick) writes the bytes of packing
  each event on its own;
* targets draw their noise ahead in blocks, in the order of one draw per step;
* :meth:`agents.knowledge.Knowledge.merge_tracks` is ``merge_track`` of each item.
"""

from __future__ import annotations

import io
import math

import msgpack
import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from agents.dynamics import clamp
from agents.knowledge import Knowledge, KnownThreat
from agents.maps.grid import Grid
from agents.types import UavType
from comms.codec import FrameError, _num, _nums
from comms.messages import TrackItem
from swarm.kernel.recorder import EventLog
from swarm.kernel.world import ALIVE, PENDING, TargetMotion, Targets, UavBody, World, _all_far_apart

any_float = st.floats(allow_nan=True, allow_infinity=True)
edge_floats = st.sampled_from([0.0, -0.0, 1.0, -1.0, math.inf, -math.inf, math.nan])


def _same(a: float, b: float) -> bool:
    """Identical floats: NaN is NaN, and 0.0 is not -0.0."""
    return (math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1.0, a) == math.copysign(1.0, b))


@settings(max_examples=examples(500))
@given(st.one_of(any_float, edge_floats), st.one_of(any_float, edge_floats), st.one_of(any_float, edge_floats))
def test_clamp_is_min_of_max(v, lo, hi):
    assert _same(clamp(v, lo, hi), min(max(v, lo), hi))


# --- sensing --------------------------------------------------------------------------------

KIND_A = UavType("A", 20.0, 40.0, 1.0, 0.5, 1500.0, 1.0, 1.0, 5000.0)
KIND_B = UavType("B", 60.0, 90.0, 0.6, 0.35, 2000.0, 2.0, 2.1, 4000.0)
KIND_C = UavType("C", 20.0, 40.0, 1.0, 0.5, 1500.0, 1.0, 1.0, 5000.0, daa_range=1200.0)
KIND_OFF = UavType("O", 20.0, 40.0, 1.0, 0.5, 1500.0, 1.0, 1.0, 5000.0, daa_range=0.0)


def _reading_by_formula(world: World, uid: int, t: float):
    """What sense() computed per UAV before sense_many(): one distance test per UAV."""
    b = world.uavs[uid]
    r = b.kind.detect_radius
    tg = world.targets
    seen = []
    if len(tg):
        xy = tg.xy
        d2 = (xy[:, 0] - b.x) ** 2 + (xy[:, 1] - b.y) ** 2
        for i in np.flatnonzero(d2 <= r * r).tolist():
            v, th = tg.v[i], tg.theta[i]
            seen.append((i, tg.x[i], tg.y[i], v * math.cos(th), v * math.sin(th), tg.value[i]))
    threats = [th.threat for th in world.threats if math.hypot(th.x - b.x, th.y - b.y) - th.radius <= r]
    # Detect and avoid: every other flying UAV within this one's range, pair by pair.
    daa = None
    if b.kind.daa_range > 0:
        daa = [(o.uid, o.x, o.y, o.v * math.cos(o.theta), o.v * math.sin(o.theta))
               for o in sorted(world.uavs.values(), key=lambda o: o.uid)
               if o.uid != uid and o.state == ALIVE and (o.x - b.x) ** 2 + (o.y - b.y) ** 2 <= b.kind.daa_range ** 2]
    return seen, threats, daa


coords = st.floats(0.0, 10_000.0)


@settings(deadline=None, max_examples=examples(100))
@given(
    st.lists(st.tuples(coords, coords, st.sampled_from([KIND_A, KIND_B, KIND_C, KIND_OFF]), st.booleans(),
                       st.floats(-math.pi, math.pi)), min_size=0, max_size=8),
    st.lists(st.tuples(coords, coords, st.floats(-math.pi, math.pi), st.floats(0.0, 20.0)), max_size=10),
    st.lists(st.tuples(coords, coords, st.floats(100.0, 3000.0)), max_size=3),
)
def test_sense_many_equals_one_by_one(uavs, targets, threats):
    tg = Targets(TargetMotion())
    for k, (x, y, th, v) in enumerate(targets):
        tg.add(x, y, th, v, 1.0 + k, np.random.default_rng(k))
    world = World(Grid(10_000.0, 10_000.0, 100.0), tg,
                  [KnownThreat(i, x, y, r, 2 * r) for i, (x, y, r) in enumerate(threats)])
    for uid, (x, y, kind, flying, theta) in enumerate(uavs):
        world.add_uav(UavBody(uid, f"U{uid}", kind, x, y, 50.0, theta, ALIVE if flying else PENDING))
    ids = world.alive_ids()
    readings = world.sense_many(ids, 7.0)
    assert len(readings) == len(ids)
    for uid, r in zip(ids, readings):
        seen, threat_ids, daa = _reading_by_formula(world, uid, 7.0)
        assert [(s.target, s.x, s.y, s.vx, s.vy, s.value) for s in r.targets] == seen
        assert [th.threat for th in r.threats] == threat_ids
        assert r.uavs == daa
        b = world.uavs[uid]
        assert (r.t, r.x, r.y, r.v, r.theta) == (7.0, b.x, b.y, b.v, b.theta)
        assert world.sense(uid, 7.0) == r


# --- codec ----------------------------------------------------------------------------------

field_values = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-(2**70), 2**70), st.booleans(),
    st.none(), st.text(max_size=3), st.binary(max_size=3),
)


def _num_each(values: list):
    try:
        return tuple(_num(v) for v in values)
    except FrameError as exc:
        return ("FrameError", str(exc))


@settings(max_examples=examples(500))
@given(st.one_of(st.lists(st.floats(allow_nan=False, allow_infinity=False), max_size=12), st.lists(field_values, max_size=8)))
def test_nums_equals_num_of_each_value(values):
    try:
        got = _nums(values)
    except FrameError as exc:
        got = ("FrameError", str(exc))
    expected = _num_each(values)
    assert got == expected
    if got and got[0] != "FrameError":
        assert all(type(v) is float for v in got)


# --- separation screen ----------------------------------------------------------------------


@settings(deadline=None, max_examples=examples(300))
@given(st.lists(st.tuples(st.floats(0.0, 3000.0), st.floats(0.0, 3000.0)), min_size=2, max_size=20),
       st.floats(1.0, 800.0))
def test_separation_screen_never_hides_a_pair(points, r):
    xy = np.array(points, dtype=float)
    if _all_far_apart(xy, r):
        assert len(cKDTree(xy).query_pairs(r)) == 0


def test_separation_screen_defers_near_pairs_and_large_swarms():
    assert _all_far_apart(np.array([[0.0, 0.0], [203.0, 0.0]]), 200.0)
    assert not _all_far_apart(np.array([[0.0, 0.0], [201.0, 0.0]]), 200.0)  # near: the k-d tree decides
    assert not _all_far_apart(np.array([[0.0, 0.0], [200.0, 0.0]]), 200.0)
    far = np.array([[1000.0 * i, 0.0] for i in range(40)])
    assert not _all_far_apart(far, 200.0)  # large swarm: always the k-d tree


@pytest.mark.parametrize("n", [0, 1, 3])
def test_targets_xy_is_an_n_by_2_array(n):
    tg = Targets(TargetMotion())
    for k in range(n):
        tg.add(10.0 * k, 20.0 * k, 0.0, 1.0, 1.0, np.random.default_rng(k))
    assert tg.xy.shape == (n, 2)
    assert tg.xy.tolist() == [[10.0 * k, 20.0 * k] for k in range(n)]
    tg.step(1.0, Grid(1000.0, 1000.0, 100.0))
    assert tg.xy.tolist() == [[x, y] for x, y in zip(tg.x, tg.y)]




_event_fields = st.one_of(st.integers(-2**63, 2**64 - 1), st.floats(allow_nan=False), st.text(max_size=40),
                          st.booleans(), st.none(), st.binary(max_size=40))
_events = st.lists(st.tuples(st.sampled_from(["pose", "rx", "target"]), st.floats(0, 1e6),
                             st.lists(_event_fields, max_size=8)), max_size=40)


def _check_flush(ticks: list[list[tuple]]) -> None:
    packer = msgpack.Packer(use_bin_type=True)
    log = EventLog()
    expected = bytearray()
    for events in ticks:
        for e in events:
            log.emit(*e)
            expected += packer.pack(e)
        log.flush()
    assert log.to_bytes() == bytes(expected)
    # (arrays of any shape: the recorder packs what it is given; swarm.events checks kinds)
    assert log.total == sum(map(len, ticks)) == len(list(msgpack.Unpacker(io.BytesIO(bytes(expected)))))


@settings(max_examples=examples(200))
@given(st.lists(_events, max_size=5), st.sampled_from([0, 14, 15, 16, 17]))
def test_batched_flush_packs_each_event_as_alone(ticks, pad):
    # pad: a tick with about the first array header sizes' worth of events
    _check_flush([[("pad", 0.0, i) for i in range(pad)]] + [[(k, t, *f) for k, t, f in tick] for tick in ticks])


@pytest.mark.parametrize("n", [0xFFFF, 0x10000])
def test_batched_flush_of_large_ticks(n):
    _check_flush([[("rx", 1.0, i, 2, 230, True) for i in range(n)], [("pose", 2.0, 0)]])


def test_target_noise_drawn_ahead_is_drawn_in_the_same_order():
    from swarm.kernel.world import _DRAW_BLOCK, _Normals

    ahead, direct = _Normals(np.random.default_rng(3)), np.random.default_rng(3)
    n = 3 * _DRAW_BLOCK // 2 + 5  # over several blocks
    assert [ahead.pair() for _ in range(n)] == [tuple(direct.standard_normal(2).tolist()) for _ in range(n)]
    # Targets sharing one generator share its draws ahead (the order of draws of one call
    # each): tests/test_many_targets.py.


_items = st.lists(st.builds(TrackItem, st.integers(0, 4), st.floats(-1e4, 1e4), st.floats(-1e4, 1e4), st.floats(-50, 50),
                            st.floats(-50, 50), st.sampled_from([0.0, 1.0, 2.0, 3.0]), st.floats(0, 10)), max_size=12)


@given(st.lists(_items, max_size=6))
def test_merge_tracks_is_merge_track_of_each_item(messages):
    one_by_one, batched = Knowledge(), Knowledge()
    for items in messages:
        for item in items:
            one_by_one.merge_track(item)
        batched.merge_tracks(items)
        assert batched.tracks == one_by_one.tracks
