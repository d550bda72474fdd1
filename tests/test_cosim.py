"""Co-simulation (issue 34, docs/embedding.md#co-simulation): the lockstep contract of
:mod:`swarm.kernel.host`, bodies driven from outside, host changes recorded and replayed.

* Time: ``Simulation(dt_s=...)``; ``run_until(t)`` stops at the last tick boundary at or before
  ``t``; ``now`` is what the changes call the present (a fault at ``now`` is accepted and acts
  at that boundary).
* One host, one log: changes made between ``run_until`` chunks, from a concurrent task that
  waits with ``wait_until``, from such a task that also awaits real I/O (a sleep, a loopback
  socket), and from ``call_at`` callbacks give one event-log hash.
* A body taken over by the host goes where the host puts it; the simulator does not move it;
  its actor goes on planning; the dynamics checker leaves it out and says so.
* Every host change is a ``host`` event, and a run written with ``write_run`` replays from its
  folder to the same hash (:func:`swarm.kernel.hostlog.schedule_recorded_host_changes`).
* Bad input: one :class:`~swarm.errors.UsageError` subclass each, the run unchanged.
"""

from __future__ import annotations

import asyncio
import math
import socket

import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from faults.schedule import Crash, Drop
from swarm import Simulation
from swarm.errors import (
    APIMisuseError,
    BadStateError,
    NotControlledError,
    NotGeographicError,
    SwarmError,
    TimeInPastError,
    UnknownUavError,
)
from swarm.events import read_events
from swarm.kernel.hostlog import schedule_recorded_host_changes
from swarm.outputs import write_run
from swarm.testing.invariants import check_events, load_run_log
from swarm.testing.invariants.safety import DynamicsChecker

SCENARIO = "paper-case1"  # 3 UAVs (B1, B2, A1), 2 targets: a few ms per simulated second
DURATION = 40.0
CHANGE_TIMES = (10.0, 20.0, 30.0)


def _sim(**kw) -> Simulation:
    return Simulation(SCENARIO, duration_s=DURATION, **kw)


def _changes(sim: Simulation, t: float) -> None:
    """What the ground station does at ``t``: a target, a drop window, at 20 s a crash now."""
    sim.add_target(5000.0 + 100 * t, 20000.0, heading_deg=t, speed=3.0)
    sim.add_fault(Drop(rate=0.5, start_s=t, end_s=t + 5.0))
    if t == 20.0:
        sim.add_fault(Crash(uav="B2", at_s=t))


def _hash(sim: Simulation) -> str:
    return sim.result().metrics["event_log_sha256"]


# --- time -------------------------------------------------------------------------------------------


@pytest.mark.asyncio
async def test_run_until_lands_on_the_hosts_ticks_and_never_passes_t():
    with _sim(dt_s=0.25) as sim:
        assert sim.dt == 0.25 and sim.n_ticks == 160
        await sim.run_until(0.25)
        assert sim.now == 0.25
        await sim.run_until(0.6)  # between boundaries: the last one before it
        assert sim.now == 0.5
        for k in range(3, 9):
            await sim.run_until(k * 0.25)
            assert sim.now == pytest.approx(k * 0.25)


def test_after_step_now_is_the_present_of_changes():
    with _sim() as sim:
        sim.step(10)
        assert sim.now == 10.0
        sim.add_fault(Crash(uav="B1", at_s=10.0))  # now: accepted
        with pytest.raises(TimeInPastError):
            sim.add_fault(Crash(uav="B1", at_s=9.0))
        sim.step()
        crashes = [e for e in read_events(sim.result().events) if e.kind == "crash"]
        assert [(e.t, e.uav_name) for e in crashes] == [(10.0, "B1")]
        assert sim.snapshot().uavs[0].state == "crashed"


# --- one host, one log ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def chunked_hash() -> str:
    """Changes made between run_until chunks (the pattern that was deterministic already)."""

    async def host() -> str:
        with _sim() as sim:
            for t in CHANGE_TIMES:
                await sim.run_until(t)
                _changes(sim, t)
            await sim.run_until(DURATION)
            return _hash(sim)

    return asyncio.run(host())


async def _station(sim: Simulation, io: str | None) -> None:
    for t in CHANGE_TIMES:
        await sim.wait_until(t)
        if io == "sleep":
            await asyncio.sleep(0.001)  # real time passes: the simulation waits
        elif io == "socket":
            a, b = socket.socketpair()
            reader, writer = await asyncio.open_connection(sock=a)
            b.sendall(b"ping")
            assert await reader.readexactly(4) == b"ping"
            writer.close()
            b.close()
        assert sim.now == t
        _changes(sim, t)


@pytest.mark.asyncio
@pytest.mark.parametrize("io", [None, "sleep", "socket"])
async def test_a_concurrent_ground_station_gives_the_chunked_hash(chunked_hash, io):
    with _sim() as sim:
        busy = asyncio.create_task(_busy())  # another task that never waits for the simulation
        await asyncio.gather(sim.run_until(DURATION), _station(sim, io))
        busy.cancel()
        assert _hash(sim) == chunked_hash
        assert sum(1 for e in read_events(sim.result().events) if e.kind == "host") == 7


async def _busy() -> None:
    while True:
        await asyncio.sleep(0)


def test_call_at_gives_the_chunked_hash(chunked_hash):
    with _sim() as sim:
        for t in CHANGE_TIMES:
            sim.call_at(t, lambda t=t: _changes(sim, t))
        sim.run()
        assert _hash(sim) == chunked_hash


@pytest.mark.asyncio
async def test_a_change_made_inside_a_tick_waits_for_the_next_boundary():
    """A task that does not wait acts while the actors think: its change is queued and takes
    effect at the end of the tick under way (and is logged there)."""
    with _sim() as sim:
        seen: list[tuple[float, int]] = []

        async def impatient():
            await asyncio.sleep(0)
            while sim.now < 5.0:
                await asyncio.sleep(0)
            tid = sim.add_target(1000.0, 1000.0)
            seen.append((sim.now, tid))

        await asyncio.gather(sim.run_until(10.0), impatient())
        (t_called, tid), = seen
        hosts = [e for e in read_events(sim.result().events) if e.kind == "host"]
        assert tid == 2 and len(hosts) == 1
        assert hosts[0].t == t_called + 1.0  # the boundary after the tick under way


@pytest.mark.asyncio
async def test_wait_until_in_the_past_or_after_the_end_is_refused():
    with _sim() as sim:
        await sim.run_until(5.0)
        with pytest.raises(TimeInPastError):
            await sim.wait_until(4.0)
        with pytest.raises(SwarmError):
            await sim.wait_until(DURATION + 1.0)
        await sim.wait_until(5.0)  # standing there: returns at once
        assert sim.now == 5.0


def test_wait_until_needs_the_host_loop():
    with _sim() as sim:
        sim.step()
        with pytest.raises(APIMisuseError):
            asyncio.run(sim.wait_until(3.0))


# --- bodies driven from outside ------------------------------------------------------------------


def _drive(sim: Simulation, until: float, x0: float = 30000.0, y0: float = 30000.0) -> None:
    """The host flies B1 north at 70 m/s from (x0, y0), one set_state per tick."""
    sim.take_control("B1")
    while sim.now < until:
        t = sim.now
        sim.set_state("B1", x0, y0 + 70.0 * (t - 10.0), math.pi / 2, 70.0)
        sim.step()


def test_a_controlled_body_goes_where_the_host_puts_it():
    with _sim() as sim:
        sim.step(10)
        _drive(sim, 20.0)
        snap = sim.snapshot()
        b1 = snap.uavs[0]
        assert b1.name == "B1" and b1.controlled and sim.controlled == ("B1",)
        assert (b1.x, b1.y, b1.v) == (30000.0, 30000.0 + 70.0 * 9, 70.0)  # where it was put at 19 s: not moved since
        assert b1.waypoint is not None and b1.speed_cmd is not None and b1.turn_rate_cmd is not None
        assert sim.actors[0].plan is not None  # it goes on planning
        poses = [e for e in read_events(sim.result().events) if e.kind == "pose" and e.uav == 0 and e.t >= 10.0]
        assert [(p.x, p.y) for p in poses] == [(30000.0, 30000.0 + 70.0 * (p.t - 10.0)) for p in poses]
        sim.release_control("B1")
        sim.step(5)
        assert sim.snapshot().uavs[0].y > 30000.0 + 70.0 * 9 + 100.0  # flown on by the simulator
        checker = DynamicsChecker()
        assert check_events(sim.result().events, sim.scenario, [checker]) == []
        assert checker.note is not None and "B1" in checker.note and checker.skipped["B1"] == 11


def test_the_dynamics_checker_judges_an_undriven_teleport():
    """The same jumps made without take_control are what the checker exists to catch: so the
    skip above is the host events', not a blind spot."""
    with _sim() as sim:
        sim.step(10)
        _drive(sim, 15.0)
        events = [e for e in read_events(sim.result().events)
                  if not (e.kind == "host" and e.change == "take_control")]
        checker = DynamicsChecker()
        assert check_events(events, sim.scenario, [checker])
        assert checker.note is None


# --- record and replay ------------------------------------------------------------------------------


def _embedded_run() -> Simulation:
    sim = _sim()
    sim.step(5)
    sim.add_target(12000.0, 30000.0, heading_deg=45.0, speed=4.0)
    sim.add_uav("A", 25000.0, 25000.0, heading_deg=90.0, name="A9")
    sim.add_fault(Drop(rate=0.3, start_s=8.0, end_s=14.0))
    sim.step(5)
    sim.add_fault(Crash(uav="B2", at_s=12.0))
    sim.set_waypoint("A1", 15000.0, 15000.0)
    _drive(sim, 18.0)
    sim.release_control("B1")
    sim.step(int(DURATION - sim.now))
    return sim


def test_an_embedded_run_replays_from_its_folder(tmp_path):
    with _embedded_run() as sim:
        result = sim.result()
    out = write_run(result, tmp_path / "run")
    scenario, events = load_run_log(out)
    hosts = [e for e in events if e.kind == "host"]
    assert [e.change for e in hosts][:5] == ["add_target", "add_uav", "add_fault", "add_fault", "set_waypoint"]
    with Simulation(scenario) as replay:
        assert schedule_recorded_host_changes(replay, events) == len(hosts)
        again = replay.run()
    assert again.metrics["event_log_sha256"] == result.metrics["event_log_sha256"]
    with Simulation(scenario) as plain:  # (and the changes did change the run)
        assert plain.run().metrics["event_log_sha256"] != result.metrics["event_log_sha256"]


def test_the_report_shows_added_faults_like_scheduled_ones():
    from swarm.viz.replay import replay_from_bytes

    with _embedded_run() as sim:
        result = sim.result()
    rp = replay_from_bytes(result.events, result.scenario)
    assert [f["kind"] for f in rp.faults] == ["drop", "crash"]
    assert rp.types[3] == "A"  # the added UAV's type


# --- bad input --------------------------------------------------------------------------------------


def test_bad_input_is_one_clear_error_each_and_changes_nothing():
    with _sim() as sim:
        sim.step(5)
        before = sim.snapshot()
        bad = [
            (NotControlledError, lambda: sim.set_state("B1", 100.0, 100.0, 0.0, 30.0)),
            (TimeInPastError, lambda: sim.add_fault(Crash(uav="B1", at_s=2.0))),
            (TimeInPastError, lambda: sim.call_at(1.0, print)),
            (UnknownUavError, lambda: sim.take_control("Z9")),
            (UnknownUavError, lambda: sim.add_fault(Crash(uav="Z9", at_s=9.0))),
            (NotGeographicError, lambda: sim.add_target(lon=10.0, lat=54.0)),
            (NotGeographicError, lambda: sim.to_lonlat(0.0, 0.0)),
        ]
        for kind, call in bad:
            with pytest.raises(kind):
                call()
        assert sim.snapshot() == before
        sim.take_control("B1")
        for args in [(math.nan, 100.0, 0.0, 30.0), (100.0, 100.0, math.inf, 30.0), (100.0, 100.0, 0.0, -1.0)]:
            with pytest.raises(BadStateError):
                sim.set_state("B1", *args)
        b1 = sim.snapshot().uavs[0]
        assert (b1.x, b1.y, b1.v, b1.theta) == (before.uavs[0].x, before.uavs[0].y, before.uavs[0].v, before.uavs[0].theta)
        sim.step()
        assert [e.change for e in read_events(sim.result().events) if e.kind == "host"] == ["take_control"]


# --- geography and endurance ------------------------------------------------------------------------


def test_geographic_hosts_use_lon_lat():
    with Simulation("geo-coast", duration_s=20.0) as sim:
        assert sim.geographic
        x, y = sim.to_local(10.45, 54.47)
        lon, lat = sim.to_lonlat(x, y)
        assert (lon, lat) == pytest.approx((10.45, 54.47), abs=1e-9)
        tid = sim.add_target(lon=10.45, lat=54.47, speed=2.0)
        name = sim.add_uav("B", lon=10.44, lat=54.46)
        sim.step(3)
        snap = sim.snapshot()
        assert snap.targets[tid].lon is not None and snap.wind is not None
        u = next(u for u in snap.uavs if u.name == name)
        assert u.lon == pytest.approx(sim.to_lonlat(u.x, u.y)[0]) and u.energy_wh is not None and u.energy_wh > 0
        assert u.state == "alive"
        sim.take_control(name)
        sim.set_state_lonlat(name, 10.45, 54.47, 0.0, 30.0)
        assert (sim.snapshot().uavs[-1].x, sim.snapshot().uavs[-1].y) == pytest.approx((x, y))


# --- the public surface ---------------------------------------------------------------------------

# Every public name of a Simulation (methods, properties, attributes), each documented in
# docs/embedding.md. A new public name fails here until it is added to both, or made private.
PUBLIC_SURFACE = {
    "actors", "add_fault", "add_target", "add_uav", "call_at", "close", "controlled", "done", "dt", "duration_s",
    "from_file", "geographic", "injector", "memory_estimate", "metrics_dict", "mode_names", "n_ticks", "now",
    "release_control", "result", "run", "run_until", "scenario", "seed", "set_state", "set_state_lonlat",
    "set_waypoint", "snapshot", "step", "subscribe", "take_control", "tick_plane", "to_local", "to_lonlat", "uav_map",
    "wait_until", "wall_seconds",
}


def test_the_public_surface_is_the_documented_one():
    import re
    from pathlib import Path

    with _sim() as sim:
        sim.step()
        surface = {n for n in set(dir(sim)) | set(vars(sim)) if not n.startswith("_")}
    assert surface == PUBLIC_SURFACE
    text = (Path(__file__).resolve().parent.parent / "docs" / "embedding.md").read_text(encoding="utf-8")
    spans = " ".join(re.findall(r"`([^`]+)`", text))
    undocumented = sorted(n for n in PUBLIC_SURFACE if not re.search(rf"\b{n}\b", spans))
    assert undocumented == []


@pytest.mark.asyncio
async def test_a_resumed_task_cannot_drive_the_simulation_too():
    with _sim() as sim:
        caught: list[BaseException] = []

        async def station():
            await sim.wait_until(3.0)
            try:
                await sim.run_until(10.0)
            except APIMisuseError as exc:
                caught.append(exc)

        await asyncio.gather(sim.run_until(5.0), station())
        assert len(caught) == 1 and sim.now == 5.0
        await sim.run_until(6.0)  # still usable
        assert sim.now == 6.0


def test_swarm_rerun_reproduces_an_embedded_run(tmp_path):
    """`swarm rerun RUNDIR` (swarm.reproduce) replays the host changes of the folder's log."""
    from swarm.reproduce import rerun

    with _embedded_run() as sim:
        write_run(sim.result(), tmp_path / "run", sim.scenario.to_dict())
    res = rerun(tmp_path / "run", tmp_path / "again")
    assert res.equal and res.first_difference_s is None


# --- the contract as a property -----------------------------------------------------------------

_CHANGE = st.one_of(
    st.tuples(st.just("target"), st.floats(1000.0, 49000.0), st.floats(1000.0, 49000.0)),
    st.tuples(st.just("drop"), st.floats(0.1, 0.9), st.integers(1, 8)),
    st.tuples(st.just("crash"), st.sampled_from(["B1", "B2", "A1"]), st.integers(0, 3)),
    st.tuples(st.just("waypoint"), st.floats(1000.0, 49000.0), st.floats(1000.0, 49000.0)),
)


def _make(sim: Simulation, change: tuple, t: float) -> None:
    kind, a, b = change
    if kind == "target":
        sim.add_target(a, b)
    elif kind == "drop":
        sim.add_fault(Drop(rate=a, start_s=t, end_s=t + b))
    elif kind == "crash":
        sim.add_fault(Crash(uav=a, at_s=t + b))
    else:
        sim.set_waypoint("A1", a, b)


@pytest.mark.slow
@settings(max_examples=examples(10), deadline=None)
@given(plan=st.lists(st.tuples(st.integers(0, 19), _CHANGE), max_size=6))
def test_chunked_call_at_and_replayed_changes_give_one_log(plan):
    """Any changes at any boundaries: made between steps, from call_at callbacks, and replayed
    from the first run's log, they give one event log."""
    plan = sorted(plan, key=lambda p: p[0])
    with Simulation(SCENARIO, duration_s=20.0) as chunked:
        for t, change in plan:
            if t > chunked.now:
                chunked.step(int(t - chunked.now))
            _make(chunked, change, float(t))
        if chunked.now < 20:
            chunked.step(int(20 - chunked.now))
        first = chunked.result()
    with Simulation(SCENARIO, duration_s=20.0) as called:
        for t, change in plan:
            called.call_at(float(t), lambda c=change, t=t: _make(called, c, float(t)))
        assert called.run().metrics["event_log_sha256"] == first.metrics["event_log_sha256"]
    with Simulation(SCENARIO, duration_s=20.0) as replay:
        assert schedule_recorded_host_changes(replay, read_events(first.events)) == len(plan)
        assert replay.run().metrics["event_log_sha256"] == first.metrics["event_log_sha256"]


def test_snapshots_say_homebound_and_landed_with_the_energy_left():
    from faults.energy import Battery

    with Simulation("geo-coast", duration_s=300.0) as sim:
        name = sim.snapshot().uavs[0].name
        sim.add_fault(Battery(uav=name, start_s=2.0, loss_frac=0.9))
        seen: list[tuple[str, float]] = []
        while not sim.done and (not seen or seen[-1][0] != "landed"):
            sim.step()
            u = sim.snapshot().uavs[0]
            if not seen or seen[-1][0] != u.state:
                assert u.energy_wh is not None
                seen.append((u.state, u.energy_wh))
        assert [s for s, _ in seen] == ["alive", "homebound", "landed"]
        assert seen[0][1] > seen[1][1] > seen[2][1] > 0.0
