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

One tick at time ``t`` (see ARCHITECTURE.md): faults and joins due at ``t`` and frames that
arrived by ``t`` are processed first (clock priorities), then every live actor is woken with its
sensor reading and the simulator waits for all of them; outputs are then handled in UAV-id
order: ground-truth metrics, radio (topology from positions, one broadcast per frame, per-link
decisions), the world integrates commands and targets by ``dt``.
"""

from __future__ import annotations

import asyncio
import gc
import math
import time
from collections import defaultdict
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from agents.actor import ActorOutput, SensorReading, UavActor
from agents.maps.grid import PREFETCH_MIN, Grid
from agents.maps.mapgroup import MapGroup, maps_share
from agents.planners import Planner, PlannerContext, PlannerError, build_planner
from agents.planners.base import Plan, PlanView
from agents.planners.batching import PlanBatcher
from comms.codec import encode
from comms.framecache import DecodeCache
from comms.mailbox import Mailbox
from comms.messages import MODE_NAMES, Hello, Message, ScanRecords, TrackItem, Tracks
from comms.radio import SPOOF_SENDER, Delivery
from faults.injector import FaultInjector
from faults.schedule import (
    PHANTOM_TARGET_ID,
    ClockSkew,
    Crash,
    Fault,
    FaultSchedule,
    Join,
    Liar,
    NavError,
    Pause,
    Restart,
    Sensor,
    Spoofer,
    Swizzle,
    fault_from_dict,
    uav_names,
)
from swarm import build
from swarm.clock import DELIVERY, FAULT, TICK, Clock
from swarm.errors import APIMisuseError, SimulationError, UsageError
from swarm.events import Event
from swarm.memory import check_memory
from swarm.metrics import Metrics
from swarm.node_faults import NodeFaults, WindowFault
from swarm.recorder import EventLog
from swarm.results import RunResult, radio_totals, run_metrics, run_result
from swarm.rng import RngTree
from swarm.scenario import Scenario, UavSpec, load_scenario
from swarm.scenario.trust import allowed
from swarm.world import ALIVE, CRASHED, PENDING, Targets, UavBody, World

# Scan records in each spoofed frame (see Simulation._spoof).
SPOOF_SCANS = 4

# Allocations between two young-generation collections during step()/run() (Python default: 700).
_GC_THRESHOLD = 70_000


@dataclass(frozen=True, slots=True)
class UavSnapshot:
    uid: int
    name: str
    type: str
    state: str  # pending | alive | crashed
    x: float
    y: float
    v: float
    theta: float
    mode: str
    target: int
    waypoint: tuple[float, float] | None


@dataclass(frozen=True, slots=True)
class TargetSnapshot:
    tid: int
    x: float
    y: float
    v: float
    theta: float
    found_t: float | None


@dataclass(frozen=True, slots=True)
class Snapshot:
    t: float
    uavs: tuple[UavSnapshot, ...]
    targets: tuple[TargetSnapshot, ...]
    coverage: float
    targets_found: int
    links: tuple[tuple[int, int], ...]


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
        # A class is named by where it lives (module:Class), as a scenario would name it.
        name = planner if planner is None or isinstance(planner, str) else f"{planner.__module__}:{planner.__qualname__}"
        if not isinstance(scenario, Scenario):
            scenario = load_scenario(scenario, planner=name, allow_planner_imports=allow_planner_imports)
        overrides: dict[str, object] = {}
        if name is not None:
            overrides["planner.name"] = name
        if planner_options is not None:
            if not isinstance(planner_options, Mapping) or not all(isinstance(k, str) and k.isidentifier()
                                                                  for k in planner_options):
                raise UsageError(f"planner_options {planner_options!r}: expected a dict of option names "
                                 f"(Python identifiers) to values")
            overrides.update({f"planner.options.{key}": value for key, value in planner_options.items()})
        if duration_s is not None:
            overrides["duration_s"] = duration_s
        if seed is not None:
            overrides["seed"] = seed
        if overrides:
            from swarm.scenario import apply_overrides

            scenario = apply_overrides(scenario, overrides, truncated=duration_s is not None,
                                       allow_planner_imports=allowed(allow_planner_imports, name))
        # Before anything is allocated: refuse a run that cannot fit (swarm.memory).
        self.memory_estimate = check_memory(scenario, memory_limit_gb)
        self.scenario = scenario
        self.seed = scenario.seed
        self.dt = scenario.dt_s
        self.duration_s = scenario.duration_s
        self.rng = RngTree(self.seed)
        self.clock = Clock()
        self.log = EventLog()
        # [recording] level "summary": rx / lost frame copies are counted per tick (_lost, _observe)
        # and logged as one "radio" event at the end of the tick (_end_tick), not one event each.
        self._summary = scenario.recording.level == "summary"
        self._rx_tick = [0, 0, 0]  # frames read, of them rejected, bytes read
        self._lost_tick: dict[str, list[int]] = {}  # cause -> [copies, bytes]
        self._build_world(scenario)
        self._build_radio(scenario)
        self._build_actors(scenario, batch_planning)
        self._populate(scenario)
        self.clock.schedule(0.0, self._tick, TICK)
        self.log.emit("start", 0.0, {
            "scenario": scenario.name, "seed": self.seed, "planner": scenario.planner.name, "dt": self.dt,
            "uavs": [[b.uid, b.name, b.kind.name] for b in self.world.uavs.values()],
            "targets": len(self.targets), "threats": len(self.world.threats),
            "faults": self.injector.schedule.to_list(),
            # (only when not the default, so a "frames" log is byte for byte what it always was)
            **({"recording": scenario.recording.level} if self._summary else {}),
        })

    # --- building (once, from the scenario) -------------------------------------------------

    def _build_world(self, sc: Scenario) -> None:
        """Ground truth (area grid, targets, threats), the metrics that observe it, UAV types."""
        self.grid = Grid(sc.area.width_m, sc.area.height_m, sc.area.cell_m)
        self.tau = sc.effective_tau
        self.types = build.uav_types(sc)
        self.speed_max_by_type = {n: t.speed_max for n, t in self.types.items()}
        self.detect_radius_by_type = {n: t.detect_radius for n, t in self.types.items()}
        self.targets = Targets(build.target_motion(sc))
        self.world = World(self.grid, self.targets, build.threats(sc))
        self.metrics = Metrics(self.grid, self.tau)
        self.names: dict[str, int] = {}  # shared with the injector: names added later resolve
        self._tick_index = 0
        # Flat (t, x, y, t, x, y, ...) per UAV and per target: an array is made from a flat
        # list of floats several times faster than from a list of tuples (results).
        self._paths: dict[int, list[float]] = {}
        self._target_paths: dict[int, list[float]] = {}
        self._sample_every = max(1, round(sc.metrics.sample_s / self.dt))

    def _build_radio(self, sc: Scenario) -> None:
        """The fault injector and the radio whose frame copies it filters."""
        self.injector = FaultInjector(FaultSchedule([]), self.names,
                                      fault_rng=lambda kind, k: self.rng.generator("fault", kind, k))
        self.radio = build.radio(
            sc,
            link_rng=lambda s, d: self.rng.generator("link", self.world.uavs[s].name, self.world.uavs[d].name),
            link_filter=self.injector,
        )
        # Each broadcast frame decoded once (with the swarm key, if [radio] auth).
        self._decoder = DecodeCache(sc.radio.frame_max_bytes, key=build.auth_key(sc))
        self._in_flight = 0

    def _build_actors(self, sc: Scenario, batch_planning: bool) -> None:
        """Shared actor settings, map storage and plan batching; the actors come with their UAVs."""
        self._actor_settings = build.actor_settings(sc)
        # The UAVs' maps share storage where they agree (same cells as maps of their own;
        # agents.maps.mapgroup): on areas small enough for dense maps, unless a knowledge horizon
        # keeps scans from ever reaching every map (maps_share).
        self._map_group = (MapGroup(self.grid, self.tau, self.dt)
                           if maps_share(self.grid.nx * self.grid.ny, self.grid.width_m, self.grid.height_m,
                                         sc.radio.horizon_m) else None)
        self.actors: dict[int, UavActor] = {}
        self._tasks: dict[int, asyncio.Task] = {}
        self._plans: dict[int, Plan] = {}
        self._batcher = PlanBatcher() if batch_planning else None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._own_loop = False
        self._barrier: asyncio.Future | None = None
        self._waiting = 0
        self._outputs: dict[int, ActorOutput] = {}
        self._failed: BaseException | None = None
        self._closed = False
        self._wall = 0.0
        # Windowed node and sensing faults while active (swarm.node_faults), and the restarts
        # under way: uid -> schedule index of the restart fault that took it down.
        self.node_faults = NodeFaults(self.rng, self.names, (self.grid.width_m, self.grid.height_m), self.dt)
        self._restarting: dict[int, int] = {}

    def _populate(self, sc: Scenario) -> None:
        """The scenario's targets (placed, then random), UAVs and faults, in that order."""
        tm = sc.targets
        for p in tm.placed:
            self.add_target(p.x_m, p.y_m, p.heading_deg, p.speed, p.value)
        for _ in range(tm.count):
            g = self.rng.generator("target", len(self.targets))
            self._add_target_rng(
                float(g.uniform(0, sc.area.width_m)), float(g.uniform(0, sc.area.height_m)),
                float(g.uniform(-math.pi, math.pi)), float(g.uniform(0, tm.speed_max)), tm.value, g,
            )
        for spec in sc.uavs:
            self._add_uav_spec(spec)
        for f in sc.faults:
            fault = fault_from_dict(f.model_dump(mode="python"))
            if isinstance(fault, Join):
                continue  # folded into the UAV's join_s by the scenario loader
            self.add_fault(fault)

    # --- construction helpers ---------------------------------------------------------------

    @classmethod
    def from_file(cls, ref: str | Path, **kw) -> Simulation:
        return cls(ref, **kw)

    def _build_planner(self, uid: int, name: str, type_name: str) -> Planner:
        """A UAV's own planner instance (agents.planners.registry)."""
        sc = self.scenario
        # (Those added before it: the same rank when a restart builds it again later.)
        rank = sum(1 for b in self.world.uavs.values() if b.kind.name == type_name and b.uid < uid)
        count = max(rank + 1, sum(1 for u in sc.uavs if u.type == type_name))
        context = PlannerContext(
            uav=uid, name=name, type=type_name, type_index=rank, type_count=count,
            area_m=(self.grid.width_m, self.grid.height_m), cell_m=self.grid.cell_m, levels=sc.map.levels,
            speed_max_by_type=dict(self.speed_max_by_type), detect_radius_by_type=dict(self.detect_radius_by_type),
            settings=sc.planner,
        )
        try:
            return build_planner(sc.planner.name, sc.planner.options_of(), context)
        except PlannerError as exc:
            raise SimulationError(str(exc)) from exc

    def _add_target_rng(self, x, y, theta, v, value, rng) -> int:
        tid = self.targets.add(x, y, theta, v, value, rng)
        self._target_paths[tid] = []
        self.metrics.appeared_t[tid] = self.clock.now  # (time to first detection counts from here)
        return tid

    def _add_uav_spec(self, spec: UavSpec) -> int:
        kind = self.types[spec.type]
        uid = len(self.world.uavs)
        name = spec.name
        assert name is not None  # filled in by the scenario's validation, or by add_uav
        speed = spec.speed if spec.speed is not None else kind.speed_max
        body = UavBody(uid, name, kind, spec.x_m, spec.y_m, speed, math.radians(spec.heading_deg),
                       PENDING, spec.join_s or 0.0)
        self.world.add_uav(body)
        self.names[name] = uid
        # Scan disks and decoded frames are shared by every UAV using them within a few ticks;
        # anti-entropy resends scans up to sync_horizon_s old, so at least 4096 disks are kept
        # (bench-100-dacmp 300 s: disk rebuilds 41k -> 19k, 9% less CPU, +90 MB peak RSS).
        self.grid.set_disk_cache_size(max(4096, 3 * len(self.world.uavs)))
        self._decoder.size = max(256, 4 * len(self.world.uavs))
        planner = self._build_planner(uid, name, spec.type)
        self.actors[uid] = UavActor(
            uid, name, kind, self.grid, self.tau, planner, self.rng.generator("uav", name),
            self._actor_settings, Mailbox(self.scenario.radio.mailbox_capacity), decoder=self._decoder,
            map_group=self._map_group,
        )
        self._paths[uid] = []
        self.clock.schedule(max(body.join_s, self.clock.now), lambda: self._join(uid), FAULT)
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

    def snapshot(self) -> Snapshot:
        uavs = []
        for uid, b in sorted(self.world.uavs.items()):
            plan = self._plans.get(uid)
            mode = self._mode_name(uid)
            uavs.append(UavSnapshot(uid, b.name, b.kind.name, b.state, b.x, b.y, b.v, b.theta, mode,
                                    plan.target if plan else -1, (plan.wx, plan.wy) if plan else None))
        tg = self.targets
        targets = tuple(TargetSnapshot(i, tg.x[i], tg.y[i], tg.v[i], tg.theta[i], self.metrics.found_t.get(i))
                        for i in range(len(tg)))
        return Snapshot(self.now, tuple(uavs), targets, self.metrics.coverage(), len(self.metrics.found_t),
                        tuple(sorted(self.radio.graph.edges())))

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

    def add_fault(self, fault: Fault) -> None:
        """Add a fault (see :mod:`faults.schedule`); node faults must not be in the past."""
        unknown = [n for _path, n in uav_names(fault) if n not in self.names]
        if unknown:
            raise UsageError(f"fault {fault.kind} names unknown UAV(s) {unknown}; known: {', '.join(self.names)}")
        if isinstance(fault, Swizzle) and not fault.start_s < fault.end_s < math.inf:
            raise UsageError(f"swizzle needs start_s < end_s < inf (its links are restored by end_s), "
                             f"got start_s={fault.start_s}, end_s={fault.end_s}")
        index = len(self.injector.schedule)  # its place in the schedule: names its random streams
        if isinstance(fault, (Crash, Join, Restart)):
            if fault.at_s < self.now:
                raise UsageError(f"{fault.kind} at {fault.at_s} s is in the past (now {self.now} s)")
            uid = self.names[fault.uav]
            at = float(max(fault.at_s, self.clock.now))
            if isinstance(fault, Crash):
                self.clock.schedule(at, lambda: self._crash(uid), FAULT)
            elif isinstance(fault, Restart):
                self.clock.schedule(at, lambda: self._restart_down(uid, index), FAULT)
                self.clock.schedule(at + fault.downtime_s, lambda: self._restart_up(uid, index), FAULT)
            else:
                self.world.uavs[uid].join_s = fault.at_s
                self.clock.schedule(at, lambda: self._join(uid), FAULT)
        elif isinstance(fault, (Pause, ClockSkew, NavError, Sensor, Liar)):
            if fault.end_s <= fault.start_s:
                raise UsageError(f"{fault.kind} ends at {fault.end_s} s, not after its start at {fault.start_s} s")
            if fault.end_s > self.now:  # (a window wholly in the past does nothing)
                wf: WindowFault = fault
                self.clock.schedule(float(max(fault.start_s, self.clock.now)), lambda: self._window_on(index, wf), FAULT)
                if math.isfinite(fault.end_s):
                    self.clock.schedule(float(fault.end_s), lambda: self._window_off(index, wf), FAULT)
        self.injector.add(fault)

    # --- node events ------------------------------------------------------------------------

    def _join(self, uid: int) -> None:
        b = self.world.uavs[uid]
        if b.state != PENDING or self.clock.now + 1e-9 < b.join_s:
            return  # already joined, crashed, or this was a superseded join time
        b.state = ALIVE
        late = b.join_s > 0
        if late:
            self.injector.note_fired("join")
        self.log.emit("join", self.clock.now, uid, b.name, b.x, b.y)

    def _crash(self, uid: int, kind: str = "crash") -> None:
        """Fail-stop (a ``crash``, or the first half of a ``restart``: ``kind`` is what fired)."""
        b = self.world.uavs[uid]
        if b.state != ALIVE:
            if b.state == PENDING and kind == "crash":
                b.state = CRASHED  # crashed before joining: never flies
                self.injector.note_fired("crash")
                self.log.emit("crash", self.clock.now, uid, b.name)
            return
        b.state = CRASHED
        if kind == "crash":
            self.injector.note_fired("crash")
        self._outputs.pop(uid, None)  # (its last command: nothing left to fly on a pause)
        for index, f in self.node_faults.active:
            if isinstance(f, Pause):
                self.node_faults.forget(index, uid)  # the process is gone: so is its pause (no resume event)
        task = self._tasks.pop(uid, None)
        if task is not None:
            task.cancel()
        for _arrival, sender, data in self.actors[uid].mailbox.drain():
            self.radio.counters.drop("receiver_down")
            self._lost(self.clock.now, sender, uid, len(data), "receiver_down")
        self._plans.pop(uid, None)
        self.log.emit("crash", self.clock.now, uid, b.name)

    def _restart_down(self, uid: int, index: int) -> None:
        """A restart's crash: only a flying UAV restarts (one pending or down is left as it is)."""
        if self.world.uavs[uid].state != ALIVE:
            return
        self._crash(uid, "restart")
        self._restarting[uid] = index

    def _restart_up(self, uid: int, index: int) -> None:
        """The rejoin: a fresh actor (empty map, knowledge, scan log; a new planner and random
        stream) on the airframe where it went down, with the speed and heading it had. The
        mailbox (the radio) and the counters (the run's accounting) carry over."""
        if self._restarting.get(uid) != index:
            return  # it never went down for this restart
        del self._restarting[uid]
        b = self.world.uavs[uid]
        old = self.actors[uid]
        actor = UavActor(
            uid, b.name, b.kind, self.grid, self.tau, self._build_planner(uid, b.name, b.kind.name),
            self.rng.generator("uav", b.name, "restart", index), self._actor_settings, old.mailbox,
            decoder=self._decoder, map_group=self._map_group,
        )
        actor.counters = old.counters
        self.actors[uid] = actor
        b.state = ALIVE
        self.injector.note_fired("restart")
        self.log.emit("restart", self.clock.now, uid, b.name, b.x, b.y)

    def _window_on(self, index: int, fault: WindowFault) -> None:
        """A node or sensing fault's window opens: it acts from this tick (swarm.node_faults)."""
        self.node_faults.active.append((index, fault))

    def _window_off(self, index: int, fault: WindowFault) -> None:
        nf = self.node_faults
        nf.active = [(i, f) for i, f in nf.active if i != index]
        for uid in sorted(self.world.uavs):
            if nf.forget(index, uid):
                self.log.emit("resume" if isinstance(fault, Pause) else "fault_off", self.clock.now,
                              *(() if isinstance(fault, Pause) else (fault.kind,)), uid)

    def _lost(self, t: float, src: int, dst: int, nbytes: int, cause: str) -> None:
        """A frame copy lost: a ``lost`` event, or (recording level "summary") counted."""
        if self._summary:
            c = self._lost_tick.get(cause)
            if c is None:
                c = self._lost_tick[cause] = [0, 0]
            c[0] += 1
            c[1] += nbytes
        else:
            self.log.emit("lost", t, src, dst, nbytes, cause)

    def _deliver(self, batch: list[Delivery]) -> None:
        uavs = self.world.uavs
        actors = self.actors
        self._in_flight -= len(batch)
        for arrival_t, sender, receiver, data in batch:
            if uavs[receiver].state != ALIVE:
                self.radio.counters.drop("receiver_down")
                self._lost(self.clock.now, sender, receiver, len(data), "receiver_down")
            elif not actors[receiver].mailbox.put(arrival_t, sender, data):
                self.radio.counters.drop("mailbox_full")
                self._lost(self.clock.now, sender, receiver, len(data), "mailbox_full")

    # --- the tick ---------------------------------------------------------------------------

    def _report(self, uid: int, out: ActorOutput | None, exc: BaseException | None) -> None:
        barrier = self._barrier
        if barrier is None or barrier.done():
            return
        if exc is not None:
            name = self.world.uavs[uid].name
            if isinstance(exc, PlannerError):
                err = SimulationError(f"UAV {name}: {exc}")
            else:
                err = SimulationError(f"UAV {name} raised {type(exc).__name__}: {exc}")
            err.__cause__ = exc
            barrier.set_exception(err)
            return
        assert out is not None  # (an actor reports an output or an exception)
        self._outputs[uid] = out
        self._waiting -= 1
        if self._waiting == 0:
            barrier.set_result(None)
        else:
            self._flush_plans_if_all_waiting()

    async def _plan_for(self, actor: UavActor, view: PlanView) -> Plan:
        """An actor's plan request (see :mod:`agents.planners.batching`)."""
        batcher = self._batcher
        assert batcher is not None  # (the actors are given _plan_for only with a batcher)
        fut = batcher.request(actor, view)
        self._flush_plans_if_all_waiting()
        return await fut

    def _flush_plans_if_all_waiting(self) -> None:
        # Every actor that has not answered this tick is waiting for a plan: nothing else can
        # happen before they get one, so plan them all in one go.
        b = self._batcher
        if b is not None and b.pending and b.pending == self._waiting:
            b.flush()

    async def _tick(self) -> None:
        """One tick at ``t``: the data flow of ARCHITECTURE.md, one phase per method.

        Faults, joins and frames due at ``t`` ran before this (clock priorities)."""
        t = self.now
        alive = self._start_tick(t)
        xy, readings = self._sense(t, alive)
        outputs = await self._wake_actors(alive, readings)
        self._observe(t, alive, outputs, readings, xy)
        self._transmit(t, alive, xy, outputs)
        self._integrate(alive, outputs)
        self._end_tick()

    def _start_tick(self, t: float) -> list[int]:
        """Select the faults active at ``t``; start the task of every UAV that just began to fly."""
        self.injector.begin_tick(t)
        alive = self.world.alive_ids()
        loop = asyncio.get_running_loop()
        plan_source = self._plan_for if self._batcher is not None else None
        for uid in alive:
            if uid not in self._tasks:
                self._tasks[uid] = loop.create_task(self.actors[uid].run(self._report, plan_source),
                                                    name=f"uav-{self.world.uavs[uid].name}")
        return alive

    def _sense(self, t: float, alive: list[int]) -> tuple[np.ndarray, dict[int, SensorReading]]:
        """Positions at ``t`` and what each live UAV senses there.

        UAVs move only in :meth:`_integrate`, so these positions also serve the safety check and
        the radio topology of this tick."""
        world = self.world
        xy = world.positions(alive)
        readings = dict(zip(alive, world.sense_many(alive, t, xy)))
        nf = self.node_faults
        if nf.active:  # pause, clock_skew, nav_error, sensor, liar (swarm.node_faults)
            nf.apply(t, alive, readings, self.actors, self._outputs.__contains__, self.log.emit,
                     self.injector.note_fired)
        elif nf.paused or nf.detected is not None:
            nf.paused, nf.truth, nf.detected = set(), {}, None
        # Every live UAV scans its disk this tick (its own map, then the ground truth and every
        # UAV that hears the record): build those disks in one vectorised pass. A pure memo.
        if len(alive) >= PREFETCH_MIN:
            bodies = [world.uavs[uid] for uid in alive]
            umap = self.actors[alive[0]].umap
            self.grid.prefetch_disks([b.x for b in bodies], [b.y for b in bodies], [b.kind.detect_radius for b in bodies],
                                     t, None if umap.dense else umap.tile_shape)
        return xy, readings

    async def _wake_actors(self, alive: list[int], readings: dict[int, SensorReading]) -> dict[int, ActorOutput]:
        """Hand every live actor its reading and wait until all of them have answered."""
        last, self._outputs = self._outputs, {}
        paused = self.node_faults.paused
        if paused:
            # Not woken: its airframe flies its last command, nothing is sent or read (and its
            # mailbox fills). _sense pauses only UAVs that answered the last tick.
            for uid in alive:
                if uid in paused:
                    prev = last[uid]
                    self._outputs[uid] = ActorOutput(prev.a, prev.omega, [], prev.plan, [])
            alive = [uid for uid in alive if uid not in paused]
        if alive:
            self._barrier = asyncio.get_running_loop().create_future()
            self._waiting = len(alive)
            for uid in alive:
                self.actors[uid].wake(readings[uid])
            try:
                await self._barrier
            finally:
                self._barrier = None
        return self._outputs

    def _observe(self, t: float, alive: list[int], outputs: dict[int, ActorOutput],
                 readings: dict[int, SensorReading], xy: np.ndarray) -> None:
        """Ground truth at ``t`` (positions as the agents saw them): modes, scans, sightings,
        poses, frames read, target positions, then safety violations; all into the log."""
        world = self.world
        plans: dict[int, tuple[int, int]] = {}
        sensed: dict[int, list[int]] = {}
        uavs = world.uavs
        last_plans = self._plans
        metrics_scan = self.metrics.scan
        paths = self._paths
        # The tick's many events are gathered and logged with one extend() per batch (the same
        # events in the same order as one emit() each, subscribers included).
        events: list[tuple] = []
        add = events.append
        nf = self.node_faults
        paused, truth = nf.paused, nf.truth
        summary, rx = self._summary, self._rx_tick
        for uid in alive:
            b = uavs[uid]
            out = outputs[uid]
            plan = out.plan
            prev = last_plans.get(uid)
            last_plans[uid] = plan
            if prev is None or prev.mode != plan.mode or prev.target != plan.target:
                add(("mode", t, uid, plan.mode, plan.target))
            plans[uid] = (plan.mode, plan.target)
            if paused and uid in paused:
                sensed[uid] = []  # a paused process reads no sensor: it scans and sees nothing
                if nf.detected is not None:
                    nf.detected.pop(uid, None)
            else:
                metrics_scan(b.x, b.y, b.kind.detect_radius, t)
                # The truth inside its detection radius (a sensor fault's misses and phantoms
                # are what the UAV believes, not what is there; see Metrics.observe).
                sensed[uid] = truth[uid] if truth and uid in truth else [s.target for s in readings[uid].targets]
            add(("pose", t, uid, b.x, b.y, b.v, b.theta, plan.mode, plan.target))
            paths[uid].extend((t, b.x, b.y))
            if summary:
                for _sender, nbytes, ok in out.received:
                    rx[0] += 1
                    rx[1] += not ok
                    rx[2] += nbytes
            else:
                events += [("rx", t, sender, uid, nbytes, ok) for sender, nbytes, ok in out.received]
        types = {u: uavs[u].kind.name for u in alive}
        events += self.metrics.observe(t, self.dt, plans, sensed, types, self.speed_max_by_type, nf.detected)
        tg = self.targets
        target_paths = self._target_paths
        for i, (x, y) in enumerate(zip(tg.x, tg.y)):
            add(("target", t, i, x, y))
            target_paths[i].extend((t, x, y))
        log = self.log
        log.extend(events)
        for kind, a, b2 in world.check_safety(alive, xy, self.scenario.safety.min_separation_m):
            log.emit("violation", t, kind, a, b2)

    def _transmit(self, t: float, alive: list[int], xy: np.ndarray, outputs: dict[int, ActorOutput]) -> None:
        """Radio: topology from positions at ``t``, every frame in UAV-id order through the
        links (and the fault injector), arrivals scheduled on the clock in batches by time."""
        self.radio.update_topology(alive, xy, self.dt)
        self.injector.set_positions(alive, xy)  # (jammers: who is inside their circles now)
        deliveries: list[Delivery] = []
        # Spoofers transmit first in the tick: their frames reach the mailboxes ahead of the
        # members' frames of the same tick (a forged scan then wins over the real one of that
        # origin and tick, if auth lets it in).
        for fault, n, rng, seq in self.injector.spoofer_due(t, self.dt):
            self._spoof(t, alive, xy, fault, n, rng, seq, deliveries)
        record_lost = self._lost

        def lost(src: int, dst: int, nbytes: int, cause: str) -> None:
            record_lost(t, src, dst, nbytes, cause)

        broadcast = self.radio.broadcast
        for uid in alive:
            out = outputs[uid]
            for frame in out.frames:
                broadcast(t, uid, frame, deliveries, lost)
            for dst, frame in out.replies:  # anti-entropy answers, to one neighbour each
                broadcast(t, uid, frame, deliveries, lost, to=dst)
        by_time: dict[float, list[Delivery]] = defaultdict(list)
        arrivals = {d[0] for d in deliveries}
        if len(arrivals) == 1:
            by_time[arrivals.pop()] = deliveries  # one arrival time (no jitter or delay): one batch
        else:
            for d in deliveries:
                by_time[d[0]].append(d)
        for at in sorted(by_time):
            batch = by_time[at]
            self._in_flight += len(batch)
            self.clock.schedule(at, partial(self._deliver, batch), DELIVERY)

    def _spoof(self, t: float, alive: list[int], xy: np.ndarray, f: Spoofer, n: int, rng: np.random.Generator,
               seq: int, out: list[Delivery]) -> None:
        """``n`` frames of spoofer ``f`` at ``t``, each to every live UAV within ``range_m`` of it,
        arriving after the radio's latency (no link: the spoofer is not in the radio graph, and
        its copies are neither lost nor faulted). Every draw is from the spoofer's own stream
        ``rng``. A frame: the forged sender's Hello at the spoofer's position, ScanRecords of
        :data:`SPOOF_SCANS` disks (the forged sender's detection radius) at uniform points of
        the area stamped ``t``, and Tracks of one phantom target (an id from
        :data:`~faults.schedule.PHANTOM_TARGET_ID` up) at a uniform point; written without the
        swarm key (the spoofer has none). Sender -1 in the deliveries and ``rx`` events (no
        member has that id): what the invariant checkers tell a spoof by."""
        members = sorted(self.world.uavs)
        if not members:
            return
        if len(alive):
            d = np.hypot(xy[:, 0] - f.x_m, xy[:, 1] - f.y_m)
            hearers = [u for u, k in zip(alive, (d <= f.range_m).tolist()) if k]
        else:
            hearers = []
        w, h = self.grid.width_m, self.grid.height_m
        arrival = t + self.scenario.radio.latency_s
        c = self.radio.counters
        for i in range(n):
            forged = self.names[f.as_uav] if f.as_uav else members[int(rng.integers(len(members)))]
            kind = self.world.uavs[forged].kind
            r = kind.detect_radius
            pts = rng.uniform((0.0, 0.0), (w, h), size=(SPOOF_SCANS, 2))
            records = [v for x, y in pts.tolist() for v in (t, x, y, r)]
            tx, ty = rng.uniform((0.0, 0.0), (w, h)).tolist()
            phantom = PHANTOM_TARGET_ID + int(rng.integers(1_000_000))
            messages: list[Message] = [
                Hello(forged, kind.name, f.x_m, f.y_m, kind.speed_min, float(rng.uniform(-math.pi, math.pi))),
                ScanRecords(forged, tuple(records)),
                Tracks((TrackItem(phantom, tx, ty, 0.0, 0.0, t, 1.0),)),
            ]
            data = encode(forged, seq + i, t, messages, key=None)
            c.sent += len(hearers)
            c.spoofed += len(hearers)
            c.bytes_sent += len(data) * len(hearers)
            out.extend(Delivery(arrival, SPOOF_SENDER, u, data) for u in hearers)

    def _integrate(self, alive: list[int], outputs: dict[int, ActorOutput]) -> None:
        """Physics: every live UAV flies its command for ``dt``, then the targets move."""
        dt = self.dt
        for uid in alive:
            out = outputs[uid]
            self.world.apply(uid, out.a, out.omega, dt, self.now)
        self.targets.step(dt, self.grid)

    def _end_tick(self) -> None:
        """Count the tick, sample the time series when due, flush the log, schedule the next."""
        if self._summary:
            self._radio_summary(self.now)
        self._tick_index += 1
        if self._tick_index % self._sample_every == 0 or self._tick_index == self.n_ticks:
            self.metrics.rows.append(self._sample())
        self.log.flush()
        self.clock.schedule(self._tick_index * self.dt, self._tick, TICK)

    def _radio_summary(self, t: float) -> None:
        """Recording level "summary": the tick's one ``radio`` event, ``[t, read, rejected,
        bytes_read, {cause: [copies, bytes]}]`` (causes sorted), covering every frame copy read
        or lost since the previous one; none for a tick with neither."""
        rx, lost = self._rx_tick, self._lost_tick
        if rx[0] or lost:
            self.log.emit("radio", t, rx[0], rx[1], rx[2], {c: lost[c] for c in sorted(lost)})
            self._rx_tick = [0, 0, 0]
            self._lost_tick = {}

    def _mode_name(self, uid: int) -> str:
        """search / surveil for a flying UAV, else down / pending."""
        b = self.world.uavs[uid]
        if b.state == CRASHED:
            return "down"
        if b.state == PENDING:
            return "pending"
        plan = self._plans.get(uid)
        return MODE_NAMES[plan.mode] if plan else "search"

    def _sample(self) -> dict:
        t = self.now
        radio = radio_totals(self)
        row = {
            "t": t,
            "coverage": self.metrics.coverage(),
            "certainty": self.metrics.certainty(t),
            "targets_found": len(self.metrics.found_t),
            "alive": len(self.world.alive_ids()),
            "sent": radio["sent"],
            "delivered": radio["delivered"],
            "dropped": radio["dropped"],
            "rejected": radio["rejected"],
            "bytes_sent": radio["bytes_sent"],
        }
        for uid, b in sorted(self.world.uavs.items()):
            row[f"mode_{b.name}"] = self._mode_name(uid)
        return row

    # --- driving ----------------------------------------------------------------------------

    def _check_usable(self) -> None:
        if self._closed:
            raise APIMisuseError("this Simulation is closed")
        if self._failed is not None:
            raise APIMisuseError(f"this Simulation failed earlier: {self._failed}")

    async def _advance(self, t_end: float, progress: Callable[[float, float], None] | None = None) -> None:
        clock = self.clock
        eps = 1e-9 * self.dt
        every = max(1, self.n_ticks // 200)
        try:
            while clock.peek() < t_end - eps:
                callback = clock.pop()
                if callback == self._tick:
                    await self._tick()
                    if progress is not None and self._tick_index % every == 0:
                        progress(self.now, t_end)
                else:
                    callback()
        except BaseException as exc:
            self._failed = exc
            raise

    async def run_until(self, t: float, progress: Callable[[float, float], None] | None = None) -> None:
        """Advance the world to time ``t`` inside the caller's running event loop."""
        self._check_usable()
        loop = asyncio.get_running_loop()
        if self._loop is None:
            self._loop = loop
        elif self._loop is not loop:
            raise APIMisuseError("this Simulation is bound to another event loop (it was driven with "
                                  "step()/run() or from another loop); drive it from one loop only")
        start = time.perf_counter()
        try:
            await self._advance(t, progress)
        finally:
            self._wall += time.perf_counter() - start

    def _run_sync(self, t: float, progress=None) -> None:
        self._check_usable()
        try:
            asyncio.get_running_loop()
        except RuntimeError:
            pass
        else:
            raise APIMisuseError("step()/run() are synchronous and cannot run inside a running event loop; "
                                  "use `await sim.run_until(t)` there")
        if self._loop is None:
            self._loop = asyncio.new_event_loop()
            self._own_loop = True
        elif not self._own_loop:
            raise APIMisuseError("this Simulation is driven by a host event loop; use `await sim.run_until(t)`")
        start = time.perf_counter()
        # Python's cyclic garbage collector re-traverses the run's caches (decoded frames, disks,
        # scan logs: tens of thousands of small objects) every few hundred allocations and finds
        # next to nothing: the run's garbage is freed by reference counting. Collecting 1/100 as
        # often saves about 4% of a paper-fig11 run. Only here, where nothing else runs until we
        # return, and restored after: the threshold belongs to the whole process.
        thresholds = gc.get_threshold()
        if thresholds[0] > 0:
            gc.set_threshold(max(thresholds[0], _GC_THRESHOLD), *thresholds[1:])
        try:
            self._loop.run_until_complete(self._advance(t, progress))
        finally:
            gc.set_threshold(*thresholds)
            self._wall += time.perf_counter() - start

    def step(self, n: int = 1) -> None:
        """Advance ``n`` ticks synchronously."""
        if n < 1:
            raise UsageError(f"step(n) needs n >= 1, got {n}")
        if self._tick_index + n > self.n_ticks:
            raise APIMisuseError(
                f"step({n}) at tick {self._tick_index} would go past the end of the run ({self.n_ticks} ticks, "
                f"{self.duration_s:g} s); step at most {self.n_ticks - self._tick_index} more, or build the "
                f"Simulation with a longer duration_s")
        self._run_sync((self._tick_index + n) * self.dt)

    def run(self, progress: Callable[[float, float], None] | None = None) -> RunResult:
        """Run synchronously to the scenario's duration and return the result."""
        self._run_sync(self.n_ticks * self.dt, progress)
        return self.result()

    def close(self) -> None:
        """Cancel the actor tasks and release a private event loop. Safe to call twice."""
        if self._closed:
            return
        self._closed = True
        tasks = list(self._tasks.values())
        self._tasks.clear()
        for task in tasks:
            task.cancel()
        if self._own_loop and self._loop is not None:
            if tasks:
                self._loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))
            self._loop.close()

    def __del__(self) -> None:
        # Dropped without close() (``Simulation(...).run()`` in a script): close it here, or
        # asyncio prints "Task was destroyed but it is pending!" once per UAV at exit. Only a
        # private loop that is not running can be driven to finish the cancellations; in a
        # host loop (run_until) the owner must close() or use `with`: a finaliser cannot wait
        # for that loop.
        if getattr(self, "_closed", True):
            return
        try:
            if self._own_loop and self._loop is not None and (self._loop.is_running() or self._loop.is_closed()):
                return
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
