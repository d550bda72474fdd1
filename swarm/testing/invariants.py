"""Invariants of a run, as a library: check a finished run's event log, or a simulation live.

Each invariant is a *checker*: an object fed the run's events in order (the records of
:mod:`swarm.events`) that collects :class:`Violation` records saying what went
wrong, when, and which UAVs / target. A :class:`Monitor` feeds several checkers at once, from a
log or live from ``sim.subscribe``::

    # after the run: `swarm run my.toml --out out/` wrote scenario.json and events.msgpack
    from swarm.testing.invariants import check_events, load_run_log
    scenario, events = load_run_log("out/")
    for v in check_events(events, scenario):   # the seven checkers a log can judge
        print(v)

    # live, e.g. in a test or a Hypothesis state machine
    from swarm.testing.invariants import Monitor, default_checkers
    monitor = Monitor(default_checkers(live=True)).attach(sim)
    sim.step(10)
    monitor.flush()
    monitor.raise_if()            # InvariantViolation listing every violation so far

What the events alone cannot tell (radio range, threats, UAV type limits, the fault schedule)
comes from the :class:`~swarm.scenario.Scenario`. Faults added while a run goes
(``sim.add_fault``) are not in the event log: give them as ``faults=`` when checking a log, or
check live (the monitor then reads the simulation's own schedule). Checkers marked *live* also
read each UAV's map through ``sim.uav_map(name)`` and only work attached to a simulation.

The invariants (``name``: class, parameters and their defaults):

* ``separation`` / ``threat``: :class:`SeparationChecker`, :class:`ThreatClearanceChecker`:
  the planner's own moves never bring two UAVs closer than ``safety.min_separation_m`` or a
  UAV inside a threat circle. A pair (or UAV) already in violation when it first appears (a
  start or join position) is excused until it has cleared once: that is the scenario's doing.
* ``dynamics``: :class:`DynamicsChecker`: consecutive poses of a UAV respect its type's limits
  (speed range, ``|a| <= accel_max``, turn radius) and the kinematics (no jumps).
* ``radio``: :class:`RadioChecker`: every ``rx`` has a legal send tick: sender and receiver both
  flying, within range, not separated by an active partition or bridge (its bridge UAV talks
  to every side), neither clogged by a swizzle; and the receiver is flying when it reads the
  frame. A frame from sender -1 (a spoofer's) is legal only within an active spoofer's
  ``range_m``. A jammer's losses are losses: nothing to check on an ``rx``. Send ticks
  considered: ``dt`` plus up to the largest possible delay (radio latency + jitter + every
  delay fault) before the ``rx``. It needs the per-frame events of ``[recording] level =
  "frames"``; on a ``"summary"`` log it checks nothing and says so in its ``unchecked`` (and
  :attr:`Monitor.unchecked`).
* ``map_monotonic`` (live): :class:`MapMonotonicityChecker`: no cell's last-seen time ever
  decreases in any UAV's map.
* ``map_agreement`` (live, liveness): :class:`MapAgreementChecker(quiet_s=20, lag_s=10)`: once the
  swarm has been connected, with no active link fault or partition and no crash or join, for
  ``quiet_s``, every live UAV knows every cell any live UAV knew ``lag_s`` earlier. With a
  knowledge horizon ``H`` (``radio.sync_horizon_m`` finite) "agree" is local: every live UAV
  knows every cell a UAV it can talk to knew ``lag_s`` earlier, among the cells within
  ``H - slack`` of both (``slack``: the largest detection radius plus the farthest a UAV flies
  in ``lag_s``, so the scans of those cells were inside both horizons all along).
* ``joiner_catch_up`` (live, liveness): :class:`JoinerCatchUpChecker(bound_s=20)`: within
  ``bound_s`` of joining, a late joiner knows everything its radio neighbours knew when it
  joined (judged only while it can talk to one of them with no link fault active); with a
  knowledge horizon, those of them within ``H - slack`` of the joiner (as for ``map_agreement``).
* ``single_watcher``, ``handover``, ``no_drop``: the assignment rules, stated once in
  docs/modelling.md ("Assignment rules"), rules 1 (:class:`SingleWatcherChecker(settle_s=30)`:
  exclusion), 2-4 (:class:`HandoverChecker(takeover_s=60, release_s=60)`: takeover, release,
  after release) and 5 (:class:`NoDropChecker(grace_s=10)`: no drop; a lost target is no
  drop). They judge only the types and pairs whose weights meet the rules' preconditions
  (:mod:`agents.assignment`, paper eq. 25-27; :meth:`RunContext.exclusion_judged`,
  :meth:`RunContext.handover_judged`).

"Can talk" means: both flying, within radio range, no active partition or bridge between them
(either way), neither clogged by a swizzle, and neither inside an active jammer of rate 1.
Times are simulated seconds; UAVs are named by their scenario names.

Node faults (docs/scenarios.md, "Node and sensing faults"): a ``restart`` is a crash then a
rejoin (the UAV is not flying in between, and ``radio`` judges it so); its new map may be
emptier than the old (``map_monotonic`` starts over with a new actor) and must catch up like
a joiner's (``joiner_catch_up``). A UAV resuming from a ``pause`` reads frames its mailbox held
since the pause began (``radio`` accepts send ticks back to then). ``map_agreement`` is not
judged while a pause lasts or a clock skew's lead does (:meth:`RunContext.node_faults_disturb`),
``joiner_catch_up``'s obligation lapses then. The checkers of the planner's behaviour excuse a
UAV under a node fault (:meth:`RunContext.impaired`): ``separation`` and ``threat`` a paused
one, one with a skewed clock or a navigation error, while the fault acts and for
``RECOVER_S`` (30 s) after; ``single_watcher``, ``handover`` and ``no_drop`` those and one
under a ``sensor`` fault, while it acts. A phantom target (id >= ``PHANTOM_TARGET_ID``: a false
alarm's or a liar's) is never judged.

Why these defaults: the planners replan every 10 s (``planner.replan_s``), so a settled
assignment may take a few replans (settle 30 s; takeover and release 60 s; a target may go
unwatched for one replan, 10 s). Maps: a neighbour's scans arrive with its next beacon (1 s);
everything else (lost, from beyond one hop, from before a heal or a join) comes back through
anti-entropy (:mod:`agents.maps.scanlog`): a digest every ``radio.sync_every_s`` (5 s) covering scans
up to ``radio.sync_settle_s`` (2 s) old, answered the next tick. A scan can therefore reach a UAV
two hops away up to about 5 + 2 + 1 s late: ``lag_s = 10``; 20 s of quiet lets that settle. Each
further hop is one more round: ``map_agreement`` allows :meth:`RunContext.relay_lag_s` of the
radio graph's diameter when that is more (and waits that much longer).

Known breaks of the current simulator (pinned as xfails in ``tests/test_invariants.py``):
``separation`` whenever UAVs cannot hear each other (they learn of each other only over the
radio).
"""

from __future__ import annotations

import abc
import math
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.assignment import exclusion_break, handover_break, watch_break
from agents.dynamics import integrate, wrap_angle
from agents.types import UavType
from comms.messages import MODE_NAMES, MODE_SURVEIL
from comms.radio import SPOOF_SENDER
from faults.base import PHANTOM_TARGET_ID, FaultKind
from faults.registry import fault_from_dict, fault_to_dict
from faults.sensing import skewed_stamps
from swarm import events as event_schema
from swarm.errors import SwarmError, UsageError
from swarm.outputs import read_run_dir
from swarm.rng import RngTree
from swarm.scenario import Scenario, parse_scenario

__all__ = [
    "Checker",
    "DynamicsChecker",
    "HandoverChecker",
    "InvariantViolation",
    "JoinerCatchUpChecker",
    "MapAgreementChecker",
    "MapMonotonicityChecker",
    "Monitor",
    "NoDropChecker",
    "RadioChecker",
    "RunContext",
    "SeparationChecker",
    "SingleWatcherChecker",
    "ThreatClearanceChecker",
    "Violation",
    "check_events",
    "default_checkers",
    "describe_fault",
    "handover_checkers",
    "load_run_log",
    "safety_checkers",
]

_EPS = 1e-6


# --- what a checker reports --------------------------------------------------------------------


@dataclass(frozen=True)
class Violation:
    """One broken invariant: which, when (simulated seconds), what, and who."""

    invariant: str
    t: float
    message: str
    uavs: tuple[str, ...] = ()
    target: int | None = None
    data: dict = field(default_factory=dict, compare=False)
    #: The faults that may explain it (:meth:`RunContext.explaining`): active on these UAVs, on
    #: their links or on everyone around its time. Empty: nothing but the planner to blame.
    faults: tuple[str, ...] = field(default=(), compare=False)

    def __str__(self) -> str:
        who = f" uavs={','.join(self.uavs)}" if self.uavs else ""
        tgt = f" target={self.target}" if self.target is not None else ""
        under = f" [under fault: {'; '.join(self.faults)}]" if self.faults else ""
        return f"[{self.invariant}] t={self.t:g} s{who}{tgt}: {self.message}{under}"


class InvariantViolation(SwarmError, AssertionError):
    """Raised by :meth:`Monitor.raise_if` / :meth:`Checker.raise_if`; ``violations`` lists them."""

    def __init__(self, violations: Sequence[Violation], limit: int = 10):
        self.violations = list(violations)
        lines = [str(v) for v in self.violations[:limit]]
        more = len(self.violations) - limit
        if more > 0:
            lines.append(f"... and {more} more")
        super().__init__(f"{len(self.violations)} invariant violation(s):\n  " + "\n  ".join(lines))


def describe_fault(f: FaultKind) -> str:
    """A fault in a few words: kind, whom it acts on, when (``drop 0.5 on B1 10-50 s``)."""
    d = fault_to_dict(f)
    kind = d.pop("kind")
    who = d.pop("uav", None) or ",".join(d.pop("uavs", None) or ())
    lo, hi = f.span()
    if hasattr(f, "at_s"):
        when = f"at {lo:g} s" if hi == lo else f"at {lo:g} s for {hi - lo:g} s"
    else:
        when = f"{lo:g}-{hi:g} s" if math.isfinite(hi) else f"from {lo:g} s"
    return " ".join(p for p in (kind, f"on {who}" if who else "", when) if p)


# --- the run's context ---------------------------------------------------------------------------


def owed_map(m: np.ndarray, skewed: Sequence[tuple[float, float]]) -> np.ndarray:
    """A UAV's map less the cells it need not pass on (times in ``skewed``, from
    :func:`skewed_stamps`, set to -inf): what 'maps agree' asks the others to learn."""
    if not skewed:
        return m
    m = m.copy()
    for lo, hi in skewed:
        m[(m >= lo) & (m <= hi)] = -np.inf
    return m


class RunContext:
    """What the checkers know about a run besides its events: the scenario's settings, UAV ids,
    names and types (from the ``start`` and ``join`` events, or the live simulation), and the
    fault schedule (``faults`` if given, else the live simulation's, else the ``start`` event's)."""

    def __init__(self, scenario: Scenario, *, sim: Any = None, faults: Iterable[FaultKind] | None = None):
        self.scenario = scenario
        self.sim = sim
        self.dt = scenario.dt_s
        self.types = {n: s.uav_type(n) for n, s in scenario.uav_types.items()}
        self.range_m = scenario.radio.range_limit_m
        self.min_separation_m = scenario.safety.min_separation_m
        self.threats = [(i, th.x_m, th.y_m, th.radius_m) for i, th in enumerate(scenario.threats)]
        self.names: dict[int, str] = {}
        self.type_name: dict[int, str] = {}
        self.uid: dict[str, int] = {}
        self._override = list(faults) if faults is not None else None
        self._start_faults: list[FaultKind] = []
        self.seed = scenario.seed  # (the start event's, if it says otherwise: a swizzle's stream)
        self._drawn: dict[int, Any] = {}  # id(fault) -> what it drew (drawn)
        self.recording: str = scenario.recording.level  # (or the start header's, below)
        for i, (name, u) in enumerate(zip(scenario.uav_names, scenario.uavs)):  # the simulator numbers them in order
            self._learn(i, name, u.type)
        if sim is not None:
            for uid, b in sim.world.uavs.items():
                self._learn(uid, b.name, b.kind.name)

    def _learn(self, uid: int, name: str, type_name: str | None) -> None:
        self.names[uid] = name
        self.uid[name] = uid
        if type_name is not None:
            self.type_name[uid] = type_name

    def on_event(self, ev: event_schema.Event) -> None:
        if isinstance(ev, event_schema.Start):
            header = ev.header
            for uid, name, type_name in header.get("uavs", []):
                self._learn(uid, name, type_name)
            self._start_faults = [fault_from_dict(d) for d in header.get("faults", [])]
            if isinstance(header.get("seed"), int):
                self.seed = header["seed"]
            self.recording = str(header.get("recording", self.recording))
        elif isinstance(ev, (event_schema.Join, event_schema.Restart)):
            uid, name = ev.uav, ev.uav_name
            type_name = self.type_name.get(uid)
            if self.sim is not None and uid in self.sim.world.uavs:
                type_name = self.sim.world.uavs[uid].kind.name
            self._learn(uid, name, type_name)

    def name(self, uid: int) -> str:
        return self.names.get(uid, f"#{uid}")

    def kind(self, uid: int) -> UavType | None:
        t = self.type_name.get(uid)
        return self.types.get(t) if t is not None else None

    def watch_judged(self, uid: int) -> bool:
        """Whether ``no_drop`` judges this UAV's type: it can turn inside its own detection radius
        (:func:`agents.assignment.watch_break`)."""
        k = self.kind(uid)
        return k is not None and watch_break(k) is None

    def exclusion_judged(self, uid: int) -> bool:
        """Whether ``single_watcher`` judges this UAV's type: its weights meet eq. 27
        (:func:`agents.assignment.exclusion_break`)."""
        k = self.kind(uid)
        return k is not None and exclusion_break(k) is None

    def handover_judged(self, slow: int, fast: int) -> bool:
        """Whether ``handover`` judges this pair: the slower one's type is slower and their
        weights meet eq. 25-26 (:func:`agents.assignment.handover_break`)."""
        ks, kf = self.kind(slow), self.kind(fast)
        return (ks is not None and kf is not None and ks.speed_max < kf.speed_max
                and handover_break(ks, kf, self.scenario.planner.dacmp.field_unit_m) is None)

    @property
    def faults(self) -> list[FaultKind]:
        if self._override is not None:
            return self._override
        if self.sim is not None:
            return self.sim.injector.schedule.faults
        return self._start_faults

    def drawn(self, f: FaultKind) -> Any:
        """What fault ``f`` drew for itself when it started (a swizzle's ``{uav id: (cut_s,
        restore_s)}``): the live simulation's, or drawn again as the simulator draws it
        (:meth:`faults.base.FaultKind.draw` from the run's seed and the fault's stream
        ``("fault", kind, k)``, ``k`` its index among the faults of its kind; the pool "every
        UAV" is every UAV known here)."""
        if self.sim is not None:
            return self.sim.injector.drawn(f)
        if id(f) not in self._drawn:
            k = [g for g in self.faults if g.kind == f.kind].index(f)
            self._drawn[id(f)] = f.draw(f.pool(self.uid), RngTree(self.seed).generator("fault", f.kind, k))
        return self._drawn[id(f)]

    def blocked(self, src: int, dst: int, t: float) -> bool:
        """True when a fault cuts the link ``src -> dst`` at ``t`` (an active partition or
        bridge between them, a swizzle that has clogged either: :meth:`FaultKind.blocks`)."""
        return any(f.blocks(t, src, dst, self) for f in self.faults)

    def jammed(self, pos: Sequence[float], t: float) -> bool:
        """Whether a fault loses every copy to or from position ``pos`` at ``t`` (a jammer of
        ``rate`` 1: :meth:`FaultKind.silences`)."""
        return any(f.silences(pos, t) for f in self.faults)

    def spoofed(self, pos: Sequence[float], t: float) -> bool:
        """Whether forged frames reach position ``pos`` at ``t`` (a spoofer: :meth:`FaultKind.forges_at`)."""
        return any(f.forges_at(pos, t) for f in self.faults)

    def impaired(self, uid: int, t: float, sensing: bool = False, after_s: float = 0.0) -> bool:
        """Whether a fault that impairs a UAV's control (pause, clock skew, navigation error;
        with ``sensing``, also its sensing: a sensor fault) acts on ``uid`` at ``t``, or did
        until less than ``after_s`` ago. Checkers of what the planner does excuse such a UAV: a
        paused one flies its last command blind, one with a skewed clock is not heard (its
        stamps are in the others' future) or hears nobody, one with a navigation error plans
        from where it is not. They judge the planner, not the fault."""
        name = self.names.get(uid)
        return any((f.impairs_control or (sensing and f.impairs_sensing)) and f.acts_on(name, t, after_s)
                   for f in self.faults)

    def explaining(self, uids: Iterable[int], t0: float, t1: float) -> list[FaultKind]:
        """The faults that may explain something these UAVs did between ``t0`` and ``t1``: acting
        at some time from ``RECOVER_S`` before ``t0`` to ``t1`` (:meth:`FaultKind.span`) and
        concerning one of them or anyone (:meth:`FaultKind.concerns`: a node fault on one of
        them, a link fault on them or on everyone, a partition, a jammer, a spoofer, a liar)."""
        names = {self.names.get(u) for u in uids}
        lo = t0 - RECOVER_S
        out: list[FaultKind] = []
        for f in self.faults:
            when = f.span()
            if when[0] <= t1 + _EPS and when[1] >= lo - _EPS and f.concerns(names):
                out.append(f)
        return out

    def node_faults_disturb(self, t: float) -> bool:
        """Whether a fault keeps the maps from agreeing at ``t`` (:meth:`FaultKind.disturbs_maps`:
        a pause, the UAV merging nothing; a clock skew until its clock's lead is over)."""
        return any(f.disturbs_maps(t) for f in self.faults)

    def skewed(self) -> list[tuple[float, float]]:
        """:func:`skewed_stamps` of this run's faults so far (for :func:`owed_map`)."""
        return skewed_stamps(self.faults, self.scenario.duration_s)

    def link_faults_active(self, t: float) -> bool:
        """Whether a fault that disturbs links (loses, delays or forges copies) is active at ``t``."""
        return any(f.disturbs_links and f.span()[0] <= t < f.span()[1] for f in self.faults)

    def max_delay_s(self) -> float:
        r = self.scenario.radio
        extra = sum(f.max_extra_delay_s() for f in self.faults)
        return r.latency_s + r.jitter_s + extra

    def in_range(self, pa: Sequence[float], pb: Sequence[float]) -> bool:
        return math.hypot(pa[0] - pb[0], pa[1] - pb[1]) <= self.range_m + _EPS

    def can_talk(self, a: int, b: int, t: float, poses: Mapping[int, Sequence[float]]) -> bool:
        pa, pb = poses.get(a), poses.get(b)
        if pa is None or pb is None or not self.in_range(pa, pb):
            return False
        if self.jammed(pa, t) or self.jammed(pb, t):
            return False
        return not (self.blocked(a, b, t) or self.blocked(b, a, t))

    def connected(self, poses: Mapping[int, Sequence[float]]) -> bool:
        """Whether the flying UAVs form one radio component (ranges only)."""
        ids = sorted(poses)
        if len(ids) <= 1:
            return True
        if not math.isfinite(self.range_m):
            return True
        seen = {ids[0]}
        todo = [ids[0]]
        while todo:
            a = todo.pop()
            for b in ids:
                if b not in seen and self.in_range(poses[a], poses[b]):
                    seen.add(b)
                    todo.append(b)
        return len(seen) == len(ids)

    def hops(self, poses: Mapping[int, Sequence[float]]) -> int:
        """The diameter of the radio graph of the flying UAVs in hops (ranges only; 1 with an
        unlimited range, 0 with one UAV); the largest component's if it is not connected."""
        ids = sorted(poses)
        if len(ids) <= 1:
            return 0
        if not math.isfinite(self.range_m):
            return 1
        nbrs = {a: [b for b in ids if b != a and self.in_range(poses[a], poses[b])] for a in ids}
        longest = 0
        for a in ids:  # breadth-first from each (tests fly tens of UAVs)
            depth = {a: 0}
            frontier = [a]
            while frontier:
                nxt = []
                for u in frontier:
                    for v in nbrs[u]:
                        if v not in depth:
                            depth[v] = depth[u] + 1
                            nxt.append(v)
                frontier = nxt
            longest = max(longest, max(depth.values()))
        return longest

    def relay_lag_s(self, hops: int) -> float:
        """How late a scan may reach a UAV ``hops`` hops from where it was made: the first hop
        with the next beacon, each further hop one anti-entropy round (a digest every
        ``sync_every_s`` covering scans ``sync_settle_s`` old, answered the next tick)."""
        r = self.scenario.radio
        return (r.beacon_every_s + self.dt + r.sync_settle_s
                + max(0, hops - 1) * (r.sync_every_s + 2 * self.dt + self.max_delay_s()))


# --- checkers ------------------------------------------------------------------------------------


# A pose's mode when the UAV watches a target (poses carry mode names: swarm.events).
SURVEIL = MODE_NAMES[MODE_SURVEIL]


def _poses(events: Sequence[event_schema.Event]) -> dict[int, tuple]:
    """uid -> (x, y, v, theta, mode name, target) of the pose events in a group."""
    return {e.uav: (e.x, e.y, e.v, e.theta, e.mode, e.target) for e in events if isinstance(e, event_schema.Pose)}


class Checker(abc.ABC):
    """Base class: implement :meth:`on_group` (events of one instant, in log order) and, for
    liveness properties, override :meth:`finish` (end of the run)."""

    name = "checker"
    live_only = False  # True: needs the simulation (reads maps), cannot run on a log alone
    max_violations = 200  # keep memory bounded when something is badly wrong

    def __init__(self) -> None:
        self.violations: list[Violation] = []
        self.ctx: RunContext | None = None
        self.truncated = 0
        # Why this checker could not judge the run (None: it could): no violations then means
        # nothing, and Monitor.unchecked says so.
        self.unchecked: str | None = None

    def bind(self, ctx: RunContext) -> None:
        self.ctx = ctx

    @property
    def context(self) -> RunContext:
        """The run's context, which :meth:`bind` gives (a :class:`Monitor` binds its checkers
        before it feeds them any event)."""
        if self.ctx is None:
            raise UsageError(f"the {self.name!r} checker is not bound to a run: feed it through a Monitor "
                             "(or call bind(RunContext(scenario)) first)")
        return self.ctx

    def attach(self, sim: Any) -> None:  # noqa: B027  (an optional hook, empty by default)
        """Called once when a monitor attaches to a live simulation (after :meth:`bind`)."""

    @abc.abstractmethod
    def on_group(self, t: float, events: list[event_schema.Event]) -> None:
        """The events of one tick at time ``t``; every checker implements it."""

    def finish(self, t_end: float) -> None:  # noqa: B027  (an optional hook, empty by default)
        """The run ended at ``t_end`` (judge pending liveness obligations)."""

    def violate(self, t: float, message: str, uavs: Iterable[int] = (), target: int | None = None, **data: Any) -> None:
        if len(self.violations) >= self.max_violations:
            self.truncated += 1
            return
        uavs = list(uavs)
        names = tuple(self.ctx.name(u) for u in uavs) if self.ctx else tuple(str(u) for u in uavs)
        since = data.get("since", t)
        faults = self.ctx.explaining(uavs, float(since), float(t)) if self.ctx else []
        self.violations.append(Violation(self.name, float(t), message, names, target, dict(data),
                                         tuple(describe_fault(f) for f in faults)))

    def raise_if(self) -> None:
        if self.violations:
            raise InvariantViolation(self.violations)


class SeparationChecker(Checker):
    """No two flying UAVs closer than ``min_separation_m`` (default: the scenario's
    ``safety.min_separation_m``) through their own moves; one violation per episode."""

    name = "separation"

    def __init__(self, min_separation_m: float | None = None, excuse_node_faults: bool = True):
        super().__init__()
        self.min_separation_m = min_separation_m
        self.excuse_node_faults = excuse_node_faults  # False: judge impaired UAVs too (known failures)
        self._prev: set[int] = set()
        self._active: set[tuple[int, int]] = set()
        self._excused: set[tuple[int, int]] = set()

    def on_group(self, t, events):
        poses = _poses(events)
        if not poses:
            return
        d_min = self.min_separation_m if self.min_separation_m is not None else self.context.min_separation_m
        ids = sorted(poses)
        close: set[tuple[int, int]] = set()
        if len(ids) >= 2:
            xy = np.array([poses[u][:2] for u in ids], dtype=float)
            d = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
            for i, j in zip(*np.nonzero(np.triu(d < d_min, 1))):
                close.add((ids[int(i)], ids[int(j)]))
                pair = (ids[int(i)], ids[int(j)])
                if pair in self._active or pair in self._excused:
                    continue
                if pair[0] not in self._prev or pair[1] not in self._prev:
                    self._excused.add(pair)  # too close from the moment they were both flying
                    continue
                ctx = self.context
                if self.excuse_node_faults and (ctx.impaired(pair[0], t, after_s=RECOVER_S)
                                                or ctx.impaired(pair[1], t, after_s=RECOVER_S)):
                    self._excused.add(pair)  # a node fault's doing (until they are apart again)
                    continue
                self._active.add(pair)
                ctx = self.context
                self.violate(t, f"{ctx.name(pair[0])} and {ctx.name(pair[1])} are "
                                f"{float(d[i, j]):.1f} m apart (< {d_min:g} m)", pair, distance_m=float(d[i, j]))
        self._active &= close
        self._excused &= close
        self._prev = set(ids)


class ThreatClearanceChecker(Checker):
    """No flying UAV inside a threat circle through its own moves (a UAV that starts or joins
    inside one is excused until it is out)."""

    name = "threat"

    def __init__(self, excuse_node_faults: bool = True) -> None:
        super().__init__()
        self.excuse_node_faults = excuse_node_faults  # False: judge impaired UAVs too (known failures)
        self._prev: set[int] = set()
        self._active: set[tuple[int, int]] = set()
        self._excused: set[tuple[int, int]] = set()

    def on_group(self, t, events):
        poses = _poses(events)
        if not poses:
            return
        ctx = self.context
        inside: set[tuple[int, int]] = set()
        for uid, p in poses.items():
            for k, x, y, r in ctx.threats:
                d = math.hypot(p[0] - x, p[1] - y)
                if d >= r:
                    continue
                key = (uid, k)
                inside.add(key)
                if key in self._active or key in self._excused:
                    continue
                if uid not in self._prev or (self.excuse_node_faults and ctx.impaired(uid, t, after_s=RECOVER_S)):
                    self._excused.add(key)  # (a node fault's doing: excused until it is out)
                    continue
                self._active.add(key)
                self.violate(t, f"{ctx.name(uid)} is {r - d:.1f} m inside threat {k} (radius {r:g} m)",
                             [uid], threat=k, depth_m=r - d)
        self._active &= inside
        self._excused &= inside
        self._prev = set(poses)


class DynamicsChecker(Checker):
    """Consecutive poses (``t``, ``t + dt``) of each UAV respect its type's hard limits
    (``speed_min <= v <= speed_max``, ``|dv| <= accel_max dt``, ``|dtheta| <= g tan(bank)/v dt``
    at the larger of the two speeds) and the kinematics (eq. 9-10: the position follows from
    speed and heading). ``tol_m``: position tolerance; limits get a relative 1e-9."""

    name = "dynamics"

    def __init__(self, tol_m: float = 1e-6):
        super().__init__()
        self.tol_m = tol_m
        self._prev: dict[int, tuple] = {}

    def on_group(self, t, events):
        poses = _poses(events)
        if not poses:
            return
        ctx = self.context
        dt = ctx.dt
        for uid, p in poses.items():
            kind = ctx.kind(uid)
            prev = self._prev.get(uid)
            self._prev[uid] = (t, *p)
            if kind is None:
                continue
            x1, y1, v1, th1 = p[:4]
            rel = 1e-9
            if not (kind.speed_min * (1 - rel) - rel <= v1 <= kind.speed_max * (1 + rel) + rel):
                self.violate(t, f"speed {v1:.6g} m/s outside [{kind.speed_min:g}, {kind.speed_max:g}]", [uid], v=v1)
            if prev is None or abs(t - prev[0] - dt) > 1e-9 * max(1.0, t):
                continue
            _, x0, y0, v0, th0 = prev[:5]
            a = (v1 - v0) / dt
            if abs(a) > kind.accel_max * (1 + rel) + rel:
                self.violate(t, f"acceleration {a:.6g} m/s^2 beyond {kind.accel_max:g}", [uid], a=a)
            omega = wrap_angle(th1 - th0) / dt
            w_max = kind.turn_rate_max(max(v0, v1))
            if abs(omega) > w_max * (1 + rel) + rel:
                self.violate(t, f"turn rate {omega:.6g} rad/s beyond {w_max:.6g} (turn radius below r_min)",
                             [uid], omega=omega)
            px, py, _, _ = integrate(x0, y0, v0, th0, a, omega, dt)
            err = math.hypot(px - x1, py - y1)
            if err > self.tol_m + 1e-9 * (abs(x1) + abs(y1)):
                self.violate(t, f"moved {err:.3g} m away from where its speed and heading take it", [uid], error_m=err)


class RadioChecker(Checker):
    """The radio never delivers beyond range, across a partition, from a UAV that was not
    flying when it sent, or to a UAV that is not flying (see the module docstring).
    ``max_delay_s``: longest possible delivery delay (default: from scenario and faults)."""

    name = "radio"

    def __init__(self, max_delay_s: float | None = None):
        super().__init__()
        self.max_delay_s = max_delay_s
        self._history: deque[tuple[float, dict[int, tuple]]] = deque()
        # A paused UAV (the pause fault) reads its mailbox when it resumes: frames sent since
        # its pause began. uid -> (pause start, pauses open: they may overlap, each logs its own
        # pause and resume); after the last resume, uid -> (pause start, resume).
        self._paused: dict[int, tuple[float, int]] = {}
        self._resumed: dict[int, tuple[float, float]] = {}

    def on_group(self, t, events):
        if self.context.recording != "frames":
            self.unchecked = (f'the log has no per-frame events (recording level "{self.context.recording}"); '
                              'the radio invariant needs [recording] level = "frames"')
            return
        ctx = self.context
        dt = ctx.dt
        for e in events:
            if e.kind == "pause":
                start, open_ = self._paused.get(e.uav, (float(e.t), 0))
                self._paused[e.uav] = (start, open_ + 1)
            elif e.kind == "resume" and e.uav in self._paused:
                start, open_ = self._paused.pop(e.uav)
                if open_ > 1:
                    self._paused[e.uav] = (start, open_ - 1)  # another pause still holds it
                else:
                    self._resumed[e.uav] = (start, float(e.t))
            elif e.kind == "crash":
                self._paused.pop(e.uav, None)
        for uid in [u for u, (_, tr) in self._resumed.items() if t > tr + dt + _EPS]:
            del self._resumed[uid]  # it has read what it held (its first tick after the resume)
        poses = _poses(events)
        max_delay = self.max_delay_s if self.max_delay_s is not None else ctx.max_delay_s()
        if poses:
            self._history.append((t, poses))
            floor = min([t, *(s for s, _ in self._paused.values()), *(s for s, _ in self._resumed.values())])
            while self._history and self._history[0][0] < floor - dt - max_delay - dt - _EPS:
                self._history.popleft()
        rx = [e for e in events if e.kind == "rx"]
        if not rx:
            return
        for e in rx:
            src, dst = e.src, e.dst
            if src == SPOOF_SENDER:
                self._check_spoof(t, dst, poses, dt, max_delay)
                continue
            if dst not in poses:
                self.violate(t, f"{ctx.name(dst)} read a frame from {ctx.name(src)} while not flying",
                             [src, dst], cause="receiver_down")
                continue
            held = self._resumed.get(dst)
            oldest = (held[0] if held is not None else t) - dt - max_delay - _EPS
            reasons: list[str] = []
            legal = False
            for s, ps in reversed(self._history):  # latest candidate send tick first
                if s > t - dt + _EPS:
                    continue
                if s < oldest:
                    break
                why = self._illegal(src, dst, s, ps)
                if why is None:
                    legal = True
                    break
                reasons.append(f"at {s:g} s {why}")
            if not legal:
                detail = "; ".join(reasons) if reasons else "no tick it could have been sent in"
                self.violate(t, f"frame {ctx.name(src)} -> {ctx.name(dst)} delivered illegally: {detail}",
                             [src, dst], reasons=reasons)

    def _check_spoof(self, t: float, dst: int, poses: dict[int, tuple], dt: float, max_delay: float) -> None:
        """A spoofer's frame (sender -1) is legal only at a receiver that is flying when it reads
        it and was within an active spoofer's ``range_m`` at a possible send tick (for one just
        resumed from a pause, back to the pause's start, as for members' frames)."""
        ctx = self.context
        if dst not in poses:
            self.violate(t, f"{ctx.name(dst)} read a spoofed frame while not flying", [dst], cause="receiver_down")
            return
        held = self._resumed.get(dst)  # a UAV resuming from a pause reads what its mailbox held
        oldest = (held[0] if held is not None else t) - dt - max_delay - _EPS
        for s, ps in reversed(self._history):
            if s > t - dt + _EPS:
                continue
            if s < oldest:
                break
            pd = ps.get(dst)
            if pd is not None and ctx.spoofed(pd, s):
                return
        self.violate(t, f"{ctx.name(dst)} read a frame from a non-member (sender {SPOOF_SENDER}) with no active "
                        "spoofer in range", [dst], cause="spoof")

    def _illegal(self, src: int, dst: int, s: float, poses: dict[int, tuple]) -> str | None:
        ps, pd = poses.get(src), poses.get(dst)
        if ps is None:
            return "the sender was not flying"
        if pd is None:
            return "the receiver was not flying"
        d = math.hypot(ps[0] - pd[0], ps[1] - pd[1])
        ctx = self.context
        if d > ctx.range_m + _EPS:
            return f"they were {d:.0f} m apart (range {ctx.range_m:g} m)"
        if ctx.blocked(src, dst, s):
            return "a partition, bridge or swizzle separated them"
        return None


class _LiveChecker(Checker):
    live_only = True
    _centres: tuple[np.ndarray, np.ndarray] | None = None  # cell centres (x, y), made on first use

    def _horizon_reach(self, window_s: float) -> float:
        """With a knowledge horizon ``H``: ``H`` less the largest detection radius and the farthest
        a UAV flies in ``window_s``; a cell that close to a UAV throughout the window had every
        scan of it inside the UAV's horizon. ``inf`` without a horizon."""
        sc = self.context.scenario
        slack = (max(s.detect_radius_m for s in sc.uav_types.values())
                 + max(s.speed_max for s in sc.uav_types.values()) * window_s)
        return sc.radio.horizon_m - slack

    def _near(self, pose: Sequence[float], reach: float) -> np.ndarray:
        """The cells whose centres lie within ``reach`` of ``pose`` (a boolean (ny, nx) mask)."""
        if reach <= 0:
            g = self._sim().grid
            return np.zeros((g.ny, g.nx), dtype=bool)
        if self._centres is None:
            g = self._sim().grid
            self._centres = (((np.arange(g.nx) + 0.5) * g.cell_m)[None, :], ((np.arange(g.ny) + 0.5) * g.cell_m)[:, None])
        cx, cy = self._centres
        return (cx - pose[0]) ** 2 + (cy - pose[1]) ** 2 <= reach * reach

    def _sim(self):
        if self.ctx is None or self.ctx.sim is None:
            raise UsageError(f"the {self.name!r} checker reads the UAVs' maps: attach it to a live Simulation "
                             "(Monitor(...).attach(sim)), it cannot check an event log alone")
        return self.ctx.sim

    def _maps(self, uids: Iterable[int]) -> dict[int, np.ndarray]:
        sim = self._sim()
        ctx = self.context
        return {u: sim.uav_map(ctx.name(u)) for u in uids}

    def _radio_lossy(self) -> bool:
        """A radio that loses frames by itself: anti-entropy converges, but in no bounded time.
        Also true in a tick in which a full mailbox dropped a frame copy (a small
        ``mailbox_capacity`` loses frames of a lossless radio the same way)."""
        r = self.context.scenario.radio
        return (r.loss_base > 0 or r.effective_loss_at_range > 0 or r.model != "disk"
                or r.bandwidth_bytes_per_s is not None or self._overflowed)

    _overflowed = False  # a mailbox dropped a frame since the previous tick (_note_overflow)
    _full_drops = 0

    def _note_overflow(self) -> None:
        """Called once per tick: whether a full mailbox dropped a frame copy since the last call."""
        n = self._sim().radio.counters.dropped.get("mailbox_full", 0)
        self._overflowed, self._full_drops = n > self._full_drops, n


class MapMonotonicityChecker(_LiveChecker):
    """A UAV's map never forgets: no cell's last-seen time decreases between two ticks."""

    name = "map_monotonic"

    def __init__(self) -> None:
        super().__init__()
        self._last: dict[int, np.ndarray] = {}
        self._actor: dict[int, object] = {}

    def attach(self, sim):
        self._snapshot(None)

    def _snapshot(self, t: float | None) -> None:
        sim = self._sim()
        for uid, b in sorted(sim.world.uavs.items()):
            if b.state == "crashed" and uid in self._last:
                continue  # a crashed UAV's map no longer changes
            cur = sim.uav_map(b.name)
            if self._actor.get(uid, sim.actors[uid]) is not sim.actors[uid]:
                self._last.pop(uid, None)  # restarted (a fresh actor): a new map, empty at first
            self._actor[uid] = sim.actors[uid]
            prev = self._last.get(uid)
            if prev is not None and t is not None:
                dec = cur < prev
                if dec.any():
                    iy, ix = (int(v[0]) for v in np.nonzero(dec))
                    self.violate(t, f"{b.name}'s map forgot {int(dec.sum())} cell(s), e.g. cell (ix={ix}, iy={iy}) "
                                    f"went from {float(prev[iy, ix]):g} to {float(cur[iy, ix]):g}",
                                 [uid], cells=int(dec.sum()), cell=(ix, iy))
            self._last[uid] = cur

    def on_group(self, t, events):
        if any(e.kind == "pose" for e in events):
            self._snapshot(t)


class MapAgreementChecker(_LiveChecker):
    """Liveness of the map CRDT: after ``quiet_s`` seconds in which the flying UAVs form one
    radio component, no link fault or partition is active and nobody crashes or joins, every
    flying UAV knows (last-seen >=) every cell any flying UAV knew ``lag_s`` seconds before;
    at most a ``tolerance`` fraction of cells may lag. Checked every ``every_s`` while quiet.
    A lossy or bandwidth-limited radio never counts as quiet unless ``allow_radio_loss``."""

    name = "map_agreement"

    def __init__(self, quiet_s: float = 20.0, lag_s: float = 10.0, tolerance: float = 0.0, every_s: float = 10.0,
                 allow_radio_loss: bool = False):
        super().__init__()
        self.quiet_s, self.lag_s, self.tolerance, self.every_s = quiet_s, lag_s, tolerance, every_s
        self.allow_radio_loss = allow_radio_loss
        self._poses: dict[int, tuple] = {}  # this tick's (for the horizon's centres)
        self._quiet_since: float | None = None
        self._members: frozenset[int] = frozenset()
        self._history: deque[tuple[float, dict[int, np.ndarray]]] = deque()
        self._last_check = -math.inf
        self._reported_window: float | None = None
        self._hops = 0  # the radio graph's largest diameter (hops) since the quiet began
        self.checks = 0  # how many times agreement was judged (a test can assert it was)

    def on_group(self, t, events):
        poses = _poses(events)
        if not poses:
            return
        self._note_overflow()
        ctx = self.context
        members = frozenset(poses)
        quiet_now = (members == self._members and not any(e.kind in ("crash", "join", "restart") for e in events)
                     and not ctx.link_faults_active(t) and not ctx.node_faults_disturb(t) and ctx.connected(poses)
                     and (self.allow_radio_loss or not self._radio_lossy()))
        if not quiet_now:
            self._quiet_since = None
        elif self._quiet_since is None:
            self._quiet_since = t
        self._members = members
        self._poses = poses
        # Scans from several hops away come round by anti-entropy, one round a hop: the lag
        # allowed grows with the radio graph's diameter over the quiet window.
        if self._quiet_since is None or self._quiet_since == t:
            self._hops = 0
        if self._quiet_since is not None:  # (history before the quiet began is never judged)
            self._hops = max(self._hops, ctx.hops(poses))
        lag = max(self.lag_s, ctx.relay_lag_s(self._hops))
        self._history.append((t, self._maps(members)))
        while self._history and self._history[0][0] < t - lag - _EPS:
            self._history.popleft()
        if self._quiet_since is None or t - self._quiet_since < self.quiet_s + (lag - self.lag_s) - _EPS:
            return
        if t - self._last_check < self.every_s - _EPS or self._reported_window == self._quiet_since:
            return
        self._last_check = t
        then_t, then = self._history[0]
        if then_t > t - lag + _EPS:
            return
        self.checks += 1
        now = self._history[-1][1]
        skewed = ctx.skewed()
        then = {u: owed_map(m, skewed) for u, m in then.items()}  # what each owes the others
        if not math.isinf(ctx.scenario.radio.horizon_m):
            self._judge_local(t, then_t, then, now, members)
            return
        known = np.maximum.reduce([m for u, m in then.items() if u in members]) if then else None
        if known is None:
            return
        for uid in sorted(members):
            behind = now[uid] < known
            frac = float(behind.mean())
            if frac > self.tolerance:
                iy, ix = (int(v[0]) for v in np.nonzero(behind))
                who = [u for u in sorted(members) if u in then and then[u][iy, ix] == known[iy, ix]]
                self.violate(t, f"after {t - self._quiet_since:g} s connected and fault-free, {ctx.name(uid)} "
                                f"still misses {int(behind.sum())} cell(s) ({frac:.1%}) that "
                                f"{', '.join(ctx.name(u) for u in who)} knew at {then_t:g} s, e.g. cell "
                                f"(ix={ix}, iy={iy}): {float(now[uid][iy, ix]):g} < {float(known[iy, ix]):g}",
                             [uid, *who[:1]], cells=int(behind.sum()), fraction=frac, quiet_since=self._quiet_since)
                self._reported_window = self._quiet_since

    def _judge_local(self, t: float, then_t: float, then: dict[int, np.ndarray], now: dict[int, np.ndarray],
                     members: frozenset[int]) -> None:
        """Agreement under a knowledge horizon (see the module docstring): pairs that can talk,
        cells within ``H - slack`` of both UAVs now."""
        ctx = self.context
        reach = self._horizon_reach(self.lag_s)
        if reach <= 0:
            return  # no cell is surely inside both horizons: nothing to judge
        poses = self._poses
        since = self._quiet_since if self._quiet_since is not None else t
        inside = {u: self._near(poses[u], reach) for u in members}
        for uid in sorted(members):
            behind = np.zeros(now[uid].shape, dtype=bool)
            who: list[int] = []
            for v in sorted(members):
                if v == uid or v not in then or not ctx.can_talk(uid, v, t, poses):
                    continue
                lag = (now[uid] < then[v]) & inside[uid] & inside[v]
                if lag.any():
                    who.append(v)
                    behind |= lag
            frac = float(behind.mean())
            if frac > self.tolerance:
                iy, ix = (int(v[0]) for v in np.nonzero(behind))
                self.violate(t, f"after {t - since:g} s connected and fault-free, {ctx.name(uid)} "
                                f"still misses {int(behind.sum())} cell(s) ({frac:.1%}) within its and its "
                                f"neighbours' horizon ({reach:g} m) that {', '.join(ctx.name(u) for u in who)} "
                                f"knew at {then_t:g} s, e.g. cell (ix={ix}, iy={iy})",
                             [uid, *who[:1]], cells=int(behind.sum()), fraction=frac, quiet_since=self._quiet_since)
                self._reported_window = self._quiet_since


class JoinerCatchUpChecker(_LiveChecker):
    """Liveness for late joiners: within ``bound_s`` of joining, a UAV knows (last-seen >=) every
    cell its radio neighbours at join time knew then (``tolerance``: fraction allowed to lag).
    Judged only if, all along, it could talk to one of those neighbours and no link fault or
    partition was active, and on a radio that loses nothing by itself (as map agreement):
    otherwise the obligation lapses. With a knowledge horizon only the cells within ``H - slack``
    of the joiner are owed (``slack``: the largest detection radius plus the farthest it flies in
    ``bound_s``; see MapAgreementChecker)."""

    name = "joiner_catch_up"

    def __init__(self, bound_s: float = 20.0, tolerance: float = 0.0):
        super().__init__()
        self.bound_s, self.tolerance = bound_s, tolerance
        self._pending: dict[int, tuple[float, np.ndarray, tuple[int, ...]]] = {}
        self.checks = 0

    def on_group(self, t, events):
        sim = self._sim()
        ctx = self.context
        poses = _poses(events)
        for e in events:
            if (e.kind == "join" and e.t > 0) or e.kind == "restart":  # a restarted UAV rejoins empty
                uid = e.uav
                j = sim.world.uavs[uid]
                nbrs = tuple(u for u, b in sorted(sim.world.uavs.items())
                             if u != uid and b.state == "alive"
                             and ctx.in_range((b.x, b.y), (j.x, j.y)))
                if nbrs:
                    maps = self._maps(nbrs)
                    skewed = ctx.skewed()
                    self._pending[uid] = (float(e.t), np.maximum.reduce([owed_map(m, skewed) for m in maps.values()]), nbrs)
        if not poses:
            return
        self._note_overflow()
        for uid, (t_join, target, nbrs) in list(self._pending.items()):
            if (uid not in poses or ctx.link_faults_active(t) or ctx.node_faults_disturb(t) or self._radio_lossy()
                    or not any(ctx.can_talk(uid, n, t, poses) for n in nbrs)):
                if t > t_join + _EPS:  # the join tick itself precedes the joiner's first pose
                    del self._pending[uid]
                continue
            behind = self._maps([uid])[uid] < target
            if not math.isinf(ctx.scenario.radio.horizon_m):  # only what its horizon holds is owed
                behind &= self._near(poses[uid], self._horizon_reach(self.bound_s))
            frac = float(behind.mean())
            if frac <= self.tolerance:
                del self._pending[uid]
                self.checks += 1
            elif t >= t_join + self.bound_s - _EPS:
                del self._pending[uid]
                self.checks += 1
                self.violate(t, f"{ctx.name(uid)} joined at {t_join:g} s and {t - t_join:g} s later still misses "
                                f"{int(behind.sum())} cell(s) ({frac:.1%}) that its neighbours "
                                f"{', '.join(ctx.name(n) for n in nbrs)} knew when it joined",
                             [uid, *nbrs], cells=int(behind.sum()), fraction=frac, joined=t_join)


# The assignment checkers excuse a UAV whose control or sensing a fault impairs
# (RunContext.impaired); the safety checkers excuse one whose control is impaired also for
# RECOVER_S after the fault: a UAV that resumes, or learns where it really is, heading into a
# threat or another UAV at full speed needs a turn or two to get out; a U-turn of the paper's
# fast type takes about 20 s.
RECOVER_S = 30.0


class _WatchChecker(Checker):
    """Helpers for the assignment invariants: watchers per target from the pose events."""

    _targets: dict[int, tuple[float, float]]  # target -> last logged (x, y), kept by the subclasses that need it
    _seen: dict[int, tuple[float, float, float]]  # target -> last (t, x, y) inside some UAV's sensor (_sightings)

    @staticmethod
    def watchers(poses: dict[int, tuple]) -> dict[int, set[int]]:
        out: dict[int, set[int]] = {}
        for uid, p in poses.items():
            # (A phantom target, a false alarm's or a liar's, is not a target: nothing to judge.)
            if p[4] == SURVEIL and 0 <= p[5] < PHANTOM_TARGET_ID:
                out.setdefault(int(p[5]), set()).add(uid)
        return out

    def excused(self, uid: int, t: float) -> bool:
        """A UAV under a node or sensing fault (RunContext.impaired) is not judged."""
        return self.context.impaired(uid, t, sensing=True)

    def _track_life(self) -> float:
        sc = self.context.scenario
        life = sc.planner.dacmp.track_max_age_s
        return float(life) if life is not None else 1.0 / sc.effective_tau

    def _sightings(self, t: float, poses: dict[int, tuple]) -> None:
        """Note every target some UAV has inside its detection radius at ``t`` (``_seen``)."""
        ctx = self.context
        for m, (x, y) in self._targets.items():
            for uid, p in poses.items():
                k = ctx.kind(uid)
                if k is not None and math.hypot(p[0] - x, p[1] - y) <= k.detect_radius:
                    self._seen[m] = (t, x, y)
                    break

    def _holds(self, uid: int, m: int, poses: dict[int, tuple]) -> bool:
        """Whether ``uid`` has target ``m`` (at its last logged position) inside its detection radius."""
        k, pos = self.context.kind(uid), self._targets.get(m)
        return (k is not None and pos is not None and uid in poses
                and math.hypot(poses[uid][0] - pos[0], poses[uid][1] - pos[1]) <= k.detect_radius)


class SingleWatcherChecker(_WatchChecker):
    """At most one UAV per type keeps a target once the handover settles: two same-type UAVs
    that can talk both watching one target for longer than ``settle_s`` is a violation."""

    name = "single_watcher"

    def __init__(self, settle_s: float = 30.0):
        super().__init__()
        self.settle_s = settle_s
        self._since: dict[tuple[int, int, int], float] = {}
        self._reported: set[tuple[int, int, int]] = set()

    def on_group(self, t, events):
        poses = _poses(events)
        if not poses:
            return
        ctx = self.context
        now: set[tuple[int, int, int]] = set()
        for m, watching in sorted(self.watchers(poses).items()):
            ws = sorted(watching)
            for i, a in enumerate(ws):
                for b in ws[i + 1:]:
                    ta, tb = ctx.type_name.get(a), ctx.type_name.get(b)
                    if ta is None or ta != tb or not ctx.exclusion_judged(a):
                        continue
                    if not ctx.can_talk(a, b, t, poses) or self.excused(a, t) or self.excused(b, t):
                        continue
                    key = (m, a, b)
                    now.add(key)
                    since = self._since.setdefault(key, t)
                    if t - since > self.settle_s + _EPS and key not in self._reported:
                        self._reported.add(key)
                        self.violate(t, f"{ctx.name(a)} and {ctx.name(b)} (both type "
                                        f"{ctx.type_name.get(a)}) have both watched target {m} for "
                                        f"{t - since:g} s while able to talk (settle time {self.settle_s:g} s)",
                                     [a, b], target=m, since=since)
        for key in list(self._since):
            if key not in now:
                del self._since[key]
                self._reported.discard(key)


class HandoverChecker(_WatchChecker):
    """Fast-to-slow handover (DACMP eq. 25-26) as observable obligations (see the module
    docstring): ``takeover_s`` for the slow UAV to start watching, ``release_s`` for the fast
    one to stop; with ``require_search`` the fast one must then be searching, not watching."""

    name = "handover"

    def __init__(self, takeover_s: float = 60.0, release_s: float = 60.0, require_search: bool = True,
                 settle_s: float = 30.0):
        super().__init__()
        self.takeover_s, self.release_s, self.require_search = takeover_s, release_s, require_search
        self.settle_s = settle_s
        # (released fast UAV, target it went on to) -> (since, target released, to whom)
        self._joined: dict[tuple[int, int], tuple[float, int, int]] = {}
        self._offer: dict[tuple[int, int], float] = {}  # (target, fast watcher) -> since
        self._overlap: dict[tuple[int, int, int], float] = {}  # (target, fast, slow) -> since
        self._reported: set[tuple] = set()
        self._prev_watchers: dict[int, set[int]] = {}
        self._targets: dict[int, tuple[float, float]] = {}
        self._seen: dict[int, tuple[float, float, float]] = {}
        #: Every (target, faster watcher) pair that was offered a takeover at some time: a free
        #: slower UAV within its D (rule 2), or one that already watches the target too.
        self.opportunities: set[tuple[int, int]] = set()

    def on_group(self, t, events):
        for e in events:
            if isinstance(e, event_schema.Target):
                self._targets[e.target] = (e.x, e.y)
        poses = _poses(events)
        if not poses:
            return
        self._sightings(t, poses)
        ctx = self.context
        watchers = self.watchers(poses)
        offers: set[tuple[int, int]] = set()
        overlaps: set[tuple[int, int, int]] = set()
        for m, ws in sorted(watchers.items()):
            pos = self._targets.get(m)
            for f in sorted(ws):
                kf = ctx.kind(f)
                if kf is None or self.excused(f, t):
                    continue
                slower = [(s, k_s) for s in ws if s != f and (k_s := ctx.kind(s)) is not None and k_s.speed_max < kf.speed_max
                          and ctx.handover_judged(s, f)]
                slower_watching = [s for s, _ in slower]
                # The release clock starts when the slower UAV has arrived (watches the target
                # from within its detection radius), as the handover metric counts it: a slow
                # UAV declaring a target from 10 km away has not taken it over yet.
                arrived = [s for s, k_s in slower if pos is not None and not self.excused(s, t)
                           and math.hypot(poses[s][0] - pos[0], poses[s][1] - pos[1]) <= k_s.detect_radius]
                for s in arrived:
                    if ctx.can_talk(f, s, t, poses):
                        key = (m, f, s)
                        overlaps.add(key)
                        since = self._overlap.setdefault(key, t)
                        if t - since > self.release_s + _EPS and ("release", key) not in self._reported:
                            self._reported.add(("release", key))
                            self.violate(t, f"fast {ctx.name(f)} kept watching target {m} for {t - since:g} s after "
                                            f"slower {ctx.name(s)} took it over (release bound {self.release_s:g} s)",
                                         [f, s], target=m, since=since, rule=3)
                if slower_watching:  # an opportunity taken already (a slower UAV claimed it)
                    self.opportunities.add((m, f))
                # Nobody knows where it is (kept from a no-fly zone's edge, unseen for the track
                # lifetime: rule 5): no slower UAV can be drawn to it, so no takeover is owed.
                seen = self._seen.get(m)
                if slower_watching or pos is None or seen is None or t - seen[0] > self._track_life() + _EPS:
                    continue
                free = [s for s, p in sorted(poses.items())
                        if s != f and p[4] != SURVEIL and not self.excused(s, t) and (k_s := ctx.kind(s)) is not None
                        and k_s.speed_max < kf.speed_max and ctx.handover_judged(s, f)
                        and math.hypot(p[0] - pos[0], p[1] - pos[1]) < k_s.influence_radius
                        and ctx.can_talk(f, s, t, poses)]
                if not free:
                    continue
                key2 = (m, f)
                offers.add(key2)
                self.opportunities.add(key2)
                since = self._offer.setdefault(key2, t)
                if t - since > self.takeover_s + _EPS and ("takeover", key2, since) not in self._reported:
                    self._reported.add(("takeover", key2, since))
                    self.violate(t, f"target {m} watched by fast {ctx.name(f)}: free slower "
                                    f"{', '.join(ctx.name(s) for s in free)} within its influence radius and able to "
                                    f"talk for {t - since:g} s, but none took over (bound {self.takeover_s:g} s)",
                                 [f, *free], target=m, since=since, rule=2)
        # The fast watcher that lets go after a takeover returns to search, or watches a target
        # that nobody else it can talk to holds (one it has found meanwhile, say); one another
        # holds it must leave within the settle time (two UAVs deciding at the same tick cannot
        # know of each other's choice: as for single_watcher).
        if self.require_search:
            for m, prev in self._prev_watchers.items():
                for f in prev:
                    if f in watchers.get(m, ()) or f not in poses or self.excused(f, t):
                        continue
                    took = [s for s in watchers.get(m, ()) if (k_s := ctx.kind(s)) is not None
                            and (k_f := ctx.kind(f)) is not None and k_s.speed_max < k_f.speed_max
                            and ctx.handover_judged(s, f)]
                    now = int(poses[f][5])
                    if took and poses[f][4] == SURVEIL and 0 <= now < PHANTOM_TARGET_ID:
                        self._joined.setdefault((f, now), (t, m, took[0]))
            for (f, now), (since, m, to) in list(self._joined.items()):
                others = self._holders_besides(f, now, t, poses, watchers)
                if not others or f not in watchers.get(now, ()) or self.excused(f, t):
                    del self._joined[(f, now)]
                elif t - since > self.settle_s + _EPS:
                    del self._joined[(f, now)]
                    self.violate(t, f"fast {ctx.name(f)} released target {m} to {ctx.name(to)} but went on to watch "
                                    f"target {now}, which {', '.join(ctx.name(w) for w in others)} holds, for "
                                    f"{t - since:g} s (settle time {self.settle_s:g} s), instead of searching or "
                                    f"watching a target nobody it can talk to holds",
                                 [f, to, *others], target=m, now_watching=now, since=since, rule=4)
        self._offer = {k: v for k, v in self._offer.items() if k in offers}
        self._overlap = {k: v for k, v in self._overlap.items() if k in overlaps}
        self._prev_watchers = {m: set(ws) for m, ws in watchers.items()}


    def _holders_besides(self, f: int, m: int, t: float, poses: dict[int, tuple],
                         watchers: dict[int, set[int]]) -> list[int]:
        """The UAVs other than ``f`` that hold ``m`` and that ``f`` can talk to, but for one of a
        faster type ``f`` takes targets over from (that is rule 2, not a breach of rule 4)."""
        ctx = self.context
        return sorted(w for w in watchers.get(m, ()) if w != f and ctx.can_talk(f, w, t, poses)
                      and self._holds(w, m, poses) and not ctx.handover_judged(f, w))


class NoDropChecker(_WatchChecker):
    """Rule 5 of docs/modelling.md, "Assignment rules": a watched target is not dropped while its
    watcher is flying and not impaired, once the watcher has held it (had it inside its
    detection radius since it began watching it): if it stops watching it, someone must be
    watching it within ``grace_s`` (a watcher that crashed is excused), unless the target is
    *lost*: no flying UAV has had it inside its detection radius for the track lifetime
    (``planner.dacmp.track_max_age_s``, default ``1 / tau``) and it was last seen farther than the
    watcher's detection radius from every no-fly zone (a target inside one, or that near one, is
    kept, not lost)."""

    name = "no_drop"

    def __init__(self, grace_s: float = 10.0):
        super().__init__()
        self.grace_s = grace_s
        self._prev: dict[int, set[int]] = {}
        self._pending: dict[int, tuple[float, int, float]] = {}  # target -> (dropped at, by, last seen then)
        self._targets: dict[int, tuple[float, float]] = {}
        self._seen: dict[int, tuple[float, float, float]] = {}  # target -> last (t, x, y) inside a sensor
        self._held: dict[int, set[int]] = {}  # target -> watchers that have held it since they began watching it

    def _lost(self, m: int, t: float, watcher: int) -> bool:
        """Nobody has seen ``m`` for the track lifetime, and it was last seen farther than the
        watcher's detection radius from every no-fly zone (nearer, the watcher kept outside may
        lose a target it could otherwise follow: it keeps it, rule 5)."""
        seen = self._seen.get(m)
        if seen is None:
            return True
        t_seen, x, y = seen
        k = self.context.kind(watcher)
        reach = k.detect_radius if k is not None else 0.0
        near = any(math.hypot(x - cx, y - cy) < r + reach for _, cx, cy, r in self.context.threats)
        return t - t_seen > self._track_life() - _EPS and not near

    def on_group(self, t, events):
        for e in events:
            if isinstance(e, event_schema.Target):
                self._targets[e.target] = (e.x, e.y)
        poses = _poses(events)
        if not poses:
            return
        self._sightings(t, poses)
        watchers = self.watchers(poses)
        held = {m: {w for w in self._held.get(m, ()) if w in ws} | {w for w in ws if self._holds(w, m, poses)}
                for m, ws in watchers.items()}
        for m in [m for m in self._pending if watchers.get(m)]:
            del self._pending[m]
        for m, (t0, w, seen) in list(self._pending.items()):
            if t - t0 > self.grace_s + _EPS:
                del self._pending[m]
                self.violate(t0, f"{self.context.name(w)} stopped watching target {m} while flying and nobody watched it "
                                 f"within {self.grace_s:g} s (not lost: seen {t0 - seen:g} s before, or last seen "
                                 f"inside a no-fly zone)", [w], target=m, now=poses.get(w, (None,) * 6)[4:6])
        for m, prev in self._prev.items():
            if watchers.get(m) or m in self._pending:
                continue
            # Only a watcher that has held the target: one still on its way may turn to another.
            alive = sorted(w for w in prev if w in self._held.get(m, ()) and w in poses and not self.excused(w, t)
                           and self.context.watch_judged(w) and not self._lost(m, t, w))
            if alive:
                self._pending[m] = (t, alive[0], self._seen[m][0] if m in self._seen else -math.inf)
        self._prev = watchers
        self._held = held

    def finish(self, t_end):
        self._pending.clear()  # not enough time left to judge


# --- running checkers ------------------------------------------------------------------------------


class Monitor:
    """Feeds events, grouped by instant, to a set of checkers; from a log (:meth:`feed` each
    event, then :meth:`finish`) or live (:meth:`attach` to a simulation, :meth:`flush` after
    each ``step``)."""

    def __init__(self, checkers: Iterable[Checker], scenario: Scenario | None = None, *,
                 faults: Iterable[FaultKind] | None = None):
        self.checkers = list(checkers)
        self.scenario = scenario
        self._faults = faults
        self.ctx: RunContext | None = RunContext(scenario, faults=faults) if scenario is not None else None
        if self.ctx is not None:
            for c in self.checkers:
                c.bind(self.ctx)
        self._t: float | None = None
        self._group: list[event_schema.Event] = []
        self._decode = event_schema.Decoder()  # (for events given as the log's arrays)
        self._unsubscribe = None
        self.t_end = 0.0
        self.events = 0

    def attach(self, sim: Any) -> Monitor:
        """Check ``sim`` live from now on (subscribes to its events)."""
        self.scenario = sim.scenario
        self.ctx = RunContext(sim.scenario, sim=sim, faults=self._faults)
        for c in self.checkers:
            c.bind(self.ctx)
        for c in self.checkers:
            c.attach(sim)
        self._unsubscribe = sim.subscribe(self.feed)
        return self

    def detach(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None

    def feed(self, ev: event_schema.Event | Sequence[Any]) -> None:
        """One event: a record of :mod:`swarm.events`, or an array as the log holds it
        (``[kind, t, ...]``: decoded here, so a hand-written log can be checked)."""
        if self.ctx is None:
            raise UsageError("Monitor needs the run's scenario: Monitor(checkers, scenario) or .attach(sim)")
        if not isinstance(ev, event_schema.Event):
            ev = self._decode(ev)
        self.events += 1
        self.ctx.on_event(ev)
        if ev.kind == "start":
            return
        t = float(ev.t)
        if self._t is not None and t != self._t:
            self.flush()
        self._t = t
        self._group.append(ev)

    def flush(self) -> None:
        """Hand the buffered events (one instant) to the checkers."""
        t, group = self._t, self._group
        if not group or t is None:  # t is set whenever there is a group (see feed)
            return
        self._group = []
        self.t_end = max(self.t_end, t)
        for c in self.checkers:
            c.on_group(t, group)

    def finish(self) -> list[Violation]:
        self.flush()
        for c in self.checkers:
            c.finish(self.t_end)
        return self.violations

    @property
    def violations(self) -> list[Violation]:
        out = [v for c in self.checkers for v in c.violations]
        return sorted(out, key=lambda v: (v.t, v.invariant))

    def raise_if(self) -> None:
        if self.violations:
            raise InvariantViolation(self.violations)

    @property
    def unchecked(self) -> dict[str, str]:
        """Checkers that could not judge the run, with why (e.g. ``radio`` on a summary log)."""
        return {c.name: c.unchecked for c in self.checkers if c.unchecked is not None}

    def by_name(self, name: str) -> Checker:
        for c in self.checkers:
            if c.name == name:
                return c
        raise KeyError(name)


def safety_checkers() -> list[Checker]:
    """Separation, threat clearance and dynamic limits: hold for any planner."""
    return [SeparationChecker(), ThreatClearanceChecker(), DynamicsChecker()]


def handover_checkers(settle_s: float = 30.0, takeover_s: float = 60.0, release_s: float = 60.0,
                      grace_s: float = 10.0) -> list[Checker]:
    """The DACMP assignment invariants (planner-specific)."""
    return [SingleWatcherChecker(settle_s), HandoverChecker(takeover_s, release_s, settle_s=settle_s), NoDropChecker(grace_s)]


def default_checkers(*, live: bool = False, handover: bool = False, liveness: bool = False) -> list[Checker]:
    """Checkers that hold for any planner: safety, dynamics, radio; with ``live`` also map
    monotonicity; with ``liveness`` (live only) map agreement and joiner catch-up; with
    ``handover`` the DACMP assignment invariants."""
    out: list[Checker] = [*safety_checkers(), RadioChecker()]
    if live:
        out.append(MapMonotonicityChecker())
        if liveness:
            out += [MapAgreementChecker(), JoinerCatchUpChecker()]
    if handover:
        out += handover_checkers()
    return out


def check_events(events: Iterable[event_schema.Event | Sequence[Any]] | bytes, scenario: Scenario,
                 checkers: Iterable[Checker] | None = None, *, faults: Iterable[FaultKind] | None = None) -> list[Violation]:
    """Run ``checkers`` over a run's events: records (:func:`swarm.events.read_events`), arrays
    as the log holds them, or the event log's bytes as ``RunResult.events`` and
    ``events.msgpack`` hold them. Returns the violations (empty: all
    invariants held).

    By default, every checker a log can judge, with its default parameters:
    ``default_checkers(handover=True)``, that is ``separation``, ``threat``, ``dynamics``,
    ``radio``, ``single_watcher``, ``handover`` and ``no_drop``. (The live checkers,
    ``map_monotonic``, ``map_agreement`` and ``joiner_catch_up``, read the UAVs' maps and
    need :class:`Monitor` attached to a simulation.) The last three are the assignment
    invariants of the surveillance handover (DACMP's, which the built-in planners share); for
    a planner of your own that watches targets by other rules, pass
    ``checkers=default_checkers()``: the first four."""
    if isinstance(events, (bytes, bytearray, memoryview)):
        events = event_schema.read_events(bytes(events))
    checkers = list(checkers) if checkers is not None else default_checkers(handover=True)
    live = [c.name for c in checkers if c.live_only]
    if live:
        raise UsageError(f"checker(s) {live} need a live simulation; use Monitor(...).attach(sim)")
    monitor = Monitor(checkers, scenario, faults=faults)
    for ev in events:
        monitor.feed(ev)
    return monitor.finish()


def load_run_log(out_dir: str | Path, *, allow_planner_imports: bool | Iterable[str] = False
                 ) -> tuple[Scenario, list[event_schema.Event]]:
    """The validated scenario (``scenario.json``) and the events (``events.msgpack``) of a
    ``swarm run --out`` folder (read by :func:`swarm.outputs.read_run_dir`). A run folder is data:
    a ``module:Class`` planner in its ``scenario.json`` is refused unless allowed here
    (``True``, or its name; :mod:`swarm.scenario.trust`)."""
    run = read_run_dir(out_dir)
    scenario = parse_scenario(run.scenario, str(run.path / "scenario.json"), truncated=True,  # may be cut short
                              allow_planner_imports=allow_planner_imports)
    return scenario, list(event_schema.read_events(run.events))
