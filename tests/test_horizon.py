"""Issue 15, points 2 and 3: the knowledge horizon ([radio] sync_horizon_m) and the event log's
recording level ([recording] level).

The horizon keeps the scan log (and the map built from it) a max-CRDT: a set of scans joined by
union, filtered by a fixed centre, which commutes with the union. The recording level "summary"
replaces per-frame events by one bounded ``radio`` event per tick.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.maps.grid import Grid
from agents.maps.scanlog import ScanLog, within
from agents.maps.umap import UncertaintyMap
from swarm.events import Lost, Radio, Rx, read_events
from swarm.experiments import bench
from swarm.kernel.simulation import Simulation
from swarm.scenario import apply_overrides, parse_scenario
from swarm.testing.invariants import JoinerCatchUpChecker, MapAgreementChecker, Monitor, RadioChecker, check_events

# --- the scan log's join, with and without a horizon ------------------------------------------------

def _scan_of(o: int, k: int) -> tuple[int, int, float, float, float]:
    """The one scan origin ``o`` made at tick ``k`` (a UAV scans once per tick: the key decides it)."""
    return o, k, float((o * 7919 + k * 104_729) % 20_000), float((o * 31_337 + k * 613) % 20_000), (500.0, 2000.0)[k % 2]


_scans = st.lists(st.builds(_scan_of, st.integers(0, 5), st.integers(0, 40)), max_size=30)
_near = st.none() | st.tuples(st.floats(0.0, 20_000.0), st.floats(0.0, 20_000.0), st.floats(1000.0, 15_000.0))


def _log(scans) -> ScanLog:
    log = ScanLog(1.0)
    for o, k, x, y, r in scans:
        log.add(o, float(k), x, y, r)
    return log


def _state(log: ScanLog) -> list:
    return list(log.scans())


def _join(a: ScanLog, b: ScanLog, near=None) -> ScanLog:
    out = ScanLog(1.0)
    out.merge(a, near)
    out.merge(b, near)
    return out


@settings(max_examples=60, deadline=None)
@given(_scans, _scans, _scans, _near)
def test_the_scan_log_join_is_commutative_associative_idempotent_with_a_horizon(sa, sb, sc, near):
    a, b, c = _log(sa), _log(sb), _log(sc)
    assert _state(_join(a, b, near)) == _state(_join(b, a, near))
    assert _state(_join(_join(a, b, near), c, near)) == _state(_join(a, _join(b, c, near), near))
    assert _state(_join(a, a, near)) == _state(_join(a, ScanLog(1.0), near))
    # The horizon commutes with the join: keep(A | B) = keep(A) | keep(B).
    assert _state(_join(_join(a, b), ScanLog(1.0), near)) == _state(_join(a, b, near))
    # Every scan kept lies inside it.
    assert all(within(s[1], s[2], near) for _, s in _join(a, b, near).scans())


@settings(max_examples=40, deadline=None)
@given(_scans, st.randoms(use_true_random=False), _near)
def test_the_map_of_the_kept_scans_does_not_depend_on_order_or_duplicates(scans, rnd, near):
    grid = Grid(20_000.0, 20_000.0, 500.0)

    def build(order) -> np.ndarray:
        log, m = ScanLog(1.0), UncertaintyMap(grid, 0.01)
        for o, k, x, y, r in order:
            if within(x, y, near) and log.add(o, float(k), x, y, r):
                m.scan(x, y, r, float(k))
        return m.to_dense()

    # One origin's scan of one tick is one scan: distinct keys, then resent / doubled copies.
    distinct = list({(o, k): (o, k, x, y, r) for o, k, x, y, r in scans}.values())
    noisy = distinct + distinct[: len(distinct) // 2]
    rnd.shuffle(noisy)
    assert np.array_equal(build(distinct), build(noisy))


def test_missing_answers_only_with_scans_inside_the_senders_horizon():
    log = _log([(1, k, 1000.0 * k, 0.0, 500.0) for k in range(20)])
    (origin, flat), = log.missing(0, 0, 2**31 - 1, (), 30.0, 100)
    assert origin == 1 and len(flat) == 4 * 20  # no horizon: everything the digest lacks
    near = (0.0, 0.0, 5500.0)
    (origin, flat), = log.missing(0, 0, 2**31 - 1, (), 30.0, 100, near)
    assert [flat[i + 1] for i in range(0, len(flat), 4)] == [1000.0 * k for k in range(6)]
    assert list(log.missing(0, 0, 2**31 - 1, (), 30.0, 100, (50_000.0, 0.0, 5000.0))) == []  # none inside
    # Scans along a long track, a horizon around a few of them: exactly those, whether the
    # horizon holds none, some or all of them; and after forgetting.
    track = ScanLog(1.0, horizon_s=300.0)
    for k in range(1000):
        track.add(2, float(k), 100.0 * k, 0.0, 500.0)
    for t_now in (999.0, 1500.0):
        track.forget_before(t_now)
        kept = {int(s[0]) for _, s in track.scans()}
        for cx, h in ((50_000.0, 3000.0), (80_000.0, 10_000.0), (0.0, 1e9)):
            got = [int(flat[i]) for _, flat in track.missing(0, 0, 2**31 - 1, (), t_now, 10_000, (cx, 0.0, h))
                   for i in range(0, len(flat), 4)]
            assert got == sorted(k for k in kept if abs(100.0 * k - cx) <= h)


# --- the horizon in a run ---------------------------------------------------------------------------


def _line(horizon_m: float | None, **over) -> dict:
    """Four fast UAVs 10 km apart on a line, 25 km radio range: the ends hear each other only
    through the middle ones (anti-entropy relays)."""
    radio: dict = {"range_m": 25_000.0}
    if horizon_m is not None:
        radio["sync_horizon_m"] = horizon_m
    doc = {
        "name": "line", "seed": 1, "duration_s": 60.0,
        "area": {"width_m": 60_000.0, "height_m": 20_000.0, "cell_m": 200.0},
        "uavs": [{"name": f"B{i}", "type": "B", "x_m": 10_000.0 + 10_000.0 * i, "y_m": 10_000.0,
                  "heading_deg": 90.0} for i in range(4)],
        "planner": {"name": "greedy"}, "radio": radio,
    }
    doc.update(over)
    return doc


def _heard_within(sim: Simulation, uid: int, h: float, path: list[float]) -> bool:
    """Every scan of another origin in ``uid``'s log lies within ``h`` of some tick of its path."""
    pts = np.array(path).reshape(-1, 3)[:, 1:]
    for origin, (_t, x, y, _r) in sim.actors[uid].scans.scans():
        if origin != uid and np.min(np.hypot(pts[:, 0] - x, pts[:, 1] - y)) > h + 90.0 + 1e-6:
            return False
    return True


@pytest.mark.slow
def test_a_horizon_keeps_far_scans_out_of_log_and_map_and_maps_agree_within_it():
    h = 12_000.0
    with Simulation(parse_scenario(_line(h))) as sim:
        mon = Monitor([MapAgreementChecker()]).attach(sim)
        while not sim.done:
            sim.step()
            mon.flush()
        mon.finish()
        result = sim.run()
        for uid in range(4):
            assert _heard_within(sim, uid, h, sim._observer.paths[uid])
        far = {o for o, _ in sim.actors[0].scans.scans()}
        beyond = sim.actors[0].counters.scans_beyond
        map0 = sim.actors[0].umap.to_dense()
    assert mon.violations == [] and mon.by_name("map_agreement").checks >= 2
    assert far <= {0, 1} and beyond > 0  # B2 (20 km), B3 (30 km): beyond the horizon
    # Without a horizon B3's scans reach B0 (relayed): the horizon is what kept them out.
    with Simulation(parse_scenario(_line(None))) as sim:
        sim.run()
        assert 3 in {o for o, _ in sim.actors[0].scans.scans()}
        assert (sim.actors[0].umap.to_dense() > map0).sum() > 100
    assert result.metrics["sim_seconds"] == 60.0


@pytest.mark.slow
def test_local_map_agreement_catches_a_radio_that_loses_one_uavs_frames():
    with Simulation(parse_scenario(_line(12_000.0))) as sim:
        send = sim._radio.broadcast

        def lossy(t, src, data, out, on_lost=None, to=None):  # the planted bug: B1's frames vanish
            if src != 1:
                send(t, src, data, out, on_lost, to)

        sim._radio.broadcast = lossy
        mon = Monitor([MapAgreementChecker()]).attach(sim)
        while not sim.done:
            sim.step()
            mon.flush()
        mon.finish()
    assert mon.violations and {v.uavs[1] for v in mon.violations} == {"B1"}
    assert all("horizon" in v.message for v in mon.violations)


@pytest.mark.slow
def test_a_late_joiner_under_a_horizon_owes_only_the_cells_within_it():
    doc = _line(12_000.0)
    doc["uavs"][0]["join_s"] = 20.0
    with Simulation(parse_scenario(doc)) as sim:
        mon = Monitor([JoinerCatchUpChecker()]).attach(sim)
        sim.step(21)
        mon.flush()
        owed = sim.uav_map("B1")  # B1 knows B2's cells, 20 km from B0: beyond B0's horizon
        while not sim.done:
            sim.step()
            mon.flush()
        mon.finish()
        assert (sim.uav_map("B0") < owed).sum() > 100  # so the whole map is not owed...
    assert mon.violations == [] and mon.by_name("joiner_catch_up").checks == 1  # ...and what is, arrived


# --- the recording level ----------------------------------------------------------------------------


def _dense(n: int, level: str) -> dict:
    """``n`` UAVs in a 10 km square, all in range of each other: each hears n - 1 beacons a second."""
    side = math.ceil(math.sqrt(n))
    return {
        "name": "dense", "seed": 2, "duration_s": 20.0,
        "area": {"width_m": 10_000.0, "height_m": 10_000.0, "cell_m": 200.0},
        "uavs": [{"name": f"U{i}", "type": "A", "x_m": 1000.0 + 8000.0 * (i % side) / side,
                  "y_m": 1000.0 + 8000.0 * (i // side) / side} for i in range(n)],
        "planner": {"name": "greedy"},
        "radio": {"range_m": 30_000.0, "loss_base": 0.2},
        "recording": {"level": level},
    }


def test_a_summary_log_counts_what_a_frames_log_lists_and_is_deterministic():
    runs = {}
    for level in ("frames", "summary", "summary"):
        with Simulation(parse_scenario(_dense(6, level))) as sim:
            r = sim.run()
        runs.setdefault(level, []).append(r)
    a, b = runs["summary"]
    assert a.events == b.events and a.metrics["event_log_sha256"] == b.metrics["event_log_sha256"]
    frames = list(read_events(runs["frames"][0].events))
    summary = list(read_events(a.events))
    assert summary[0].header["recording"] == "summary" and "recording" not in frames[0].header
    assert not {e.kind for e in summary} & {"rx", "lost"}
    # Everything but the radio's events is the same (the level changes no decision).
    assert [e for e in frames[1:] if e.kind not in ("rx", "lost")] == [e for e in summary[1:] if e.kind != "radio"]
    # Each tick's radio event holds that tick's totals (lost copies from delivery at the next tick).
    rx: dict[float, list[int]] = {}
    lost: dict[str, list[int]] = {}
    for e in frames:
        if isinstance(e, Rx):
            c = rx.setdefault(e.t, [0, 0, 0])
            c[0] += 1
            c[1] += not e.accepted
            c[2] += e.bytes
        elif isinstance(e, Lost):
            c = lost.setdefault(e.cause, [0, 0])
            c[0] += 1
            c[1] += e.bytes
    radio = [e for e in summary if isinstance(e, Radio)]
    assert {e.t: [e.read, e.rejected, e.bytes_read] for e in radio if e.read} == rx
    total: dict[str, list[int]] = {}
    for e in radio:
        for cause, (n, nbytes) in e.lost.items():
            c = total.setdefault(cause, [0, 0])
            c[0] += n
            c[1] += nbytes
    assert total == lost and lost["loss"][0] > 0
    # A summary log replays (the animation's reader): the same poses, no radio links.
    from swarm.viz.replay import replay_from_bytes

    doc = _dense(6, "summary")
    got, want = replay_from_bytes(a.events, doc), replay_from_bytes(runs["frames"][0].events, doc)
    assert np.array_equal(got.x, want.x, equal_nan=True) and np.array_equal(got.y, want.y, equal_nan=True)


def test_the_radio_checker_says_it_cannot_check_a_summary_log():
    sc = parse_scenario(_dense(4, "summary"))
    with Simulation(sc) as sim:
        r = sim.run()
    checker = RadioChecker()
    assert check_events(r.events, sc, [checker]) == []
    assert checker.unchecked is not None and "frames" in checker.unchecked
    mon = Monitor([RadioChecker()], sc)
    for e in read_events(r.events):
        mon.feed(e)
    mon.finish()
    assert set(mon.unchecked) == {"radio"}
    # On a frames log it judges, and says nothing.
    frames = apply_overrides(sc, {"recording.level": "frames"})
    with Simulation(frames) as sim:
        r = sim.run()
    mon = Monitor([RadioChecker()], frames)
    for e in read_events(r.events):
        mon.feed(e)
    assert mon.finish() == [] and mon.unchecked == {}


@pytest.mark.slow
def test_summary_log_bytes_per_uav_second_stay_flat_as_the_swarm_gets_denser():
    def per_uav_s(n: int, level: str) -> float:
        with Simulation(parse_scenario(_dense(n, level))) as sim:
            r = sim.run()
        return len(r.events) / (n * 20.0)

    frames = per_uav_s(30, "frames") / per_uav_s(6, "frames")
    summary = per_uav_s(30, "summary") / per_uav_s(6, "summary")
    assert frames > 2.0  # one rx per neighbour: grows with density
    assert summary < 1.1  # bounded: pose + a share of one radio event per tick


# --- digests and anti-entropy bytes flat in swarm size -----------------------------------------------


def _lattice(side: int, horizon_m: float | None) -> dict:
    """side x side fast UAVs 10 km apart (same density at every size), 15 km radio range."""
    radio: dict = {"range_m": 15_000.0}
    if horizon_m is not None:
        radio["sync_horizon_m"] = horizon_m
    w = 10_000.0 * side
    return {
        "name": "lattice", "seed": 0, "duration_s": 40.0,
        "area": {"width_m": w, "height_m": w, "cell_m": 250.0},
        "uavs": [{"name": f"U{i}", "type": "B", "x_m": 5000.0 + 10_000.0 * (i % side),
                  "y_m": 5000.0 + 10_000.0 * (i // side)} for i in range(side * side)],
        "planner": {"name": "greedy"}, "radio": radio, "recording": {"level": "summary"},
    }


@pytest.mark.slow
def test_digest_size_and_anti_entropy_bytes_per_uav_second_are_flat_in_swarm_size_with_a_horizon():
    def figures(side: int, h: float | None) -> dict:
        with Simulation(parse_scenario(_lattice(side, h))) as sim:
            r = sim.run()
            return bench.anti_entropy_figures(sim, bench.uav_ticks(r) * sim.dt)

    # 49 and 144 UAVs (an edge UAV hears fewer: the means differ by the share of edge UAVs only).
    small, big = figures(7, 15_000.0), figures(12, 15_000.0)
    assert big["digest_bytes_mean"] < 1.15 * small["digest_bytes_mean"]
    assert big["anti_entropy_bytes_per_uav_s"] < 1.15 * small["anti_entropy_bytes_per_uav_s"]
    assert big["scan_log_max"] <= 1.1 * small["scan_log_max"]
    # Without the horizon they grow with the swarm (each UAV learns the scans of UAVs far away).
    free = figures(12, None)
    assert free["digest_bytes_mean"] > 2 * big["digest_bytes_mean"]
    assert free["scan_log_max"] > 2 * big["scan_log_max"]
