"""What the checkers know about a run besides its events (:class:`RunContext`: the scenario,
the UAVs, the faults and the excuses the fault kinds grant), and what they report
(:class:`Violation`)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import swarm.events as event_schema
from agents.assignment import exclusion_break, handover_break, watch_break
from agents.types import UavType
from faults.base import FaultKind
from faults.registry import fault_from_dict, fault_to_dict
from faults.sensing import skewed_stamps
from swarm.errors import SwarmError
from swarm.kernel.rng import RngTree
from swarm.scenario import Scenario

EPS = 1e-6  # (s, m: slack for floating-point comparisons of times and distances)


# --- what a checker reports --------------------------------------------------------------------


@dataclass(frozen=True)
class Violation:
    """One broken invariant: which, when (simulated seconds), what, and who."""

    invariant: str
    t: float
    message: str
    uavs: tuple[str, ...] = ()
    target: int | None = None
    data: dict[str, Any] = field(default_factory=dict, compare=False)
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
        # (issue 26) Polygon no-fly zones (agents.zones.Keepout, ids after the circles'): judged
        # by the threat checker with their signed distance, as the circles are, and a target
        # last seen in or near one is kept, not lost (no_drop, issue 33).
        self.zones: list[Any] = []
        if scenario.no_fly:
            from swarm.geo.frame import frame_for
            from swarm.geo.geography import zone_keepouts

            geo = scenario.geo
            self.zones = zone_keepouts(scenario, frame_for(geo.crs, geo.area, scenario.area.cell_m) if geo else None)
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
            for uid, b in sim._world.uavs.items():
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
            if self.sim is not None and uid in self.sim._world.uavs:
                type_name = self.sim._world.uavs[uid].kind.name
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
            faults: list[FaultKind] = self.sim.injector.schedule.faults
            return faults
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
            if when[0] <= t1 + EPS and when[1] >= lo - EPS and f.concerns(names):
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
        return math.hypot(pa[0] - pb[0], pa[1] - pb[1]) <= self.range_m + EPS

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


# The assignment checkers excuse a UAV whose control or sensing a fault impairs
# (RunContext.impaired); the safety checkers excuse one whose control is impaired also for
# RECOVER_S after the fault: a UAV that resumes, or learns where it really is, heading into a
# threat or another UAV at full speed needs a turn or two to get out; a U-turn of the paper's
# fast type takes about 20 s.
RECOVER_S = 30.0
