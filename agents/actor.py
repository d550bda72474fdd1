"""One UAV as an asyncio actor: its own map, knowledge, planner, random stream and inbox.

Each tick the simulator wakes every live actor with its :class:`SensorReading` and waits until
all have answered. An actor's step only touches its own state and returns an
:class:`ActorOutput` (command, encoded frames, task); the simulator then processes outputs in
UAV-id order, so the result does not depend on which task the event loop happens to run first.

A step: drain the inbox (decode, schema-check, merge; malformed frames, and with ``[radio]
auth`` frames failing their MAC, are counted as rejected and skipped) -> own scan and sightings
-> replan if due -> local planner (APF) -> outbox.
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
from typing import cast

import numpy as np

from agents.apf import ApfSettings, apf_command
from agents.inbox import Heard, check_frame
from agents.knowledge import Knowledge, KnownThreat, Peer
from agents.maps.grid import MISSING as _MISSING  # a memo miss (None is a memoised value: a disk off the grid)
from agents.maps.grid import Disk, Grid
from agents.maps.mapgroup import MapGroup
from agents.maps.scanlog import ScanLog
from agents.maps.umap import UncertaintyMap
from agents.planners.base import Plan, Planner, PlannerError, PlanView
from agents.station import loiter
from agents.types import UavType
from agents.zones import Keepout
from comms.codec import AuthError, FrameError, Packed, decode, encode, pack_hello, pack_intent, pack_scans, pack_tracks
from comms.framecache import DecodeCache
from comms.mailbox import Mailbox
from comms.messages import (
    MODE_SEARCH,
    MODE_SURVEIL,
    NO_TARGET,
    Message,
    ScanDigest,
    ScanRecords,
    ThreatItem,
    Threats,
    TrackItem,
)
from comms.settings import RadioSettings

# Items per Tracks message, so one frame stays far below the size cap (an item is < 80 bytes).
_TRACKS_PER_FRAME = 400
# Neighbours expected to answer one digest (see UavActor._answer_digests).
_ANSWERERS = 2


def _planner_name(planner: object) -> str:
    return f"{type(planner).__module__}:{type(planner).__qualname__}"


def _planner_error(planner: object, exc: Exception) -> PlannerError:
    if isinstance(exc, PlannerError):
        return exc
    return PlannerError(f"planner {_planner_name(planner)} raised {type(exc).__name__}: {exc}")


def _answer_hash(me: int, sender: int, t_cut: float) -> int:
    """A well-mixed non-negative integer of (me, sender, round): who answers which digest."""
    h = (me * 0x9E3779B97F4A7C15 + sender * 0xC2B2AE3D27D4EB4F + int(t_cut * 16) * 0x165667B19E3779F9)
    h &= 0xFFFFFFFFFFFFFFFF
    h ^= h >> 31
    h = (h * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    return h ^ (h >> 29)


# Bytes of a packed scan (four msgpack floats) and room left in a frame for its header.
_SCAN_BYTES = 36
_FRAME_SLACK = 256
# A liar's fabrications (UavActor.lie): bytes of a ScanRecords message's own header (at most),
# of a packed track item, and the made-up origin ids its fake scans carry (see lie()).
_MSG_BYTES = 16
_TRACK_BYTES = 80
_GHOST_ORIGIN = 1_000_000_000
_GHOSTS_PER_UAV = 4096


@dataclass(frozen=True, slots=True)
class SensedTarget:
    target: int
    x: float
    y: float
    vx: float
    vy: float
    value: float


@dataclass(frozen=True, slots=True)
class EnergyReading:
    """What a UAV with an energy budget knows of it this tick (issues 26, 33, swarm.mission):
    its pad at the base; the next point of its way home (round the no-fly zones); ``must_go``:
    its energy left is down to what that way home takes against the mean wind, plus the
    reserve; ``spare_s``: the seconds of flight at its present power it has beyond that (0
    when it must go); ``handover_s``: the setting of that name; ``wind_mps``: the mean wind's
    speed (what it budgets a relief's way against)."""

    home_x: float
    home_y: float
    way_x: float
    way_y: float
    must_go: bool
    cruise_mps: float  # the airspeed it flies home at (its type's minimum-power speed)
    spare_s: float = math.inf
    handover_s: float = 60.0
    wind_mps: float = 0.0


# What a UAV flying home beacons as its intent's target (with search mode): not free (issue 33).
HOME_TARGET = -2
# A watcher asks for relief this many times the nearest free UAV's straight flight time ahead
# (plus handover_s): room for its turns, the gusts and a way round a zone (issue 33, rule 6).
RELIEF_MARGIN = 1.5


# Another UAV as the detect-and-avoid sensor gives it: (uav id, x, y, vx, vy).
SensedUav = tuple[int, float, float, float, float]


@dataclass(slots=True)
class SensorReading:
    """What the UAV's own sensors give it this tick (ground truth inside its detection radius).

    ``uavs``: the other UAVs inside its detect-and-avoid range (``UavType.daa_range``), in id
    order, placed relative to where the UAV believes it is (a sensor measures range and bearing);
    ``None`` when it has no such sensor (range 0)."""

    t: float
    x: float
    y: float
    v: float
    theta: float
    targets: list[SensedTarget]
    threats: list[KnownThreat]
    uavs: list[SensedUav] | None = None
    energy: EnergyReading | None = None  # (issue 26: only UAVs with an energy budget)


@dataclass(slots=True)
class ActorOutput:
    a: float
    omega: float
    frames: list[bytes]
    plan: Plan
    received: list[tuple[int, int, bool]]  # (sender, nbytes, accepted) for frames drained this tick
    replies: list[tuple[int, bytes]] = field(default_factory=list)  # (receiver, frame): unicast
    speed: float = math.nan  # the speed the local planner steers towards (m/s)


@dataclass(frozen=True, slots=True)
class ActorSettings:
    dt: float = 1.0
    replan_s: float = 10.0
    surveillance: bool = True
    peer_timeout_s: float = 5.0
    # A watcher circles its target at max(loiter_radius_factor * R_s, loiter_turn_factor * its
    # turn radius at minimum speed), steered by a vector field whose approach gain is loiter_gain.
    loiter_radius_factor: float = 0.5
    loiter_turn_factor: float = 1.25
    loiter_gain: float = 1.0
    # ... and feels the threats' repulsion (eq. 30) with apf.k_rep times this (see UavActor.act).
    loiter_threat_weight: float = 0.15
    # A watcher whose target went out of sight inside (or by) a no-fly zone patrols the zone's
    # boundary this far beyond the threat guard's band (agents.station.patrol; our choice: the
    # guard, which turns a UAV closing on an edge within a turn radius plus threat_margin_m,
    # stays quiet on the patrol line, and a type-A UAV sees 0.6 km into the zone).
    patrol_margin_m: float = 150.0
    # The scenario's [radio] settings (comms.settings.RadioSettings, their one definition): the
    # frame size cap, the beacon and tracks periods, and anti-entropy (sync_*: agents.maps.scanlog),
    # with its knowledge horizon (horizon_m: heard scans centred farther than this from the UAV
    # are neither applied nor logged, and digests are answered with scans within it of the
    # digest's sender only).
    radio: RadioSettings = field(default_factory=RadioSettings)
    apf: ApfSettings = field(default_factory=ApfSettings)
    # The swarm key ([radio] auth): frames are sent with their MAC and heard frames without the
    # right one are rejected (comms.codec). None: no authentication.
    auth_key: bytes | None = None
    # Geographic scenarios (issue 26; empty / None otherwise, and then nothing below runs):
    # polygon no-fly zones and the area's boundary, known before take-off (agents.zones), which
    # the APF repels and guards like the circles; and the cells outside the area polygon as one
    # disk-like mask, stamped into the map as seen at every tick before planning, so that q = 0
    # there: nothing to search (the pyramids, guide points and every planner read q).
    zones: tuple[Keepout, ...] = ()
    outside: Disk | None = None
    # (issue 33) [endurance]: free UAVs answer watchers' relief requests (rule 6 of
    # docs/modelling.md's assignment rules; UavActor._answer_relief). Off without endurance.
    relief: bool = False
    uav_types: tuple[UavType, ...] = ()  # (the run's types: a relief's turn radius, _flight_s)


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
    messages_ignored: int = 0  # other heard messages no honest UAV sends (see _drain_inbox)


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
        self.scans = ScanLog(settings.dt, radio.sync_horizon_s)
        self._log_scans = radio.sync_every_s > 0  # without anti-entropy nothing reads the log
        # The knowledge horizon, its square (None: none), and where the UAV is this tick (set by observe).
        h = self._horizon_m = radio.horizon_m
        self._horizon2 = None if math.isinf(h) else h * h
        self._here = (0.0, 0.0)
        self._digests: list[ScanDigest] = []  # heard this tick, answered in the outbox
        self._next_digest = -math.inf
        self._digest_start = 0  # where the next digest begins when one frame cannot hold it all
        self._scans_per_frame = max(1, (radio.frame_max_bytes - _FRAME_SLACK) // _SCAN_BYTES)
        # A scan is applied and logged only if it is plausible: a radius up to the area's size and
        # a centre at most that far outside the area (absurd numbers would make the disk's bounds
        # overflow). Own scans obey the same rule, so every logged scan is one peers accept.
        self._max_scan_r = max(grid.width_m, grid.height_m)
        # Shared by the simulation's actors so each broadcast frame is decoded once (a pure
        # memo: the same bytes give the same immutable Frame).
        # (A shared decoder decodes with the swarm's key, as settings.auth_key.)
        self._decode = decoder.decode if decoder is not None else partial(decode, max_bytes=radio.frame_max_bytes,
                                                                          key=settings.auth_key)
        self._cache = decoder
        # Sent through a shared decoder with the swarm's key, a frame is remembered there as
        # decoded (DecodeCache.encode): its receivers find it without running the codec.
        self._encode = (decoder.encode if decoder is not None and decoder.key == settings.auth_key
                        else partial(encode, key=settings.auth_key))
        self._bounds = (self._max_scan_r, grid.width_m, grid.height_m, settings.dt)  # agents.inbox.check_frame's
        # Heard scans older than this are anti-entropy resends (a beacon carries the scans of the
        # last beacon period): sent to this UAV alone, their disks are not worth sharing.
        self._fresh_s = radio.beacon_every_s + 2 * settings.dt
        # (The polygon no-fly zones among the zones: a watcher keeps a target inside one as
        # inside a circle, rule 5 of docs/modelling.md's "Assignment rules".)
        self.knowledge = Knowledge(tuple(z for z in settings.zones if not z.inverted))
        self.plan: Plan | None = None
        # (issues 26, 33) Endurance: flying home (no replanning on the way), the target it
        # handed over and whether a relief held it then; the relief it asked for (target, when it
        # must go: its beacons then say it searches, with that target); the target it is on
        # its way to take over from a watcher that asked (no replanning until it holds it).
        self.homebound = False
        self.operator_goal: tuple[float, float] | None = None  # (set_waypoint: an operator's waypoint)
        self.handed_target = NO_TARGET
        self.relieved = False
        self.relief_asked: tuple[int, float] | None = None
        self._releasing = False
        self._relieving = NO_TARGET
        self._types = {k.name: k for k in settings.uav_types}
        self.counters = ActorCounters()
        self._next_replan = -math.inf
        self._next_beacon = -math.inf
        self._next_tracks = -math.inf
        self._pending_scans: list[float] = []
        self._received: list[tuple[int, int, bool]] = []
        self._seq = 0
        # A liar's fabrications (see lie()): scans to make this tick, then to send; tracks to send.
        self._lies: list[tuple[float, float, float]] = []
        self._lie_scans: list[tuple[int, float, float, float, float]] = []
        self._lie_tracks: list[tuple[int, float, float]] = []
        self.lie_sink: Callable[[int], None] | None = None  # told how many fabrications were sent
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
        self._here = (r.x, r.y)  # the knowledge horizon's centre (_drain_inbox)
        self._received = self._drain_inbox(t)
        radius = self.kind.detect_radius
        d = self.grid.disk_stamp(r.x, r.y, radius)  # = umap.scan(); the disk is shared
        if d is not None:
            self.umap.stamp(d, t)
        if self.settings.outside is not None:  # (issue 26: outside the area polygon, always "seen")
            self.umap.stamp(self.settings.outside, t)
        self._pending_scans.extend((t, r.x, r.y, radius))
        if self._log_scans and self._plausible(r.x, r.y, radius):
            self.scans.add(self.uid, t, r.x, r.y, radius)
        if self._lies:
            self._fabricate(t)
        k = self.knowledge
        for st in r.targets:
            k.see_target(st.target, st.x, st.y, st.vx, st.vy, t, st.value)
        for th in r.threats:
            k.add_threat(th.threat, th.x, th.y, th.radius, th.d_max)
        if r.energy is not None and (self._energy(r) or self._releasing):
            return None  # homebound, or keeping its target until a relief holds it: no replanning
        if self.operator_goal is not None and self._to_operator_goal(r):
            return None  # flying to the operator's waypoint: no replanning on the way
        if self.settings.relief:
            if self._relieving == NO_TARGET:
                self._answer_relief(r)
            if self._relieving != NO_TARGET and self._relieve(r):
                return None  # on its way to take a target over: no replanning
        if self.plan is None or t >= self._next_replan or self._reached(r):
            s = self.settings
            return PlanView(t, self.uid, self.kind, r.x, r.y, r.v, r.theta, self.umap, k, self.rng,
                            self.grid, s.replan_s, s.surveillance, self.plan)
        return None

    def _energy(self, r: SensorReading) -> bool:
        """(issues 26, 33) Endurance: True while flying home (along the way the reading gives).

        A watcher asks for relief (rule 6 of docs/modelling.md's assignment rules) once its spare
        flight is down to ``handover_s`` plus :data:`RELIEF_MARGIN` times the time the nearest
        free UAV it hears needs to reach its target (:meth:`_relief_eta`); from then its beacons say it searches, with its
        target's id (a relief request), while it keeps circling and sending the target's track
        (it does not replan meanwhile: it keeps its target).
        It lets go and turns home when a peer watches the target with it inside its own
        detection radius (a relief holds it), when its plan no longer watches the target
        (another took it over: it asked because it must go soon, so it goes), or when its energy
        says go. Any other UAV goes home when its energy says go."""
        e = r.energy
        assert e is not None
        if self.homebound:
            self.plan = Plan(e.way_x, e.way_y)
            return True
        plan = self.plan
        watching = plan is not None and plan.mode == MODE_SURVEIL
        asked = self.relief_asked
        if asked is not None and watching and plan is not None and plan.target != asked[0]:
            asked = self.relief_asked = (plan.target, asked[1])  # (it watches another now: relief for that one)
        held = False
        if watching:
            assert plan is not None
            m = plan.target
            if asked is None and e.spare_s <= e.handover_s + RELIEF_MARGIN * self._relief_eta(r, m, e.wind_mps):
                self.relief_asked = (m, r.t + e.spare_s)
                self._releasing = True
            held = self.relief_asked is not None and self._relief_holds(r, m)
            if not (held or e.must_go):
                return False
        elif not e.must_go and asked is None:  # (asked, and its target taken over: it goes)
            return False
        self.homebound = True
        self.handed_target = plan.target if watching and plan is not None else NO_TARGET
        held = held or (asked is not None and not watching)  # (its target taken over: relieved)
        if watching and self.relief_asked is None:
            self.relief_asked = (self.handed_target, r.t)  # (asked at the last moment: a fault's doing)
        self.relieved = held
        self.plan = Plan(e.way_x, e.way_y)
        self._releasing = False
        self._relieving = NO_TARGET
        return True

    def _free_peers(self, t: float) -> list[Peer]:
        """The peers heard within the peer timeout that search with no target (not watching,
        not on their way to a target, not going home)."""
        timeout = self.settings.peer_timeout_s
        return [p for p in self.knowledge.peers.values()
                if p.uav != self.uid and p.mode == MODE_SEARCH and p.target == NO_TARGET
                and t - p.t_intent <= timeout and t - p.t_pose <= timeout]

    def _flight_s(self, x: float, y: float, v: float, theta: float, type_name: str, tx: float, ty: float,
                  wind: float) -> float:
        """Seconds a UAV at ``(x, y)`` flying ``v`` on heading ``theta`` needs to reach ``(tx, ty)``:
        the turn towards it at its type's turn radius at that speed, then straight, at ``v`` less
        the mean wind's speed (rule 6's reckoning)."""
        kind = self._types.get(type_name)
        turn = 0.0
        if kind is not None:
            off = abs(math.remainder(math.atan2(ty - y, tx - x) - theta, 2 * math.pi))
            turn = off * kind.r_min(max(v, kind.speed_min))
        return (turn + math.hypot(tx - x, ty - y)) / max(v - wind, 1.0)

    def _relief_eta(self, r: SensorReading, m: int, wind: float) -> float:
        """Seconds the nearest free peer it hears needs to reach target ``m`` (:meth:`_flight_s`);
        0 when it hears none or does not know where ``m`` is."""
        tr = self.knowledge.tracks.get(m)
        if tr is None:
            return 0.0
        tx, ty = tr.predict(r.t)
        etas = [self._flight_s(p.x, p.y, p.v, p.theta, p.type, tx, ty, wind) for p in self._free_peers(r.t)]
        return min(etas, default=0.0)

    def _relief_holds(self, r: SensorReading, m: int) -> bool:
        """A peer watches ``m`` (its beacons say so) from within its own detection radius of it
        (as it last said where it is, against where this UAV predicts the target)."""
        tr = self.knowledge.tracks.get(m)
        if tr is None:
            return False
        tx, ty = tr.predict(r.t)
        t, timeout, types = r.t, self.settings.peer_timeout_s, self._types
        return any(p.mode == MODE_SURVEIL and p.target == m and not p.asks and t - p.t_intent <= timeout
                   and math.hypot(p.x - tx, p.y - ty) <= (types[p.type].detect_radius if p.type in types
                                                          else self.kind.detect_radius)
                   for p in self.knowledge.peers.values() if p.uav != self.uid)

    def _answer_relief(self, r: SensorReading) -> None:
        """A free UAV that hears a relief request (a peer searching with a target's id) goes to
        take that target over when it is the one of the free UAVs it hears (and itself) that
        reaches the target first (ties: the lowest id), nobody else already watches or relieves
        the target, and its own energy leaves it the way there plus ``handover_s`` twice."""
        plan = self.plan
        if self.homebound or (plan is not None and (plan.mode != MODE_SEARCH or plan.target != NO_TARGET)):
            return
        t, timeout = r.t, self.settings.peer_timeout_s
        peers = [p for p in self.knowledge.peers.values() if p.uav != self.uid and t - p.t_intent <= timeout]
        asks = sorted((p.target, p.uav) for p in peers if p.asks)
        if not asks:
            return
        wind = r.energy.wind_mps if r.energy is not None else 0.0
        free = self._free_peers(t)
        for m, asker in asks:
            tr = self.knowledge.tracks.get(m)
            if tr is None or any(p.mode == MODE_SURVEIL and p.target == m for p in peers if p.uav != asker):
                # (someone else watches it, or is on the way: a relief beacons that it watches)
                continue
            tx, ty = tr.predict(t)
            mine = self._flight_s(r.x, r.y, r.v, r.theta, self.kind.name, tx, ty, wind)
            if any((self._flight_s(p.x, p.y, p.v, p.theta, p.type, tx, ty, wind), p.uav) < (mine, self.uid) for p in free):
                continue
            e = r.energy
            if e is not None and e.spare_s < mine + 2.0 * e.handover_s:
                continue
            self._relieving = m
            self.plan = Plan(tx, ty, MODE_SEARCH, m)
            return

    def _relieve(self, r: SensorReading) -> bool:
        """On its way to take target ``_relieving`` over: True while it flies there (towards the
        target's predicted position), and while it watches the target from within its detection
        radius until the watcher that asked has gone (it does not replan meanwhile: the asker,
        still beaconing its request, would look like a watcher it should yield to); then it
        plans as usual from the next replan. It gives up when the target's track is gone or
        another UAV holds it."""
        m = self._relieving
        tr = self.knowledge.tracks.get(m)
        t = r.t
        if tr is None or t - tr.t > self.settings.replan_s * 20:
            self._relieving, self.plan = NO_TARGET, None
            return False
        tx, ty = tr.predict(t)
        timeout, radius = self.settings.peer_timeout_s, self.kind.detect_radius
        if math.hypot(r.x - tx, r.y - ty) <= radius:
            self.plan = Plan(tx, ty, MODE_SURVEIL, m)
            if any(p.asks and p.target == m and t - p.t_intent <= timeout for p in self.knowledge.peers.values()):
                return True  # it holds the target; the watcher that asked has not gone yet (no replanning)
            self._relieving = NO_TARGET
            self._next_replan = t + self.settings.replan_s
            return False
        if any(p.mode == MODE_SURVEIL and p.target == m and not p.asks and t - p.t_intent <= timeout
               and math.hypot(p.x - tx, p.y - ty) <= radius for p in self.knowledge.peers.values() if p.uav != self.uid):
            self._relieving, self.plan = NO_TARGET, None  # someone holds it
            return False
        self.plan = Plan(tx, ty, MODE_SEARCH, m)
        return True

    def goto(self, x: float, y: float) -> None:
        """An operator's waypoint (the embedding API's ``set_waypoint``, a ground station's
        reposition): fly to ``(x, y)`` searching, without replanning, until there (within one
        turn radius, or 1.5 ticks of flight); then plan afresh. Energy still sends it home first."""
        self.operator_goal = (x, y)
        if not self.homebound:
            self.plan = Plan(x, y)
            self._releasing = False

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
        self.homebound = False
        self.handed_target = NO_TARGET
        self.relieved = False
        self.relief_asked = None
        self._releasing = False
        self._relieving = NO_TARGET
        self.plan = None
        self._next_replan = -math.inf

    # --- a liar (the liar fault; swarm.node_faults) ----------------------------------------

    def lie(self, scans: Sequence[tuple[float, float, float]], tracks: Sequence[tuple[int, float, float]]) -> None:
        """Make this Byzantine UAV claim, this tick, the scans ``(x, y, radius)`` it never made
        and sightings ``(target, x, y)`` of targets that do not exist (set by the simulation
        before it wakes the actor; the draws are the fault's).

        The fake scans are stamped with the UAV's own time, stamped into its own map and scan
        log as if real (so its map, its log and what it sends agree: anti-entropy spreads them
        like any scan) and sent with its next beacon; the tracks go with that beacon, stamped
        then. Receivers keep one scan per origin and tick (agents.maps.scanlog), so the j-th
        fake scan of a tick carries the made-up origin ``_GHOST_ORIGIN + uid * 4096 + j``, as a
        member holding the swarm key can. What does not fit in the beacon frame is dropped;
        :attr:`lie_sink` is told how many were sent."""
        self._lies.extend(scans)
        self._lie_tracks.extend(tracks)

    def _fabricate(self, t: float) -> None:
        ghost = _GHOST_ORIGIN + (self.uid * _GHOSTS_PER_UAV) % (2**30)
        for j, (x, y, radius) in enumerate(self._lies):
            origin = ghost + j % _GHOSTS_PER_UAV
            d = self.grid.disk_stamp(x, y, radius)
            if d is not None:
                self.umap.stamp(d, t)
            if self._log_scans and self._plausible(x, y, radius):
                self.scans.add(origin, t, x, y, radius)
            self._lie_scans.append((origin, t, x, y, radius))
        self._lies = []

    def _pack_lies(self, t: float, msgs: list[Message | Packed], room: int) -> int:
        """Add the pending fabrications to a beacon's messages while they fit; returns the room
        left."""
        sent = 0
        by_origin: dict[int, list[float]] = {}
        for origin, tr, x, y, radius in self._lie_scans:
            flat = by_origin.get(origin)
            cost = _SCAN_BYTES + (0 if flat is not None else _MSG_BYTES)
            if room - cost < 2 * _FRAME_SLACK:
                break
            if flat is None:
                flat = by_origin[origin] = []
            flat.extend((tr, x, y, radius))
            room -= cost
            sent += 1
        for origin, flat in by_origin.items():
            msgs.append(pack_scans(origin, flat))
        items = []
        for target, x, y in self._lie_tracks:
            if room - _TRACK_BYTES < 2 * _FRAME_SLACK:
                break
            items.append(TrackItem(target, x, y, 0.0, 0.0, t, 1.0))
            room -= _TRACK_BYTES
        if items:
            msgs.append(pack_tracks(items))
            sent += len(items)
        self._lie_scans, self._lie_tracks = [], []
        if sent and self.lie_sink is not None:
            self.lie_sink(sent)
        return room

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
        if self.homebound and r.energy is not None:  # (issue 26) home at the minimum-power speed
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
        replies = self._answer_digests(t) if self._digests else []
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

    def _drain_inbox(self, t: float) -> list[tuple[int, int, bool]]:
        received: list[tuple[int, int, bool]] = []
        frames = self.mailbox.drain()
        if not frames:
            return received
        append = received.append
        k = self.knowledge
        peers = k.peers
        me = self.uid
        stamp = self.umap.stamp
        disk_stamp = self.grid.disk_stamp
        known_disk = self.grid.disk_lookup()  # disk_stamp's memo, without the call (hot loop)
        umap = self.umap
        # A resent scan missing from the memo is stamped into a tiled map of its own directly
        # (UncertaintyMap.stamp_once: 35 -> 15 us; group maps keep their own bookkeeping).
        once = umap.stamp_once if type(umap) is UncertaintyMap and not umap.dense else None
        old = t - self._fresh_s
        decode_frame = self._decode
        cache = self._cache
        counters = self.counters
        log_add = self.scans.add_tick if self._log_scans else None
        # A frame that decodes can still carry numbers no honest UAV sends (a time of 1e308 s,
        # a threat with no influence ring): the receiver ignores and counts such messages.
        # What it accepts of a frame (agents.inbox.check_frame) is the same for every receiver
        # at this tick: checked once, kept beside the shared decoded frame.
        bounds, grid = self._bounds, self.grid
        derived = cache.derived if cache is not None else None
        delivered = ignored = strange = beyond = 0
        horizon2 = self._horizon2
        here_x, here_y = self._here
        for _arrival, sender, data in frames:
            heard: Heard | None = None
            frame = None
            # Another receiver may have decoded (and checked) these very bytes already (shared cache).
            if derived is not None and type(data) is bytes:
                heard = derived(data)  # type: ignore[assignment]  # (a Heard: only actors keep values)
                if heard is None or heard.t != t or heard.grid is not grid or heard.bounds != bounds:
                    heard = None
                    frame = cache.lookup(data)  # type: ignore[union-attr]  # (derived: cache is not None)
            if heard is None:
                if frame is None:
                    try:
                        frame = decode_frame(data)
                    except AuthError:  # (a FrameError too)
                        counters.rejected += 1
                        counters.rejected_auth += 1
                        append((sender, len(data), False))
                        continue
                    except FrameError:
                        counters.rejected += 1
                        append((sender, len(data), False))
                        continue
                heard = check_frame(frame, t, bounds, grid)
                if cache is not None and type(data) is bytes:
                    cache.keep(data, heard)
            delivered += 1
            append((sender, len(data), True))
            ignored += heard.ignored
            strange += heard.strange
            for origin, tick, scan, key in heard.scans:
                if horizon2 is not None and (scan[1] - here_x) ** 2 + (scan[2] - here_y) ** 2 > horizon2:
                    beyond += 1  # beyond the knowledge horizon (= not scanlog.within(...))
                elif log_add is None or log_add(origin, tick, scan):  # new to us (else already applied)
                    # = umap.scan(x, y, r, t_rec); the disk is shared by every map applying
                    # this record (grid memo).
                    d = known_disk(key, _MISSING)
                    if d is _MISSING:
                        if once is not None and scan[0] < old:
                            once(*key, scan[0])  # (a resend: this map's cells only, no shared disk)
                            continue
                        d = disk_stamp(*key)
                    if d is not None:
                        stamp(d, scan[0])
            ft = heard.t_frame
            for m in heard.hellos:
                if m.uav != me:
                    p = peers.get(m.uav) or k.peer(m.uav)
                    if ft >= p.t_pose:
                        p.type, p.x, p.y, p.v, p.theta, p.t_pose = m.type, m.x, m.y, m.v, m.theta, ft
            for i in heard.intents:
                if i.uav != me:
                    p = peers.get(i.uav) or k.peer(i.uav)
                    if ft >= p.t_intent:
                        p.wx, p.wy, p.mode, p.target, p.t_intent = i.wx, i.wy, i.mode, i.target, ft
                        if i.mode == MODE_SEARCH and i.target >= 0:  # (issue 33) a relief request
                            p.mode, p.asks = MODE_SURVEIL, True
                        elif p.asks:
                            p.asks = False
            if heard.tracks:
                k.merge_tracks(heard.tracks)
            for th in heard.threats:
                k.add_threat(*th)
            for dg in heard.digests:
                if dg.uav != me:
                    self._digests.append(dg)
        counters.delivered += delivered
        counters.scans_ignored += ignored
        counters.scans_beyond += beyond
        counters.messages_ignored += strange
        return received

    def _answer_digests(self, t: float) -> list[tuple[int, bytes]]:
        """Send each digest's sender the scans it lacks (anti-entropy, agents.maps.scanlog), as
        frames addressed to it alone.

        Not every neighbour answers: in a dense swarm a digest is heard by hundreds of UAVs,
        and all answering would send the same scans hundreds of times. Each UAV answers when a
        hash of (itself, the sender, the digest's cut) falls in the first ``2 / n`` of its range,
        ``n`` the neighbours it hears: about two answer each digest, different ones each round
        (no random draw: the UAVs' streams are their planners'). With two or fewer neighbours
        every one answers.
        """
        replies: list[tuple[int, bytes]] = []
        budget = self.settings.radio.sync_max_records
        per_frame = self._scans_per_frame
        timeout = self.settings.peer_timeout_s
        peers = self.knowledge.peers
        n = sum(1 for p in peers.values() if t - p.t_pose <= timeout)
        horizon = self._horizon_m
        for dg in self._digests:
            if n > _ANSWERERS and _answer_hash(self.uid, dg.uav, dg.t_cut) % n >= _ANSWERERS:
                continue
            near = None
            if not math.isinf(horizon):
                # The sender's horizon, centred where its Hello (on the digest's own beacon) put it.
                p = peers.get(dg.uav)
                if p is None or math.isinf(p.t_pose):
                    continue  # no pose heard: where its horizon lies is unknown
                near = (p.x, p.y, horizon)
            msgs: list[Message | Packed] = []
            room = per_frame  # scans the current frame can still take
            for origin, flat in self.scans.missing(dg.tick0, dg.lo, dg.hi, dg.bitmaps, min(dg.t_cut, t), budget,
                                                   near):
                budget -= len(flat) // 4
                self.counters.scans_resent += len(flat) // 4
                while flat:
                    take, flat = flat[:4 * room], flat[4 * room:]
                    msgs.append(ScanRecords(origin, tuple(take)))
                    room -= len(take) // 4
                    if room == 0:
                        replies.append((dg.uav, self._frame(t, msgs)))
                        msgs, room = [], per_frame
            if msgs:
                replies.append((dg.uav, self._frame(t, msgs)))
            if budget <= 0:
                break
        self._digests = []
        self.counters.resent_bytes += sum(len(f) for _, f in replies)
        return replies

    def _frame(self, t: float, messages: Sequence[Message | Packed]) -> bytes:
        self._seq += 1
        self.counters.frames_sent += 1
        return self._encode(self.uid, self._seq, t, messages)

    def _intent(self, plan: Plan) -> tuple[int, int]:
        """The mode and target its beacons announce: its plan's, but (issue 33) a watcher asking
        for relief says it searches with its target's id, a relief on its way says it watches
        the target, and a UAV going home says it searches with :data:`HOME_TARGET`."""
        if self._releasing and self.relief_asked is not None:
            return MODE_SEARCH, self.relief_asked[0]
        if self.homebound:
            return MODE_SEARCH, HOME_TARGET
        if self._relieving != NO_TARGET:
            return MODE_SURVEIL, self._relieving
        return plan.mode, plan.target

    def _outbox(self, r: SensorReading, plan: Plan) -> list[bytes]:
        t = r.t
        s = self.settings.radio
        frames: list[bytes] = []
        if t >= self._next_beacon:
            # Hello, Intent and ScanRecords, packed straight away (the same bytes; see codec).
            msgs: list[Message | Packed] = [
                pack_hello(self.uid, self.kind.name, r.x, r.y, r.v, r.theta),
                pack_intent(self.uid, plan.wx, plan.wy, *self._intent(plan)),
            ]
            room = s.frame_max_bytes - _FRAME_SLACK - _SCAN_BYTES * (len(self._pending_scans) // 4)
            if self._pending_scans:
                msgs.append(pack_scans(self.uid, self._pending_scans))
                self._pending_scans = []
            if self._lie_scans or self._lie_tracks:
                room = self._pack_lies(t, msgs, room)
            if s.sync_every_s > 0 and t >= self._next_digest and room > _FRAME_SLACK:
                # The digest rides on the beacon (no extra frame); a long run's digest is split
                # over several beacons (agents.maps.scanlog.ScanLog.digest).
                t_cut = t - s.sync_settle_s
                self.scans.forget_before(t)
                tick0, lo, hi, bitmaps, self._digest_start = self.scans.digest(t_cut, self._digest_start, room)
                msgs.append(ScanDigest(self.uid, t_cut, tick0, lo, hi, bitmaps))
                self.counters.digests_sent += 1
                self.counters.digest_bytes += sum(len(b) + 8 for _, b in bitmaps)
                self._next_digest = t + s.sync_every_s - 1e-9
            frames.append(self._frame(t, msgs))
            self._next_beacon = t + s.beacon_every_s - 1e-9
        k = self.knowledge
        if t >= self._next_tracks and (k.tracks or k.threats):
            # Packed straight from the tracks: the bytes of Tracks(TrackItem(...) of each).
            items = [tr for _, tr in sorted(k.tracks.items())]
            threats = Threats(tuple(ThreatItem(th.threat, th.x, th.y, th.radius, th.d_max)
                                    for _, th in sorted(k.threats.items())))
            first = True
            for i in range(0, max(len(items), 1), _TRACKS_PER_FRAME):
                msgs = [pack_tracks(items[i:i + _TRACKS_PER_FRAME])]
                if first and threats.items:
                    msgs.append(threats)
                first = False
                frames.append(self._frame(t, msgs))
            self._next_tracks = t + s.tracks_every_s - 1e-9
        return frames


__all__ = ["HOME_TARGET", "NO_TARGET", "ActorOutput", "ActorSettings", "EnergyReading", "SensedTarget", "SensedUav",
           "SensorReading", "UavActor"]
