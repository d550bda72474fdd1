"""Which scans a UAV's map is made of: enough to tell where two maps can differ without
comparing them cell by cell.

A UAV's map starts never-seen everywhere and changes only by stamping scan disks (its own, one
per tick, and the ones it hears), each a per-cell max. Two maps made of the same scans are
therefore equal, and two maps can differ only inside the disks of the scans one has and the
other lacks. :class:`MapRecords` keeps, per origin UAV, the run of ticks whose scans the map
applied (``lo..hi``, no gap), the few applied outside it, and the disks of the last
:data:`KEEP_TICKS` ticks of each run. :func:`differences` lists the disks of the scans in one
map but not the other, or says it cannot (scans it no longer holds the disks of, times off the
tick grid, a map written some other way): the caller then compares the maps.

The DACMP planner uses it to skip the cell-by-cell comparison of maps planned in the same tick
(:mod:`agents.pyramid_reuse`): in a swarm that hears itself well they differ by this tick's own
scans only.
"""

from __future__ import annotations

from agents.grid import Disk
from agents.umap import UncertaintyMap

# Disks kept per origin: the newest ticks of its run (the scans two maps usually differ by).
KEEP_TICKS = 8
# Scans applied outside their origin's run, beyond which the summary gives up (lossy radio
# with long gaps: the maps are compared instead).
MAX_EXTRA = 64


class MapRecords:
    """The scans stamped into one map (see the module docstring). Call :meth:`stamp` for every
    scan the map gets; any other write to the map makes the summary unusable."""

    __slots__ = ("umap", "dt", "runs", "extra", "usable", "_version")

    def __init__(self, umap: UncertaintyMap, dt: float):
        self.umap = umap
        self.dt = dt
        # origin -> [lo, hi, {tick: disk} of the run's newest ticks]
        self.runs: dict[int, list] = {}
        self.extra: dict[tuple[int, int], Disk] = {}  # (origin, tick) -> disk, outside the runs
        self.usable = umap.version == 0  # a map written before it was summarised: never
        self._version = umap.version

    def stamp(self, origin: int, t: float, d: Disk) -> None:
        """Stamp origin's scan of time ``t`` (disk ``d``) into the map, and note it."""
        umap = self.umap
        umap.stamp(d, t)
        if not self.usable:
            return
        if umap.version != self._version + 1:  # written in between by someone else
            self.usable = False
            return
        self._version = umap.version
        k = round(t / self.dt)
        if k * self.dt != t:  # off the tick grid: (origin, tick) would not name one scan
            self.usable = False
            return
        run = self.runs.get(origin)
        if run is None:
            self.runs[origin] = [k, k, {k: d}]
            return
        lo, hi, recent = run
        if k == hi + 1:
            recent[k] = d
            recent.pop(k - KEEP_TICKS, None)
            run[1] = hi = k
            extra = self.extra
            while extra and (origin, hi + 1) in extra:  # the run has caught up with them
                hi += 1
                recent[hi] = extra.pop((origin, hi))
                recent.pop(hi - KEEP_TICKS, None)
                run[1] = hi
        elif lo <= k <= hi or (origin, k) in self.extra:
            pass  # applied already (a resent scan): the map did not change
        elif k == lo - 1:
            run[0] = k  # an older scan, late: its disk is not kept
        else:
            self.extra[(origin, k)] = d
            if len(self.extra) > MAX_EXTRA:
                self.usable = False

    def has(self, origin: int, k: int) -> bool:
        run = self.runs.get(origin)
        return (run is not None and run[0] <= k <= run[1]) or (origin, k) in self.extra

    def disk(self, origin: int, k: int) -> Disk | None:
        run = self.runs.get(origin)
        if run is not None and k in run[2]:
            return run[2][k]
        return self.extra.get((origin, k))


def differences(a: MapRecords, b: MapRecords, limit: int = 64) -> list[Disk] | None:
    """The disks of the scans one of the two maps has and the other lacks (the maps are equal
    outside them), or None when the summaries cannot tell (or more than ``limit`` differ)."""
    if not (a.usable and b.usable) or a.umap.version != a._version or b.umap.version != b._version:
        return None
    if a.dt != b.dt:
        return None
    out: list[Disk] = []
    for origin in a.runs.keys() | b.runs.keys():
        ra, rb = a.runs.get(origin), b.runs.get(origin)
        if ra is not None and rb is not None and ra[0] == rb[0] and ra[1] == rb[1]:
            continue
        # Ticks in one run and not the other: both runs' ends must be recent.
        for mine, theirs, run in ((a, b, ra), (b, a, rb)):
            if run is None:
                continue
            other = theirs.runs.get(origin)
            lo, hi = run[0], run[1]
            if other is not None:
                if lo < other[0] or hi - other[1] > KEEP_TICKS:
                    return None
                lo = max(lo, other[1] + 1)
            elif hi - lo >= KEEP_TICKS:
                return None
            for k in range(lo, hi + 1):
                if not theirs.has(origin, k):
                    d = mine.disk(origin, k)
                    if d is None:
                        return None
                    out.append(d)
                    if len(out) > limit:
                        return None
    for mine, theirs in ((a, b), (b, a)):
        for (origin, k), d in mine.extra.items():
            if not theirs.has(origin, k):
                out.append(d)
                if len(out) > limit:
                    return None
    return out
