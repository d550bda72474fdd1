"""The tick plane's radio (issue 36, T3) against the per-actor radio, its oracle.

``Radio(tick_plane=True)`` keeps its links as arrays, brings the networkx graph up to date only
when it is read, and sends a tick's frames at once when nothing can happen to a copy
(``broadcast_all``); ``Radio(tick_plane=False)`` updates the graph every tick and sends copy by
copy. Over random positions, ranges, losses, jitter, bandwidth caps and link faults, the two give
the same copies in the same order, the same losses, counters and fault counts, the same graph
(nodes in the same order, edges reported the same way round, the same edge data), the same
neighbours, and consume the same numbers from every link's stream. The tick's shared pair query
(``swarm.pairs.TickPairs``) is checked against the k-d tree and numpy ways it replaces, and whole
simulations with and without the tick plane against each other (event logs, the radio graph,
mailboxes), mailbox overflow and crashed receivers included.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from comms.mailbox import Mailbox
from comms.radio import Delivery, Radio
from comms.settings import LinkModel, LogDistance
from faults.cuts import Jammer
from faults.injector import FaultInjector
from faults.schedule import Burst, Corrupt, Delay, Drop, Duplicate, FaultSchedule, Partition
from swarm.pairs import TickPairs, pairs_within

N = 8  # ids 0..N-1, named U0..
NAMES = {f"U{k}": k for k in range(N)}


def _link_rng(src: int, dst: int) -> np.random.Generator:
    return np.random.default_rng([11, src, dst])


def _link_rngs(links: list[tuple[int, int]]) -> list[np.random.Generator]:
    return [_link_rng(s, d) for s, d in links]


def _window(draw: st.DrawFn) -> dict[str, float]:
    start = draw(st.integers(0, 6))
    return {"start_s": float(start), "end_s": float(start + draw(st.integers(1, 6)))}


@st.composite
def link_faults(draw: st.DrawFn) -> list:
    """Some link faults, each active in a window of the run (so ticks go both ways)."""
    makers = [
        lambda: Drop(rate=draw(st.sampled_from([0.2, 1.0])), **_window(draw)),
        lambda: Duplicate(rate=0.4, **_window(draw)),
        lambda: Delay(extra_s=0.5, jitter_s=draw(st.sampled_from([0.0, 0.2])), **_window(draw)),
        lambda: Corrupt(rate=0.3, **_window(draw)),
        lambda: Burst(p_enter_bad=0.3, p_exit_bad=0.4, loss_good=0.05, loss_bad=0.9, **_window(draw)),
        lambda: Partition(groups=(("U0", "U1", "U2"), ("U3", "U4", "U5")), **_window(draw)),
        lambda: Jammer(x_m=500.0, y_m=500.0, radius_m=400.0, rate=0.5, **_window(draw)),
    ]
    picks = draw(st.lists(st.integers(0, len(makers) - 1), max_size=3))
    return [makers[k]() for k in picks]


@st.composite
def link_models(draw: st.DrawFn) -> LinkModel:
    kind = draw(st.sampled_from(["disk", "disk", "lossy", "log_distance"]))
    range_m = draw(st.sampled_from([None, 250.0, 400.0, 1000.0]))
    jitter = draw(st.sampled_from([0.0, 0.0, 0.2]))
    bw = draw(st.sampled_from([None, None, 300.0]))
    latency = draw(st.sampled_from([0.0, 0.05]))
    if kind == "disk":
        return LinkModel(range_m=range_m, latency_s=latency, jitter_s=jitter, bandwidth_bytes_per_s=bw)
    if kind == "lossy":
        return LinkModel(range_m=range_m, loss_base=0.1, loss_at_range=0.6, latency_s=latency, jitter_s=jitter,
                         bandwidth_bytes_per_s=bw)
    return LinkModel(range_m=range_m, log_distance=LogDistance(tx_power_dbm=-40.0), latency_s=latency,
                     bandwidth_bytes_per_s=bw)


tick_moves = st.lists(  # per tick: {id: (x, y)} of the live nodes (ids come and go)
    st.dictionaries(st.integers(0, N - 1), st.tuples(st.integers(0, 40), st.integers(0, 40)), max_size=N),
    min_size=1, max_size=8,
)
tick_frames = st.lists(  # per tick: (sender, size, unicast to or None); senders may be down
    st.lists(st.tuples(st.integers(0, N - 1), st.integers(1, 120), st.none() | st.integers(0, N - 1)), max_size=10),
    min_size=8, max_size=8,
)


class Lost(list):
    def __call__(self, src: int, dst: int, nbytes: int, cause: str) -> None:
        self.append((src, dst, nbytes, cause))


def _graph_view(radio: Radio) -> tuple:
    g = radio.graph
    return list(g.nodes), sorted(g.edges()), sorted((u, v, tuple(sorted(d.items()))) for u, v, d in g.edges(data=True))


@settings(deadline=None, max_examples=examples(200))
@given(tick_moves, tick_frames, link_models(), link_faults(), st.booleans(), st.integers(0, 2))
def test_tick_plane_radio_equals_the_per_copy_radio(moves, frames, model, faults, shared_pairs, read_every):
    injectors = [FaultInjector(FaultSchedule(list(faults)), NAMES, lambda kind, k: np.random.default_rng([3, k]))
                 for _ in range(2)]
    old = Radio(model, _link_rng, injectors[0], _link_rngs, tick_plane=False)
    new = Radio(model, _link_rng, injectors[1], _link_rngs, tick_plane=True, batch_min_links=0)
    reach = max(model.radius_m, 1.0) * 1.5 if math.isfinite(model.radius_m) else math.inf
    tick_pairs = TickPairs(reach)
    batched = 0
    for k, nodes in enumerate(moves):
        t = float(k)
        ids = sorted(nodes)
        xy = np.array([(nodes[u][0] * 25.0, nodes[u][1] * 25.0) for u in ids], dtype=float).reshape(-1, 2)
        for inj in injectors:
            inj.begin_tick(t)
            inj.set_positions(ids, xy)
        old.update_topology(ids, xy, 1.0)
        pairs = tick_pairs.of(ids, xy).within(model.radius_m)[:2] if shared_pairs else None
        new.update_topology(ids, xy, 1.0, pairs)
        sends = [(src, bytes([k, src]) * (size // 2 + 1), to) for src, size, to in frames[k]]
        out_old: list[Delivery] = []
        lost_old, lost_new = Lost(), Lost()
        for src, data, to in sends:
            old.broadcast(t, src, data, out_old, lost_old, to=to)
        batch = new.broadcast_all(t, sends, lost_new)
        if batch is not None:
            batched += 1
            out_new = batch.deliveries()
        else:
            out_new = []
            for src, data, to in sends:
                new.broadcast(t, src, data, out_new, lost_new, to=to)
        assert out_new == out_old
        assert lost_new == lost_old
        assert new.counters == old.counters
        assert injectors[1].fired == injectors[0].fired
        for u in range(N):
            assert new.neighbours(u) == old.neighbours(u)
        if read_every and k % read_every == 0:  # the graph, read now and then (synced when read)
            assert nx.utils.graphs_equal(new.graph, old.graph)
            assert _graph_view(new) == _graph_view(old)
    assert _graph_view(new) == _graph_view(old)
    # Every link's stream at the same place (a stream made by one radio and not the other:
    # never drawn from).
    streams_old, streams_new = old._link_rngs, new._link_rngs
    for link in streams_old.keys() | streams_new.keys():
        a = streams_old.get(link) or _link_rng(*link)
        b = streams_new.get(link) or _link_rng(*link)
        assert a.bit_generator.state == b.bit_generator.state, link
    # (the arrays' way was taken when it could be: no filter active, no log-distance model, no jitter,
    # not lossy with a bandwidth cap)
    if not faults and model.log_distance is None and model.jitter_s == 0.0 and (
            model.lossless or model.bandwidth_bytes_per_s is None):
        assert batched == len(moves)


@settings(deadline=None, max_examples=examples(200))
@given(st.lists(st.tuples(st.integers(0, 60), st.integers(0, 60)), max_size=40),
       st.sampled_from([0.0, 1.0, 25.0, 100.0, 500.0]), st.sampled_from([100.0, 700.0, math.inf]),
       st.sampled_from([1.0, 25.0]))
def test_tick_pairs_are_the_pairs_within_each_range(pts, r, extra, scale):
    """The shared query at its reach, filtered at a range, gives the k-d tree's and numpy's pairs
    at that range, in (i, j) order, with the squared distances the per-actor code computes."""
    xy = np.array([(x * scale, y * scale) for x, y in pts], dtype=float).reshape(-1, 2)
    tp = TickPairs(r + extra)
    ids = list(range(len(pts)))
    i, j, d2 = tp.of(ids, xy).within(r)
    got = list(zip(i.tolist(), j.tolist()))
    assert got == sorted(got)
    expected = sorted(map(tuple, pairs_within(xy, r).tolist()))
    assert got == expected
    if len(xy) >= 2:
        from scipy.spatial import cKDTree

        assert got == sorted(map(tuple, cKDTree(xy).query_pairs(r, output_type="ndarray").tolist()))
    if got:
        a, b = np.array(i), np.array(j)
        assert np.array_equal(d2, ((xy[a] - xy[b]) ** 2).sum(axis=1))
    assert tp.of(ids, xy.copy()) is tp.of(ids, xy) and tp.queries == 1  # one query for these positions


def test_mailbox_put_many_is_put_in_turn():
    for cap, before, k in [(5, 0, 3), (5, 2, 3), (5, 4, 3), (5, 5, 2), (1, 0, 4), (3, 1, 0)]:
        one, many = Mailbox(cap), Mailbox(cap)
        for m in (one, many):
            for q in range(before):
                m.put(0.5, 9, bytes([q]))
        senders, frames = list(range(k)), [bytes([10 + q]) for q in range(k)]
        took = sum(one.put(1.0, s, f) for s, f in zip(senders, frames))
        assert many.put_many([(1.0, s, f) for s, f in zip(senders, frames)]) == took
        assert many.stats == one.stats
        assert many.drain() == one.drain()


# ---------------------------------------------------------------------------------------------
# whole runs: the tick plane's radio, pair query and deliveries against the per-actor path
# ---------------------------------------------------------------------------------------------

def _run(scenario: str, tick_plane: bool, overrides: dict, duration_s: float | None, seed: int = 0):
    from swarm import Simulation
    from swarm.scenario import apply_overrides, load_scenario

    sc = apply_overrides(load_scenario(scenario), overrides) if overrides else scenario
    with Simulation(sc, duration_s=duration_s, seed=seed, tick_plane=tick_plane) as sim:
        graphs = []
        while not sim.done:
            sim.step()
            if sim._tick_index % 7 == 0:
                graphs.append(_graph_view(sim._radio))
        graphs.append(_graph_view(sim._radio))
        mail = {u: (a.mailbox.stats, len(a.mailbox)) for u, a in sim.actors.items()}
        return sim.metrics_dict()["event_log_sha256"], graphs, mail, sim._radio.counters


@pytest.mark.parametrize("scenario, overrides, duration_s", [
    ("paper-fig11", {}, 60.0),  # unlimited range, 6 UAVs
    ("paper-case2", {"radio.mailbox_capacity": 2}, 120.0),  # full mailboxes: copies lost in batch order
    # every fault kind: crashes (receivers down), spoofers, partitions, delays (6 s: slow)
    pytest.param("demo-all-faults", {}, None, marks=pytest.mark.slow),
    ("paper-case3", {"radio.range_m": 10000.0, "radio.bandwidth_bytes_per_s": 400.0}, 120.0),  # links come and go
    ("paper-case3", {"radio.range_m": 10000.0, "radio.loss_base": 0.05, "radio.loss_at_range": 0.4}, 120.0),  # lossy
])
def test_tick_plane_runs_equal_per_actor_runs(scenario, overrides, duration_s, monkeypatch):
    # (the arrays' way for every batch, however small: the case's swarms are)
    monkeypatch.setattr("comms.radio.BATCH_MIN_LINKS", 0)
    monkeypatch.setattr("swarm.kernel.transmission._BATCH_MIN_COPIES", 0)
    plane = _run(scenario, True, overrides, duration_s)
    oracle = _run(scenario, False, overrides, duration_s)
    assert plane[0] == oracle[0]  # the event log, byte for byte
    assert plane[1] == oracle[1]  # the radio graph, read every 7 ticks
    assert plane[2] == oracle[2]  # mailboxes: accepted, dropped full, depth, queued
    assert plane[3] == oracle[3]  # radio counters, drops by cause
    assert {"paper-case2": "mailbox_full", "demo-all-faults": "receiver_down",
            "paper-case3": "bandwidth" if "radio.bandwidth_bytes_per_s" in overrides else "loss"}.get(scenario, "") \
        in {"", *plane[3].dropped}  # (what each case is for)
