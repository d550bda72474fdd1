"""Live invariants of the maps (they read the UAVs' maps: :class:`Monitor` attached to a
simulation): never forget, agree when quiet, a joiner catches up."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

import swarm.events as event_schema
from swarm.errors import UsageError
from swarm.testing.invariants.checker import Checker, poses_of
from swarm.testing.invariants.context import EPS, owed_map


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
            g = self._sim()._grid
            return np.zeros((g.ny, g.nx), dtype=bool)
        if self._centres is None:
            g = self._sim()._grid
            self._centres = (((np.arange(g.nx) + 0.5) * g.cell_m)[None, :], ((np.arange(g.ny) + 0.5) * g.cell_m)[:, None])
        cx, cy = self._centres
        return (cx - pose[0]) ** 2 + (cy - pose[1]) ** 2 <= reach * reach

    def _sim(self) -> Any:  # a live Simulation (RunContext.sim)
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
        return not self.context.scenario.radio.loses_nothing or self._overflowed

    _overflowed = False  # a mailbox dropped a frame since the previous tick (_note_overflow)
    _full_drops = 0

    def _note_overflow(self) -> None:
        """Called once per tick: whether a full mailbox dropped a frame copy since the last call."""
        n = self._sim()._radio.counters.dropped.get("mailbox_full", 0)
        self._overflowed, self._full_drops = n > self._full_drops, n


class MapMonotonicityChecker(_LiveChecker):
    """A UAV's map never forgets: no cell's last-seen time decreases between two ticks."""

    name = "map_monotonic"

    def __init__(self) -> None:
        super().__init__()
        self._last: dict[int, np.ndarray] = {}
        self._actor: dict[int, object] = {}

    def attach(self, sim: Any) -> None:
        self._snapshot(None)

    def _snapshot(self, t: float | None) -> None:
        sim = self._sim()
        for uid, b in sorted(sim._world.uavs.items()):
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

    def on_group(self, t: float, events: list[event_schema.Event]) -> None:
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
        self.poses_of: dict[int, tuple[Any, ...]] = {}  # this tick's (for the horizon's centres)
        self._quiet_since: float | None = None
        self._members: frozenset[int] = frozenset()
        self._history: deque[tuple[float, dict[int, np.ndarray]]] = deque()
        self._last_check = -math.inf
        self._reported_window: float | None = None
        self._hops = 0  # the radio graph's largest diameter (hops) since the quiet began
        self.checks = 0  # how many times agreement was judged (a test can assert it was)

    def on_group(self, t: float, events: list[event_schema.Event]) -> None:
        poses = poses_of(events)
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
        self.poses_of = poses
        # Scans from several hops away come round by anti-entropy, one round a hop: the lag
        # allowed grows with the radio graph's diameter over the quiet window.
        if self._quiet_since is None or self._quiet_since == t:
            self._hops = 0
        if self._quiet_since is not None:  # (history before the quiet began is never judged)
            self._hops = max(self._hops, ctx.hops(poses))
        lag = max(self.lag_s, ctx.relay_lag_s(self._hops))
        self._history.append((t, self._maps(members)))
        while self._history and self._history[0][0] < t - lag - EPS:
            self._history.popleft()
        if self._quiet_since is None or t - self._quiet_since < self.quiet_s + (lag - self.lag_s) - EPS:
            return
        if t - self._last_check < self.every_s - EPS or self._reported_window == self._quiet_since:
            return
        self._last_check = t
        then_t, then = self._history[0]
        if then_t > t - lag + EPS:
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
        poses = self.poses_of
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

    def on_group(self, t: float, events: list[event_schema.Event]) -> None:
        sim = self._sim()
        ctx = self.context
        poses = poses_of(events)
        for e in events:
            if (isinstance(e, event_schema.Join) and e.t > 0) or isinstance(e, event_schema.Restart):  # (restarted: empty)
                uid = e.uav
                j = sim._world.uavs[uid]
                nbrs = tuple(u for u, b in sorted(sim._world.uavs.items())
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
                if t > t_join + EPS:  # the join tick itself precedes the joiner's first pose
                    del self._pending[uid]
                continue
            behind = self._maps([uid])[uid] < target
            if not math.isinf(ctx.scenario.radio.horizon_m):  # only what its horizon holds is owed
                behind &= self._near(poses[uid], self._horizon_reach(self.bound_s))
            frac = float(behind.mean())
            if frac <= self.tolerance:
                del self._pending[uid]
                self.checks += 1
            elif t >= t_join + self.bound_s - EPS:
                del self._pending[uid]
                self.checks += 1
                self.violate(t, f"{ctx.name(uid)} joined at {t_join:g} s and {t - t_join:g} s later still misses "
                                f"{int(behind.sum())} cell(s) ({frac:.1%}) that its neighbours "
                                f"{', '.join(ctx.name(n) for n in nbrs)} knew when it joined",
                             [uid, *nbrs], cells=int(behind.sum()), fraction=frac, joined=t_join)
