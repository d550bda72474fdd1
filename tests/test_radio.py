"""Tests for comms.radio (Radio, LinkModel), the fault injector as its link filter
(faults.injector.FaultInjector with faults.schedule faults) and comms.mailbox.Mailbox.

Every radio is built with a deterministic link-rng factory: link (src, dst) gets
``numpy.random.default_rng([seed, src, dst])``.
"""

from __future__ import annotations

import math
from collections import Counter

import networkx as nx
import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from comms.codec import FrameError, decode, encode
from comms.mailbox import Mailbox
from comms.messages import Hello, Intent, ScanRecords
from comms.radio import Delivery, Radio
from comms.settings import LinkModel
from faults.injector import FaultInjector
from faults.schedule import Burst, Corrupt, Delay, Drop, Duplicate, FaultSchedule, Partition

IDS = {"a": 0, "b": 1, "c": 2}
CLOSE = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])  # three nodes all within any range


def link_rng(seed: int = 0):
    return lambda src, dst: np.random.default_rng([seed, src, dst])


def make_radio(model: LinkModel | None = None, link_filter=None, seed: int = 0) -> Radio:
    return Radio(model or LinkModel(), link_rng(seed), link_filter)


def injector(*faults) -> FaultInjector:
    return FaultInjector(FaultSchedule(list(faults)), IDS)


def frame(sender: int = 0, seq: int = 0, t: float = 0.0) -> bytes:
    return encode(sender, seq, t, [Hello(sender, "A", 1.0, 2.0, 30.0, 0.5), Intent(sender, 5.0, 6.0, 0, -1)])


def pairs(out: list[Delivery]) -> list[tuple[int, int]]:
    return [(d.sender, d.receiver) for d in out]


def all_broadcast(radio: Radio, t: float, ids, data: bytes = b"x" * 20, on_lost=None) -> list[Delivery]:
    out: list[Delivery] = []
    for u in ids:
        radio.broadcast(t, u, data, out, on_lost)
    return out


class LostLog(list):
    """Records ``on_lost(src, dst, nbytes, cause)`` calls.

    Always truthy: the radio tests ``if on_lost:``, which an empty list would fail.
    """

    def __call__(self, src, dst, nbytes, cause):
        self.append((src, dst, nbytes, cause))

    def __bool__(self) -> bool:
        return True


# ---------------------------------------------------------------------------------------------
# range and topology
# ---------------------------------------------------------------------------------------------

positions = st.lists(st.tuples(st.integers(0, 60), st.integers(0, 60)), min_size=0, max_size=9)


@settings(deadline=None)
@given(positions, st.integers(1, 40).map(lambda r: r * 25.0), st.sampled_from([0.0, 0.01, 0.5]))
def test_copies_go_exactly_to_nodes_within_range(pts, range_m, latency):
    xy = np.array([(x * 25.0, y * 25.0) for x, y in pts], dtype=float).reshape(-1, 2)
    ids = [2 * i + 1 for i in range(len(pts))]  # sorted ids that are not 0..n-1
    radio = make_radio(LinkModel(range_m=range_m, latency_s=latency))
    radio.update_topology(ids, xy, 1.0)
    t = 3.0
    out = all_broadcast(radio, t, ids)
    expected = Counter()
    for i, u in enumerate(ids):
        for j, w in enumerate(ids):
            dx, dy = xy[i] - xy[j]
            if i != j and dx * dx + dy * dy <= range_m * range_m:
                expected[(u, w)] += 1
    # loss 0: every in-range neighbour gets exactly one copy, nobody else gets any
    assert Counter(pairs(out)) == expected
    assert all(d.arrival_t == t + latency for d in out)
    assert radio.counters.sent == sum(expected.values())
    assert radio.counters.dropped_total == 0
    for u in ids:
        assert radio.neighbours(u) == sorted(w for (s, w) in expected if s == u)
    for u, w, attrs in radio.graph.edges(data=True):
        assert attrs["distance"] <= range_m
        assert attrs["loss"] == 0.0
        i, j = ids.index(u), ids.index(w)
        assert attrs["distance"] == pytest.approx(float(np.hypot(*(xy[i] - xy[j]))))


def test_unlimited_range_connects_everyone():
    radio = make_radio(LinkModel(range_m=None))
    xy = np.array([[0.0, 0.0], [1e6, 0.0], [0.0, 1e7]])
    radio.update_topology([0, 1, 2], xy, 1.0)
    out = all_broadcast(radio, 0.0, [0, 1, 2])
    assert sorted(pairs(out)) == [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]


def test_range_boundary_is_inclusive():
    radio = make_radio(LinkModel(range_m=500.0))
    radio.update_topology([0, 1, 2], np.array([[0.0, 0.0], [300.0, 400.0], [0.0, -500.1]]), 1.0)
    assert radio.neighbours(0) == [1]
    assert radio.neighbours(2) == []
    assert radio.neighbours(1) == [0]


def test_nodes_not_in_topology_neither_send_nor_receive():
    radio = make_radio(LinkModel(range_m=1000.0))
    xy = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [30.0, 0.0]])
    radio.update_topology([0, 1, 2, 3], xy, 1.0)
    assert len(all_broadcast(radio, 0.0, [0, 1, 2, 3])) == 12
    # node 2 fails, node 3 has not joined yet... both leave the graph
    radio.update_topology([0, 1], xy[:2], 1.0)
    sent_before = radio.counters.sent
    out: list[Delivery] = []
    radio.broadcast(1.0, 2, b"from a dead node", out)
    radio.broadcast(1.0, 3, b"from a dead node", out)
    assert out == [] and radio.counters.sent == sent_before
    out = all_broadcast(radio, 1.0, [0, 1])
    assert sorted(pairs(out)) == [(0, 1), (1, 0)]
    assert set(radio.graph.nodes) == {0, 1}
    assert radio.neighbours(2) == [] and radio.neighbours(3) == []
    # a node never given to update_topology at all
    fresh = make_radio()
    fresh.update_topology([5, 6], np.array([[0.0, 0.0], [1.0, 1.0]]), 1.0)
    out = []
    fresh.broadcast(0.0, 7, b"x", out)
    assert out == []
    # rejoining restores both directions
    radio.update_topology([0, 1, 2], xy[:3], 1.0)
    assert sorted(pairs(all_broadcast(radio, 2.0, [0, 1, 2]))) == [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]


# ---------------------------------------------------------------------------------------------
# loss
# ---------------------------------------------------------------------------------------------


def test_loss_base_one_loses_every_copy():
    radio = make_radio(LinkModel(range_m=1000.0, loss_base=1.0, loss_at_range=1.0))
    radio.update_topology([0, 1, 2], CLOSE, 1.0)
    lost = LostLog()
    out = []
    for t in range(20):
        out += all_broadcast(radio, float(t), [0, 1, 2], b"y" * 7, lost)
    assert out == []
    assert radio.counters.sent == 120
    assert radio.counters.dropped == {"loss": 120}
    assert radio.counters.dropped_total == 120
    assert len(lost) == 120 and {c for *_, c in lost} == {"loss"} and {n for _, _, n, _ in lost} == {7}
    assert radio.counters.bytes_sent == 120 * 7


def test_loss_rate_matches_link_model():
    model = LinkModel(range_m=1000.0, loss_base=0.2, loss_at_range=0.2)
    radio = make_radio(model, seed=11)
    radio.update_topology([0, 1], np.array([[0.0, 0.0], [100.0, 0.0]]), 1.0)
    out = []
    n = 4000
    for t in range(n):
        radio.broadcast(float(t), 0, b"z", out)
    assert abs(len(out) / n - 0.8) < 0.03  # ~4.7 sigma
    assert radio.counters.dropped["loss"] == n - len(out)


@settings(deadline=None)
@given(
    st.floats(0.0, 1.0),
    st.floats(0.0, 1.0),
    st.floats(1.0, 1e5),
    st.floats(0.0, 1.0),
)
def test_loss_curve(base, at_range, range_m, frac):
    base, at_range = min(base, at_range), max(base, at_range)  # loss never falls with distance (test_propagation)
    m = LinkModel(range_m=range_m, loss_base=base, loss_at_range=at_range)
    assert m.loss(0.0) == base
    assert m.loss(range_m) == pytest.approx(at_range, abs=1e-15)
    # quadratic in between, clamped beyond the range
    assert m.loss(frac * range_m) == pytest.approx(base + (at_range - base) * frac * frac, abs=1e-12)
    assert m.loss(2.0 * range_m) == pytest.approx(at_range, abs=1e-15)
    lo, hi = min(base, at_range), max(base, at_range)
    assert lo - 1e-15 <= m.loss(frac * range_m) <= hi + 1e-15
    # unlimited range: the base loss everywhere
    for r in (None, math.inf):
        assert LinkModel(range_m=r, loss_base=base, loss_at_range=at_range).loss(frac * 1e9) == base


def test_edge_loss_attribute_follows_distance():
    model = LinkModel(range_m=1000.0, loss_base=0.1, loss_at_range=0.5)
    radio = make_radio(model)
    radio.update_topology([0, 1, 2], np.array([[0.0, 0.0], [500.0, 0.0], [0.0, 1000.0]]), 1.0)
    assert radio.graph.edges[0, 1]["loss"] == pytest.approx(0.1 + 0.4 * 0.25)
    assert radio.graph.edges[0, 2]["loss"] == pytest.approx(0.5)
    assert not radio.graph.has_edge(1, 2)  # 1118 m apart


# ---------------------------------------------------------------------------------------------
# incremental topology: the same graph as one rebuilt from scratch every tick
# ---------------------------------------------------------------------------------------------

moving_swarm = st.lists(  # per tick: {id: (x, y)} of the live nodes (ids come and go)
    st.dictionaries(st.integers(0, 11), st.tuples(st.integers(0, 40), st.integers(0, 40)), max_size=12),
    min_size=1, max_size=8,
)


@settings(deadline=None, max_examples=examples(150))
@given(moving_swarm, st.sampled_from([None, 250.0, 400.0, 1000.0]), st.sampled_from([(0.0, 0.0), (0.1, 0.6)]))
def test_incremental_topology_equals_rebuilt_graph(ticks, range_m, loss):
    model = LinkModel(range_m=range_m, loss_base=loss[0], loss_at_range=loss[1])
    radio = make_radio(model)
    for nodes in ticks:
        ids = sorted(nodes)
        xy = np.array([(nodes[u][0] * 25.0, nodes[u][1] * 25.0) for u in ids], dtype=float).reshape(-1, 2)
        radio.update_topology(ids, xy, 1.0)
        fresh = make_radio(model)
        fresh.update_topology(ids, xy, 1.0)
        assert nx.utils.graphs_equal(radio.graph, fresh.graph)  # nodes, edges and edge data
        assert list(radio.graph.nodes) == [u for u in radio.graph.nodes if u in nodes]  # no dead node kept
        # and the edge attributes are exactly the link model's, at the exact distance
        for u, v, attrs in radio.graph.edges(data=True):
            i, j = ids.index(u), ids.index(v)
            d = float(np.hypot(xy[i, 0] - xy[j, 0], xy[i, 1] - xy[j, 1]))
            assert attrs == {"distance": d, "loss": model.loss(d)}
        for u in range(12):
            expected = sorted(radio.graph.adj[u]) if u in nodes else []
            assert radio.neighbours(u) == fresh.neighbours(u) == expected


# ---------------------------------------------------------------------------------------------
# per-link random streams
# ---------------------------------------------------------------------------------------------


def _independence_run(with_third: bool, faults) -> tuple[list, list]:
    model = LinkModel(range_m=1000.0, loss_base=0.3, loss_at_range=0.6, latency_s=0.05, jitter_s=0.1)
    inj = injector(*faults) if faults is not None else None
    radio = make_radio(model, inj, seed=5)
    ids = [0, 1, 2] if with_third else [0, 1]
    xy = np.array([[0.0, 0.0], [400.0, 0.0], [0.0, 300.0]])[: len(ids)]
    out: list[Delivery] = []
    for k in range(60):
        t = k * 0.5
        radio.update_topology(ids, xy, 0.5)
        if inj is not None:
            inj.begin_tick(t)
        if with_third:  # node 2 speaks first, so its draws would come first on a shared stream
            radio.broadcast(t, 2, frame(2, k, t), out)
        # with node 2 present, 0 and 1 also send copies to it (links 0->2, 1->2) in between
        radio.broadcast(t, 0, frame(0, k, t), out)
        radio.broadcast(t, 1, frame(1, k, t), out)
    on_01 = [(d.arrival_t, d.data) for d in out if (d.sender, d.receiver) == (0, 1)]
    on_10 = [(d.arrival_t, d.data) for d in out if (d.sender, d.receiver) == (1, 0)]
    return on_01, on_10


@pytest.mark.parametrize(
    "faults",
    [
        None,
        (Drop(rate=0.2), Duplicate(rate=0.3), Delay(extra_s=0.5, jitter_s=0.2), Corrupt(rate=0.2)),
        (Burst(p_enter_bad=0.2, p_exit_bad=0.4, loss_good=0.05, loss_bad=0.9),),
    ],
    ids=["no-faults", "drop-dup-delay-corrupt", "burst"],
)
def test_each_directed_link_has_its_own_stream(faults):
    ref_01, ref_10 = _independence_run(with_third=False, faults=faults)
    got_01, got_10 = _independence_run(with_third=True, faults=faults)
    assert len(ref_01) > 10 and len(ref_10) > 10
    assert got_01 == ref_01
    assert got_10 == ref_10


def test_adding_traffic_on_other_links_does_not_change_a_link():
    """Node 2's extra frames (on links 2->0, 2->1) leave links 0->1 and 1->0 alone."""
    model = LinkModel(range_m=1000.0, loss_base=0.4, jitter_s=0.3)

    def run(extra: bool):
        radio = make_radio(model, seed=9)
        radio.update_topology([0, 1, 2], CLOSE, 1.0)
        out: list[Delivery] = []
        for k in range(80):
            if extra and k % 3 == 0:
                for _ in range(5):
                    radio.broadcast(float(k), 2, b"noise", out)
            radio.broadcast(float(k), 0, bytes([k]), out)
            radio.broadcast(float(k), 1, bytes([k]), out)
        return [d for d in out if d.sender in (0, 1) and d.receiver in (0, 1)]

    quiet, busy = run(False), run(True)
    assert quiet == busy
    assert 0 < len(quiet) < 160  # some copies lost, some delivered


def test_same_seed_same_result_different_seed_different_result():
    model = LinkModel(range_m=1000.0, loss_base=0.5, jitter_s=1.0)

    def run(seed):
        radio = make_radio(model, seed=seed)
        radio.update_topology([0, 1, 2], CLOSE, 1.0)
        out = []
        for k in range(30):
            out += all_broadcast(radio, float(k), [0, 1, 2])
        return out

    assert run(1) == run(1)
    assert run(1) != run(2)


# ---------------------------------------------------------------------------------------------
# bandwidth
# ---------------------------------------------------------------------------------------------


def test_bandwidth_cap_drops_frames_over_budget():
    radio = make_radio(LinkModel(range_m=1000.0, bandwidth_bytes_per_s=100.0))
    radio.update_topology([0, 1, 2], CLOSE, 1.0)  # bucket starts full: 100 bytes
    lost = LostLog()
    out: list[Delivery] = []
    radio.broadcast(0.0, 0, b"a" * 60, out, lost)  # 40 left
    assert len(out) == 2
    radio.broadcast(0.0, 0, b"b" * 60, out, lost)  # over budget: not transmitted
    assert len(out) == 2
    assert radio.counters.dropped == {"bandwidth": 2}
    assert lost == [(0, 1, 60, "bandwidth"), (0, 2, 60, "bandwidth")]
    radio.broadcast(0.0, 0, b"c" * 40, out, lost)  # exactly the remaining budget
    assert len(out) == 4
    radio.broadcast(0.0, 0, b"d", out, lost)  # empty bucket
    assert radio.counters.dropped == {"bandwidth": 4}
    # each sender has its own budget
    radio.broadcast(0.0, 1, b"e" * 100, out, lost)
    assert len(out) == 6
    # half a second refills 50 bytes
    radio.update_topology([0, 1, 2], CLOSE, 0.5)
    radio.broadcast(0.5, 0, b"f" * 51, out, lost)
    assert len(out) == 6
    radio.broadcast(0.5, 0, b"f" * 50, out, lost)
    assert len(out) == 8
    # the bucket holds at most one second of traffic, so a frame over bw never fits
    for _ in range(5):
        radio.update_topology([0, 1, 2], CLOSE, 1.0)
    radio.broadcast(10.0, 2, b"g" * 101, out, lost)
    assert len(out) == 8
    radio.broadcast(10.0, 2, b"g" * 100, out, lost)
    assert len(out) == 10
    assert radio.counters.dropped == {"bandwidth": 8}  # 4 frames over budget x 2 neighbours


def test_no_bandwidth_limit_by_default():
    radio = make_radio(LinkModel(range_m=1000.0))
    radio.update_topology([0, 1], CLOSE[:2], 1.0)
    out = []
    for _ in range(100):
        radio.broadcast(0.0, 0, b"q" * 60000, out)
    assert len(out) == 100 and radio.counters.dropped_total == 0


# ---------------------------------------------------------------------------------------------
# fault injection as the link filter
# ---------------------------------------------------------------------------------------------

ALL_LINKS = [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]


def fault_radio(*faults, model: LinkModel | None = None, seed: int = 0):
    inj = injector(*faults)
    radio = make_radio(model or LinkModel(range_m=1000.0), inj, seed=seed)
    radio.update_topology([0, 1, 2], CLOSE, 1.0)
    return inj, radio


def tick(inj: FaultInjector, radio: Radio, t: float, data: bytes = b"p" * 16, on_lost=None) -> list[Delivery]:
    inj.begin_tick(t)
    return all_broadcast(radio, t, [0, 1, 2], data, on_lost)


@pytest.mark.parametrize("one_way", [False, True])
def test_partition_blocks_crossing_copies_while_active(one_way):
    inj, radio = fault_radio(Partition(groups=(("a",), ("b", "c")), start_s=10.0, end_s=20.0, one_way=one_way))
    assert sorted(pairs(tick(inj, radio, 5.0))) == ALL_LINKS
    assert inj.fired["partition"] == 0
    if one_way:  # only earlier group -> later group, i.e. a -> b and a -> c
        allowed = [(1, 0), (1, 2), (2, 0), (2, 1)]
    else:
        allowed = [(1, 2), (2, 1)]
    blocked = len(ALL_LINKS) - len(allowed)
    for k, t in enumerate([10.0, 12.0, 19.999]):
        lost = LostLog()
        assert sorted(pairs(tick(inj, radio, t, on_lost=lost))) == allowed
        assert {(s, d) for s, d, _, _ in lost} == set(ALL_LINKS) - set(allowed)
        assert {c for *_, c in lost} == {"partition"}
        assert inj.fired["partition"] == blocked * (k + 1)
    assert radio.counters.dropped == {"partition": 3 * blocked}
    # healed at end_s (half-open window)
    for t in (20.0, 25.0):
        assert sorted(pairs(tick(inj, radio, t))) == ALL_LINKS
    assert inj.fired["partition"] == 3 * blocked


def test_partition_leaves_ungrouped_uavs_alone():
    ids = {"a": 0, "b": 1, "c": 2}
    inj = FaultInjector(FaultSchedule([Partition(groups=(("a",), ("b",)))]), ids)
    radio = make_radio(LinkModel(), inj)
    radio.update_topology([0, 1, 2], CLOSE, 1.0)
    assert sorted(pairs(tick(inj, radio, 0.0))) == [(0, 2), (1, 2), (2, 0), (2, 1)]


def test_drop_scoped_to_one_uav():
    inj, radio = fault_radio(Drop(rate=1.0, uavs=("b",)))
    lost = LostLog()
    out = []
    for t in range(10):
        out += tick(inj, radio, float(t), on_lost=lost)
    assert Counter(pairs(out)) == Counter({(0, 2): 10, (2, 0): 10})
    assert Counter((s, d) for s, d, _, _ in lost) == Counter({(0, 1): 10, (1, 0): 10, (1, 2): 10, (2, 1): 10})
    assert {c for *_, c in lost} == {"drop"}
    assert inj.fired["drop"] == 40
    assert radio.counters.dropped == {"drop": 40}


def test_drop_scoped_to_a_directed_link():
    inj, radio = fault_radio(Drop(rate=1.0, links=(("a", "b"),)))
    out = tick(inj, radio, 0.0)
    assert sorted(pairs(out)) == [(0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]
    assert inj.fired["drop"] == 1


def test_duplicate_rate_one_makes_two_copies():
    inj, radio = fault_radio(Duplicate(rate=1.0))
    data = frame()
    out = tick(inj, radio, 1.0, data)
    assert Counter(pairs(out)) == Counter({link: 2 for link in ALL_LINKS})
    assert all(d.data == data and d.arrival_t == 1.0 for d in out)
    assert radio.counters.duplicated == 6
    assert inj.fired["duplicate"] == 6
    assert radio.counters.sent == 6  # copies offered, not copies created


def test_two_duplicate_faults_make_three_copies():
    inj, radio = fault_radio(Duplicate(rate=1.0), Duplicate(rate=1.0, uavs=("a",)))
    out = tick(inj, radio, 0.0)
    c = Counter(pairs(out))
    assert c[(0, 1)] == c[(0, 2)] == c[(1, 0)] == c[(2, 0)] == 3
    assert c[(1, 2)] == c[(2, 1)] == 2


def test_corrupt_rate_one_changes_the_bytes():
    inj, radio = fault_radio(Corrupt(rate=1.0, bytes=1))
    out = []
    sent = {}
    for k in range(30):
        data = encode(k % 3, k, float(k), [ScanRecords(k % 3, (float(k), 1.0, 2.0, 3.0)), Intent(k % 3, 1.0, 2.0, 1, 4)])
        sent[k] = data
        inj.begin_tick(float(k))
        radio.broadcast(float(k), k % 3, data, out)
    assert len(out) == 60
    assert inj.fired["corrupt"] == 60
    for d in out:
        original = sent[int(d.arrival_t)]
        assert d.data != original
        assert len(d.data) == len(original)
        assert sum(a != b for a, b in zip(d.data, original)) == 1
        try:
            got = decode(d.data)
        except FrameError:
            continue
        assert got != decode(original)


def test_delay_adds_extra_time():
    inj, radio = fault_radio(Delay(extra_s=2.5), model=LinkModel(range_m=1000.0, latency_s=0.1))
    out = tick(inj, radio, 4.0)
    assert len(out) == 6
    assert all(d.arrival_t == pytest.approx(4.0 + 0.1 + 2.5) for d in out)
    assert inj.fired["delay"] == 6


def test_delay_jitter_stays_in_window():
    inj, radio = fault_radio(Delay(extra_s=1.0, jitter_s=0.5, uavs=("c",)))
    extras = []
    for t in range(50):
        out = tick(inj, radio, float(t))
        assert len(out) == 6
        for d in out:
            if 2 in (d.sender, d.receiver):
                extras.append(d.arrival_t - t)
            else:
                assert d.arrival_t == float(t)
    assert len(extras) == 200
    assert all(1.0 <= e < 1.5 for e in extras)
    assert max(extras) - min(extras) > 0.3  # the jitter is not constant
    assert inj.fired["delay"] == 200


def test_burst_enter_bad_at_once_drops_everything():
    inj, radio = fault_radio(Burst(p_enter_bad=1.0, p_exit_bad=0.0, loss_good=0.0, loss_bad=1.0, start_s=5.0))
    out = []
    for t in range(5):
        out += tick(inj, radio, float(t))
    assert len(out) == 30  # before the window
    lost = LostLog()
    for t in range(5, 40):
        assert tick(inj, radio, float(t), on_lost=lost) == []
    assert len(lost) == 35 * 6 and {c for *_, c in lost} == {"burst"}
    assert inj.fired["burst"] == 35 * 6


def test_burst_chain_alternates_per_link():
    """p_enter_bad = p_exit_bad = 1: each link's chain flips state on every copy."""
    inj, radio = fault_radio(Burst(p_enter_bad=1.0, p_exit_bad=1.0, loss_good=0.0, loss_bad=1.0))
    per_tick = []
    for t in range(6):
        per_tick.append(sorted(pairs(tick(inj, radio, float(t)))))
    # copy 1 enters bad (lost), copy 2 leaves (delivered), copy 3 enters again (lost), ...
    assert per_tick == [[], ALL_LINKS, [], ALL_LINKS, [], ALL_LINKS]
    # each link's chain advances only with its own copies: two more frames from node 0 put
    # links 0->1 and 0->2 through bad (lost) and back to good (delivered) ...
    out: list[Delivery] = []
    inj.begin_tick(6.0)
    radio.broadcast(6.0, 0, b"x", out)
    assert out == []
    radio.broadcast(6.0, 0, b"x", out)
    assert pairs(out) == [(0, 1), (0, 2)]
    # ... while the other links, untouched, still lose their next copy
    out = []
    radio.broadcast(7.0, 1, b"x", out)
    radio.broadcast(7.0, 2, b"x", out)
    assert out == []


def test_burst_never_entering_bad_loses_nothing():
    inj, radio = fault_radio(Burst(p_enter_bad=0.0, p_exit_bad=0.5, loss_good=0.0, loss_bad=1.0))
    out = []
    for t in range(20):
        out += tick(inj, radio, float(t))
    assert len(out) == 120 and inj.fired["burst"] == 0


def test_fired_counts_only_faults_that_acted():
    inert = Drop(rate=1.0, start_s=1000.0, end_s=2000.0)  # window never opens in this run
    never_covers = Drop(rate=1.0, links=(("a", "a"),))  # a self-link: no copy ever uses it
    inj, radio = fault_radio(inert, never_covers, Duplicate(rate=1.0, uavs=("b",)), Delay(extra_s=0.5, start_s=3.0))
    assert inj.fired == {"drop": 0, "duplicate": 0, "delay": 0}
    out = []
    for t in range(6):
        out += tick(inj, radio, float(t))
    assert inj.fired["drop"] == 0
    assert inj.fired["duplicate"] == 6 * 4  # 4 links touch b, 6 ticks
    assert inj.fired["delay"] == 3 * 6  # ticks 3..5: once per copy offered (duplicates share it)
    assert len(out) == 6 * (6 + 4)
    assert radio.counters.dropped_total == 0


def test_injector_idle_and_fired_keys():
    inj = injector(Drop(rate=1.0, start_s=1.0, end_s=2.0), Partition(groups=(("a",), ("b",)), start_s=5.0))
    assert set(inj.fired) == {"drop", "partition"} and not any(inj.fired.values())
    inj.begin_tick(0.0)
    assert inj.idle
    inj.begin_tick(1.0)
    assert not inj.idle
    inj.begin_tick(2.0)
    assert inj.idle
    inj.begin_tick(5.0)
    assert not inj.idle and inj.blocked(0, 1) and inj.blocked(1, 0) and not inj.blocked(0, 2)


def test_fault_order_in_schedule_does_not_matter():
    inj, radio = fault_radio(Delay(extra_s=1.0), Drop(rate=1.0))
    for t in range(3):
        assert tick(inj, radio, float(t)) == []
    assert inj.fired["drop"] == 18
    assert inj.fired["delay"] == 0, "no copy was delayed: they were all dropped"

    def run(*faults):
        inj, radio = fault_radio(*faults, seed=3)
        out = []
        for t in range(40):
            out += tick(inj, radio, float(t))
        return out

    assert run(Drop(rate=0.5), Duplicate(rate=0.5)) == run(Duplicate(rate=0.5), Drop(rate=0.5))


def test_corrupt_flips_exactly_the_requested_number_of_bytes():
    inj, radio = fault_radio(Corrupt(rate=1.0, bytes=2))
    data = b"abcd"
    out = []
    for t in range(100):
        out += tick(inj, radio, float(t), data)
    assert len(out) == 600
    for d in out:
        assert sum(a != b for a, b in zip(d.data, data)) == 2


# ---------------------------------------------------------------------------------------------
# mailbox
# ---------------------------------------------------------------------------------------------


def test_mailbox_drops_and_counts_frames_beyond_capacity():
    mb = Mailbox(3)
    results = [mb.put(float(i), i, bytes([i])) for i in range(5)]
    assert results == [True, True, True, False, False]
    assert len(mb) == 3
    assert (mb.stats.accepted, mb.stats.dropped_full, mb.stats.max_depth) == (3, 2, 3)
    assert mb.drain() == [(0.0, 0, b"\x00"), (1.0, 1, b"\x01"), (2.0, 2, b"\x02")]  # FIFO, oldest kept
    assert len(mb) == 0 and mb.drain() == []
    assert mb.put(9.0, 9, b"\x09") is True
    assert (mb.stats.accepted, mb.stats.dropped_full, mb.stats.max_depth) == (4, 2, 3)
    assert mb.drain() == [(9.0, 9, b"\x09")]


@settings(deadline=None)
@given(st.integers(1, 10), st.lists(st.booleans(), max_size=60))
def test_mailbox_invariants(capacity, ops):
    """ops: True = put, False = drain; a model queue predicts every result."""
    mb = Mailbox(capacity)
    model: list = []
    accepted = dropped = depth = 0
    for i, op in enumerate(ops):
        if op:
            ok = mb.put(float(i), i, b"f")
            assert ok == (len(model) < capacity)
            if ok:
                model.append((float(i), i, b"f"))
                accepted += 1
                depth = max(depth, len(model))
            else:
                dropped += 1
        else:
            assert mb.drain() == model
            model = []
        assert len(mb) == len(model) <= capacity
    assert (mb.stats.accepted, mb.stats.dropped_full, mb.stats.max_depth) == (accepted, dropped, depth)


@pytest.mark.parametrize("capacity", [0, -1])
def test_mailbox_rejects_bad_capacity(capacity):
    with pytest.raises(ValueError, match=rf"mailbox capacity must be >= 1, got {capacity}"):
        Mailbox(capacity)


def test_radio_to_mailbox_end_to_end():
    """Deliveries put into bounded mailboxes: overflow is counted per receiver."""
    radio = make_radio(LinkModel(range_m=1000.0))
    radio.update_topology([0, 1, 2], CLOSE, 1.0)
    boxes = {u: Mailbox(4) for u in (0, 1, 2)}
    out = []
    for k in range(3):
        out += all_broadcast(radio, float(k), [0, 1, 2], frame(0, k, float(k)))
    for d in sorted(out, key=lambda d: (d.arrival_t, d.sender, d.receiver)):
        boxes[d.receiver].put(d.arrival_t, d.sender, d.data)
    for mb in boxes.values():
        assert mb.stats.accepted == 4 and mb.stats.dropped_full == 2
        assert all(decode(data).seq in (0, 1) for _, _, data in mb.drain())


@pytest.mark.parametrize("faults", [False, True])
def test_streams_made_together_are_the_streams_made_one_by_one(faults):
    """A radio given ``link_rngs`` (issue 25: a dense swarm's first tick makes tens of thousands
    of link streams) makes them in bulk when a new link first needs one: the same copies and
    losses as making each when first needed, with links coming and going."""
    from swarm.kernel.rng import RngTree

    tree = RngTree(4)

    def one(s: int, d: int) -> np.random.Generator:
        return tree.generator("link", s, d)

    def many(links: list[tuple[int, int]]) -> list[np.random.Generator]:
        return tree.generators([("link", s, d) for s, d in links])

    model = LinkModel(range_m=60.0, loss_base=0.2, loss_at_range=0.6, jitter_s=0.2)
    runs = []
    for bulk in (None, many):
        flt = injector(Drop(rate=0.3), Duplicate(rate=0.5)) if faults else None
        radio = Radio(model, one, flt, link_rngs=bulk)
        pos = np.random.default_rng(2).uniform(0, 100, (6, 2))
        out: list[Delivery] = []
        for k in range(60):
            pos = pos + np.random.default_rng(k).normal(0, 8, pos.shape)
            radio.update_topology(list(range(6)), pos, 1.0)
            for u in range(6):
                radio.broadcast(float(k), u, bytes([k, u]), out)
        runs.append(out)
    assert runs[0] == runs[1] and len(runs[0]) > 100
