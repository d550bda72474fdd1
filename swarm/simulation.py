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

One tick at time ``t`` (see ARCHITECTURE.md): faults, joins and frames due by ``t`` first
(clock priorities), then the tick's phases, each a call into the part that owns it: start
(:mod:`swarm.faulting`, :mod:`swarm.fleet`), mission (wind, energy: :mod:`swarm.mission`), sense
(the world, the tick faults, the energy readings), wake the actors and wait for all of them
(:mod:`swarm.fleet`), observe (:mod:`swarm.observer`), transmit (:mod:`swarm.transmission`),
integrate (the world), end (sampling, the log, the next tick). This class builds those parts,
runs the phases, drives the clock, and is the embedding API; it knows no fault kind.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from agents.actor import ActorOutput, SensorReading, UavActor
from agents.maps.grid import PREFETCH_MIN, Grid
from agents.maps.mapgroup import MapGroup, maps_share
from comms.framecache import DecodeCache
from faults.base import FaultKind
from faults.injector import FaultInjector
from faults.registry import fault_from_dict
from swarm import build
from swarm.clock import TICK, Clock
from swarm.driving import LoopBinding
from swarm.errors import APIMisuseError, UsageError
from swarm.events import Event
from swarm.faulting import RunFaults
from swarm.fleet import Fleet
from swarm.memory import check_memory
from swarm.metrics import Metrics
from swarm.mission_phase import NO_MISSION
from swarm.observer import Observer
from swarm.recorder import EventLog
from swarm.results import RunResult, radio_totals, run_metrics, run_result
from swarm.rng import RngTree
from swarm.scenario import Scenario, UavSpec
from swarm.snapshot import Snapshot, TargetSnapshot, UavSnapshot, take_snapshot
from swarm.transmission import Transmission
from swarm.world import PENDING, Targets, UavBody, World

__all__ = ["Simulation", "Snapshot", "TargetSnapshot", "UavSnapshot"]


class Simulation:
    def __init__(
        self,
        scenario: Scenario | str | Path,
        *,
        seed: int | None = None,
        planner: str | type | None = None,
        planner_options: Mapping[str, Any] | None = None,
        duration_s: float | None = None,
        batch_planning: bool = True,
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
        ``memory_limit_gb``: refuse (:class:`~swarm.memory.MemoryLimitError`) a scenario whose
        estimated memory is above it (default: ``SWARM_MEMORY_LIMIT_GB``, else half of this
        machine's memory)."""
        scenario = build.configured(scenario, seed, planner, planner_options, duration_s, allow_planner_imports)
        # Before anything is allocated: refuse a run that cannot fit (swarm.memory).
        self.memory_estimate = check_memory(scenario, memory_limit_gb)
        self.scenario = sc = scenario
        self.seed = sc.seed
        self.dt = sc.dt_s
        self.duration_s = sc.duration_s
        self.rng = RngTree(self.seed)
        self.clock = Clock()
        self.log = EventLog()
        self.names: dict[str, int] = {}  # shared with the faults: names added later resolve
        self._tick_index = 0
        self._sample_every = max(1, round(sc.metrics.sample_s / self.dt))
        self._binding = LoopBinding()  # the event loop that drives it (swarm.driving)
        # Ground truth (area grid, targets, threats), the metrics that observe it, UAV types.
        self.grid = Grid(sc.area.width_m, sc.area.height_m, sc.area.cell_m)
        self.tau = sc.effective_tau
        self.types = build.uav_types(sc)
        self.speed_max_by_type = {n: t.speed_max for n, t in self.types.items()}
        self.targets = Targets(build.target_motion(sc))
        self.world = World(self.grid, self.targets, build.threats(sc))
        self.metrics = Metrics(self.grid, self.tau)
        self.geography = build.geography(sc, self.grid, self.world, self.metrics)  # (issue 26: polygons; None without)
        self.observer = Observer(self.world, self.metrics, self.log, self.dt, sc.recording.level == "summary",
                                 sc.safety.min_separation_m)
        # The UAVs' maps share storage where they agree (agents.maps.mapgroup): on areas small
        # enough for dense maps, unless a knowledge horizon keeps scans from every map (maps_share).
        self.map_group = (MapGroup(self.grid, self.tau, self.dt)
                          if maps_share(self.grid.nx * self.grid.ny, self.grid.width_m, self.grid.height_m,
                                        sc.radio.horizon_m) else None)
        # Each broadcast frame decoded once (with the swarm key, if [radio] auth).
        self._decoder = DecodeCache(sc.radio.frame_max_bytes, key=build.auth_key(sc))
        self.fleet = Fleet(sc, self.world, self.grid, self.tau, self.rng, self.log, build.actor_settings(sc, self.geography),
                           self._decoder, self.map_group, batch_planning,
                           lost=lambda src, dst, n, cause: self.transmission.lose(self.clock.now, src, dst, n, cause))
        self.fleet.types = self.types
        self.faults = RunFaults(self.clock, self.world, self.fleet, self.log, self.rng, self.names,
                                (self.grid.width_m, self.grid.height_m), self.dt, sc.radio.latency_s)
        uavs = self.world.uavs
        self.radio = build.radio(
            sc, link_rng=lambda s, d: self.rng.generator("link", uavs[s].name, uavs[d].name),
            link_filter=self.faults.injector,
            link_rngs=lambda links: self.rng.generators([("link", uavs[s].name, uavs[d].name) for s, d in links]))
        self.faults.radio = self.radio
        self.transmission = Transmission(self.radio, self.clock, self.world, self.fleet.actors, self.observer.lost)
        self._populate(sc)
        self.mission = build.mission(self)  # (issues 26, 33: wind and endurance; None without)
        self._mission = self.mission or NO_MISSION  # (the mission phase; without them, one that does nothing)
        self.clock.schedule(0.0, self._tick, TICK)
        self.log.emit("start", 0.0, {
            "scenario": sc.name, "seed": self.seed, "planner": sc.planner.name, "dt": self.dt,
            "uavs": [[b.uid, b.name, b.kind.name] for b in self.world.uavs.values()],
            "targets": len(self.targets), "threats": len(self.world.threats),
            "faults": self.faults.schedule.to_list(),
            # (only when not the default, so a "frames" log is byte for byte what it always was)
            **({"recording": sc.recording.level} if self.observer.summary else {}),
        })

    def _populate(self, sc: Scenario) -> None:
        """The scenario's targets (placed, then random), UAVs and faults, in that order."""
        tm = sc.targets
        for p in tm.placed:
            self.add_target(p.x_m, p.y_m, p.heading_deg, p.speed, p.value)
        ids = build.add_random_targets(sc, self.targets, self.rng, self.geography)
        self.metrics.appeared_t.update(dict.fromkeys(ids, self.clock.now))
        for spec in sc.uavs:
            self._add_uav_spec(spec)
        for f in sc.faults:
            fault = fault_from_dict(f.model_dump(mode="python"))
            if not fault.applied_by_loader:  # (a join: folded into the UAV's join_s)
                self.add_fault(fault)

    @classmethod
    def from_file(cls, ref: str | Path, **kw) -> Simulation:
        return cls(ref, **kw)

    def _add_target_rng(self, x, y, theta, v, value, rng) -> int:
        tid = self.targets.add(x, y, theta, v, value, rng)
        self.metrics.appeared_t[tid] = self.clock.now  # (time to first detection counts from here)
        return tid

    def _add_uav_spec(self, spec: UavSpec) -> int:
        kind = self.types[spec.type]
        uid = len(self.world.uavs)
        name = spec.name
        assert name is not None  # filled in by the scenario's validation, or by add_uav
        speed = spec.speed if spec.speed is not None else kind.speed_max
        self.world.add_uav(UavBody(uid, name, kind, spec.x_m, spec.y_m, speed, math.radians(spec.heading_deg),
                                   PENDING, spec.join_s or 0.0))
        self.names[name] = uid
        # Scan disks and decoded frames are shared by every UAV using them within a few ticks;
        # anti-entropy resends scans up to sync_horizon_s old, so at least 4096 disks are kept
        # (bench-100-dacmp 300 s: disk rebuilds 41k -> 19k, 9% less CPU, +90 MB peak RSS).
        self.grid.set_disk_cache_size(max(4096, 3 * len(self.world.uavs)))
        self._decoder.size = max(256, 4 * len(self.world.uavs))
        self.fleet.add(uid)
        self.observer.paths[uid] = []
        self.faults.set_join(uid, spec.join_s or 0.0)
        return uid

    # --- public API: inspection -------------------------------------------------------------

    @property
    def now(self) -> float:
        """World time: ``k * dt`` after ``k`` ticks."""
        return self._tick_index * self.dt

    @property
    def done(self) -> bool:
        return self._tick_index >= self.n_ticks

    @property
    def n_ticks(self) -> int:
        return int(round(self.duration_s / self.dt))

    @property
    def actors(self) -> dict[int, UavActor]:
        """Each UAV's actor, by UAV id (a restart replaces it)."""
        return self.fleet.actors

    @property
    def injector(self) -> FaultInjector:
        """The run's fault schedule (``injector.schedule``) and what fired (``injector.fired``)."""
        return self.faults.injector

    def snapshot(self) -> Snapshot:
        """Where everything is now (plain records: safe to keep)."""
        return take_snapshot(self.now, self.world, self.fleet, self.metrics, self.radio.graph.edges())

    def uav_map(self, name: str) -> np.ndarray:
        """A copy of one UAV's own last-seen map (what it believes, not the truth)."""
        return self.actors[self._uid(name)].umap.to_dense()

    def subscribe(self, callback: Callable[[Event], None], kinds: Iterable[str] | None = None) -> Callable[[], None]:
        """Call ``callback(event)`` for each event as it is logged, a record of :mod:`swarm.events`
        with UAV and mode names (optionally only some kinds); returns an unsubscribe function.
        Subscribed before the first tick, it gets the ``start`` header first."""
        return self.log.subscribe(callback, kinds)

    def _uid(self, name: str) -> int:
        if name not in self.names:
            raise UsageError(f"no UAV named {name!r}; known: {', '.join(self.names)}")
        return self.names[name]

    def mode_names(self) -> dict[str, str]:
        """Each UAV's mode now, by name: search / surveil, or down / pending."""
        return {b.name: self.fleet.mode_name(uid) for uid, b in sorted(self.world.uavs.items())}

    # --- public API: changing the run -------------------------------------------------------

    def add_target(self, x: float, y: float, heading_deg: float = 0.0, speed: float = 0.0, value: float = 1.0) -> int:
        if not self.grid.contains(x, y):
            raise UsageError(f"target position ({x}, {y}) is outside the area {self.grid.width_m} x {self.grid.height_m} m")
        if not 0.0 <= speed <= self.targets.motion.speed_max:
            raise UsageError(f"target speed {speed} outside [0, {self.targets.motion.speed_max}] m/s")
        tid = len(self.targets)
        return self._add_target_rng(x, y, math.radians(heading_deg), speed, value, self.rng.generator("target", tid))

    def add_uav(self, type: str, x: float, y: float, heading_deg: float = 0.0, speed: float | None = None,
                name: str | None = None, join_s: float | None = None) -> str:
        """Add a UAV; it joins at ``join_s`` (default: the next tick). Returns its name."""
        if type not in self.types:
            raise UsageError(f"unknown UAV type {type!r}; known: {', '.join(self.types)}")
        if name is None:
            k = 1 + sum(1 for b in self.world.uavs.values() if b.kind.name == type)
            name = f"{type}{k}"
            while name in self.names:
                k += 1
                name = f"{type}{k}"
        if name in self.names:
            raise UsageError(f"a UAV named {name!r} already exists")
        if not self.grid.contains(x, y):
            raise UsageError(f"UAV position ({x}, {y}) is outside the area")
        kind = self.types[type]
        if speed is not None and not kind.speed_min <= speed <= kind.speed_max:
            raise UsageError(f"speed {speed} outside type {type}'s range [{kind.speed_min}, {kind.speed_max}]")
        join = self.now if join_s is None else max(join_s, self.now)
        spec = UavSpec(name=name, type=type, x_m=x, y_m=y, heading_deg=heading_deg, speed=speed, join_s=join)
        self._add_uav_spec(spec)
        return name

    def add_fault(self, fault: FaultKind) -> None:
        """Add a fault (an instance of a kind of :mod:`faults.schedule`, or of one registered
        elsewhere); faults that happen at a time must not be in the past."""
        self.faults.add(fault)

    # --- the tick ---------------------------------------------------------------------------

    async def _tick(self) -> None:
        """One tick at ``t``: the data flow of ARCHITECTURE.md, one phase per call.

        Faults, joins and frames due at ``t`` ran before this (clock priorities)."""
        t = self.now
        self.faults.begin_tick(t)
        self._mission.begin_tick(t)  # energy, relief, landings, launches; the wind
        alive = self.world.alive_ids()
        self.fleet.start_tasks(alive)
        xy, readings = self._sense(t, alive)
        outputs = await self.fleet.wake(alive, readings, self.faults.tick.paused)
        self.observer.observe(t, alive, outputs, readings, xy, self.fleet.plans, self.faults.tick,
                              self.speed_max_by_type)
        self.transmission.transmit(t, self.dt, alive, xy, outputs, first=self.faults.transmit(t, self.dt, alive, xy))
        self._integrate(alive, outputs)
        self._end_tick()

    def _sense(self, t: float, alive: list[int]) -> tuple[np.ndarray, dict[int, SensorReading]]:
        """Positions at ``t`` and what each live UAV senses there (after the tick faults).

        UAVs move only in :meth:`_integrate`, so these positions also serve the safety check and
        the radio topology of this tick."""
        world = self.world
        xy = world.positions(alive)
        readings = dict(zip(alive, world.sense_many(alive, t, xy)))
        self.faults.sense(t, alive, readings, self.fleet.outputs.__contains__)
        self._mission.sense(t, alive, readings)  # each UAV's energy reading and its way home
        # Every live UAV scans its disk this tick (its map, the truth, every UAV hearing the
        # record): build those disks in one vectorised pass. A pure memo.
        if len(alive) >= PREFETCH_MIN:
            bodies = [world.uavs[uid] for uid in alive]
            umap = self.actors[alive[0]].umap
            self.grid.prefetch_disks([b.x for b in bodies], [b.y for b in bodies], [b.kind.detect_radius for b in bodies],
                                     t, None if umap.dense else umap.tile_shape)
        return xy, readings

    def _integrate(self, alive: list[int], outputs: dict[int, ActorOutput]) -> None:
        """Physics: every live UAV flies its command for ``dt``, then the targets move."""
        dt = self.dt
        for uid in alive:
            out = outputs[uid]
            self.world.apply(uid, out.a, out.omega, dt, self.now)
        self.targets.step(dt, self.grid)

    def _end_tick(self) -> None:
        """Count the tick, sample the time series when due, flush the log, schedule the next."""
        self.observer.end_tick(self.now)
        self._tick_index += 1
        if self._tick_index % self._sample_every == 0 or self._tick_index == self.n_ticks:
            self.observer.sample(self.now, radio_totals(self), self.mode_names)
        self.log.flush()
        self.clock.schedule(self._tick_index * self.dt, self._tick, TICK)

    # --- driving ----------------------------------------------------------------------------

    async def _advance(self, t_end: float, progress: Callable[[float, float], None] | None = None) -> None:
        clock = self.clock
        eps = 1e-9 * self.dt
        every = max(1, self.n_ticks // 200)
        while clock.peek() < t_end - eps:
            callback = clock.pop()
            if callback == self._tick:
                await self._tick()
                if progress is not None and self._tick_index % every == 0:
                    progress(self.now, t_end)
            else:
                callback()

    async def run_until(self, t: float, progress: Callable[[float, float], None] | None = None) -> None:
        """Advance the world to time ``t`` inside the caller's running event loop."""
        await self._binding.in_host_loop(lambda: self._advance(t, progress))

    def step(self, n: int = 1) -> None:
        """Advance ``n`` ticks synchronously."""
        if n < 1:
            raise UsageError(f"step(n) needs n >= 1, got {n}")
        if self._tick_index + n > self.n_ticks:
            raise APIMisuseError(
                f"step({n}) at tick {self._tick_index} would go past the end of the run ({self.n_ticks} ticks, "
                f"{self.duration_s:g} s); step at most {self.n_ticks - self._tick_index} more, or build the "
                f"Simulation with a longer duration_s")
        self._binding.in_own_loop(lambda: self._advance((self._tick_index + n) * self.dt))

    def run(self, progress: Callable[[float, float], None] | None = None) -> RunResult:
        """Run synchronously to the scenario's duration and return the result."""
        self._binding.in_own_loop(lambda: self._advance(self.n_ticks * self.dt, progress))
        return self.result()

    @property
    def wall_seconds(self) -> float:
        """Wall-clock seconds spent advancing it (``metrics.json``'s ``wall_seconds``)."""
        return self._binding.wall_seconds

    def close(self) -> None:
        """Cancel the actor tasks and release a private event loop. Safe to call twice."""
        if not self._binding.closed:
            self._binding.close(self.fleet.cancel())

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

    def __exit__(self, *exc) -> None:
        self.close()

    # --- results ---------------------------------------------------------------------------

    def metrics_dict(self) -> dict:
        """The run's metrics so far (what ``metrics.json`` holds; see :mod:`swarm.results`)."""
        return run_metrics(self)

    def result(self) -> RunResult:
        """Everything the run produced so far, for :func:`swarm.outputs.write_run`."""
        return run_result(self)

