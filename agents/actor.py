"""One UAV as an asyncio actor: its own map, knowledge, planner, random stream and inbox.

Each tick the simulator wakes every live actor with its :class:`SensorReading` and waits until
all have answered. An actor's step only touches its own state and returns an
:class:`ActorOutput` (command, encoded frames, task); the simulator then processes outputs in
UAV-id order, so the result does not depend on which task the event loop happens to run first.

A step: merge the inbox (:mod:`agents.inbox`: decode, schema-check, merge; malformed frames,
and with ``[radio] auth`` frames failing their MAC, are counted as rejected and skipped; in a
simulation with the tick plane the receive service, :mod:`swarm.kernel.receiving`, has merged
every live actor's inbox just before the step, with the same code and the same result) -> own
scan (and what an :class:`OutboxHook` claims) and sightings -> replan if due -> local planner
(APF) -> outbox (beacons, tracks, and answers to the digests heard: :mod:`agents.antientropy`).
The replan sits between two halves (:meth:`UavActor.observe`, :meth:`UavActor.act`) so that the
simulator can serve every UAV due in one tick with one batched planner call
(:mod:`agents.planners.batching`); a decision is still made from the UAV's own view and random stream.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable, Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Protocol, cast

import numpy as np

from agents.antientropy import AntiEntropy
from agents.apf import apf_command
from agents.inbox import HeardMemo, HeardScan, Inbox
from agents.inputs import ActorSettings, SensedUav, SensorReading
from agents.knowledge import Knowledge, Peer
from agents.maps.grid import Grid
from agents.maps.mapgroup import MapGroup
from agents.maps.scanlog import ScanLog
from agents.maps.scanlog_oracle import OracleScanLog
from agents.maps.umap import UncertaintyMap
from agents.planners.base import Plan, Planner, PlannerError, PlanView
from agents.relief import HOME_TARGET, Relief
from agents.station import loiter
from agents.tracksync import TrackSync
from agents.types import UavType
from comms.codec import (
    FRAME_SLACK,
    SCAN_BYTES,
    Packed,
    encode,
    pack_hello,
    pack_intent,
    pack_scans,
)
from comms.framecache import DecodeCache
from comms.mailbox import Mailbox
from comms.messages import (
    MODE_SURVEIL,
    NO_TARGET,
    Message,
    ScanDigest,
    TrackDigest,
)


def _planner_name(planner: object) -> str:
    return f"{type(planner).__module__}:{type(planner).__qualname__}"


def _planner_error(planner: object, exc: Exception) -> PlannerError:
    if isinstance(exc, PlannerError):
        return exc
    return PlannerError(f"planner {_planner_name(planner)} raised {type(exc).__name__}: {exc}")


@dataclass(slots=True)
class ActorOutput:
    a: float
    omega: float
    frames: list[bytes]
    plan: Plan
    received: list[tuple[int, int, bool]]  # (sender, nbytes, accepted) for frames drained this tick
    replies: list[tuple[int, bytes]] = field(default_factory=list)  # (receiver, frame): unicast
    speed: float = math.nan  # the speed the local planner steers towards (m/s)


@dataclass(slots=True)
class ActorCounters:
    delivered: int = 0  # frames decoded and merged
    rejected: int = 0  # frames that failed decoding or the schema (auth failures included)
    rejected_auth: int = 0  # of those, frames that failed their MAC (not written with the swarm key)
    frames_sent: int = 0
    plans: int = 0
    scans_resent: int = 0  # scans sent in answer to neighbours' digests
    scans_ignored: int = 0  # heard scan records outside any sane range (time, place, radius)
    scans_beyond: int = 0  # heard scan records centred beyond the knowledge horizon (not applied)
    digests_sent: int = 0  # anti-entropy digests (one per sync_every_s, on the beacon)
    digest_bytes: int = 0  # their bitmaps' bytes, plus 8 per origin listed (ScanLog.digest's measure)
    resent_bytes: int = 0  # bytes of the frames answering neighbours' digests
    messages_ignored: int = 0  # other heard messages no honest UAV sends (agents.inbox.check_frame)


class OutboxHook(Protocol):
    """What a fault adds to a UAV's own claims and beacons (:attr:`UavActor.outbox_hook`;
    :class:`faults.adversary.Lies`, for one). The actor calls it and does not know what it
    adds."""

    def observed(self, actor: UavActor, t: float) -> None:
        """After the UAV's own scan at ``t`` (in :meth:`UavActor.observe`, before its sightings):
        scans to claim as made (:meth:`UavActor.claim_scan`)."""

    def beacon(self, t: float, messages: list[Message | Packed], room: int) -> int:
        """Messages to add to the beacon frame sent at ``t`` (after its Hello, Intent and own
        scans, before a digest) while they fit in ``room`` bytes; returns the room left."""


class UavActor:
    def __init__(
        self,
        uid: int,
        name: str,
        kind: UavType,
        grid: Grid,
        tau: float,
        planner: Planner,
        rng: np.random.Generator,
        settings: ActorSettings,
        mailbox: Mailbox,
        decoder: DecodeCache | None = None,
        map_group: MapGroup | None = None,
        tick_plane: bool = True,
        served: bool = False,
    ):
        self.uid = uid
        self.name = name
        self.kind = kind
        self.grid = grid
        self.planner = planner
        self.rng = rng
        self.settings = settings
        self.mailbox = mailbox
        # Its own map; in a MapGroup (agents.maps.mapgroup) it shares storage with the others' maps
        # (the same cells as a map of its own).
        self.umap = map_group.new_map() if map_group is not None else UncertaintyMap(grid, tau)
        radio = settings.radio
        # (issue 36) The scan log as arrays (tick_plane), or kept per origin: the oracle.
        self.scans = (ScanLog if tick_plane else OracleScanLog)(settings.dt, radio.sync_horizon_s)
        self._log_scans = radio.sync_every_s > 0  # without anti-entropy nothing reads the log
        self.anti_entropy = AntiEntropy(uid, radio, self.scans)  # (its digests and answers)
        # A scan is applied and logged only if it is plausible: a radius up to the area's size and
        # a centre at most that far outside the area (absurd numbers would make the disk's bounds
        # overflow). Own scans obey the same rule, so every logged scan is one peers accept.
        self._max_scan_r = max(grid.width_m, grid.height_m)
        # What it hears (agents.inbox). ``decoder``: the simulation's actors share it, so each broadcast
        # frame is decoded and checked once; it decodes with the swarm's key, as settings.auth_key.
        self.inbox = Inbox(uid, grid, self._max_scan_r, settings.dt, radio, decoder, settings.auth_key)
        # Sent through a shared decoder with the swarm's key, a frame is remembered there as
        # decoded (DecodeCache.encode): its receivers find it without running the codec.
        self._encode = (decoder.encode if decoder is not None and decoder.key == settings.auth_key
                        else partial(encode, key=settings.auth_key))
        # (The polygon no-fly zones among the zones: a watcher keeps a target inside one as
        # inside a circle, rule 5 of docs/modelling.md's "Assignment rules".)
        self.knowledge = Knowledge(tuple(z for z in settings.zones if not z.inverted))
        self.plan: Plan | None = None
        # (issues 26, 33) Endurance: going home, relief on station (agents.relief).
        self.relief = Relief(uid, kind, self.knowledge, settings.peer_timeout_s, settings.replan_s,
                             {k.name: k for k in settings.uav_types})
        self.operator_goal: tuple[float, float] | None = None  # (set_waypoint: an operator's waypoint)
        self.counters = ActorCounters()
        self._next_replan = -math.inf
        self._next_beacon = -math.inf
        # (issue 36, M1) How it sends tracks and threats: periodic or on change (agents.tracksync).
        self.track_sync = TrackSync(uid, radio)
        self._pending_scans: list[float] = []
        self._received: list[tuple[int, int, bool]] = []
        self._seq = 0
        # What a fault adds to its claims and beacons (an OutboxHook); None: nothing.
        self.outbox_hook: OutboxHook | None = None
        # (issue 36) True when the simulation's receive service (swarm.kernel.receiving) merges
        # its inbox each tick before its step: observe() then only reads what was merged.
        self.served = served
        # Task plumbing (see run()).
        self._pending: SensorReading | None = None
        self._waiter: asyncio.Future[SensorReading] | None = None

    # --- the asyncio side -------------------------------------------------------------------

    def wake(self, reading: SensorReading) -> None:
        """Hand the actor this tick's reading (called by the simulator)."""
        if self._waiter is not None and not self._waiter.done():
            self._waiter.set_result(reading)
        else:
            self._pending = reading

    async def run(self, report: Callable[[int, ActorOutput | None, BaseException | None], None],
                  plan_source: Callable[[UavActor, PlanView], Awaitable[Plan]] | None = None) -> None:
        """The actor task: wait for a tick, step, report; until cancelled (crash or end).

        With ``plan_source`` the actor hands its :class:`PlanView` to it and awaits the plan, so
        the simulator can plan every UAV that is due this tick in one vectorised pass (each still
        with its own map and random stream); without it the actor calls its planner itself.
        """
        loop = asyncio.get_running_loop()
        while True:
            if self._pending is not None:
                reading, self._pending = self._pending, None
            else:
                self._waiter = loop.create_future()
                reading = await self._waiter
                self._waiter = None
            try:
                view = self.observe(reading)
                if view is not None:
                    try:
                        plan = await plan_source(self, view) if plan_source is not None else self.planner.plan(view)
                    except Exception as exc:  # the planner's, not the actor's: say so
                        raise _planner_error(self.planner, exc) from exc
                    if not isinstance(plan, Plan):
                        raise PlannerError(f"planner {_planner_name(self.planner)} returned {type(plan).__name__}, "
                                           f"not a Plan")
                    self.adopt(plan, reading.t)
                out = self.act(reading)
            except Exception as exc:  # surfaced by the simulator with the UAV's name
                report(self.uid, None, exc)
                raise
            report(self.uid, out, None)

    # --- one tick ---------------------------------------------------------------------------

    def step(self, r: SensorReading) -> ActorOutput:
        """One tick, synchronously: :meth:`observe`, plan if due, :meth:`act`."""
        view = self.observe(r)
        if view is not None:
            self.adopt(self.planner.plan(view), r.t)
        return self.act(r)

    def observe(self, r: SensorReading) -> PlanView | None:
        """First half of a tick: merge the inbox, own scan and sightings. Returns the view to
        plan from when a replan is due (time, or waypoint reached), else ``None``."""
        t = r.t
        if not self.served:  # (served: the receive service merged it before this step)
            self.receive(r)
        radius = self.kind.detect_radius
        self.claim_scan(self.uid, t, r.x, r.y, radius)
        if self.settings.outside is not None:  # (issue 26: outside the area polygon, always "seen")
            self.umap.stamp(self.settings.outside, t)
        self._pending_scans.extend((t, r.x, r.y, radius))
        if self.outbox_hook is not None:
            self.outbox_hook.observed(self, t)
        k = self.knowledge
        for st in r.targets:
            k.see_target(st.target, st.x, st.y, st.vx, st.vy, t, st.value)
        for th in r.threats:
            k.add_threat(th.threat, th.x, th.y, th.radius, th.d_max)
        relief = self.relief
        if r.energy is not None:
            home = relief.home(r, self.plan)
            if home is not None:
                self.plan = home
                return None  # homebound: no replanning on the way
            if relief.releasing:
                return None  # keeping its target until a relief holds it: no replanning
        if self.operator_goal is not None and self._to_operator_goal(r):
            return None  # flying to the operator's waypoint: no replanning on the way
        if self.settings.relief:
            if relief.relieving == NO_TARGET:
                plan = relief.answer(r, self.plan)
                if plan is not None:
                    self.plan = plan
            if relief.relieving != NO_TARGET:
                going, self.plan = relief.relieve(r)
                if going:
                    return None  # on its way to take a target over: no replanning
                if self.plan is not None:
                    self._next_replan = t + self.settings.replan_s  # (it holds the target: plans as usual)
        if self.plan is None or t >= self._next_replan or self._reached(r):
            s = self.settings
            return PlanView(t, self.uid, self.kind, r.x, r.y, r.v, r.theta, self.umap, k, self.rng,
                            self.grid, s.replan_s, s.surveillance, self.plan)
        return None

    def receive(self, r: SensorReading, memo: HeardMemo | None = None) -> None:
        """Merge the frames in its mailbox, heard at ``r.t`` where it senses itself (its own
        reading), into its map, scan log and knowledge (:meth:`agents.inbox.Inbox.merge`). The
        first thing of its step, or done for it by the receive service just before the step
        (:attr:`served`), with the same result (:meth:`~agents.inbox.Inbox.take`, sharing its
        per-tick ``memo`` among receivers)."""
        scans = self.scans if self._log_scans else None
        if memo is None:
            self._received = self.inbox.merge(self.mailbox.drain(), r.t, r.x, r.y, self.umap, self.knowledge, scans,
                                              self.counters)
        else:
            self._received = self.inbox.take(self.mailbox.drain(), r.t, r.x, r.y, self.umap, self.knowledge, scans,
                                             self.counters, memo)

    def heard(self, r: SensorReading, memo: HeardMemo) -> list[HeardScan]:
        """The receive service's first step of :meth:`receive` (:mod:`swarm.kernel.receiving`):
        the frames in its mailbox, heard at ``r.t``, looked up in the tick's ``memo``, counted
        and merged into its knowledge (:meth:`~agents.inbox.Inbox.hear`); returns their scans.
        Then the service tests them against its horizon and :meth:`apply_heard` applies those
        within it."""
        self._received, heard = self.inbox.hear(self.mailbox.drain(), r.t, self.knowledge, self.counters, memo)
        return heard

    def apply_heard(self, r: SensorReading, near: Sequence[HeardScan], beyond: int) -> None:
        """The receive service's last step of :meth:`receive`: the heard scans within its
        knowledge horizon (``near``, in order; ``beyond``: how many were not) logged and
        stamped into its map (:meth:`~agents.inbox.Inbox.apply_scans`)."""
        self.counters.scans_beyond += beyond
        self.inbox.apply_scans(near, r.t, self.umap, self.scans if self._log_scans else None)

    def goto(self, x: float, y: float) -> None:
        """An operator's waypoint (the embedding API's ``set_waypoint``, a ground station's
        reposition): fly to ``(x, y)`` searching, without replanning, until there (within one
        turn radius, or 1.5 ticks of flight); then plan afresh. Energy still sends it home first."""
        self.operator_goal = (x, y)
        if not self.relief.homebound:
            self.plan = Plan(x, y)
            self.relief.releasing = False

    def _to_operator_goal(self, r: SensorReading) -> bool:
        """True while on the way to the operator's waypoint; at it, forget it and replan now."""
        assert self.operator_goal is not None
        gx, gy = self.operator_goal
        reach = max(1.5 * r.v * self.settings.dt, self.kind.r_min(max(r.v, 1e-9)))
        if math.hypot(gx - r.x, gy - r.y) > reach:
            if self.plan is None or (self.plan.wx, self.plan.wy) != (gx, gy):
                self.plan = Plan(gx, gy)
            return True
        self.operator_goal = None
        self._next_replan = -math.inf
        return False

    def replan_next_tick(self) -> None:
        """Ask for a plan at the next tick, keeping the current one until then (for a host whose
        planner will now answer differently: the PettingZoo environment's new action). A UAV
        flying home (endurance) does not replan: it keeps its way home."""
        self._next_replan = -math.inf

    def relaunch(self) -> None:
        """(issue 26) Back in the air from the base with what it knew: plan afresh."""
        self.relief.reset()
        self.plan = None
        self._next_replan = -math.inf

    def claim_scan(self, origin: int, t: float, x: float, y: float, radius: float) -> None:
        """Take the scan of a disk ``(x, y, radius)`` at ``t`` as made: stamped into the UAV's map
        (the disk is shared, grid memo) and logged as ``origin``'s when plausible. Its own scan
        each tick, and what an :class:`OutboxHook` claims."""
        d = self.grid.disk_stamp(x, y, radius)  # = umap.scan()
        if d is not None:
            self.umap.stamp(d, t)
        if self._log_scans and self._plausible(x, y, radius):
            self.scans.add(origin, t, x, y, radius)

    def adopt(self, plan: Plan, t: float) -> None:
        """Take a new plan (made from this tick's :class:`PlanView`)."""
        self.plan = plan
        self.counters.plans += 1
        self._next_replan = t + self.settings.replan_s

    def act(self, r: SensorReading) -> ActorOutput:
        """Second half of a tick: the local planner (APF) towards the plan, then the outbox."""
        s = self.settings
        t = r.t
        k = self.knowledge
        plan = cast(Plan, self.plan)  # (set: observe() asks for a plan while there is none)
        speed = self.kind.speed_max
        if self.relief.homebound and r.energy is not None:  # (issue 26) home at the minimum-power speed
            speed = r.energy.cruise_mps
        goal_x, goal_y = plan.wx, plan.wy
        apf = s.apf
        if plan.mode == MODE_SURVEIL and plan.target in k.tracks:
            goal_x, goal_y, speed, patrol = loiter(self.kind, s, k, r, k.tracks[plan.target], apf.threat_margin_m)
            # With the full eq. 30 field a watcher stays about 1.7 km off a no-fly zone's edge, and
            # its target, 1.5-2 km from it, is lost as soon as it nears the zone (most of Case 2's
            # lost targets). A weaker field lets it follow to about 0.75 km; the threat guard
            # (agents.apf) still keeps it out. On patrol (agents.station.patrol) none: the patrol line is the
            # field (with 0.15 k_rep it flew 260 m farther out, seeing that much less of the zone).
            apf = replace(apf, k_rep=apf.k_rep * (0.0 if patrol else s.loiter_threat_weight))
        others = self._others(r, k.recent_peers(t, s.peer_timeout_s))
        if s.zones:  # (issue 26: polygon zones and the area's boundary)
            a, omega = apf_command(self.kind, r.x, r.y, r.v, r.theta, goal_x, goal_y, speed,
                                   list(k.threats.values()), others, apf, s.dt, zones=s.zones)
        else:
            a, omega = apf_command(self.kind, r.x, r.y, r.v, r.theta, goal_x, goal_y, speed,
                                   list(k.threats.values()), others, apf, s.dt)
        received, self._received = self._received, []
        frames = self._outbox(r, plan)
        replies: list[tuple[int, bytes]] = []
        if self.inbox.digests:
            heard = self.inbox.take_digests()
            scan_digests = [d for d in heard if type(d) is ScanDigest]
            if scan_digests:
                replies = self.anti_entropy.answer(scan_digests, t, k.peers, s.peer_timeout_s, self._frame,
                                                   self.counters)
            if len(scan_digests) < len(heard):  # (issue 36, M1) track digests: tracks on change
                replies += self.track_sync.answer([d for d in heard if type(d) is TrackDigest], t, k, k.peers,
                                                  s.peer_timeout_s, self._frame)
        return ActorOutput(a, omega, frames, plan, received, replies, speed)

    def _others(self, r: SensorReading, peers: list[Peer]) -> list[tuple[float, float, float, float]]:
        """The other UAVs collision avoidance steers clear of, ``(x, y, vx, vy)`` in id order.

        Without a detect-and-avoid sensor (``r.uavs`` is None): every UAV heard within the
        peer timeout, as last heard. With one, the sensor decides inside its range: a UAV it
        senses is taken as sensed (true position and velocity now, whatever the radio said or
        failed to say), and a heard pose inside the range where the sensor sees no UAV of that id
        is not believed (a stale, lost or forged report); beyond the range the radio is all
        there is."""
        me = self.uid
        sensed = r.uavs
        if sensed is None:
            return [(p.x, p.y, p.v * math.cos(p.theta), p.v * math.sin(p.theta)) for p in peers if p.uav != me]
        if not peers:
            return [o[1:] for o in sensed]
        seen = {o[0] for o in sensed}
        x, y = r.x, r.y
        r2 = self.kind.daa_range * self.kind.daa_range
        merged: list[SensedUav] = list(sensed)
        for p in peers:
            u = p.uav
            if u != me and u not in seen and (p.x - x) ** 2 + (p.y - y) ** 2 > r2:
                merged.append((u, p.x, p.y, p.v * math.cos(p.theta), p.v * math.sin(p.theta)))
        if len(merged) > len(sensed):
            merged.sort()
        return [o[1:] for o in merged]

    def _plausible(self, x: float, y: float, radius: float) -> bool:
        m = self._max_scan_r
        return 0.0 <= radius <= m and -m <= x <= self.grid.width_m + m and -m <= y <= self.grid.height_m + m

    def _reached(self, r: SensorReading) -> bool:
        p = self.plan
        # A watcher circles its target: reaching that waypoint is not a reason to replan.
        return p is not None and p.mode != MODE_SURVEIL and math.hypot(p.wx - r.x, p.wy - r.y) < 1.5 * r.v * self.settings.dt

    def _frame(self, t: float, messages: Sequence[Message | Packed]) -> bytes:
        self._seq += 1
        self.counters.frames_sent += 1
        return self._encode(self.uid, self._seq, t, messages)

    def _outbox(self, r: SensorReading, plan: Plan) -> list[bytes]:
        t = r.t
        s = self.settings.radio
        frames: list[bytes] = []
        if t >= self._next_beacon:
            # Hello, Intent and ScanRecords, packed straight away (the same bytes; see codec).
            msgs: list[Message | Packed] = [
                pack_hello(self.uid, self.kind.name, r.x, r.y, r.v, r.theta),
                pack_intent(self.uid, plan.wx, plan.wy, *self.relief.intent(plan)),
            ]
            room = s.frame_max_bytes - FRAME_SLACK - SCAN_BYTES * (len(self._pending_scans) // 4)
            if self._pending_scans:
                msgs.append(pack_scans(self.uid, self._pending_scans))
                self._pending_scans = []
            if self.outbox_hook is not None:
                room = self.outbox_hook.beacon(t, msgs, room)
            track_digest = self.track_sync.digest(t, self.knowledge)  # (issue 36, M1: tracks on change)
            if track_digest is not None:
                msgs.append(track_digest)
                room -= 16 + 14 * len(self.knowledge.tracks) + 6 * len(self.knowledge.threats)  # (about its bytes)
            digest = self.anti_entropy.digest(t, room, self.counters)  # (riding on the beacon: no extra frame)
            if digest is not None:
                msgs.append(digest)
            frames.append(self._frame(t, msgs))
            self._next_beacon = t + s.beacon_every_s - 1e-9
        # Tracks and threats: every one every tracks_every_s, or on change ([radio] tracks).
        frames += self.track_sync.outbox(t, self.knowledge, self._frame)
        return frames


__all__ = ["HOME_TARGET", "NO_TARGET", "ActorOutput", "OutboxHook", "UavActor"]
