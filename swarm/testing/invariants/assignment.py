"""The assignment invariants of the surveillance handover (docs/modelling.md, "Assignment
rules"): one watcher per target, handovers as the rules say, no target dropped."""

from __future__ import annotations

import math
from typing import Any

import swarm.events as event_schema
from faults.base import PHANTOM_TARGET_ID
from swarm.testing.invariants.checker import SURVEIL, Checker, poses_of
from swarm.testing.invariants.context import EPS


class _WatchChecker(Checker):
    """Helpers for the assignment invariants: watchers per target from the pose events."""

    _targets: dict[int, tuple[float, float]]  # target -> last logged (x, y), kept by the subclasses that need it
    _seen: dict[int, tuple[float, float, float]]  # target -> last (t, x, y) inside some UAV's sensor (_sightings)
    _home: set[int]  # (issue 33) UAVs on their way home: from their rtb to their landing (_homeward)

    def _homeward(self, events: list[Any]) -> None:
        """Note who turns home (``rtb``) and who is no longer on the way (landed, launched, crashed)."""
        if not hasattr(self, "_home"):
            self._home = set()
        for e in events:
            if isinstance(e, event_schema.ReturnToBase):
                self._home.add(e.uav)
            elif isinstance(e, (event_schema.Landed, event_schema.Launched, event_schema.Crash)):
                self._home.discard(e.uav)

    def free(self, uid: int, p: tuple[Any, ...]) -> bool:
        """A UAV is free while it searches with no target (not on its way to take one over) and
        is not on its way home (rule 2's wording)."""
        return p[4] != SURVEIL and p[5] < 0 and uid not in self._home

    @staticmethod
    def watchers(poses: dict[int, tuple[Any, ...]]) -> dict[int, set[int]]:
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

    def _sightings(self, t: float, poses: dict[int, tuple[Any, ...]]) -> None:
        """Note every target some UAV has inside its detection radius at ``t`` (``_seen``)."""
        ctx = self.context
        for m, (x, y) in self._targets.items():
            for uid, p in poses.items():
                k = ctx.kind(uid)
                if k is not None and math.hypot(p[0] - x, p[1] - y) <= k.detect_radius:
                    self._seen[m] = (t, x, y)
                    break

    def _holds(self, uid: int, m: int, poses: dict[int, tuple[Any, ...]]) -> bool:
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

    def on_group(self, t: float, events: list[event_schema.Event]) -> None:
        poses = poses_of(events)
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
                    if t - since > self.settle_s + EPS and key not in self._reported:
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
    one to stop once the slow one has the target in sight, and not before (rule 3); with
    ``require_search`` the fast one must then be searching, not watching."""

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
        self._reported: set[tuple[Any, ...]] = set()
        self._prev_watchers: dict[int, set[int]] = {}
        self._targets: dict[int, tuple[float, float]] = {}
        self._seen: dict[int, tuple[float, float, float]] = {}
        # target -> watchers that have held it since they began watching it (rule 3's "in sight")
        self._held: dict[int, set[int]] = {}
        # target -> its owner, as the handover metric (swarm.kernel.metrics) has it: the UAV that held
        # it last, kept while it watches it (a newcomer takes it over only at its release)
        self._owner: dict[int, int] = {}
        #: Every (target, faster watcher) pair that was offered a takeover at some time: a free
        #: slower UAV within its D (rule 2), or, the faster one being the target's owner (the one
        #: a handover would be from), a slower one on its way to it (watching, not yet holding).
        self.opportunities: set[tuple[int, int]] = set()

    def on_group(self, t: float, events: list[event_schema.Event]) -> None:
        for e in events:
            if isinstance(e, event_schema.Target):
                self._targets[e.target] = (e.x, e.y)
        self._homeward(events)
        poses = poses_of(events)
        if not poses:
            return
        self._sightings(t, poses)
        ctx = self.context
        watchers = self.watchers(poses)
        held = {m: {w for w in self._held.get(m, ()) if w in ws} | {w for w in ws if self._holds(w, m, poses)}
                for m, ws in watchers.items()}
        for m, ws in watchers.items():
            old = self._owner.get(m)
            if old is None or old not in ws:
                holders = sorted(w for w in ws if self._holds(w, m, poses))
                if holders:
                    self._owner[m] = holders[0]
        self._early_release(t, poses, watchers, held)
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
                        if t - since > self.release_s + EPS and ("release", key) not in self._reported:
                            self._reported.add(("release", key))
                            self.violate(t, f"fast {ctx.name(f)} kept watching target {m} for {t - since:g} s after "
                                            f"slower {ctx.name(s)} took it over (release bound {self.release_s:g} s)",
                                         [f, s], target=m, since=since, rule=3)
                if slower_watching and self._owner.get(m) == f and not arrived:
                    # an opportunity taken already: a slower UAV is on its way to take it from its owner
                    self.opportunities.add((m, f))
                # Nobody knows where it is (kept from a no-fly zone's edge, unseen for the track
                # lifetime: rule 5): no slower UAV can be drawn to it, so no takeover is owed.
                seen = self._seen.get(m)
                if slower_watching or pos is None or seen is None or t - seen[0] > self._track_life() + EPS:
                    continue
                # (issue 33) A slower UAV on its way to relieve the watcher (rule 6: its pose searches
                # with the target's id) is taking the target over already.
                if any(p[4] != SURVEIL and p[5] == m and s != f and (k_s := ctx.kind(s)) is not None
                       and k_s.speed_max < kf.speed_max and ctx.handover_judged(s, f) for s, p in poses.items()):
                    continue
                free = [s for s, p in sorted(poses.items())
                        if s != f and self.free(s, p) and not self.excused(s, t) and (k_s := ctx.kind(s)) is not None
                        and k_s.speed_max < kf.speed_max and ctx.handover_judged(s, f)
                        and math.hypot(p[0] - pos[0], p[1] - pos[1]) < k_s.influence_radius
                        and ctx.can_talk(f, s, t, poses)]
                if not free:
                    continue
                key2 = (m, f)
                offers.add(key2)
                self.opportunities.add(key2)
                since = self._offer.setdefault(key2, t)
                if t - since > self.takeover_s + EPS and ("takeover", key2, since) not in self._reported:
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
                elif t - since > self.settle_s + EPS:
                    del self._joined[(f, now)]
                    self.violate(t, f"fast {ctx.name(f)} released target {m} to {ctx.name(to)} but went on to watch "
                                    f"target {now}, which {', '.join(ctx.name(w) for w in others)} holds, for "
                                    f"{t - since:g} s (settle time {self.settle_s:g} s), instead of searching or "
                                    f"watching a target nobody it can talk to holds",
                                 [f, to, *others], target=m, now_watching=now, since=since, rule=4)
        self._offer = {k: v for k, v in self._offer.items() if k in offers}
        self._overlap = {k: v for k, v in self._overlap.items() if k in overlaps}
        self._prev_watchers = {m: set(ws) for m, ws in watchers.items()}
        self._held = held

    def _early_release(self, t: float, poses: dict[int, tuple[Any, ...]], watchers: dict[int, set[int]],
                       held: dict[int, set[int]]) -> None:
        """Rule 3's "and not before": a faster watcher that has held a target stops watching it
        while a slower UAV it can talk to watches it and none of the slower watchers has held
        it since it began watching it (the relief does not have it in sight yet), nobody else
        holds it, the target is not lost (rule 5) and the faster one did not turn home (its
        ``rtb`` at that instant: rule 6 governs a departure for home)."""
        ctx = self.context
        for m, prev in sorted(self._prev_watchers.items()):
            now = watchers.get(m, set())
            for f in sorted(prev - now):
                kf = ctx.kind(f)
                if kf is None or f not in poses or self.excused(f, t) or f not in self._held.get(m, ()) or f in self._home:
                    continue
                slower = [s for s in sorted(now) if (k_s := ctx.kind(s)) is not None and k_s.speed_max < kf.speed_max
                          and ctx.handover_judged(s, f) and not self.excused(s, t) and ctx.can_talk(f, s, t, poses)]
                if not slower or any(s in held.get(m, ()) for s in slower):
                    continue
                if any(self._holds(w, m, poses) for w in now) or self._lost(m, t):
                    continue
                self.violate(t, f"fast {ctx.name(f)} stopped watching target {m} before its slower relief "
                                f"{', '.join(ctx.name(s) for s in slower)} had it in sight (rule 3: a faster watcher keeps "
                                f"the target until a slower one watching it has held it)",
                             [f, *slower], target=m, rule=3)

    def _lost(self, m: int, t: float) -> bool:
        """Nobody has had ``m`` inside a detection radius for the track lifetime (rule 5)."""
        seen = self._seen.get(m)
        return seen is None or t - seen[0] > self._track_life() - EPS


    def _holders_besides(self, f: int, m: int, t: float, poses: dict[int, tuple[Any, ...]],
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
    watcher's detection radius from every no-fly zone, circle or polygon (a target inside one, or
    that near one, is kept, not lost).

    (Issue 33, rule 6.) A watcher that turns home (its ``rtb``) is judged the same way, but its
    departure is excused when it left unrelieved (its ``relief`` event says ``unrelieved``) and,
    when it asked for relief (``relief`` ``asked``, by the time ``by`` it had to go), no free
    flying UAV could have reached the target by then: each was farther from it than its
    ``speed_max`` plus the mean wind's speed times the time left, or its own energy sent it
    home by ``2 handover_s`` after the departure, or it was on its way to another target
    (its pose: search mode with that target's id, as a relief flies to the watcher it answers)
    at some time between the request and the departure (one UAV answers one request)."""

    name = "no_drop"

    def __init__(self, grace_s: float = 10.0):
        super().__init__()
        self.grace_s = grace_s
        self._asks: dict[tuple[int, int], tuple[float, float, list[int]]] = {}  # (w, m) -> (t, by, who could reach)
        self._unrelieved: set[tuple[int, int]] = set()
        self._departures: list[tuple[float, int, int]] = []  # unrelieved drops to judge: (t, watcher, target)
        self._last_poses: dict[int, tuple[Any, ...]] = {}
        self._went_home: dict[int, list[float]] = {}  # uav -> its rtb times
        self._answering: dict[int, dict[int, list[float]]] = {}  # uav -> target it went to relieve -> [first, last] t
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
        near = (any(math.hypot(x - cx, y - cy) < r + reach for _, cx, cy, r in self.context.threats)
                or any(z.clearance(x, y)[0] < reach for z in self.context.zones))  # circles and polygons alike
        return t - t_seen > self._track_life() - EPS and not near

    def on_group(self, t: float, events: list[event_schema.Event]) -> None:
        for e in events:
            if isinstance(e, event_schema.Target):
                self._targets[e.target] = (e.x, e.y)
        self._homeward(events)
        poses = poses_of(events) or self._last_poses  # (the mission's events follow their tick's poses)
        for e in events:
            if isinstance(e, event_schema.Relief):
                if e.status == "asked":
                    self._asks[(e.uav, e.target)] = (t, e.by, self._could_reach(t, e.target, e.by, poses))
                elif e.status == "unrelieved":
                    self._unrelieved.add((e.uav, e.target))
            elif isinstance(e, event_schema.ReturnToBase):
                self._went_home.setdefault(e.uav, []).append(t)
        self._judge_departures(t)
        if not poses_of(events):
            return
        self._last_poses = poses
        for uid, p in poses.items():
            if p[4] != SURVEIL and p[5] >= 0:  # (on its way to take a target over: rule 6)
                span = self._answering.setdefault(uid, {}).setdefault(int(p[5]), [t, t])
                span[1] = t
        self._sightings(t, poses)
        watchers = self.watchers(poses)
        held = {m: {w for w in self._held.get(m, ()) if w in ws} | {w for w in ws if self._holds(w, m, poses)}
                for m, ws in watchers.items()}
        for m in [m for m in self._pending if watchers.get(m)]:
            del self._pending[m]
        for m, (t0, w, seen) in list(self._pending.items()):
            if t - t0 > self.grace_s + EPS:
                del self._pending[m]
                if (w, m) in self._unrelieved:
                    self._departures.append((t0, w, m))  # (judged once the candidates' energy shows: _judge_departures)
                    continue
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

    def _judge_departures(self, t: float, final: bool = False) -> None:
        """Rule 6: an unrelieved departure at ``t0`` is a drop if a UAV that could reach the
        target when relief was asked did not itself turn home (its energy said go) before
        ``t0 + 2 handover_s`` (a candidate needs energy for the way there and some watching).
        Judged once that time has passed."""
        e = self.context.scenario.endurance
        wait = 2.0 * e.handover_s if e is not None else 0.0
        for item in list(self._departures):
            t0, w, m = item
            if t < t0 + wait - EPS and not final:
                continue
            self._departures.remove(item)
            if final and t < t0 + wait - EPS:
                continue  # not enough time left to judge
            ask = self._asks.get((w, m))
            if ask is None:
                continue  # (it never asked: it went at its first reading, nobody could have come)
            could = [u for u in ask[2] if not any(ask[0] <= h <= t0 + wait + EPS for h in self._went_home.get(u, []))
                     and not any(other != m and first <= t0 + EPS and last >= ask[0] - EPS
                                 for other, (first, last) in self._answering.get(u, {}).items())]
            if not could:
                continue  # nobody could have relieved it in time
            names = ", ".join(self.context.name(u) for u in could)
            self.violate(t0, f"{self.context.name(w)} went home from target {m} unrelieved, but {names} "
                             f"could have reached it in the {ask[1] - ask[0]:g} s between its relief request at "
                             f"{ask[0]:g} s and its departure", [w, *could], target=m, since=ask[0], rule=6)

    def _could_reach(self, t: float, m: int, by: float, poses: dict[int, tuple[Any, ...]]) -> list[int]:
        """The free flying UAVs (not impaired) that could reach target ``m`` by ``by``: within
        ``(by - t)`` times their ``speed_max`` plus the mean wind's speed (rule 6)."""
        pos = self._targets.get(m)
        if pos is None:
            return []
        sc = self.context.scenario
        wind = sc.wind.speed_mps if sc.wind is not None else 0.0
        out = []
        for uid, p in sorted(poses.items()):
            k = self.context.kind(uid)
            if k is None or not self.free(uid, p) or self.excused(uid, t):
                continue
            if math.hypot(p[0] - pos[0], p[1] - pos[1]) <= (by - t) * (k.speed_max + wind) + EPS:
                out.append(uid)
        return out

    def finish(self, t_end: float) -> None:
        self._pending.clear()  # not enough time left to judge
        self._judge_departures(t_end, final=True)
