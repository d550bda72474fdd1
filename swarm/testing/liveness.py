"""Liveness after faults: once every fault is over, a quiet period, then the swarm has recovered.

:class:`SwarmMachine <swarm.testing.stateful.SwarmMachine>` ends each example with this check
(its *liveness mode*); it works on any live :class:`~swarm.kernel.simulation.Simulation`::

    report = quiesce(sim, faults_end_s=sim.now)   # heal first: no fault may still be active
    report.raise_if()

What is checked, precisely (``T0``: the end of the last fault, when the quiet period starts;
``Q``: :func:`quiet_period_s`; *live*: flying, i.e. ``state == "alive"``, at ``T0`` and
throughout the quiet period; a paused UAV is live again once its pause is over, a restarted one
once it has rejoined):

* **maps agree**: for every two live UAVs ``a`` and ``b`` that were in one radio component (the
  radio graph's edges, multi-hop) at every tick of ``[T0, T0 + Q]``, ``b``'s map at ``T0 + Q``
  knows every cell at least as recently as ``a``'s map did at ``T0`` (last-seen times,
  cellwise ``>=``). A liar's fake scans count as scans: they are in maps because someone
  merged them, and anti-entropy spreads them like any scan (they are the cells it claims).
  Judged only on a radio that loses nothing by itself (disk model, no loss, no bandwidth
  limit): on a lossy radio anti-entropy converges with probability 1 but in no bounded time,
  so the report says ``maps: not judged (lossy radio)`` rather than pass or fail.
* **targets are watched again**: a target that a UAV was watching (pose mode surveil) when a
  node fault hit that UAV (crash, pause, restart), and that nobody watches at ``T0``, is
  watched again (some live UAV's pose declares it) within :func:`reassign_bound_s` of ``T0``,
  provided that at ``T0`` the planner watches targets (``planner.surveillance``: every planner
  that may run with it watches, the search planners through the shared logic), a live UAV not
  watching anything knows the target's track, and the radio loses nothing by itself. Otherwise
  the obligation is listed as not judged, with why.
* **tracks spread** (issue 36, M1): for every two live UAVs ``a`` and ``b`` in one radio
  component at every tick of ``[T0, T0 + Qt]``, ``b`` holds at ``T0 + Qt`` a track of every
  target ``a`` held one of at ``T0`` (a UAV that missed a track gets it). Judged, like the maps,
  only on a radio that loses nothing by itself.

The bounds, from the scenario's settings (``dt`` the tick, ``lat`` = ``radio.latency_s +
radio.jitter_s``, ``n`` the live UAVs):

* ``Q = sync_settle_s + n * (sync_every_s + 2 dt + lat) + max(0, skew)``: anti-entropy compares
  digests every ``sync_every_s``; in each round every live UAV next to one that holds a scan it
  lacks gets it (a digest, answered the next tick, delivered ``lat`` later), so in a connected
  component of ``n`` UAVs ``n - 1`` rounds reach everyone, plus one round of slack for a link
  that was in range at the digest and not at the answer; scans younger than
  ``sync_settle_s`` are not in a digest yet. ``skew`` is the largest clock error a
  ``clock_skew`` fault had when it ended: the cells that UAV stamped ahead of time are refused by
  every receiver (stamped later than its clock) until true time passes their stamp.
* tracks: ``Qt = n * (D + dt + lat)``, ``D`` = :func:`agents.tracksync.track_delay_s`: how long
  a track may take to reach a neighbour that lacks it. ``radio.tracks = "periodic"``:
  ``D = tracks_every_s`` (every UAV sends every track it knows that often). ``"on_change"``:
  ``D = max(tracks_every_s, E + beacon_every_s + 2 dt + 2 lat)``, ``E`` the track digest's period
  (``sync_every_s``, or ``tracks_every_s`` with anti-entropy off): the lacking UAV's next digest
  goes out on a beacon within ``E + beacon_every_s``, every neighbour that holds a track it lacks
  answers it the next tick, and the answer is merged the tick after. A hop per ``D + dt + lat``;
  ``n`` hops, one of slack, plus ``max(0, skew)``, as for ``Q`` (a sighting stamped by a clock
  ahead is refused until true time passes it).
* reassignment: ``B = D + peer_timeout_s + 2 * replan_s + 2 dt + lat``: the track
  must reach a free UAV (within ``D``, above), the lost watcher's intent
  must expire (``peer_timeout_s``, 5 s), then a replan (``replan_s``; two, as a plan made just
  before the expiry still counts the old watcher).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.inputs import ActorSettings
from agents.tracksync import track_delay_s
from comms.messages import MODE_NAMES, MODE_SURVEIL
from faults.base import FaultKind
from faults.sensing import max_skew_at_end, skewed_stamps
from swarm.testing.invariants import InvariantViolation, Violation, owed_map

if TYPE_CHECKING:
    from swarm.scenario import Scenario

__all__ = ["LivenessReport", "RecoveryWatch", "quiesce", "quiet_period_s", "radio_loses_nothing",
           "reassign_bound_s", "tracks_period_s"]

_EPS = 1e-6
PEER_TIMEOUT_S = ActorSettings().peer_timeout_s  # (not a scenario setting)


def radio_loses_nothing(scenario: Scenario) -> bool:
    """Whether the scenario's radio, without faults, delivers every frame in range."""
    return bool(scenario.radio.loses_nothing)


def _lat(scenario: Scenario) -> float:
    return float(scenario.radio.latency_s + scenario.radio.jitter_s)


def quiet_period_s(scenario: Scenario, n_live: int, faults: Iterable[FaultKind] = ()) -> float:
    """``Q`` of the module docstring."""
    r = scenario.radio
    dt = scenario.dt_s
    rounds = max(1, n_live)
    every = r.sync_every_s if r.sync_every_s > 0 else math.inf  # no anti-entropy: no bound
    return r.sync_settle_s + rounds * (every + 2 * dt + _lat(scenario)) + max_skew_at_end(faults)


def reassign_bound_s(scenario: Scenario) -> float:
    """``B`` of the module docstring."""
    return (track_delay_s(scenario.radio, scenario.dt_s) + PEER_TIMEOUT_S + 2 * scenario.planner.replan_s
            + 2 * scenario.dt_s + _lat(scenario))


def tracks_period_s(scenario: Scenario, n_live: int, faults: Iterable[FaultKind] = ()) -> float:
    """``Qt`` of the module docstring."""
    return (max(1, n_live) * (track_delay_s(scenario.radio, scenario.dt_s) + scenario.dt_s + _lat(scenario))
            + max_skew_at_end(faults))


def _watchers(sim: Any) -> dict[int, int]:
    """uid -> watched target, for every flying UAV whose plan is to watch one."""
    out = {}
    for s in sim.snapshot().uavs:
        if s.state == "alive" and s.mode == _SURVEIL and s.target >= 0:
            out[s.uid] = int(s.target)
    return out


_SURVEIL = MODE_NAMES[MODE_SURVEIL]  # the snapshot's name of the mode


class RecoveryWatch:
    """Follows a live run (call :meth:`observe` after every step, :meth:`fault` for every fault
    added) and remembers which targets lost their watcher to a node fault."""

    def __init__(self, sim: Any):
        self.sim = sim
        self.watching: dict[int, int] = {}  # uid -> target, as of the last observe
        self.orphaned: dict[int, tuple[float, str]] = {}  # target -> (when, the lost watcher's name)
        self._hit: list[tuple[float, float, str]] = []  # (from, until, name): node faults pending

    def fault(self, f: FaultKind) -> None:
        away = f.absence()  # (crash, restart, pause: when its UAV does not work)
        if away is not None:
            self._hit.append((*away, str(getattr(f, "uav", ""))))

    def observe(self) -> None:
        t = self.sim.now
        names = {b.uid: b.name for b in self.sim._world.uavs.values()}
        hit = {name for t0, t1, name in self._hit if t0 <= t + _EPS and t < t1 - _EPS}
        # A paused UAV still shows its old plan: under a node fault nobody counts as watching.
        now = {u: m for u, m in _watchers(self.sim).items() if names[u] not in hit}
        for uid, m in self.watching.items():
            if names[uid] in hit and now.get(uid) != m:
                self.orphaned.setdefault(m, (t, names[uid]))
        for m in set(now.values()):
            self.orphaned.pop(m, None)
        self.watching = now


@dataclass
class LivenessReport:
    """What :func:`quiesce` judged: violations, and obligations not judged with the reason."""

    t0: float
    quiet_s: float
    violations: list[Violation] = field(default_factory=list)
    judged: list[str] = field(default_factory=list)
    not_judged: list[str] = field(default_factory=list)

    def raise_if(self) -> None:
        if self.violations:
            raise InvariantViolation(self.violations)


def _components(edges: Iterable[tuple[int, int]], nodes: Iterable[int]) -> dict[int, int]:
    parent = {n: n for n in nodes}

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b in edges:
        if a in parent and b in parent:
            parent[find(a)] = find(b)
    return {n: find(n) for n in parent}


def quiesce(sim: Any, *, faults_end_s: float, watch: RecoveryWatch | None = None,
            step: Any = None) -> LivenessReport:
    """Run the quiet period and judge the obligations of the module docstring. No fault may be
    active at or after ``faults_end_s`` (the caller ends them); the run first goes on to that
    time. ``step(n)`` advances the run (default ``sim.step``; a state machine passes its own, so
    its invariants are checked all along)."""
    step = step or sim.step
    sc = sim.scenario
    dt = sim.dt
    while sim.now < faults_end_s - _EPS and not sim.done:
        step(1)
        if watch is not None:
            watch.observe()
    t0 = sim.now
    live = [uid for uid, b in sorted(sim._world.uavs.items()) if b.state == "alive"]
    names = {uid: sim._world.uavs[uid].name for uid in live}
    q = quiet_period_s(sc, len(live), sim.injector.schedule.faults)
    lossless = radio_loses_nothing(sc)
    report = LivenessReport(t0, q)
    # What each UAV knew at T0 and owes its peers (less the stamps of a skewed clock: never owed).
    skewed = skewed_stamps(sim.injector.schedule, sim.scenario.duration_s)
    at_t0 = {uid: owed_map(sim.uav_map(names[uid]), skewed) for uid in live}
    # (issue 36, M1) The targets each UAV held a track of at T0: owed to its component.
    qt = tracks_period_s(sc, len(live), sim.injector.schedule.faults)
    tracks_t0 = {uid: set(sim.actors[uid].knowledge.tracks) for uid in live}
    tracks_done = False
    # Reassignment obligations, fixed at T0.
    pending: dict[int, float] = {}
    if watch is not None:
        watch.observe()
        # (a planner that cannot watch, surveils = False, is refused with surveillance on)
        planner_watches = sc.planner.surveillance
        watched = set(_watchers(sim).values())
        free = [uid for uid in live if uid not in _watchers(sim)]
        for m, (t_lost, who) in sorted(watch.orphaned.items()):
            if m in watched:
                continue
            known = [u for u in free if m in sim.actors[u].knowledge.tracks]
            why = ("the planner does not watch targets" if not planner_watches else
                   "the radio is lossy" if not lossless else
                   "no free live UAV knows its track" if not known else "")
            if why:
                report.not_judged.append(f"target {m} (watcher {who} lost at {t_lost:g} s): {why}")
            else:
                pending[m] = t_lost
    maps_done = False
    if not math.isfinite(q):
        report.not_judged.append("maps: no anti-entropy (radio.sync_every_s = 0), so no bound")
        maps_done, q = True, 0.0
    bound = reassign_bound_s(sc)
    together = {(a, b): True for a in live for b in live if a < b}
    horizon = max(q, qt, bound if pending else 0.0)
    ticks = int(math.ceil(horizon / dt - 1e-9))
    for _ in range(ticks):
        if sim.done:
            break
        step(1)
        comp = _components(sim._radio.graph.edges(), live)
        alive_now = {uid for uid in live if sim._world.uavs[uid].state == "alive"}
        for pair in together:
            a, b = pair
            if a not in alive_now or b not in alive_now or comp[a] != comp[b]:
                together[pair] = False
        seen = set(_watchers(sim).values())
        for m in [m for m in pending if m in seen]:
            del pending[m]
            report.judged.append(f"target {m} watched again by {sim.now - t0:g} s")
        if sim.now - t0 >= q - _EPS and not maps_done:
            _judge_maps(sim, report, live, names, at_t0, together, lossless, alive_now)
            maps_done = True
        if sim.now - t0 >= qt - _EPS and not tracks_done:
            _judge_tracks(sim, report, names, tracks_t0, together, lossless, alive_now, qt)
            tracks_done = True
    for m in sorted(pending):
        if sim.now - t0 >= bound - _EPS:
            report.violations.append(Violation(
                "liveness", sim.now, f"target {m} lost its watcher at {pending[m]:g} s and nobody watched it "
                f"within {bound:g} s of the faults ending at {t0:g} s (bound track delay + peer timeout + "
                "2 replans + 2 ticks + latency)", target=m))
        else:
            report.not_judged.append(f"target {m}: the run ended before the bound")
    if not maps_done:
        report.not_judged.append(f"maps: the run ended before the quiet period of {q:g} s")
    if not tracks_done:
        report.not_judged.append(f"tracks: the run ended before {qt:g} s")
    return report


def _ordered_pairs(together: dict[tuple[int, int], bool]) -> list[tuple[int, int]]:
    """Both orders of every pair of UAVs connected all along, in id order."""
    return [xy for (a, b), ok in sorted(together.items()) if ok for xy in ((a, b), (b, a))]


def _judge_tracks(sim: Any, report: LivenessReport, names: dict[int, str], at_t0: dict[int, set[int]],
                  together: dict[tuple[int, int], bool], lossless: bool, alive_now: set[int], qt: float) -> None:
    """The "tracks spread" obligation of the module docstring, judged ``qt`` after ``T0``."""
    if not lossless:
        report.not_judged.append("tracks: not judged (lossy radio)")
        return
    now = {uid: sim.actors[uid].knowledge.tracks for uid in at_t0 if uid in alive_now}
    ordered = _ordered_pairs(together)
    for x, y in ordered:
        missing = sorted(at_t0[x] - now[y].keys())
        if missing:
            report.violations.append(Violation(
                "liveness", sim.now, f"{sim.now - report.t0:g} s after the faults ended ({report.t0:g} s), "
                f"{names[y]} still has no track of target(s) {missing} that {names[x]} held then, although "
                f"connected all along (bound {qt:g} s)", (names[y], names[x]), data={"targets": missing}))
    report.judged.append(f"tracks: {len(ordered)} ordered pair(s) connected all along")


def _judge_maps(sim: Any, report: LivenessReport, live: list[int], names: dict[int, str],
                at_t0: dict[int, np.ndarray], together: dict[tuple[int, int], bool], lossless: bool,
                alive_now: set[int]) -> None:
    if not lossless:
        report.not_judged.append("maps: not judged (lossy radio)")
        return
    now = {uid: sim.uav_map(names[uid]) for uid in live if uid in alive_now}
    ordered = _ordered_pairs(together)
    for x, y in ordered:
        behind = now[y] < at_t0[x]
        if behind.any():
            iy, ix = (int(v[0]) for v in np.nonzero(behind))
            report.violations.append(Violation(
                "liveness", sim.now, f"{sim.now - report.t0:g} s after the faults ended ({report.t0:g} s), "
                f"{names[y]} still misses {int(behind.sum())} cell(s) that {names[x]} knew then, although "
                f"connected all along, e.g. cell (ix={ix}, iy={iy}): {float(now[y][iy, ix]):g} < "
                f"{float(at_t0[x][iy, ix]):g} (quiet period {report.quiet_s:g} s)",
                (names[y], names[x]), data={"cells": int(behind.sum())}))
    report.judged.append(f"maps: {len(ordered)} ordered pair(s) connected all along")
