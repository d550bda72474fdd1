"""Ground-truth metrics (DACMP-SPEC "Metrics"), computed by the simulator, never by agents.

* ``coverage``: fraction of cells scanned at least once by any UAV (the paper's coverage rate);
* ``certainty``: eq. 8, ``1 - mean(q)`` over the union of all real scans;
* ``targets_found``: targets seen at least once;
* surveillance: per target, the share of time since first detection during which some UAV in
  surveillance mode had it inside its detection radius; per UAV, seconds in each mode;
  handovers (below).

A UAV *watches* a target while it is in surveillance mode assigned to it, and *holds* it while
it also has it inside its detection radius (ground truth): a UAV on its way to a target watches
it but does not hold it yet. A target's *owner* is the UAV that held it last. A handover (the
paper's "the low-speed UAVs replaced the high-speed UAVs to monitor the target") is a new UAV
taking a target over from its owner: it holds the target, and it started watching it before
the owner stopped watching it (the two assignments overlap: it came because of the target,
not by chance after the target was dropped). It is logged when both hold: at the owner's
release, or at the newcomer's arrival if the owner had already let go. Its ``latency_s`` is the
spec's "time from the slow UAV's arrival to the fast UAV's release" (negative when the owner
left before the newcomer arrived). An owner that stops watching while nobody holds the target
logs a ``release``.

Detection-to-watch measures (:meth:`Metrics.assignment`, in ``metrics.json``; docs/outputs.md):
per target, the time from its appearance to its first detection, the time from that detection
to the first tick a UAV of the scenario's slowest type holds it (its *slow watcher*), and the
share of its time since detection during which some UAV held it (``watched_share``: unlike the
surveillance ratio, only a UAV assigned to that target counts); per UAV, the share of its flying time spent watching
(surveillance mode) and searching.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import swarm.events as ev
from agents.maps.grid import Grid
from agents.maps.umap import DENSE_MAX_CELLS, NEVER, UncertaintyMap
from comms.messages import MODE_SURVEIL
from swarm.events import Wire

_BLOCK = 64  # cells per side of the blocks whose q certainty() recomputes on large areas


class TruthHistogram:
    """The cells of a dense ground truth counted by last-seen value, brought up to date from the
    cells changed since the last read: certainty and coverage without q of every cell each time
    (issue 36; :attr:`Metrics.incremental`).

    The ground truth holds the (float32) times it was stamped at, or -inf. Each such value has a
    key, ``rint(value / dt) + 1`` (0: never seen), registered when a stamp at that time lands
    (:meth:`stamped`; two times sharing a key, or a cell value never registered, turn the
    histogram off for good: the callers then read the whole map, as without it). A read
    (:meth:`update`) compares the map with its copy at the previous read and moves the changed
    cells (those inside the area polygon, if any) between keys. Then

    * coverage is the cells not under key 0;
    * ``mean(q) = sum over keys of count * q(value) / n``, q computed by the map's own float32
      operations (:meth:`UncertaintyMap.q_into`) on the values: the q each of those cells has.
      Every q is a multiple of the float32 unit of the smallest nonzero one; while the sum of all
      of them stays below 2**52 such units (checked at each read), every float64 partial sum in
      any order is exact, so this is bit for bit numpy's float64 mean of the whole q array.
      Otherwise (a very small ``tau * dt`` on a large grid) :meth:`mean_q` says None and the
      caller computes the whole map.
    """

    def __init__(self, union: UncertaintyMap, dt: float, inside: np.ndarray | None):
        self.union = union
        self.inv_dt = 1.0 / dt
        self.inside = None if inside is None else np.ascontiguousarray(inside).reshape(-1)
        self.n = int(np.count_nonzero(inside)) if inside is not None else union.grid.nx * union.grid.ny
        self.snap = union.to_dense()  # the map at the last read
        self.values = np.full(64, np.nan, dtype=np.float32)  # key -> its value (NaN: none yet)
        self.values[0] = NEVER
        self.count = np.zeros(64, dtype=np.int64)  # key -> cells
        self.count[0] = self.n
        self.valid = bool(np.all(self.snap == NEVER))  # (a map fresh from Metrics: all never seen)
        self.dirty = False
        self._last_t: float | None = None

    def stamped(self, t: float) -> None:
        """A stamp at ``t`` landed on the map: register its value's key."""
        self.dirty = True
        if t == self._last_t or not self.valid:
            return  # (every UAV of a tick stamps at the same t)
        self._last_t = t
        v = np.float32(t)
        k = round(float(v) * self.inv_dt) + 1 if math.isfinite(t) else 0
        if k < 1:
            self.valid = False
            return
        if k >= len(self.values):
            grow = max(2 * len(self.values), k + 1)
            self.values = np.concatenate((self.values, np.full(grow - len(self.values), np.nan, np.float32)))
            self.count = np.concatenate((self.count, np.zeros(grow - len(self.count), np.int64)))
        have = self.values[k]
        if np.isnan(have):
            self.values[k] = v
        elif have != v:
            self.valid = False

    def _keys(self, v: np.ndarray) -> np.ndarray | None:
        """The keys of the values ``v`` (None if one is not registered)."""
        k = np.maximum(np.rint(v.astype(np.float64) * self.inv_dt), -1.0)  # (-inf -> -1)
        k += 1.0
        if len(k) and k.max() >= len(self.values):
            return None
        ki = k.astype(np.intp)
        if not np.array_equal(self.values[ki], v):  # (NaN, unregistered, never equals)
            return None
        return ki

    def update(self) -> bool:
        """Bring the counts up to date with the map; False if the histogram is off."""
        if not self.valid:
            return False
        if not self.dirty:
            return True
        self.dirty = False
        seen = self.union.to_dense_view().reshape(-1)
        snap = self.snap.reshape(-1)
        idx = np.flatnonzero(seen != snap)
        if not len(idx):
            return True
        new, old = seen[idx], snap[idx]
        snap[idx] = new
        if self.inside is not None:
            keep = self.inside[idx]
            new, old = new[keep], old[keep]
        kn, ko = self._keys(new), self._keys(old)
        if kn is None or ko is None:
            self.valid = False
            return False
        m = len(self.values)
        self.count += np.bincount(kn, minlength=m)
        self.count -= np.bincount(ko, minlength=m)
        return True

    def covered(self) -> int:
        """Cells (inside the polygon) seen at least once (after :meth:`update`)."""
        return self.n - int(self.count[0])

    def mean_q(self, t: float) -> float | None:
        """``np.mean(q at t, dtype=float64)`` over the cells (after :meth:`update`), or None when
        the sum could not be shown exact."""
        if self.n == 0:
            return None
        present = np.flatnonzero(self.count)
        vals = self.values[present]
        q = self.union.q_into(t, vals, np.empty(len(vals), dtype=np.float32)).astype(np.float64)
        if not np.all(np.isfinite(q)):
            return None
        cnt = self.count[present].astype(np.float64)
        nz = q[q != 0.0]
        if len(nz):
            unit = 2.0 ** (int(np.frexp(nz)[1].min()) - 24)  # the float32 unit of the smallest |q|
            if float(np.sum(cnt * np.abs(q))) >= unit * 2.0 ** 52:
                return None
        return float(np.sum(cnt * q)) / self.n


@dataclass(slots=True)
class Handover:
    t: float
    target: int
    from_uav: int
    to_uav: int
    from_type: str
    to_type: str
    latency_s: float  # the owner's release time minus the newcomer's arrival


@dataclass
class Metrics:
    grid: Grid
    tau: float
    union: UncertaintyMap = field(init=False)
    found_t: dict[int, float] = field(default_factory=dict)
    watched_s: dict[int, float] = field(default_factory=dict)
    mode_s: dict[int, dict[str, float]] = field(default_factory=dict)
    owner: dict[int, int] = field(default_factory=dict)  # target -> UAV that held it last
    released_at: dict[int, float] = field(default_factory=dict)  # target -> when its owner stopped watching
    watch_since: dict[tuple[int, int], float] = field(default_factory=dict)  # (uid, target) -> start
    arrived: dict[tuple[int, int], float] = field(default_factory=dict)  # (uid, target) -> first hold
    handovers: list[Handover] = field(default_factory=list)
    appeared_t: dict[int, float] = field(default_factory=dict)  # target -> when it was added (0 at the start)
    held_s: dict[int, float] = field(default_factory=dict)  # found target -> seconds some UAV held it
    # (issue 33) Watch continuity: found target -> the last tick some UAV held it, and its gaps
    # (unheld stretches after it was first found) so far: (count, longest s).
    last_held: dict[int, float] = field(default_factory=dict)
    gaps: dict[int, tuple[int, float]] = field(default_factory=dict)
    tick_s: float = 0.0  # (the run's dt, noted by observe)
    first_hold: dict[tuple[int, str], float] = field(default_factory=dict)  # (target, UAV type) -> first hold
    rows: list[dict[str, Any]] = field(default_factory=list)
    # (issue 26) The cells inside the area polygon, (ny, nx) bools: coverage and certainty
    # count those only. None: every cell (a rectangle).
    inside: np.ndarray | None = None
    # (issue 36, the tick plane) Certainty and coverage of a dense ground truth from the cells
    # changed since the last sample (:class:`TruthHistogram`: the same numbers); False: from the
    # whole map each time (the oracle). ``dt``: the run's tick, which keys the stamp times.
    incremental: bool = False
    dt: float = 1.0
    # Per-UAV radio/receive statistics live in the actors; these are the ground-truth views.

    def __post_init__(self) -> None:
        # The ground truth is one dense map for the whole area (one per simulation): certainty
        # (eq. 8) is a mean over every cell anyway.
        self.union = UncertaintyMap(self.grid, self.tau, tile="dense")
        # Large areas: remember which 64 x 64 blocks were ever scanned, and keep q in a buffer
        # where every other cell is exactly 1 (never seen), so certainty only recomputes q
        # where something was seen: the same array, so the same mean, as computing q everywhere
        # (on small grids that is as fast: they do so); coverage likewise only counts there.
        # Needs the union to be written through scan() only.
        self._touched: np.ndarray | None = None
        self._q: np.ndarray | None = None
        if self.grid.nx * self.grid.ny > DENSE_MAX_CELLS:
            self._touched = np.zeros((-(-self.grid.ny // _BLOCK), -(-self.grid.nx // _BLOCK)), dtype=bool)
        self._hist: TruthHistogram | None = None
        if self.incremental and self._touched is None:
            self._hist = TruthHistogram(self.union, self.dt, self.inside)

    @property
    def n_cells(self) -> int:
        return self.grid.nx * self.grid.ny

    def scan(self, x: float, y: float, radius: float, t: float) -> None:
        d = self.grid.disk_stamp(x, y, radius)  # shared with the scanning UAV's own map
        if d is not None:
            self.union.stamp(d, t)
            if self._hist is not None:
                self._hist.stamped(t)
            if self._touched is not None:
                self._touched[d.iy0 // _BLOCK : (d.iy1 - 1) // _BLOCK + 1, d.ix0 // _BLOCK : (d.ix1 - 1) // _BLOCK + 1] = True

    @property
    def covered_cells(self) -> int:
        """Cells scanned at least once: those the union has seen. Counted when asked (a few
        times per run) rather than per scan (every UAV, every tick): the same number."""
        if self._hist is not None and self._hist.update():
            return self._hist.covered()
        seen = self.union.to_dense_view()
        if self.inside is not None:
            return int(np.count_nonzero((seen != NEVER) & self.inside))
        if self._touched is None:
            return int(np.count_nonzero(seen != NEVER))
        return sum(int(np.count_nonzero(seen[rows, cols] != NEVER)) for rows, cols in self._touched_runs())

    def coverage(self) -> float:
        if self.inside is not None:
            return self.covered_cells / max(1, int(np.count_nonzero(self.inside)))
        return self.covered_cells / self.n_cells

    def _touched_runs(self) -> list[tuple[slice, slice]]:
        """``(rows, cols)`` of each run of touched blocks along each block row (large areas)."""
        touched = self._touched
        assert touched is not None  # large areas only (the callers check)
        # Runs start where a block is touched and its left neighbour is not, end where the next
        # one is not.
        padded = np.zeros((touched.shape[0], touched.shape[1] + 2), dtype=np.int8)
        padded[:, 1:-1] = touched
        edges = np.diff(padded, axis=1)
        starts = np.argwhere(edges == 1)
        stops = np.argwhere(edges == -1)
        return [(slice(by * _BLOCK, (by + 1) * _BLOCK), slice(bx0 * _BLOCK, bx1 * _BLOCK))
                for (by, bx0), (_, bx1) in zip(starts.tolist(), stops.tolist())]

    def certainty(self, t: float) -> float:
        """Eq. 8, ``1 - mean(q)`` over every cell: exactly ``np.mean(union.uncertainty(t))``."""
        if self._hist is not None and self._hist.update():
            mean = self._hist.mean_q(t)
            if mean is not None:
                return 1.0 - mean
        if self.inside is not None:  # (over the cells inside the area polygon only)
            return 1.0 - float(np.mean(self.union.uncertainty(t)[self.inside], dtype=np.float64))
        if self._touched is None:
            return 1.0 - float(np.mean(self.union.uncertainty(t), dtype=np.float64))
        q = self._q
        if q is None:
            q = self._q = np.ones(self.grid.shape, dtype=np.float32)  # q of a never-seen cell
        seen = self.union.to_dense_view()
        for rows, cols in self._touched_runs():
            self.union.q_into(t, seen[rows, cols], q[rows, cols])
        return 1.0 - float(np.mean(q, dtype=np.float64))

    def observe(self, t: float, dt: float, plans: dict[int, tuple[int, int]], sensed: dict[int, list[int]],
                types: dict[int, str], speed_max: dict[str, float],
                detected: dict[int, list[int]] | None = None) -> list[Wire]:
        """Account one tick. ``plans``: uid -> (mode, target); ``sensed``: uid -> target ids
        inside its detection radius. ``detected`` (a sensor fault: some UAVs' sensors miss
        targets): uid -> the real targets its sensor reported, for those UAVs; a target is
        found when a sensor reports it (a miss is not a find, a false alarm is never a target),
        while holding and watching stay the ground truth of ``sensed``. Returns events to log
        (found, handover, release)."""
        events: list[Wire] = []
        for uid, targets in sensed.items():
            if detected is not None:
                targets = detected.get(uid, targets)
            for m in targets:
                if m not in self.found_t:
                    self.found_t[m] = t
                    events.append(ev.found(t=t, target=m, uav=uid))
        watching: dict[int, set[int]] = {}
        holding: dict[int, set[int]] = {}
        covered: set[int] = set()
        for uid, (mode, target) in plans.items():
            ms = self.mode_s.setdefault(uid, {"search": 0.0, "surveil": 0.0})
            if mode == MODE_SURVEIL:
                ms["surveil"] += dt
                seen = sensed.get(uid, ())
                covered.update(seen)
                if target >= 0:
                    watching.setdefault(target, set()).add(uid)
                    self.watch_since.setdefault((uid, target), t)
                    if target in seen:
                        holding.setdefault(target, set()).add(uid)
                        self.arrived.setdefault((uid, target), t)
            else:
                ms["search"] += dt
        for key in [k for k in self.watch_since if k[0] not in watching.get(k[1], ())]:
            del self.watch_since[key]
            self.arrived.pop(key, None)
        # Only targets some UAV covers or holds gain time: visit those, not every found target
        # (10^5 targets: tens of thousands found; these dicts are only read by key).
        found, watched_s, held_s = self.found_t, self.watched_s, self.held_s
        for m in covered:
            if m in found:
                watched_s[m] = watched_s.get(m, 0.0) + dt
        last_held, gaps = self.last_held, self.gaps
        self.tick_s = dt
        for m in holding:
            if m in found:
                held_s[m] = held_s.get(m, 0.0) + dt
                since = last_held.get(m, found[m] - dt)
                if t - since > dt + 1e-9:
                    n, longest = gaps.get(m, (0, 0.0))
                    gaps[m] = (n + 1, max(longest, t - since - dt))
                last_held[m] = t
        for m, uids in holding.items():
            for uid in uids:
                self.first_hold.setdefault((m, types.get(uid, "?")), t)
        for m in sorted(set(self.owner) | set(holding)):
            old = self.owner.get(m)
            if old is not None and old in watching.get(m, ()):
                self.released_at.pop(m, None)
                continue  # the owner is (again) on it: a newcomer waits for its release
            if old is not None and m not in self.released_at:
                self.released_at[m] = t
                if not holding.get(m):
                    events.append(ev.release(t=t, target=m, uav=old))
            arrivals = sorted((self.arrived[(u, m)], u) for u in holding.get(m, ()) if u != old)
            if not arrivals:
                continue
            arrived, new = arrivals[0]
            if old is not None and self.watch_since[(new, m)] <= self.released_at[m]:
                latency = self.released_at[m] - arrived
                self.handovers.append(Handover(t, m, old, new, types.get(old, "?"), types.get(new, "?"), latency))
                events.append(ev.handover(t=t, target=m, from_uav=old, to_uav=new))
            self.owner[m] = new
            self.released_at.pop(m, None)
        return events

    def surveillance_ratio(self, t_end: float) -> dict[int, float]:
        out = {}
        for m, t0 in sorted(self.found_t.items()):
            span = t_end - t0
            out[m] = self.watched_s.get(m, 0.0) / span if span > 0 else 0.0
        return out

    def fast_to_slow_handovers(self, speed_max_by_type: dict[str, float]) -> int:
        return sum(
            1 for h in self.handovers
            if speed_max_by_type.get(h.from_type, math.inf) > speed_max_by_type.get(h.to_type, math.inf)
        )

    def assignment(self, targets: int, uav_types: dict[int, str], speed_max_by_type: dict[str, float],
                   t_end: float) -> dict[str, Any]:
        """The detection-to-watch measures of a run (module docstring; names in docs/outputs.md).

        ``targets``: how many the run has (ids ``0 .. targets - 1``); ``uav_types``: uid -> type
        name of every UAV the run has had (the slowest of their types is the "slow" type)."""
        speeds = [speed_max_by_type.get(k, math.inf) for k in set(uav_types.values())]
        slowest = min(speeds) if speeds else math.inf
        slow = {k for k in set(uav_types.values()) if speed_max_by_type.get(k, math.inf) == slowest}
        detection: dict[str, float | None] = {}
        to_slow: dict[str, float | None] = {}
        watched: dict[str, float] = {}
        continuity: dict[str, dict[str, float]] = {}
        for m in range(targets):
            t0 = self.found_t.get(m)
            detection[str(m)] = None if t0 is None else t0 - self.appeared_t.get(m, 0.0)
            if t0 is None:
                to_slow[str(m)] = None
                continue
            firsts = [t for (tm, k), t in self.first_hold.items() if tm == m and k in slow]
            to_slow[str(m)] = min(firsts) - t0 if firsts else None
            span = t_end - t0
            watched[str(m)] = self.held_s.get(m, 0.0) / span if span > 0 else 0.0
            n, longest = self.gaps.get(m, (0, 0.0))
            open_gap = t_end - self.last_held.get(m, t0 - self.tick_s) - self.tick_s
            if open_gap > 1e-9:  # (unheld at the end: that stretch is a gap too)
                n, longest = n + 1, max(longest, open_gap)
            continuity[str(m)] = {"gaps": n, "longest_gap_s": longest, "watched_share": watched[str(m)]}
        per_uav: dict[int, dict[str, float]] = {}
        total = {"search": 0.0, "surveil": 0.0}
        for uid in sorted(uav_types):
            ms = self.mode_s.get(uid, {"search": 0.0, "surveil": 0.0})
            flying = ms["search"] + ms["surveil"]
            per_uav[uid] = {"watching": ms["surveil"] / flying if flying > 0 else 0.0,
                            "searching": ms["search"] / flying if flying > 0 else 0.0}
            total["search"] += ms["search"]
            total["surveil"] += ms["surveil"]
        flying = total["search"] + total["surveil"]
        return {
            "time_to_first_detection_s": detection,
            "time_to_slow_watcher_s": to_slow,
            "watched_share": watched,
            "watched_share_mean": float(np.mean(list(watched.values()))) if watched else 0.0,
            "watch_continuity": continuity,
            "slow_types": sorted(slow),
            "uav_time_share": {"watching": total["surveil"] / flying if flying > 0 else 0.0,
                               "searching": total["search"] / flying if flying > 0 else 0.0},
            "per_uav": per_uav,
        }
