"""The simulation: builds the world, the actors, the radio and the faults from a scenario,
and advances them on a virtual clock.

Drive it from your own event loop::

    sim = Simulation(load_scenario("paper-case1"), seed=3)
    await sim.run_until(600.0)

or synchronously (tests, Hypothesis state machines, scripts)::

    sim.step()            # one dt
    result = sim.run()    # to the scenario's duration

A simulation is bound to the first event loop that drives it: the host's running loop for
``run_until``, or a private loop for ``step``/``run``. Mixing the two raises a clear error.
Library code never prints, exits or calls ``asyncio.run``.

Between two ticks the simulation stands at a tick boundary, where a host acts
(:mod:`swarm.kernel.host`: its changes, ``call_at``, ``wait_until``; logged by :mod:`swarm.kernel.hostlog`).
One tick runs the phases listed in :mod:`swarm.kernel` (boundary, start, mission, sense, wake,
observe, transmit, integrate, end), each a call into the part that owns it. This class has those
parts built (:mod:`swarm.kernel.assembly`), places the scenario's targets, UAVs and faults on them,
runs the phases, drives the clock, and is the embedding API; it knows no fault kind.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

import swarm.events as ev
from agents.actor import ActorOutput, UavActor
from agents.inputs import SensorReading
from agents.maps.grid import PREFETCH_MIN
from faults.injector import FaultInjector
from faults.registry import fault_from_dict
from swarm.errors import APIMisuseError, UsageError
from swarm.events import Event
from swarm.kernel import build
from swarm.kernel.assembly import assemble, configured
from swarm.kernel.clock import TICK
from swarm.kernel.driving import LoopBinding
from swarm.kernel.host import Host, HostApi
from swarm.kernel.memory import check_memory
from swarm.kernel.mission_phase import NO_MISSION
from swarm.kernel.results import RunResult, radio_totals, run_metrics, run_result
from swarm.kernel.snapshot import Snapshot, TargetSnapshot, UavSnapshot, take_snapshot
from swarm.kernel.world import PENDING, UavBody
from swarm.scenario import Scenario, UavSpec

__all__ = ["Simulation", "Snapshot", "TargetSnapshot", "UavSnapshot"]


class Simulation(HostApi):
    def __init__(
        self,
        scenario: Scenario | str | Path,
        *,
        seed: int | None = None,
        planner: str | type | None = None,
        planner_options: Mapping[str, Any] | None = None,
        duration_s: float | None = None,
        dt_s: float | None = None,
        batch_planning: bool = True,
        tick_plane: bool = True,
        memory_limit_gb: float | None = None,
        allow_planner_imports: bool | Iterable[str] = False,
    ):
        """``planner``: a planner name (built-in, entry point or ``"module:Class"``) or a class,
        instead of the scenario's; ``planner_options``: options of the planner that runs (set
        over the scenario's options for it, key by key, and checked against its signature).
        ``allow_planner_imports``: a ``module:Class`` planner named in a scenario *file* given by
        path is refused unless ``True`` (or its name is among these); a planner given here is
        always allowed (see :mod:`swarm.scenario.trust`).
        ``batch_planning``: serve all UAVs that replan in the same tick with one vectorised
        planner call (same event log as planning one by one, only faster; see
        :mod:`agents.planners.batching`). ``False`` makes each actor call its planner itself.
        ``tick_plane``: do the tick's array work (receiving, frames, geometry, radio delivery) in
        per-tick services for all UAVs at once (issue 36; same event log). ``False`` runs the
        per-actor code those services replace: the oracle the tick-plane tests compare against.
        ``memory_limit_gb``: refuse (:class:`~swarm.kernel.memory.MemoryLimitError`) a scenario whose
        estimated memory is above it (default: ``SWARM_MEMORY_LIMIT_GB``, else half of this
        machine's memory). ``dt_s``: the tick (default: the scenario's), e.g. a host's own step."""
        scenario = configured(scenario, seed, planner, planner_options, duration_s, allow_planner_imports, dt_s)
        # Before anything is allocated: refuse a run that cannot fit (swarm.kernel.memory).
        self.memory_estimate = check_memory(scenario, memory_limit_gb)
        self.scenario = sc = scenario
        self.seed = sc.seed
        self.dt = sc.dt_s
        self.duration_s = sc.duration_s
        self._tick_index = 0
        self._sample_every = max(1, round(sc.metrics.sample_s / self.dt))
        self._binding = LoopBinding()  # the event loop that drives it (swarm.kernel.driving)
        self._advancing = False  # inside run_until (a second driver is refused)
        # The parts, built in dependency order (swarm.kernel.assembly).
        self.tick_plane = tick_plane
        p = assemble(sc, batch_planning, tick_plane)
        self._rng, self._clock, self._log, self._names = p.rng, p.clock, p.log, p.names
        self._grid, self._types, self._targets, self._geography = p.grid, p.types, p.targets, p.geography
        self._world, self._metrics, self._observer = p.world, p.metrics, p.observer
        self._map_group, self._decoder, self._radio, self._transmission = p.map_group, p.decoder, p.radio, p.transmission
        self._fleet, self._mission, self._faults = p.fleet, p.mission, p.faults
        self._mission_phase = self._mission or NO_MISSION  # (without wind and endurance, a phase that does nothing)
        self._speed_max_by_type = {n: t.speed_max for n, t in self._types.items()}
        self._host = Host(self)  # the host's side: changes, alarms, bodies driven from outside (swarm.kernel.host)
        self._populate(sc)
        if self._mission is not None:
            self._mission.equip()  # (once the scenario's UAVs are all placed: their batteries and pads)
        self._clock.schedule(0.0, self._tick, TICK)
        self._log.emit(ev.start(t=0.0, header={
            "scenario": sc.name, "seed": self.seed, "planner": sc.planner.name, "dt": self.dt,
            "uavs": [[b.uid, b.name, b.kind.name] for b in self._world.uavs.values()],
            "targets": len(self._targets), "threats": len(self._world.threats),
            "faults": self._faults.schedule.to_list(),
            # (only when not the default, so a "frames" log is byte for byte what it always was)
            **({"recording": sc.recording.level} if self._observer.summary else {}),
        }))

    def _populate(self, sc: Scenario) -> None:
        """The scenario's targets (placed, then random), UAVs and faults, in that order."""
        tm = sc.targets
        for i, p in enumerate(tm.placed):
            self._add_target_rng(p.x_m, p.y_m, math.radians(p.heading_deg), p.speed, p.value, self._rng.generator("target", i))
        ids = build.add_random_targets(sc, self._targets, self._rng, self._geography)
        self._metrics.appeared_t.update(dict.fromkeys(ids, self._clock.now))
        for spec in sc.uavs:
            self._add_uav_spec(spec)
        for f in sc.faults:
            fault = fault_from_dict(f.model_dump(mode="python"))
            if not fault.applied_by_loader:  # (a join: folded into the UAV's join_s)
                self._faults.add(fault)

    @classmethod
    def from_file(cls, ref: str | Path, **kw: Any) -> Simulation:
        return cls(ref, **kw)

    def _add_target_rng(self, x: float, y: float, theta: float, v: float, value: float,
                        rng: np.random.Generator) -> int:
        tid = self._targets.add(x, y, theta, v, value, rng)
        self._metrics.appeared_t[tid] = self._clock.now  # (time to first detection counts from here)
        return tid

    def _add_uav_spec(self, spec: UavSpec) -> int:
        kind = self._types[spec.type]
        uid = len(self._world.uavs)
        name = spec.name
        assert name is not None  # filled in by the scenario's validation, or by add_uav
        speed = spec.speed if spec.speed is not None else kind.speed_max
        self._world.add_uav(UavBody(uid, name, kind, spec.x_m, spec.y_m, speed, math.radians(spec.heading_deg),
                                   PENDING, spec.join_s or 0.0))
        self._names[name] = uid
        # Scan disks and decoded frames are shared by every UAV using them within a few ticks;
        # anti-entropy resends scans up to sync_horizon_s old, so at least 4096 disks are kept
        # (bench-100-dacmp 300 s: disk rebuilds 41k -> 19k, 9% less CPU, +90 MB peak RSS).
        self._grid.set_disk_cache_size(max(4096, 3 * len(self._world.uavs)))
        self._decoder.size = max(256, 4 * len(self._world.uavs))
        self._fleet.add(uid)
        self._observer.paths[uid] = []
        self._faults.set_join(uid, spec.join_s or 0.0)
        return uid

    # --- public API: inspection -------------------------------------------------------------

    @property
    def now(self) -> float:
        """The tick boundary the world stands at: ``k * dt`` after ``k`` ticks (while a tick is
        under way, the boundary it started from)."""
        return self._tick_index * self.dt

    @property
    def done(self) -> bool:
        return self._tick_index >= self.n_ticks

    @property
    def n_ticks(self) -> int:
        return int(round(self.duration_s / self.dt))

    @property
    def actors(self) -> dict[int, UavActor]:
        """Each UAV's actor, by UAV id (a restart replaces it): for diagnostics and tests."""
        return self._fleet.actors

    @property
    def injector(self) -> FaultInjector:
        """The run's fault schedule (``injector.schedule``) and what fired (``injector.fired``)."""
        return self._faults.injector

    def snapshot(self) -> Snapshot:
        """Where everything is now (plain records: safe to keep)."""
        return take_snapshot(self)

    def uav_map(self, name: str) -> np.ndarray:
        """A copy of one UAV's own last-seen map (what it believes, not the truth)."""
        return self.actors[self._host.uid(name)].umap.to_dense()

    def subscribe(self, callback: Callable[[Event], None], kinds: Iterable[str] | None = None) -> Callable[[], None]:
        """Call ``callback(event)`` for each event as it is logged, a record of :mod:`swarm.events`
        with UAV and mode names (optionally only some kinds); returns an unsubscribe function.
        Subscribed before the first tick, it gets the ``start`` header first."""
        return self._log.subscribe(callback, kinds)

    def mode_names(self) -> dict[str, str]:
        """Each UAV's mode now, by name: search / surveil, or down / pending."""
        return {b.name: self._fleet.mode_name(uid) for uid, b in sorted(self._world.uavs.items())}

    # --- the tick ---------------------------------------------------------------------------

    async def _tick(self) -> None:
        """One tick at ``t``: the phases listed in :mod:`swarm.kernel`, one call each.

        Faults, joins and frames due at ``t`` ran before this (clock priorities)."""
        t = self.now
        self._host.in_tick = True
        self._faults.begin_tick(t)
        self._mission_phase.begin_tick(t)  # energy, relief, landings, launches; the wind
        alive = self._world.alive_ids()
        self._fleet.start_tasks(alive)
        xy, readings = self._sense(t, alive)
        outputs = await self._fleet.wake(alive, readings, self._faults.tick.paused)
        self._observer.observe(t, alive, outputs, readings, xy, self._fleet.plans, self._faults.tick,
                              self._speed_max_by_type)
        self._transmission.transmit(t, self.dt, alive, xy, outputs, first=self._faults.transmit(t, self.dt, alive, xy))
        self._integrate(alive, outputs)
        self._end_tick()
        self._host.in_tick = False

    def _sense(self, t: float, alive: list[int]) -> tuple[np.ndarray, dict[int, SensorReading]]:
        """Positions at ``t`` and what each live UAV senses there (after the tick faults).

        UAVs move only in :meth:`_integrate`, so these positions also serve the safety check and
        the radio topology of this tick."""
        world = self._world
        self._grid.new_tick()  # (issue 36, T8: the maps' shared tiles, agents.maps.tiles)
        xy = world.positions(alive)
        readings = dict(zip(alive, world.sense_many(alive, t, xy)))
        self._faults.sense(t, alive, readings, self._fleet.outputs.__contains__)
        self._mission_phase.sense(t, alive, readings)  # each UAV's energy reading and its way home
        # Every live UAV scans its disk this tick (its map, the truth, every UAV hearing the
        # record): build those disks in one vectorised pass. A pure memo.
        if len(alive) >= PREFETCH_MIN:
            bodies = [world.uavs[uid] for uid in alive]
            umap = self.actors[alive[0]].umap
            self._grid.prefetch_disks([b.x for b in bodies], [b.y for b in bodies], [b.kind.detect_radius for b in bodies],
                                     t, None if umap.dense else umap.tile_shape)
        return xy, readings

    def _integrate(self, alive: list[int], outputs: dict[int, ActorOutput]) -> None:
        """Physics: every live UAV the simulator flies (not the host's: swarm.kernel.host) flies its
        command for ``dt``, then the targets move."""
        dt = self.dt
        if self._host.controlled:
            alive = [uid for uid in alive if uid not in self._host.controlled]
        self._world.fly(alive, [(outputs[uid].a, outputs[uid].omega) for uid in alive], dt, self.now)
        self._targets.step(dt, self._grid)

    def _end_tick(self) -> None:
        """Count the tick, sample the time series when due, flush the log, schedule the next."""
        self._observer.end_tick(self.now)
        self._tick_index += 1
        if self._tick_index % self._sample_every == 0 or self._tick_index == self.n_ticks:
            self._observer.sample(self.now, radio_totals(self), self.mode_names)
        self._log.flush()
        self._clock.schedule(self._tick_index * self.dt, self._tick, TICK)

    # --- driving ----------------------------------------------------------------------------

    async def _advance(self, k_end: int, progress: Callable[[float, float], None] | None = None) -> None:
        """Run every tick up to boundary ``k_end``, serving each boundary reached (swarm.kernel.host)."""
        clock, host = self._clock, self._host
        eps = 1e-9 * self.dt
        t_end = k_end * self.dt
        every = max(1, self.n_ticks // 200)
        while True:
            if host.due() and clock.peek() >= self.now - eps:
                await host.serve()
            if clock.peek() >= t_end - eps:
                break
            callback = clock.pop()
            if callback == self._tick:
                await self._tick()
                if progress is not None and self._tick_index % every == 0:
                    progress(self.now, t_end)
            else:
                callback()

    async def run_until(self, t: float, progress: Callable[[float, float], None] | None = None) -> None:
        """Run every tick that ends at or before ``t`` inside the caller's running event loop:
        afterwards ``now`` is the last tick boundary at or before ``t`` (never past it)."""
        if not isinstance(t, (int, float)) or math.isnan(t):
            raise UsageError(f"run_until: t = {t!r} is not a number of seconds")
        if self._advancing:
            raise APIMisuseError("run_until: this Simulation is already advancing (called from a task it resumed, or "
                                 "twice at once); one driver calls run_until, other tasks use wait_until")
        k_end = max(self._tick_index, math.floor(t / self.dt + 1e-9)) if math.isfinite(t) else self.n_ticks

        async def advance() -> None:
            self._advancing = True
            try:
                await asyncio.sleep(0)  # (host tasks started with it make their first wait_until first)
                await self._advance(k_end, progress)
            finally:
                self._advancing = False

        await self._binding.in_host_loop(advance)

    def step(self, n: int = 1) -> None:
        """Advance ``n`` ticks synchronously."""
        if n < 1:
            raise UsageError(f"step(n) needs n >= 1, got {n}")
        if self._tick_index + n > self.n_ticks:
            raise APIMisuseError(
                f"step({n}) at tick {self._tick_index} would go past the end of the run ({self.n_ticks} ticks, "
                f"{self.duration_s:g} s); step at most {self.n_ticks - self._tick_index} more, or build the "
                f"Simulation with a longer duration_s")
        self._binding.in_own_loop(lambda: self._advance(self._tick_index + n))

    def run(self, progress: Callable[[float, float], None] | None = None) -> RunResult:
        """Run synchronously to the scenario's duration and return the result."""
        self._binding.in_own_loop(lambda: self._advance(self.n_ticks, progress))
        return self.result()

    @property
    def wall_seconds(self) -> float:
        """Wall-clock seconds spent advancing it (``metrics.json``'s ``wall_seconds``)."""
        return self._binding.wall_seconds

    def close(self) -> None:
        """Cancel the actor tasks and release a private event loop. Safe to call twice."""
        if not self._binding.closed:
            self._binding.close(self._fleet.cancel())

    def __del__(self) -> None:
        # Dropped without close() (a script's run()): else asyncio prints "Task was destroyed" per UAV.
        binding = getattr(self, "_binding", None)
        try:
            if binding is not None and binding.can_close_in_finaliser():
                self.close()
        except Exception:  # interpreter shutdown, or a host loop running in this thread
            pass

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- results ---------------------------------------------------------------------------

    def metrics_dict(self) -> dict[str, Any]:
        """The run's metrics so far (what ``metrics.json`` holds; see :mod:`swarm.kernel.results`)."""
        return run_metrics(self)

    def result(self) -> RunResult:
        """Everything the run produced so far, for :func:`swarm.outputs.write_run`."""
        return run_result(self)

