"""One UAV's endurance duties (issues 26 and 33): going home when its energy says so, asking
for relief on station before it must (rule 6 of docs/modelling.md's "Assignment rules"), and,
free, answering another's request and taking its target over.

:class:`Relief` holds that state for one actor (:class:`agents.actor.UavActor` makes one and
calls it from its tick); it reads the actor's :class:`~agents.knowledge.Knowledge` and returns
the plans to fly, so the actor keeps its own work (planning, steering, the radio). The mission
phase (:mod:`swarm.kernel.mission`) reads what it decided: :attr:`Relief.homebound`,
:attr:`Relief.asked`, :attr:`Relief.handed_target`, :attr:`Relief.relieved`.
"""

from __future__ import annotations

import math

from agents.inputs import SensorReading
from agents.knowledge import Knowledge, Peer
from agents.planners.base import Plan
from agents.types import UavType
from comms.messages import MODE_SEARCH, MODE_SURVEIL, NO_TARGET

__all__ = ["HOME_TARGET", "RELIEF_MARGIN", "Relief"]


# What a UAV flying home beacons as its intent's target (with search mode): not free (issue 33).
HOME_TARGET = -2
# A watcher asks for relief this many times the nearest free UAV's straight flight time ahead
# (plus handover_s): room for its turns, the gusts and a way round a zone (issue 33, rule 6).
RELIEF_MARGIN = 1.5


class Relief:
    """One UAV's going home and relief on station (module docstring).

    State: ``homebound`` (flying home: no replanning on the way); ``handed_target`` (the target
    it watched when it turned home) and ``relieved`` (whether a relief held it then); ``asked``
    (the relief it asked for: target, when it must go; its beacons then say it searches, with
    that target); ``releasing`` (keeping its target until a relief holds it: no replanning);
    ``relieving`` (the target it is on its way to take over from a watcher that asked)."""

    def __init__(self, uid: int, kind: UavType, knowledge: Knowledge, peer_timeout_s: float, replan_s: float,
                 types: dict[str, UavType]):
        self.uid = uid
        self.kind = kind
        self.knowledge = knowledge
        self.peer_timeout_s = peer_timeout_s
        self.replan_s = replan_s
        self.types = types
        self.homebound = False
        self.handed_target = NO_TARGET
        self.relieved = False
        self.asked: tuple[int, float] | None = None
        self.asked_at = -math.inf
        self.releasing = False
        self.relieving = NO_TARGET
        self.heard: dict[tuple[int, int], float] = {}  # (asker, target) -> when it first heard the request

    def reset(self) -> None:
        """Back in the air from the base (a relaunch): nothing owed, nothing asked."""
        self.homebound = False
        self.handed_target = NO_TARGET
        self.relieved = False
        self.asked = None
        self.asked_at = -math.inf
        self.releasing = False
        self.relieving = NO_TARGET
        self.heard = {}

    def intent(self, plan: Plan) -> tuple[int, int]:
        """The mode and target its beacons announce: its plan's, but a watcher asking for relief
        says it searches with its target's id, a relief on its way says it watches the target,
        and a UAV going home says it searches with :data:`HOME_TARGET`."""
        if self.releasing and self.asked is not None:
            return MODE_SEARCH, self.asked[0]
        if self.homebound:
            return MODE_SEARCH, HOME_TARGET
        if self.relieving != NO_TARGET:
            return MODE_SURVEIL, self.relieving
        return plan.mode, plan.target

    def home(self, r: SensorReading, plan: Plan | None) -> Plan | None:
        """The plan home (along the way the reading gives) while it flies home; None while it
        does not (its plan stays).

        A watcher asks for relief (rule 6 of docs/modelling.md's assignment rules) once its time
        on station (:meth:`station_s`) is down to ``handover_s`` plus :data:`RELIEF_MARGIN`
        times the time the nearest free UAV it hears needs to reach its target (:meth:`eta`),
        announcing ``by``: now plus that time on station. From then its beacons say it searches,
        with its target's id (a relief request), while it keeps circling and sending the
        target's track (it does not replan meanwhile: it keeps its target).
        It lets go and turns home when a peer watches the target with it inside its own
        detection radius (a relief holds it), when its plan no longer watches the target
        (another took it over: it asked because it must go soon, so it goes), when another
        watcher with a lower id asks for relief for the same target (two that asked at once
        would otherwise both keep it), or when its energy says go. Any
        other UAV goes home when its energy says go."""
        e = r.energy
        assert e is not None
        if self.homebound:
            return Plan(e.way_x, e.way_y)
        watching = plan is not None and plan.mode == MODE_SURVEIL
        asked = self.asked
        if asked is not None and watching and plan is not None and plan.target != asked[0]:
            asked = self.asked = (plan.target, asked[1])  # (it watches another now: relief for that one)
        held = False
        if watching:
            assert plan is not None
            m = plan.target
            if asked is None:
                station = self.station_s(r, m)
                if station <= e.handover_s + RELIEF_MARGIN * self.eta(r, m, e.wind_mps):
                    self.asked, self.asked_at = (m, r.t + station), r.t
                    self.releasing = True
            held = self.asked is not None and (self.holds(r, m) or self.yields(r, m))
            if not (held or e.must_go):
                return None
        elif not e.must_go and asked is None:  # (asked, and its target taken over: it goes)
            return None
        self.homebound = True
        self.handed_target = plan.target if watching and plan is not None else NO_TARGET
        held = held or (asked is not None and not watching)  # (its target taken over: relieved)
        if watching and self.asked is None:
            self.asked = (self.handed_target, r.t)  # (asked at the last moment: a fault's doing)
        self.relieved = held
        self.releasing = False
        self.relieving = NO_TARGET
        return Plan(e.way_x, e.way_y)

    def station_s(self, r: SensorReading, m: int) -> float:
        """The seconds a watcher of target ``m`` may stay on station for sure (rule 6): its spare
        flight (:class:`~agents.inputs.EnergyReading`: at the most power its type draws, the way home with the
        worst turn onto it) less what flying farther from home may take meanwhile: from where
        it is to the target and a detection radius beyond (the loiter circle), and the target's
        drift at its track's speed all the while."""
        e = r.energy
        assert e is not None
        tr = self.knowledge.tracks.get(m)
        if tr is None:
            return e.spare_s
        tx, ty = tr.predict(r.t)
        k = e.home_s_per_m
        away = math.hypot(r.x - tx, r.y - ty) + self.kind.detect_radius
        return max(e.spare_s - k * away, 0.0) / (1.0 + k * math.hypot(tr.vx, tr.vy))

    def yields(self, r: SensorReading, m: int) -> bool:
        """Another watcher with a lower id asks for relief for ``m`` too (an order both know:
        positions as heard may be stale, and each might think the other nearer)."""
        t, timeout = r.t, self.peer_timeout_s
        return any(p.asks and p.target == m and t - p.t_intent <= timeout and p.uav < self.uid
                   for p in self.knowledge.peers.values())

    def free_peers(self, t: float) -> list[Peer]:
        """The peers heard within the peer timeout that search with no target (not watching,
        not on their way to a target, not going home)."""
        timeout = self.peer_timeout_s
        return [p for p in self.knowledge.peers.values()
                if p.uav != self.uid and p.mode == MODE_SEARCH and p.target == NO_TARGET
                and t - p.t_intent <= timeout and t - p.t_pose <= timeout]

    def flight_s(self, x: float, y: float, v: float, theta: float, type_name: str, tx: float, ty: float,
                 wind: float) -> float:
        """Seconds a UAV at ``(x, y)`` flying ``v`` on heading ``theta`` needs to reach ``(tx, ty)``:
        the turn towards it at its type's turn radius at that speed, then straight, at ``v`` less
        the mean wind's speed (rule 6's reckoning)."""
        kind = self.types.get(type_name)
        turn = 0.0
        if kind is not None:
            off = abs(math.remainder(math.atan2(ty - y, tx - x) - theta, 2 * math.pi))
            turn = off * kind.r_min(max(v, kind.speed_min))
        return (turn + math.hypot(tx - x, ty - y)) / max(v - wind, 1.0)

    def eta(self, r: SensorReading, m: int, wind: float) -> float:
        """Seconds the nearest free peer it hears needs to reach target ``m`` (:meth:`flight_s`);
        0 when it hears none or does not know where ``m`` is."""
        tr = self.knowledge.tracks.get(m)
        if tr is None:
            return 0.0
        tx, ty = tr.predict(r.t)
        etas = [self.flight_s(p.x, p.y, p.v, p.theta, p.type, tx, ty, wind) for p in self.free_peers(r.t)]
        return min(etas, default=0.0)

    def holds(self, r: SensorReading, m: int) -> bool:
        """A peer watches ``m`` from within its own detection radius of it (as it last said where
        it is, against where this UAV predicts the target), its beacons say so, and the last of
        them was sent a replanning period or more after this UAV asked for relief: a UAV that
        watched ``m`` beside it before it asked has replanned by then, and may have left the
        target to it by the exclusion rule (the nearer keeps it); one asking at the same moment
        says so by then."""
        tr = self.knowledge.tracks.get(m)
        if tr is None:
            return False
        tx, ty = tr.predict(r.t)
        t, timeout, types = r.t, self.peer_timeout_s, self.types
        return any(p.mode == MODE_SURVEIL and p.target == m and not p.asks and t - p.t_intent <= timeout
                   and p.t_intent >= self.asked_at + self.replan_s
                   and math.hypot(p.x - tx, p.y - ty) <= (types[p.type].detect_radius if p.type in types
                                                          else self.kind.detect_radius)
                   for p in self.knowledge.peers.values() if p.uav != self.uid)

    def answer(self, r: SensorReading, plan: Plan | None) -> Plan | None:
        """A free UAV that hears a relief request (a peer searching with a target's id) goes to
        take that target over when nobody else already watches or relieves the target, it is
        the one of the free UAVs it hears (and itself) that reaches the target first (ties: the
        lowest id) or, ``k`` of them reaching it before it, ``k`` replanning periods have passed
        since it first heard the request (a faster one that cannot afford it stays put: the next
        goes), and its own spare flight (:class:`~agents.inputs.EnergyReading`), less what the way there and a
        detection radius beyond take of it, covers the way there plus ``handover_s`` twice. Of
        several such requests it answers the one whose target it reaches first. Returns the
        plan there (None: it does not go)."""
        if self.homebound or (plan is not None and (plan.mode != MODE_SEARCH or plan.target != NO_TARGET)):
            return None
        t, timeout = r.t, self.peer_timeout_s
        peers = [p for p in self.knowledge.peers.values() if p.uav != self.uid and t - p.t_intent <= timeout]
        asks = sorted((p.target, p.uav) for p in peers if p.asks)
        self.heard = {(a, m): self.heard.get((a, m), t) for m, a in asks}
        if not asks:
            return None
        wind = r.energy.wind_mps if r.energy is not None else 0.0
        free = self.free_peers(t)
        best: tuple[float, int, float, float] | None = None  # (its flight time, target, where)
        for m, asker in asks:
            tr = self.knowledge.tracks.get(m)
            if tr is None or any(p.mode == MODE_SURVEIL and p.target == m for p in peers if p.uav != asker):
                # (someone else watches it, or is on the way: a relief beacons that it watches)
                continue
            tx, ty = tr.predict(t)
            mine = self.flight_s(r.x, r.y, r.v, r.theta, self.kind.name, tx, ty, wind)
            ahead = sum((self.flight_s(p.x, p.y, p.v, p.theta, p.type, tx, ty, wind), p.uav) < (mine, self.uid) for p in free)
            if ahead and t - self.heard[(asker, m)] < ahead * self.replan_s - 1e-9:
                continue
            e = r.energy
            if e is not None and e.spare_s - e.home_s_per_m * (math.hypot(tx - r.x, ty - r.y) + self.kind.detect_radius) \
                    < mine + 2.0 * e.handover_s:
                continue
            if best is None or (mine, m) < best[:2]:
                best = (mine, m, tx, ty)
        if best is None:
            return None
        self.relieving = best[1]
        return Plan(best[2], best[3], MODE_SEARCH, best[1])

    def relieve(self, r: SensorReading) -> tuple[bool, Plan | None]:
        """On its way to take target ``relieving`` over: ``(True, plan)`` while it flies there
        (towards the target's predicted position), and while it watches the target from within
        its detection radius until the watcher that asked has gone (it does not replan
        meanwhile: the asker, still beaconing its request, would look like a watcher it should
        yield to). Then ``(False, plan)``: it holds the target and plans as usual from its next
        replan (the caller sets it). It gives up, ``(False, None)``, when the target's track is
        gone or another UAV holds it."""
        m = self.relieving
        tr = self.knowledge.tracks.get(m)
        t = r.t
        if tr is None or t - tr.t > self.replan_s * 20:
            self.relieving = NO_TARGET
            return False, None
        tx, ty = tr.predict(t)
        timeout, radius = self.peer_timeout_s, self.kind.detect_radius
        if math.hypot(r.x - tx, r.y - ty) <= radius:
            plan = Plan(tx, ty, MODE_SURVEIL, m)
            if any(p.asks and p.target == m and t - p.t_intent <= timeout for p in self.knowledge.peers.values()):
                return True, plan  # it holds the target; the watcher that asked has not gone yet (no replanning)
            self.relieving = NO_TARGET
            return False, plan
        if any(p.mode == MODE_SURVEIL and p.target == m and not p.asks and t - p.t_intent <= timeout
               and math.hypot(p.x - tx, p.y - ty) <= radius for p in self.knowledge.peers.values() if p.uav != self.uid):
            self.relieving = NO_TARGET  # someone holds it
            return False, None
        return True, Plan(tx, ty, MODE_SEARCH, m)
