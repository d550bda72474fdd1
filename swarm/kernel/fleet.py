"""The UAVs' actors: building them, their lifecycle (join, fail-stop, revive) and the tick's
wake phase (every live actor gets its reading; the simulation waits for all their outputs).

Each UAV is an asyncio task (:class:`agents.actor.UavActor`) started on its first tick. A tick
wakes the live ones that are not paused and waits on one future that the last answer resolves;
when every actor still to answer is waiting for a plan, the plans are made in one batched call
(:mod:`agents.planners.batching`).
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Mapping
from typing import Any

import swarm.events as ev
from agents.actor import ActorOutput, UavActor
from agents.inputs import ActorSettings, SensorReading
from agents.maps.grid import Grid
from agents.maps.mapgroup import MapGroup
from agents.planners import Planner, PlannerContext, PlannerError, build_planner
from agents.planners.base import Plan, PlanView
from agents.planners.batching import PlanBatcher
from agents.types import UavType
from comms.framecache import DecodeCache
from comms.mailbox import Mailbox
from comms.messages import MODE_NAMES
from swarm.errors import SimulationError
from swarm.kernel.receiving import Receiving
from swarm.kernel.recorder import EventLog
from swarm.kernel.rng import RngTree
from swarm.kernel.world import ALIVE, CRASHED, LANDED, PENDING, World
from swarm.scenario import Scenario

# What a fleet reports of a frame copy it had to drop: (sender, receiver, bytes, cause).
LostCopy = Callable[[int, int, int, str], None]


class Fleet:
    """The actors of one simulation, by UAV id, and their tasks."""

    def __init__(self, sc: Scenario, world: World, grid: Grid, tau: float, rng: RngTree, log: EventLog,
                 settings: ActorSettings, decoder: DecodeCache, map_group: MapGroup | None,
                 batch_planning: bool, types: dict[str, UavType], actors: dict[int, UavActor], lost: LostCopy,
                 tick_plane: bool = True):
        """``actors``: the run's actors by UAV id, filled here as UAVs are added (shared with the
        transmission, which fills their mailboxes); ``lost``: how a frame copy the fleet drops
        is counted (a down or landed UAV's unread frames). ``tick_plane`` (issue 36): each
        actor's (:class:`~agents.actor.UavActor`: its scan log as arrays), and the woken actors'
        inboxes are merged by :mod:`swarm.kernel.receiving` at the start of the wake phase, not
        by each actor in its step."""
        self.tick_plane = tick_plane
        self.scenario = sc
        self.world = world
        self.grid = grid
        self.tau = tau
        self.rng = rng
        self.log = log
        self.settings = settings
        self.decoder = decoder
        self.map_group = map_group
        self.lost = lost  # (a down UAV's unread frames: counted lost by the radio's owner)
        self.types = types
        self.actors = actors
        self.tasks: dict[int, asyncio.Task[None]] = {}
        self.plans: dict[int, Plan] = {}  # each flying UAV's last plan
        self.outputs: dict[int, ActorOutput] = {}  # this tick's (and, until replaced, the last)
        self.returning: dict[int, float] = {}  # UAVs down that will be revived: when
        self.batcher = PlanBatcher() if batch_planning else None
        self.receiving = Receiving(actors) if tick_plane else None
        self._barrier: asyncio.Future[None] | None = None
        self._waiting = 0

    # --- building ------------------------------------------------------------------------------

    def planner(self, uid: int, name: str, type_name: str) -> Planner:
        """A UAV's own planner instance (agents.planners.registry)."""
        sc = self.scenario
        # (Those added before it: the same rank when a restart builds it again later.)
        rank = sum(1 for b in self.world.uavs.values() if b.kind.name == type_name and b.uid < uid)
        count = max(rank + 1, sum(1 for u in sc.uavs if u.type == type_name))
        context = PlannerContext(
            uav=uid, name=name, type=type_name, type_index=rank, type_count=count,
            area_m=(self.grid.width_m, self.grid.height_m), cell_m=self.grid.cell_m, levels=sc.map.levels,
            speed_max_by_type={n: t.speed_max for n, t in self.types.items()},
            detect_radius_by_type={n: t.detect_radius for n, t in self.types.items()},
            settings=sc.planner,
        )
        try:
            return build_planner(sc.planner.name, sc.planner.options_of(), context)
        except PlannerError as exc:
            raise SimulationError(str(exc)) from exc

    def add(self, uid: int, stream_key: tuple[str | int, ...] = (), mailbox: Mailbox | None = None) -> UavActor:
        """A fresh actor for the UAV ``uid`` (empty map, knowledge, scan log; a new planner and
        the random stream ``("uav", name, *stream_key)``)."""
        b = self.world.uavs[uid]
        actor = UavActor(
            uid, b.name, b.kind, self.grid, self.tau, self.planner(uid, b.name, b.kind.name),
            self.rng.generator("uav", b.name, *stream_key), self.settings,
            mailbox if mailbox is not None else Mailbox(self.scenario.radio.mailbox_capacity),
            decoder=self.decoder, map_group=self.map_group, tick_plane=self.tick_plane,
            served=self.receiving is not None,
        )
        self.actors[uid] = actor
        return actor

    # --- lifecycle -----------------------------------------------------------------------------

    def join(self, uid: int, now: float) -> bool:
        """The UAV starts flying at its join time; True if it was a late joiner."""
        b = self.world.uavs[uid]
        if b.state != PENDING or now + 1e-9 < b.join_s:
            return False  # already joined, crashed, or this was a superseded join time
        b.state = ALIVE
        self.log.emit(ev.join(t=now, uav=uid, uav_name=b.name, x=b.x, y=b.y))
        return b.join_s > 0

    def fail_stop(self, uid: int, now: float) -> None:
        """Take the UAV down: it no longer senses, sends, receives or moves. A pending one never
        flies; a flying (or landed) one's task is cancelled and its unread frames are lost. A
        crash sticks: a landed UAV that crashes is never launched again (swarm.kernel.mission)."""
        b = self.world.uavs[uid]
        if b.state == CRASHED:
            return
        was_alive = b.state in (ALIVE, LANDED)
        b.state = CRASHED
        if was_alive:
            self.outputs.pop(uid, None)  # (its last command: nothing left to fly on a pause)
            task = self.tasks.pop(uid, None)
            if task is not None:
                task.cancel()
            for _arrival, sender, data in self.actors[uid].mailbox.drain():
                self.lost(sender, uid, len(data), "receiver_down")
            self.plans.pop(uid, None)
        self.log.emit(ev.crash(t=now, uav=uid, uav_name=b.name))

    def revive(self, uid: int, now: float, stream_key: tuple[str | int, ...]) -> None:
        """A UAV that is down flies again where it went down, with the speed and heading it had,
        and a fresh actor. The mailbox (the radio) and the counters (the run's accounting)
        carry over."""
        b = self.world.uavs[uid]
        old = self.actors[uid]
        self.returning.pop(uid, None)
        self.add(uid, stream_key, mailbox=old.mailbox).counters = old.counters
        b.state = ALIVE
        self.log.emit(ev.restart(t=now, uav=uid, uav_name=b.name, x=b.x, y=b.y))

    def land(self, uid: int) -> None:
        """(issue 33) A returning UAV lands at its base: it no longer flies, senses or sends
        (from the next tick) until :meth:`launch`; its task waits, its plan is dropped."""
        b = self.world.uavs[uid]
        if b.state == ALIVE:
            b.state = LANDED
            self.plans.pop(uid, None)

    def launch(self, uid: int, x: float, y: float, v: float, theta: float) -> None:
        """(issue 33) A landed UAV takes off from ``(x, y)``: the frames that reached it on the
        ground are lost, and its actor plans afresh with what it knew."""
        b = self.world.uavs[uid]
        if b.state != LANDED:
            return
        b.x, b.y, b.v, b.theta = x, y, v, theta
        b.state = ALIVE
        actor = self.actors[uid]
        for _arrival, sender, data in actor.mailbox.drain():
            self.lost(sender, uid, len(data), "receiver_down")
        actor.relaunch()

    def mode_name(self, uid: int) -> str:
        """search / surveil for a flying UAV, else down / pending / landed."""
        state = self.world.uavs[uid].state
        if state == CRASHED:
            return "down"
        if state == PENDING:
            return "pending"
        if state == LANDED:
            return "landed"
        plan = self.plans.get(uid)
        return MODE_NAMES[plan.mode] if plan else "search"

    # --- the wake phase ------------------------------------------------------------------------

    def start_tasks(self, alive: list[int]) -> None:
        """Start the task of every UAV that has just begun to fly."""
        loop = asyncio.get_running_loop()
        plan_source = self._plan_for if self.batcher is not None else None
        for uid in alive:
            if uid not in self.tasks:
                self.tasks[uid] = loop.create_task(self.actors[uid].run(self._report, plan_source),
                                                   name=f"uav-{self.world.uavs[uid].name}")

    async def wake(self, alive: list[int], readings: Mapping[int, SensorReading],
                   paused: set[int]) -> dict[int, ActorOutput]:
        """Hand every live actor its reading and wait until all of them have answered. A paused
        one is not woken: its airframe flies its last command, nothing is sent or read (its
        mailbox fills). Only UAVs that answered the last tick are ever paused. With the receive
        service the woken actors' inboxes are merged first, in UAV-id order (swarm.kernel.receiving)."""
        last, self.outputs = self.outputs, {}
        if paused:
            for uid in alive:
                if uid in paused:
                    prev = last[uid]
                    self.outputs[uid] = ActorOutput(prev.a, prev.omega, [], prev.plan, [], speed=prev.speed)
            alive = [uid for uid in alive if uid not in paused]
        if alive:
            if self.receiving is not None:  # (the tick plane: their inboxes, merged for them)
                self.receiving.receive(alive, readings)
            self._barrier = asyncio.get_running_loop().create_future()
            self._waiting = len(alive)
            for uid in alive:
                self.actors[uid].wake(readings[uid])
            try:
                await self._barrier
            finally:
                self._barrier = None
        return self.outputs

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
        self.outputs[uid] = out
        self._waiting -= 1
        if self._waiting == 0:
            barrier.set_result(None)
        else:
            self._flush_plans_if_all_waiting()

    async def _plan_for(self, actor: UavActor, view: PlanView) -> Plan:
        """An actor's plan request (see :mod:`agents.planners.batching`)."""
        batcher = self.batcher
        assert batcher is not None  # (the actors are given _plan_for only with a batcher)
        fut = batcher.request(actor, view)
        self._flush_plans_if_all_waiting()
        return await fut

    def _flush_plans_if_all_waiting(self) -> None:
        # Every actor that has not answered this tick is waiting for a plan: nothing else can
        # happen before they get one, so plan them all in one go.
        b = self.batcher
        if b is not None and b.pending and b.pending == self._waiting:
            b.flush()

    def cancel(self) -> list[asyncio.Task[Any]]:
        """Cancel every task; returns them (to be awaited by the loop's owner)."""
        tasks = list(self.tasks.values())
        self.tasks.clear()
        for task in tasks:
            task.cancel()
        return tasks
