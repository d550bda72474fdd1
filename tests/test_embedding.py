"""Embedding the simulator in a host asyncio program, and the errors of driving it wrongly.

* ``await sim.run_until(t)`` shares the host's event loop: other tasks make progress while it
  runs, and the event log is byte for byte the one ``sim.run()`` writes (same scenario, seed).
* A simulation is bound to the loop that first drives it: its own private loop for
  ``step()``/``run()``, the host's for ``run_until``. Mixing them, calling ``step()`` inside a
  running loop, or using a closed simulation raises :class:`swarm.errors.APIMisuseError`
  (a caller's mistake; the simulation stays usable from its own loop). An actor that raises is
  a :class:`swarm.errors.SimulationError` (the run failed), and the simulation is then done for.
"""

from __future__ import annotations

import asyncio

import pytest

from swarm import Simulation
from swarm.errors import APIMisuseError, SimulationError, SwarmError

SCENARIO = "paper-case1"  # 3 UAVs, 2 targets: a few ms per simulated second
DURATION = 40.0


def _sim(**kw) -> Simulation:
    return Simulation(SCENARIO, duration_s=DURATION, **kw)


def _run_hash(**kw) -> str:
    with _sim(**kw) as sim:
        return sim.run().metrics["event_log_sha256"]


@pytest.fixture(scope="module")
def sync_hash() -> str:
    """The event-log hash of the synchronous run everything below must reproduce (a sync
    fixture: ``run()`` cannot be called inside the async tests' running loop)."""
    return _run_hash()


@pytest.fixture(scope="module")
def sync_hash_seed2() -> str:
    return _run_hash(seed=2)


# --- run_until beside other tasks -----------------------------------------------------------------


@pytest.mark.asyncio
async def test_run_until_shares_the_loop_with_other_tasks_and_logs_what_run_logs(sync_hash):
    sim = _sim()
    seen: list[float] = []  # sim.now as the other task saw it, one entry per loop turn
    stop = asyncio.Event()

    async def other_task():
        while not stop.is_set():
            seen.append(sim.now)
            await asyncio.sleep(0)

    other = asyncio.create_task(other_task())
    try:
        await sim.run_until(DURATION)
    finally:
        stop.set()
        await other
    try:
        assert sim.done and sim.now == pytest.approx(DURATION)
        assert sim.result().metrics["event_log_sha256"] == sync_hash
        # The other task ran while the simulation did, not only before or after it: it saw many
        # different simulated times strictly inside the run.
        inside = {t for t in seen if 0.0 < t < sim.now}
        assert len(inside) >= DURATION / 4, f"the other task saw only {sorted(inside)}"
    finally:
        sim.close()


@pytest.mark.asyncio
async def test_two_simulations_interleaved_in_one_loop_each_log_what_run_logs(sync_hash, sync_hash_seed2):
    assert sync_hash_seed2 != sync_hash
    with _sim() as a, _sim(seed=2) as b:
        await asyncio.gather(a.run_until(DURATION), b.run_until(DURATION))
        assert a.result().metrics["event_log_sha256"] == sync_hash
        assert b.result().metrics["event_log_sha256"] == sync_hash_seed2


@pytest.mark.asyncio
async def test_run_until_in_pieces_is_one_run(sync_hash):
    with _sim() as sim:
        for t in (0.5, 7.0, 7.0, 19.25, DURATION):  # off-tick times and a repeat are fine
            await sim.run_until(t)
            await asyncio.sleep(0)
        assert sim.done
        assert sim.result().metrics["event_log_sha256"] == sync_hash


# --- binding to one loop --------------------------------------------------------------------------


def test_stepped_simulation_refuses_run_until_from_another_loop(sync_hash):
    with _sim() as sim:
        sim.step(3)
        with pytest.raises(APIMisuseError, match="bound to another event loop"):
            asyncio.run(sim.run_until(10.0))
        # The refused call changed nothing: the simulation goes on from its own loop.
        assert sim.now == pytest.approx(3 * sim.dt)
        assert sim.run().metrics["event_log_sha256"] == sync_hash


def test_simulation_driven_by_a_host_loop_refuses_step_and_run():
    sim = _sim()
    asyncio.run(sim.run_until(5.0))
    try:
        with pytest.raises(APIMisuseError, match="driven by a host event loop"):
            sim.step()
        with pytest.raises(APIMisuseError, match="driven by a host event loop"):
            sim.run()
    finally:
        sim.close()


def test_run_until_from_a_second_loop_is_refused():
    sim = _sim()
    asyncio.run(sim.run_until(3.0))
    try:
        with pytest.raises(APIMisuseError, match="bound to another event loop"):
            asyncio.run(sim.run_until(6.0))
    finally:
        sim.close()


@pytest.mark.asyncio
async def test_step_and_run_inside_a_running_loop_are_refused(sync_hash):
    with _sim() as sim:
        with pytest.raises(APIMisuseError, match="inside a running event loop"):
            sim.step()
        with pytest.raises(APIMisuseError, match="inside a running event loop"):
            sim.run()
        # Neither bound the simulation: this loop can still drive it, to the same log.
        assert sim.now == 0.0
        await sim.run_until(DURATION)
        assert sim.result().metrics["event_log_sha256"] == sync_hash


def test_a_closed_simulation_refuses_everything_and_closes_twice():
    sim = _sim()
    sim.step(2)
    sim.close()
    sim.close()  # safe to call twice
    with pytest.raises(APIMisuseError, match="closed"):
        sim.step()
    with pytest.raises(APIMisuseError, match="closed"):
        sim.run()
    with pytest.raises(APIMisuseError, match="closed"):
        asyncio.run(sim.run_until(5.0))
    never_driven = _sim()
    never_driven.close()
    with pytest.raises(APIMisuseError, match="closed"):
        never_driven.step()


@pytest.mark.asyncio
async def test_a_simulation_closed_in_its_host_loop_refuses_run_until():
    sim = _sim()
    await sim.run_until(3.0)
    sim.close()
    with pytest.raises(APIMisuseError, match="closed"):
        await sim.run_until(6.0)


def test_misuse_is_a_swarm_error_and_a_runtime_error_but_not_a_simulation_error():
    assert issubclass(APIMisuseError, SwarmError) and issubclass(APIMisuseError, RuntimeError)
    assert not issubclass(APIMisuseError, SimulationError)
    assert not issubclass(SimulationError, APIMisuseError)


# --- an actor that raises: the run failed -------------------------------------------------------


def _break_an_actor(sim: Simulation, name: str, at_s: float) -> None:
    actor = sim.actors[sim._names[name]]
    act = actor.act

    def act_then_fail(reading):
        if reading.t >= at_s:
            raise ZeroDivisionError("planted")
        return act(reading)

    actor.act = act_then_fail


def test_an_actor_that_raises_is_a_simulation_error_then_the_simulation_is_unusable():
    with _sim() as sim:
        _break_an_actor(sim, "A1", at_s=5.0)
        with pytest.raises(SimulationError, match="UAV A1 raised ZeroDivisionError: planted") as info:
            sim.run()
        assert not isinstance(info.value, APIMisuseError)
        assert isinstance(info.value.__cause__, ZeroDivisionError)
        assert sim.now == pytest.approx(5.0)
        with pytest.raises(APIMisuseError, match="failed earlier"):
            sim.step()


@pytest.mark.asyncio
async def test_an_actor_that_raises_under_run_until_is_a_simulation_error():
    with _sim() as sim:
        _break_an_actor(sim, "B1", at_s=2.0)
        with pytest.raises(SimulationError, match="UAV B1 raised"):
            await sim.run_until(DURATION)
        with pytest.raises(APIMisuseError, match="failed earlier"):
            await sim.run_until(DURATION)
