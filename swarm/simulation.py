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
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from agents.actor import ActorOutput, ActorSettings, UavActor
from agents.apf import ApfSettings
from agents.knowledge import KnownThreat
from agents.maps.grid import PREFETCH_MIN, Grid
from agents.maps.mapgroup import MapGroup
from agents.maps.umap import DENSE_MAX_CELLS
from agents.planners import make_planner
from agents.planners.base import Plan
from agents.planners.batching import PlanBatcher
from agents.types import UavType
from comms.framecache import DecodeCache
from comms.mailbox import Mailbox
from comms.radio import Delivery, LinkModel, Radio
from faults.injector import FaultInjector
from faults.schedule import Crash, Fault, FaultSchedule, Join, fault_from_dict
from swarm.clock import DELIVERY, FAULT, TICK, Clock
from swarm.errors import SimulationError, UsageError
from swarm.metrics import Metrics
from swarm.recorder import EventLog
from swarm.rng import RngTree
from swarm.scenario import Scenario, UavSpec, load_scenario
from swarm.world import ALIVE, CRASHED, PENDING, TargetMotion, Targets, UavBody, World

MODE_NAMES = {0: "search", 1: "surveil"}

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


@dataclass
class RunResult:
    """Everything a finished (or stopped) run produced; :mod:`swarm.outputs` writes it."""

    metrics: dict
    timeseries: list[dict]
    events: bytes
    paths: dict[str, np.ndarray]  # UAV name -> (n, 3) rows of (t, x, y)
    target_paths: dict[int, np.ndarray]
    union_last_seen: np.ndarray
    threats: list[KnownThreat]
    area: tuple[float, float]
    uav_types: dict[str, str] = field(default_factory=dict)


def uav_type_from_spec(name: str, spec) -> UavType:
    return UavType(
        name=name,
        speed_min=spec.speed_min,
        speed_max=spec.speed_max,
        accel_max=spec.accel_max,
        bank_max_rad=math.radians(spec.bank_max_deg),
        detect_radius=spec.detect_radius_m,
        w_t=spec.w_t,
        w_r=spec.w_r,
        influence_radius=spec.influence_radius_m,
    )


class Simulation:
    def __init__(
        self,
        scenario: Scenario | str | Path,
        *,
        seed: int | None = None,
        planner: str | None = None,
        duration_s: float | None = None,
        batch_planning: bool = True,
    ):
        """``batch_planning``: serve all UAVs that replan in the same tick with one vectorised
        planner call (same event log as planning one by one, only faster; see
        :mod:`agents.planners.batching`). ``False`` makes each actor call its planner itself."""
        if not isinstance(scenario, Scenario):
            scenario = load_scenario(scenario)
        overrides = {}
        if planner is not None:
            overrides["planner.name"] = planner
        if duration_s is not None:
            overrides["duration_s"] = duration_s
        if seed is not None:
            overrides["seed"] = seed
        if overrides:
            from swarm.scenario import apply_overrides

            scenario = apply_overrides(scenario, overrides)
        sc = scenario
        self.scenario = sc
        self.seed = sc.seed
        self.dt = sc.dt_s
        self.duration_s = sc.duration_s
        self.rng = RngTree(self.seed)
        self.grid = Grid(sc.area.width_m, sc.area.height_m, sc.area.cell_m)
        self.tau = sc.effective_tau
        self.clock = Clock()
        self._tick_index = 0
        self._in_flight = 0
        self.log = EventLog()
        self.types = {name: uav_type_from_spec(name, spec) for name, spec in sc.uav_types.items()}
        self.speed_max_by_type = {n: t.speed_max for n, t in self.types.items()}
        self.detect_radius_by_type = {n: t.detect_radius for n, t in self.types.items()}

        tm = sc.targets
        self.targets = Targets(TargetMotion(tm.speed_max, tm.accel_max, tm.accel_sigma, tm.turn_sigma, tm.turn_rate_max,
                                                  tm.turn_reversion_s))
        threats = [KnownThreat(i, th.x_m, th.y_m, th.radius_m, th.d_max) for i, th in enumerate(sc.threats)]
        self.world = World(self.grid, self.targets, threats)
        self.metrics = Metrics(self.grid, self.tau)
        # The UAVs' maps share storage where they agree (same cells as maps of their own;
        # agents.maps.mapgroup): on areas small enough for dense maps.
        self._map_group = MapGroup(self.grid, self.tau, self.dt) if self.grid.nx * self.grid.ny <= DENSE_MAX_CELLS else None

        self.names: dict[str, int] = {}  # shared with the injector: names added later resolve
        self.actors: dict[int, UavActor] = {}
        self._tasks: dict[int, asyncio.Task] = {}
        self._plans: dict[int, Plan] = {}
        # Flat (t, x, y, t, x, y, ...) per UAV and per target: an array is made from a flat
        # list of floats several times faster than from a list of tuples (result()).
        self._paths: dict[int, list[float]] = {}
        self._target_paths: dict[int, list[float]] = {}

        self.injector = FaultInjector(FaultSchedule([]), self.names)
        r = sc.radio
        self.radio = Radio(
            LinkModel(r.range_m, r.loss_base, r.loss_at_range, r.latency_s, r.jitter_s, r.bandwidth_bytes_per_s),
            link_rng=lambda s, d: self.rng.generator("link", self.world.uavs[s].name, self.world.uavs[d].name),
            link_filter=self.injector,
        )
        ap = sc.planner.apf
        self._decoder = DecodeCache(r.frame_max_bytes)  # each broadcast frame decoded once
        self._actor_settings = ActorSettings(
            dt=self.dt,
            replan_s=sc.planner.replan_s,
            beacon_every_s=r.beacon_every_s,
            tracks_every_s=r.tracks_every_s,
            sync_every_s=r.sync_every_s,
            sync_settle_s=r.sync_settle_s,
            sync_max_records=r.sync_max_records,
            sync_horizon_s=r.sync_horizon_s,
            frame_max_bytes=r.frame_max_bytes,
            surveillance=sc.planner.surveillance,
            loiter_radius_factor=sc.planner.loiter_radius_factor,
            loiter_turn_factor=sc.planner.loiter_turn_factor,
            loiter_gain=sc.planner.loiter_gain,
            apf=ApfSettings(ap.k_att, ap.k_rep, ap.uav_b, ap.uav_c, ap.uav_dmax_m, sc.safety.min_separation_m,
                            cpa_horizon_s=ap.lookahead_s),
        )

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

        self._loop: asyncio.AbstractEventLoop | None = None
        self._own_loop = False
        self._barrier: asyncio.Future | None = None
        self._waiting = 0
        self._outputs: dict[int, ActorOutput] = {}
        self._batcher = PlanBatcher() if batch_planning else None
        self._failed: BaseException | None = None
        self._closed = False
        self._wall = 0.0
        self._sample_every = max(1, round(sc.metrics.sample_s / self.dt))
        self.clock.schedule(0.0, self._tick, TICK)
        self.log.emit("start", 0.0, {
            "scenario": sc.name, "seed": self.seed, "planner": sc.planner.name, "dt": self.dt,
            "uavs": [[b.uid, b.name, b.kind.name] for b in self.world.uavs.values()],
            "targets": len(self.targets), "threats": len(threats),
            "faults": self.injector.schedule.to_list(),
        })

    # --- construction helpers ---------------------------------------------------------------

    @classmethod
    def from_file(cls, ref: str | Path, **kw) -> Simulation:
        return cls(load_scenario(ref), **kw)

    def _add_target_rng(self, x, y, theta, v, value, rng) -> int:
        tid = self.targets.add(x, y, theta, v, value, rng)
        self._target_paths[tid] = []
        return tid

    def _add_uav_spec(self, spec: UavSpec) -> int:
        kind = self.types[spec.type]
        uid = len(self.world.uavs)
        name = spec.name
        speed = spec.speed if spec.speed is not None else kind.speed_max
        body = UavBody(uid, name, kind, spec.x_m, spec.y_m, speed, math.radians(spec.heading_deg),
                       PENDING, spec.join_s or 0.0)
        self.world.add_uav(body)
        self.names[name] = uid
        # Scan disks and decoded frames are shared by every UAV using them within a few ticks.
        self.grid.set_disk_cache_size(max(256, 3 * len(self.world.uavs)))
        self._decoder.size = max(256, 4 * len(self.world.uavs))
        planner = make_planner(self.scenario.planner, levels=self.scenario.map.levels,
                               speed_max_by_type=self.speed_max_by_type,
                               detect_radius_by_type=self.detect_radius_by_type)
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

    def subscribe(self, callback: Callable[[tuple], None], kinds: Iterable[str] | None = None) -> Callable[[], None]:
        """Call ``callback(event)`` for each event (optionally only some kinds); returns an unsubscribe function."""
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
        names = set(self.names)
        referenced = list(getattr(fault, "uavs", ())) + [n for pair in getattr(fault, "links", ()) for n in pair]
        referenced += [n for g in getattr(fault, "groups", ()) for n in g]
        if isinstance(fault, (Crash, Join)):
            referenced.append(fault.uav)
        unknown = [n for n in referenced if n not in names]
        if unknown:
            raise UsageError(f"fault {fault.kind} names unknown UAV(s) {unknown}; known: {', '.join(self.names)}")
        if isinstance(fault, (Crash, Join)):
            if fault.at_s < self.now:
                raise UsageError(f"{fault.kind} at {fault.at_s} s is in the past (now {self.now} s)")
            uid = self.names[fault.uav]
            if isinstance(fault, Crash):
                self.clock.schedule(max(fault.at_s, self.clock.now), lambda: self._crash(uid), FAULT)
            else:
                self.world.uavs[uid].join_s = fault.at_s
                self.clock.schedule(max(fault.at_s, self.clock.now), lambda: self._join(uid), FAULT)
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

    def _crash(self, uid: int) -> None:
        b = self.world.uavs[uid]
        if b.state != ALIVE:
            if b.state == PENDING:
                b.state = CRASHED  # crashed before joining: never flies
                self.injector.note_fired("crash")
                self.log.emit("crash", self.clock.now, uid, b.name)
            return
        b.state = CRASHED
        self.injector.note_fired("crash")
        task = self._tasks.pop(uid, None)
        if task is not None:
            task.cancel()
        for _arrival, sender, data in self.actors[uid].mailbox.drain():
            self.radio.counters.drop("receiver_down")
            self.log.emit("lost", self.clock.now, sender, uid, len(data), "receiver_down")
        self._plans.pop(uid, None)
        self.log.emit("crash", self.clock.now, uid, b.name)

    def _deliver(self, batch: list[Delivery]) -> None:
        uavs = self.world.uavs
        actors = self.actors
        self._in_flight -= len(batch)
        for arrival_t, sender, receiver, data in batch:
            if uavs[receiver].state != ALIVE:
                self.radio.counters.drop("receiver_down")
                self.log.emit("lost", self.clock.now, sender, receiver, len(data), "receiver_down")
            elif not actors[receiver].mailbox.put(arrival_t, sender, data):
                self.radio.counters.drop("mailbox_full")
                self.log.emit("lost", self.clock.now, sender, receiver, len(data), "mailbox_full")

    # --- the tick ---------------------------------------------------------------------------

    def _report(self, uid: int, out: ActorOutput | None, exc: BaseException | None) -> None:
        barrier = self._barrier
        if barrier is None or barrier.done():
            return
        if exc is not None:
            name = self.world.uavs[uid].name
            err = SimulationError(f"UAV {name} raised {type(exc).__name__}: {exc}")
            err.__cause__ = exc
            barrier.set_exception(err)
            return
        self._outputs[uid] = out
        self._waiting -= 1
        if self._waiting == 0:
            barrier.set_result(None)
        else:
            self._flush_plans_if_all_waiting()

    async def _plan_for(self, actor: UavActor, view) -> Plan:
        """An actor's plan request (see :mod:`agents.planners.batching`)."""
        fut = self._batcher.request(actor, view)
        self._flush_plans_if_all_waiting()
        return await fut

    def _flush_plans_if_all_waiting(self) -> None:
        # Every actor that has not answered this tick is waiting for a plan: nothing else can
        # happen before they get one, so plan them all in one go.
        b = self._batcher
        if b is not None and b.pending and b.pending == self._waiting:
            b.flush()

    async def _tick(self) -> None:
        t = self._tick_index * self.dt
        dt = self.dt
        world = self.world
        self.injector.begin_tick(t)
        alive = world.alive_ids()
        loop = asyncio.get_running_loop()
        for uid in alive:
            if uid not in self._tasks:
                plan_source = self._plan_for if self._batcher is not None else None
                self._tasks[uid] = loop.create_task(self.actors[uid].run(self._report, plan_source), name=f"uav-{world.uavs[uid].name}")
        # Positions at t: UAVs move only in the physics step at the end of the tick, so these
        # also serve the safety check and the radio topology below.
        xy = world.positions(alive)
        readings = dict(zip(alive, world.sense_many(alive, t, xy)))
        # Every live UAV scans its disk this tick (its own map, then the ground truth and every
        # UAV that hears the record): build those disks in one vectorised pass. A pure memo.
        if len(alive) >= PREFETCH_MIN:
            bodies = [world.uavs[uid] for uid in alive]
            umap = self.actors[alive[0]].umap
            self.grid.prefetch_disks([b.x for b in bodies], [b.y for b in bodies], [b.kind.detect_radius for b in bodies],
                                     t, None if umap.dense else umap.tile_shape)
        self._outputs = {}
        if alive:
            self._barrier = loop.create_future()
            self._waiting = len(alive)
            for uid in alive:
                self.actors[uid].wake(readings[uid])
            try:
                await self._barrier
            finally:
                self._barrier = None
        outputs = self._outputs
        log = self.log

        # Ground truth: scans, sightings, modes (positions at t, as the agents saw them).
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
        for uid in alive:
            b = uavs[uid]
            out = outputs[uid]
            plan = out.plan
            prev = last_plans.get(uid)
            last_plans[uid] = plan
            if prev is None or prev.mode != plan.mode or prev.target != plan.target:
                add(("mode", t, uid, plan.mode, plan.target))
            metrics_scan(b.x, b.y, b.kind.detect_radius, t)
            plans[uid] = (plan.mode, plan.target)
            sensed[uid] = [s.target for s in readings[uid].targets]
            add(("pose", t, uid, b.x, b.y, b.v, b.theta, plan.mode, plan.target))
            paths[uid].extend((t, b.x, b.y))
            events += [("rx", t, sender, uid, nbytes, ok) for sender, nbytes, ok in out.received]
        types = {u: world.uavs[u].kind.name for u in alive}
        events += self.metrics.observe(t, dt, plans, sensed, types, self.speed_max_by_type)
        tg = self.targets
        target_paths = self._target_paths
        for i, (x, y) in enumerate(zip(tg.x, tg.y)):
            add(("target", t, i, x, y))
            target_paths[i].extend((t, x, y))
        log.extend(events)

        # Radio: topology from positions at t (xy), then every frame in UAV-id order.
        for kind, a, b in world.check_safety(alive, xy, self.scenario.safety.min_separation_m):
            log.emit("violation", t, kind, a, b)
        self.radio.update_topology(alive, xy, dt)
        deliveries: list[Delivery] = []

        def lost(src: int, dst: int, nbytes: int, cause: str) -> None:
            log.emit("lost", t, src, dst, nbytes, cause)

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
            self.clock.schedule(at, lambda batch=batch: self._deliver(batch), DELIVERY)

        # Physics.
        for uid in alive:
            out = outputs[uid]
            world.apply(uid, out.a, out.omega, dt)
        tg.step(dt, self.grid)

        self._tick_index += 1
        if self._tick_index % self._sample_every == 0 or self._tick_index == self.n_ticks:
            self.metrics.rows.append(self._sample())
        log.flush()
        self.clock.schedule(self._tick_index * dt, self._tick, TICK)

    def _mode_name(self, uid: int) -> str:
        """search / surveil for a flying UAV, else down / pending."""
        b = self.world.uavs[uid]
        if b.state == CRASHED:
            return "down"
        if b.state == PENDING:
            return "pending"
        plan = self._plans.get(uid)
        return MODE_NAMES[plan.mode] if plan else "search"

    def _radio_totals(self) -> dict:
        c = self.radio.counters
        delivered = sum(a.counters.delivered for a in self.actors.values())
        rejected = sum(a.counters.rejected for a in self.actors.values())
        queued = sum(len(a.mailbox) for a in self.actors.values())
        return {
            "sent": c.sent,
            "delivered": delivered,
            "dropped": c.dropped_total,
            "rejected": rejected,
            "bytes_sent": c.bytes_sent,
            "duplicated": c.duplicated,
            "dropped_by_cause": dict(sorted(c.dropped.items())),
            "in_flight": self._in_flight + queued,  # scheduled on the clock or unread in a mailbox
        }

    def _sample(self) -> dict:
        t = self.now
        radio = self._radio_totals()
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
            raise SimulationError("this Simulation is closed")
        if self._failed is not None:
            raise SimulationError(f"this Simulation failed earlier: {self._failed}")

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
            raise SimulationError("this Simulation is bound to another event loop (it was driven with "
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
            raise SimulationError("step()/run() are synchronous and cannot run inside a running event loop; "
                                  "use `await sim.run_until(t)` there")
        if self._loop is None:
            self._loop = asyncio.new_event_loop()
            self._own_loop = True
        elif not self._own_loop:
            raise SimulationError("this Simulation is driven by a host event loop; use `await sim.run_until(t)`")
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

    # --- results ----------------------------------------------------------------------------

    def metrics_dict(self) -> dict:
        sc = self.scenario
        t = self.now
        m = self.metrics
        radio = self._radio_totals()
        per_uav = {}
        for uid, b in sorted(self.world.uavs.items()):
            a = self.actors[uid]
            per_uav[b.name] = {
                "type": b.kind.name,
                "state": b.state,
                "mode_seconds": m.mode_s.get(uid, {"search": 0.0, "surveil": 0.0}),
                "frames_sent": a.counters.frames_sent,
                "frames_delivered": a.counters.delivered,
                "frames_rejected": a.counters.rejected,
                "mailbox_dropped_full": a.mailbox.stats.dropped_full,
                "mailbox_max_depth": a.mailbox.stats.max_depth,
                "plans": a.counters.plans,
                "scans_known": a.scans.count,  # own and heard scans in its log (agents.maps.scanlog)
                "scans_resent": a.counters.scans_resent,  # answers to neighbours' digests
                "scans_ignored": a.counters.scans_ignored,  # heard scans with absurd values
            }
        surv = m.surveillance_ratio(t)
        return {
            "scenario": sc.name,
            "planner": sc.planner.name,
            "seed": self.seed,
            "sim_seconds": t,
            "wall_seconds": round(self._wall, 3),
            "coverage": m.coverage(),
            "certainty": m.certainty(t),
            "targets_found": len(m.found_t),
            "targets_total": len(self.targets),
            "surveillance_ratio_mean": float(np.mean(list(surv.values()))) if surv else 0.0,
            "surveillance_ratio": {str(k): v for k, v in surv.items()},
            "handovers": len(m.handovers),
            "handovers_fast_to_slow": m.fast_to_slow_handovers(self.speed_max_by_type),
            "handover_list": [
                {"t": h.t, "target": h.target, "from": self.world.uavs[h.from_uav].name,
                 "to": self.world.uavs[h.to_uav].name, "from_type": h.from_type, "to_type": h.to_type,
                 "latency_s": h.latency_s} for h in m.handovers
            ],
            "radio": radio,
            "violations": dict(self.world.violations),
            "faults_applied": dict(sorted(self.injector.fired.items())),
            "per_uav": per_uav,
            "events": self.log.total,
            "event_log_sha256": self.log.sha256(),
        }

    def result(self) -> RunResult:
        events = self.log.to_bytes()
        metrics = self.metrics_dict()
        return RunResult(
            metrics=metrics,
            timeseries=list(self.metrics.rows),
            events=events,
            paths={self.world.uavs[u].name: np.array(p, dtype=float).reshape(-1, 3) for u, p in self._paths.items()},
            target_paths={i: np.array(p, dtype=float).reshape(-1, 3) for i, p in self._target_paths.items()},
            union_last_seen=self.metrics.union.to_dense(),
            threats=list(self.world.threats),
            area=(self.grid.width_m, self.grid.height_m),
            uav_types={b.name: b.kind.name for b in self.world.uavs.values()},
        )
