"""The node and sensing faults (pause, restart, clock_skew, nav_error, sensor, liar), end to end:
each fires, has its effect in the run, keeps the invariants and the determinism, and reads from
a scenario's [[faults]] as it is given in Python."""

from __future__ import annotations

import math
import tomllib
from collections import Counter

import numpy as np
import pytest

import swarm.kernel.simulation as simulation_module
from agents.maps.umap import NEVER
from faults.schedule import (
    PHANTOM_TARGET_ID,
    ClockSkew,
    Liar,
    NavError,
    Pause,
    Restart,
    Sensor,
    fault_from_dict,
    fault_to_dict,
)
from swarm import Simulation
from swarm import events as ev
from swarm.events import read_events
from swarm.scenario import parse_scenario
from swarm.testing.invariants import JoinerCatchUpChecker, Monitor, check_events, default_checkers
from tests.conftest import DATA

B1, B2, A1, A2 = 0, 1, 2, 3


def _doc(duration_s: float = 120.0, **radio) -> dict:
    """faults-small without its faults, every UAV flying from the start."""
    with open(DATA / "faults-small.toml", "rb") as fh:
        doc = tomllib.load(fh)
    doc["faults"] = []
    doc["uavs"][3].pop("join_s")
    doc["duration_s"] = duration_s
    doc["radio"].update(radio)
    return doc


def _scenario(duration_s: float = 120.0, **radio):
    return parse_scenario(_doc(duration_s, **radio), "node-faults")


def _run(faults, duration_s: float = 120.0, planner: str = "greedy", seed: int = 1, **radio):
    sc = _scenario(duration_s, **radio)
    with Simulation(sc, seed=seed, planner=planner) as sim:
        for f in faults:
            sim.add_fault(f)
        result = sim.run()
    return sc, result, list(read_events(result.events))


def _clean(sc, result, faults) -> None:
    assert result.metrics["violations"]["dynamics"] == 0
    assert [str(v) for v in check_events(result.events, sc, faults=faults)] == []  # every log checker


# --- pause ------------------------------------------------------------------------------------


def test_pause_stops_the_actor_and_fills_its_mailbox():
    f = Pause(uav="B1", start_s=20.0, end_s=60.0)
    sc, result, events = _run([f], mailbox_capacity=20)
    assert result.metrics["faults_applied"] == {"pause": 1}
    assert [e for e in events if e.kind in ("pause", "resume")] == [ev.Pause(20.0, B1, "B1"), ev.Resume(60.0, B1, "B1")]
    # Nothing heard from it (a frame sent at 19 s arrives by 20 s), nothing read by it.
    assert not [e for e in events if e.kind == "rx" and e.src == B1 and 21.0 <= e.t < 60.0]
    assert not [e for e in events if e.kind == "rx" and e.dst == B1 and 20.0 <= e.t < 60.0]
    # Its mailbox overflowed, and it read what it held when it resumed.
    full = [e for e in events if e.kind == "lost" and e.cause == "mailbox_full"]
    assert full and {e.dst for e in full} == {B1}
    assert sum(1 for e in events if e.kind == "rx" and e.dst == B1 and e.t == 60.0) == 20
    # It kept flying (a pose every tick, the last plan) on its last command.
    poses = [e for e in events if e.kind == "pose" and e.uav == B1 and 20.0 <= e.t < 60.0]
    assert len(poses) == 40 and len({(e.mode, e.target) for e in poses}) == 1
    assert result.metrics["per_uav"]["B1"]["mailbox_dropped_full"] == len(full)
    _clean(sc, result, [f])


def test_a_pause_on_a_uav_that_is_down_does_nothing():
    faults = [Restart(uav="B1", at_s=10.0, downtime_s=40.0), Pause(uav="B1", start_s=20.0, end_s=30.0)]
    sc, result, events = _run(faults)
    assert result.metrics["faults_applied"] == {"pause": 0, "restart": 1}
    assert not [e for e in events if e.kind in ("pause", "resume")]


# --- restart ----------------------------------------------------------------------------------


def test_restart_rejoins_with_an_empty_memory_where_it_went_down():
    f = Restart(uav="B1", at_s=30.0, downtime_s=10.0)
    sc = _scenario()
    with Simulation(sc, seed=1) as sim:
        sim.add_fault(f)
        # (map_agreement is left out: this scenario's maps lag more than 10 s without any fault.)
        monitor = Monitor([*default_checkers(live=True), JoinerCatchUpChecker()]).attach(sim)
        sim.step(30)
        old = sim.actors[B1]
        assert np.isfinite(sim.uav_map("B1")).any() and old.knowledge.peers
        last = (sim._world.uavs[B1].x, sim._world.uavs[B1].y)
        seen = []  # at the rejoin (before its first tick): what the new actor knows

        def at_restart(_event):
            new = sim.actors[B1]
            seen.append((new, (sim.uav_map("B1") == NEVER).all(), dict(new.knowledge.peers),
                         dict(new.knowledge.tracks), new.scans.count, new.plan,
                         sim._world.uavs[B1].state, (sim._world.uavs[B1].x, sim._world.uavs[B1].y)))

        sim.subscribe(at_restart, kinds={"restart"})
        sim.step(90)  # the crash at 30 s, the rejoin at 40 s (before the tick at 40 s)
        (new, empty, peers, tracks, scans, plan, state, where), = seen
        assert new is not old and new.mailbox is old.mailbox and new.counters is old.counters
        assert empty and not peers and not tracks and scans == 0 and plan is None
        assert state == "alive" and where == last
        monitor.flush()
        result = sim.result()
        monitor.finish()
    events = list(read_events(result.events))
    assert [e for e in events if e.kind in ("crash", "restart")] == [
        ev.Crash(30.0, B1, "B1"), ev.Restart(40.0, B1, "B1", *last)]
    assert result.metrics["faults_applied"] == {"restart": 1}
    assert monitor.violations == []
    assert monitor.by_name("joiner_catch_up").checks == 1  # it caught up with its neighbours
    # It sends again (the radio checker accepts it: failed only between crash and restart).
    assert [e for e in events if e.kind == "rx" and e.src == B1 and e.t > 41.0]
    _clean(sc, result, [f])
    # Its first life drew what it drew without the fault (the new life has a stream of its own).
    _, base, base_events = _run([])
    assert [e for e in events[1:] if e.t < 30.0 and e.kind != "host"] == [e for e in base_events[1:] if e.t < 30.0]


def test_restart_of_a_uav_not_flying_does_nothing():
    sc, result, events = _run([Restart(uav="B1", at_s=10.0, downtime_s=5.0),
                               Restart(uav="B1", at_s=12.0, downtime_s=5.0)])  # down at 12 s: ignored
    assert result.metrics["faults_applied"] == {"restart": 1}
    assert [e.kind for e in events if e.kind in ("crash", "restart")] == ["crash", "restart"]


# --- clock skew -------------------------------------------------------------------------------


def test_a_clock_ahead_is_ignored_and_never_pins_a_receivers_cells():
    f = ClockSkew(uav="B1", start_s=10.0, offset_s=30.0)
    sc = _scenario(60.0)
    with Simulation(sc, seed=1) as sim:
        sim.add_fault(f)
        for _ in range(50):
            sim.step()
            for uid in (B2, A1, A2):  # no cell of another UAV's map is stamped after its clock
                assert sim.uav_map(sim._world.uavs[uid].name).max() <= sim.now - sim.dt + 1e-6
        assert sim.uav_map("B1").max() >= sim.now - sim.dt + 30.0 - 1e-6  # its own stamps are skewed
        ignored = {u: sim.actors[u].counters.messages_ignored for u in (B2, A1, A2)}
        result = sim.result()
    assert result.metrics["faults_applied"] == {"clock_skew": 1}
    assert ignored[B2] > 0  # its frames, stamped in B2's future (A1 and A2 are at the edge of its range)
    assert ev.FaultOn(10.0, "clock_skew", B1, "B1") in list(read_events(result.events))


def test_a_clock_behind_is_heard_and_hears_nobody():
    f = ClockSkew(uav="B1", start_s=10.0, end_s=40.0, offset_s=-5.0, drift=-0.1)
    sc, result, events = _run([f], duration_s=60.0)
    assert result.metrics["faults_applied"] == {"clock_skew": 1}
    assert ev.FaultOff(40.0, "clock_skew", B1, "B1") in events
    per = result.metrics["per_uav"]
    assert per["B1"]["messages_ignored"] > 0  # the others' frames are in its future
    assert all(per[n]["messages_ignored"] == 0 for n in ("B2", "A1", "A2"))
    # Its frames are accepted: every rx of a frame of B1 in the window was merged.
    heard = [e for e in events if e.kind == "rx" and e.src == B1 and 12.0 <= e.t < 40.0]
    assert heard and all(e.accepted for e in heard)
    _clean(sc, result, [f])


def test_maps_in_a_group_stay_a_max_of_what_they_applied_under_skew(monkeypatch):
    """A UAV stamping from its future inside a MapGroup: every map equals, cell for cell, the
    map of its own it would have without the group (the group only shares storage)."""
    faults = [ClockSkew(uav="B1", start_s=5.0, end_s=30.0, offset_s=20.0, drift=0.2),
              ClockSkew(uav="A1", start_s=15.0, offset_s=-3.0)]
    sc = _scenario(50.0)

    def maps(group: bool):
        if not group:
            monkeypatch.setattr(simulation_module, "maps_share", lambda *_: False)
        with Simulation(sc, seed=2) as sim:
            assert (sim._map_group is not None) == group
            for f in faults:
                sim.add_fault(f)
            sim.run()
            return sim._log.sha256(), {n: sim.uav_map(n) for n in sim._names}

    grouped, own = maps(True), maps(False)
    assert grouped[0] == own[0]
    for name in own[1]:
        np.testing.assert_array_equal(grouped[1][name], own[1][name])


# --- navigation error -------------------------------------------------------------------------


def test_nav_bias_shifts_what_it_believes_not_the_ground_truth():
    f = NavError(uav="B1", bias_x_m=2000.0, bias_y_m=-1000.0)
    sc = _scenario(20.0)
    with Simulation(sc, seed=1) as sim:
        sim.add_fault(f)
        sim.step(5)
        b = sim._world.uavs[B1]
        t = sim.now - sim.dt
        umap, union = sim.uav_map("B1"), sim._metrics.union.to_dense()
        grid = sim._grid
        # Where it was at the last tick (it has moved by one step since), and where it believed.
        x0, y0 = b.x - b.v * math.cos(b.theta) * sim.dt, b.y - b.v * math.sin(b.theta) * sim.dt
        (ix, bx), (iy, by) = (v.tolist() for v in grid.cells_of(np.array([x0, x0 + 2000.0]),
                                                                   np.array([y0, y0 - 1000.0])))
        assert union[iy, ix] == pytest.approx(t)  # the truth: scanned where it is
        assert umap[by, bx] == pytest.approx(t)  # its own map: stamped where it believes it is
        assert umap[iy, ix] < union[iy, ix]  # ... and not where it is (2.2 km off, radius 2 km)
        peer = sim.actors[B2].knowledge.peers[B1]  # its Hello: the believed position
        assert peer.x - 2000.0 == pytest.approx(b.x, abs=200.0) and peer.y + 1000.0 == pytest.approx(b.y, abs=200.0)
        result = sim.result()
    assert result.metrics["faults_applied"] == {"nav_error": 1}


def test_nav_noise_is_drawn_from_the_faults_own_stream():
    f = NavError(uav="B1", noise_m=100.0)
    sc, a, _ = _run([f], duration_s=60.0)
    _, b, _ = _run([f], duration_s=60.0)
    _, c, _ = _run([], duration_s=60.0)
    assert a.metrics["event_log_sha256"] == b.metrics["event_log_sha256"] != c.metrics["event_log_sha256"]
    _clean(sc, a, [f])


# --- sensor -----------------------------------------------------------------------------------


@pytest.mark.slow  # two 200 s runs (about 1.3 s)
def test_a_blind_sensor_finds_no_target_and_false_alarms_are_not_targets():
    sc, base, _ = _run([], duration_s=200.0)
    assert base.metrics["targets_found"] > 0
    blind = Sensor(p_detect=0.0, false_alarm_rate=0.2)
    sc, result, events = _run([blind], duration_s=200.0)
    assert result.metrics["targets_found"] == 0 and not [e for e in events if e.kind == "found"]
    assert result.metrics["faults_applied"]["sensor"] > 0
    _clean(sc, result, [blind])


def test_false_alarms_reach_the_knowledge_as_phantom_targets():
    f = Sensor(uavs=("B1",), p_detect=1.0, false_alarm_rate=0.5)
    sc = _scenario(40.0)
    with Simulation(sc, seed=1) as sim:
        sim.add_fault(f)
        sim.run()
        phantoms = [m for m in sim.actors[B1].knowledge.tracks if m >= PHANTOM_TARGET_ID]
        fired = sim.injector.fired["sensor"]
        found = set(sim._metrics.found_t)
    assert phantoms and fired >= len(phantoms)  # (each false alarm fires; all are B1's)
    assert all(m < PHANTOM_TARGET_ID for m in found)


# --- liar -------------------------------------------------------------------------------------


@pytest.mark.slow  # two 300 s DACMP runs (about 5 s)
def test_a_liar_lowers_coverage():
    f = Liar(uav="B1", scans_per_s=20.0, tracks_per_s=0.5)
    sc, base, _ = _run([], duration_s=300.0, planner="dacmp")
    sc, lied, _ = _run([f], duration_s=300.0, planner="dacmp")
    assert lied.metrics["coverage"] < base.metrics["coverage"] - 0.05
    # Every fabrication made was sent (they fit in the beacons): 20 + 0.5 a second for 300 s.
    assert lied.metrics["faults_applied"] == {"liar": 300 * 20 + 150}
    _clean(sc, lied, [f])


def test_the_others_believe_the_liars_scans():
    f = Liar(uav="B1", scans_per_s=10.0)
    sc = _scenario(30.0)
    with Simulation(sc, seed=1) as sim:
        sim.add_fault(f)
        sim.run()
        truth = sim._metrics.union.to_dense() != NEVER
        believed = sim.uav_map("B2") != NEVER
    assert (believed & ~truth).sum() > 0  # cells nobody scanned, which B2 takes for scanned


# --- as data, and together ----------------------------------------------------------------------

ALL_SIX = [
    Pause(uav="B2", start_s=15.0, end_s=35.0),
    Restart(uav="A1", at_s=20.0, downtime_s=12.5),
    ClockSkew(uav="A2", start_s=5.0, end_s=50.0, offset_s=2.0, drift=0.05),
    NavError(uav="B1", start_s=10.0, bias_x_m=300.0, noise_m=30.0),
    Sensor(uavs=("B1", "A2"), p_detect=0.7, false_alarm_rate=0.05),
    Liar(uav="A2", start_s=30.0, scans_per_s=3.0, tracks_per_s=0.2),
]


def test_toml_faults_round_trip_and_run_as_the_python_api():
    doc = _doc(90.0)
    doc["faults"] = [{k: v for k, v in fault_to_dict(f).items() if v is not None} for f in ALL_SIX]
    sc = parse_scenario(doc, "node-faults")
    assert [fault_from_dict(f.model_dump(mode="python")) for f in sc.faults] == ALL_SIX
    with Simulation(sc, seed=3) as sim:
        from_toml = sim.run()
    _, from_api, _ = (lambda r: r)(_run(ALL_SIX, duration_s=90.0, seed=3))
    a = list(read_events(from_toml.events))
    b = list(read_events(from_api.events))
    # The same run (the start event lists the scenario's faults, host events those added).
    assert a[1:] == [e for e in b[1:] if e.kind != "host"]
    assert from_toml.metrics["faults_applied"] == from_api.metrics["faults_applied"]
    assert all(from_toml.metrics["faults_applied"][f.kind] > 0 for f in ALL_SIX)


@pytest.mark.parametrize("planner", ["greedy", "dacmp"])
def test_all_six_together_deterministic_and_clean(planner):
    sc, a, _ = _run(ALL_SIX, duration_s=90.0, planner=planner, seed=4)
    _, b, _ = _run(ALL_SIX, duration_s=90.0, planner=planner, seed=4)
    assert a.metrics["event_log_sha256"] == b.metrics["event_log_sha256"]
    assert a.metrics["faults_applied"] == b.metrics["faults_applied"]
    _clean(sc, a, ALL_SIX)


def test_faults_added_while_running():
    sc = _scenario(60.0)
    with Simulation(sc, seed=1) as sim:
        sim.step(10)
        sim.add_fault(Pause(uav="B1", start_s=5.0, end_s=20.0))  # started in the past: from now
        sim.add_fault(Pause(uav="B2", start_s=0.0, end_s=5.0))  # over: nothing
        sim.add_fault(Restart(uav="A1", at_s=15.0, downtime_s=3.0))
        with pytest.raises(Exception, match="in the past"):
            sim.add_fault(Restart(uav="A1", at_s=5.0, downtime_s=3.0))
        result = sim.run()
    events = list(read_events(result.events))
    assert [e for e in events if e.kind in ("pause", "resume")] == [ev.Pause(10.0, B1, "B1"), ev.Resume(20.0, B1, "B1")]
    assert Counter(e.kind for e in events)["restart"] == 1
