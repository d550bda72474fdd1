"""UAV maps stored as one shared map plus the few scans each has beyond it.

Every UAV keeps its own map: the per-cell max of the scan disks it applied (its own scans and
the ones it heard). In a swarm that hears itself well those maps are nearly the same: each has
every scan up to the last tick or two, plus its own latest. Storing and stamping each one
separately stamps every scan once per UAV, and that memory traffic is a large share of a run.

A :class:`MapGroup` stores the scans every member map has once, in a shared *base* map, and
each member keeps only the scans it has beyond the base (its *extra* scans, with their disks).
A scan moves into the base when the last member gets it. A member's content is
``max(base, its extra scans)``, which is exactly the max over the scans it applied: the same
numbers, cell for cell, as a map of its own (``max`` is commutative, associative and
idempotent). Only storage is shared; what a UAV knows is unchanged.

A member that falls behind (a scan others have had for :data:`LAG_TICKS` ticks still missing:
lost frames, a partition, a crash, a UAV not yet joined) leaves the group: it gets an array of
its own, built from the base and its extra scans, and from then on is an ordinary map. (When
fewer members have such a scan than lack it, those few leave instead.) So
does a member written other than by :meth:`GroupMap.stamp` (``scan``, ``cover``, ``merge``).
A map made after the base holds a scan starts on its own (it lacks what the base has).

Reading a member's cells builds them from the base and its extra scans: whole maps into a
buffer the map keeps (rebuilt only after it changed), a few cells (``q_at``) or a region
(:meth:`UncertaintyMap.region`) directly. A member's content changes only when it stamps a
scan (moving a scan into the base changes no member's cells), so the boxes it records for
:meth:`UncertaintyMap.take_changes` are its own stamps' disks, as for an ordinary map.
"""

from __future__ import annotations

import math
from typing import cast

import numpy as np

from agents.maps.grid import Disk, DiskKey, Grid
from agents.maps.umap import DENSE_MAX_CELLS, UncertaintyMap

# A scan some members have and others still lack after this many ticks of the group's clock
# makes those others leave (radio frames arrive within a tick or two when they arrive at all).
LAG_TICKS = 8
# The base's scans of this many recent ticks are listed by key (see MapGroup._known); the list
# is pruned when it grows past _PRUNE_AT.
KNOWN_TICKS = 64
_PRUNE_AT = 8192


def maps_share(cells: int, width_m: float, height_m: float, horizon_m: float) -> bool:
    """Whether the UAVs' maps of an area of ``cells`` cells, ``width_m x height_m``, with a
    knowledge horizon of ``horizon_m`` (``radio.sync_horizon_m``, inf: none) form a
    :class:`MapGroup`: on grids small enough for dense maps, unless the horizon is shorter than
    the area's diagonal. Then some scans never reach every map (a UAV does not apply scans
    beyond its horizon), members only pay for the group and leave it within :data:`LAG_TICKS`
    ticks (bench-dense-300: 299 of 300 in its first 10 s)."""
    return cells <= DENSE_MAX_CELLS and horizon_m >= math.hypot(width_m, height_m)


ScanKey = tuple[DiskKey, float]  # a stamped scan: its disk's (x, y, radius) and its t
Extra = dict[ScanKey, tuple[Disk, float]]  # a member's scans beyond the base: key -> (disk, t)


class MapGroup:
    """A shared base map and its member maps (see the module docstring)."""

    def __init__(self, grid: Grid, tau: float, dt: float):
        self.base = UncertaintyMap(grid, tau, tile="dense")
        # The base's cells: a live read-only view (the base is a dense map written in place).
        self.base_cells = self.base.to_dense_view()
        # Each member (in the order they joined) and its extra scans: the very dict the member
        # reads its cells from (the group moves scans out of it into the base).
        self._members: dict[GroupMap, Extra] = {}
        self.dt = dt
        # Scans some but not all members have: key -> members holding it, and the group clock
        # when it was first stamped (insertion order is that order).
        self._holders: dict[ScanKey, int] = {}
        self._since: dict[ScanKey, float] = {}
        # Scans in the base of the last KNOWN_TICKS ticks (key -> t): a member stamping one
        # again (a resent scan) must not take it for a new one. Older ones are checked against
        # the base's cells instead (the set stays small however long the run).
        self._in_base: dict[ScanKey, float] = {}
        self._prune_at = _PRUNE_AT
        self.clock = -np.inf  # the latest scan time stamped into a member
        self.left = 0  # members that left (for tests and benchmarks)

    @property
    def members(self) -> list[GroupMap]:
        """The member maps, in the order they joined (those that left are not)."""
        return list(self._members)

    def new_map(self) -> UncertaintyMap:
        """A map for a new UAV: a member while the base is empty, else an ordinary map."""
        if self._in_base or self._holders:
            return UncertaintyMap(self.base.grid, self.base.tau)
        extra: Extra = {}
        m = GroupMap(self, extra)
        self._members[m] = extra
        return m

    # --- called by members ------------------------------------------------------------------

    def stamped(self, extra: Extra, key: ScanKey, d: Disk, t: float) -> None:
        """A member whose extra scans are ``extra`` stamped the scan ``key`` (disk ``d`` at ``t``)."""
        if key in extra:
            return
        if t > self.clock:
            self.clock = t
            advanced = True
        else:
            advanced = False
        n = self._holders.get(key)
        if n is not None or not self._known(key, d, t):
            extra[key] = (d, t)
            n = 1 if n is None else n + 1
            if n >= len(self._members):
                self._to_base(key)
            else:
                if n == 1:
                    self._since[key] = self.clock
                self._holders[key] = n
        if advanced:  # (only the clock moving can make a scan overdue)
            self._expire()

    def _known(self, key: ScanKey, d: Disk, t: float) -> bool:
        """Whether a scan no member is waiting for is in the base already (stamping it again
        changes nothing)."""
        if t >= self.clock - KNOWN_TICKS * self.dt:
            return key in self._in_base  # every recent scan of the base is listed
        view = self.base_cells[d.rows, d.cols]
        return bool((view >= d.values(t)).all())  # (-inf outside the disk: always true there)

    def _to_base(self, key: ScanKey) -> None:
        """Every member has this scan: stamp it into the base, drop it from the members."""
        self._holders.pop(key, None)
        self._since.pop(key, None)
        in_base = self._in_base
        in_base[key] = key[1]
        if len(in_base) > self._prune_at:
            oldest = self.clock - KNOWN_TICKS * self.dt
            self._in_base = {k: t for k, t in in_base.items() if t >= oldest}
            self._prune_at = max(_PRUNE_AT, 2 * len(self._in_base))  # (amortised: a big swarm keeps more)
        for extra in self._members.values():  # (never empty here: every member has the scan)
            d, t = extra.pop(key)
        self.base.stamp(d, t)

    def _expire(self) -> None:
        """A scan some members have had for LAG_TICKS ticks and others still lack: the smaller
        side leaves (those lacking it on a tie), so the scan is in every remaining member or
        in none."""
        since = self._since
        limit = self.clock - LAG_TICKS * self.dt
        while since:
            key, t0 = next(iter(since.items()))
            if t0 >= limit:
                return
            lacking = [m for m, extra in self._members.items() if key not in extra]
            having = [m for m, extra in self._members.items() if key in extra]
            for m in (lacking if len(lacking) <= len(having) else having):
                self.release(m)  # (settles the scan: to the base, or dropped with its last holder)

    def release(self, member: GroupMap) -> None:
        """Give ``member`` an array of its own (:meth:`GroupMap.detach`) and take it out of the
        group (nothing if it is not a member)."""
        extra = self._members.pop(member, None)
        if extra is None:
            return
        member.detach()
        self.left += 1
        for key in extra:
            n = self._holders.get(key)
            if n is None:
                continue
            if n > 1:
                self._holders[key] = n - 1
            else:  # its last holder left: no member waits for it any more
                del self._holders[key]
                self._since.pop(key, None)
        # With one member fewer, scans the others all have go to the base.
        for key in [k for k, n in self._holders.items() if n >= len(self._members)]:
            if self._members:
                self._to_base(key)
            else:
                self._holders.pop(key)
                self._since.pop(key)


class GroupMap(UncertaintyMap):
    """A member of a :class:`MapGroup`: an :class:`UncertaintyMap` (dense) whose cells are the
    group's base and its extra scans while it is a member, an array of its own after.

    Every method gives an ordinary map's numbers. One difference: while it is a member,
    :meth:`to_dense_view` is a view of cells built for the call, not of live storage (it does
    not follow later stamps; call it again after them)."""

    __slots__ = ("_group", "_extra", "_writes", "_built")

    def __init__(self, group: MapGroup, extra: Extra):
        base = group.base
        self.grid, self.tau = base.grid, base.tau
        self.tile_shape, self.dense = base.tile_shape, True
        self._nty = self._ntx = 1
        self._tiles = {}  # the built cells (a buffer), or the map's own array once it left
        self._own, self._share = set(), None  # (UncertaintyMap's tile sharing: tiled maps only)
        self._changes = None  # UncertaintyMap.track_changes
        self.derived = None
        self._writes = 0  # stamps while a member: the built cells are current while it is unchanged
        self._group = group
        self._extra: Extra | None = extra  # key -> (disk, t), kept with the group; None: left
        self._built = -1  # _writes when the buffer was built

    @property
    def base(self) -> UncertaintyMap:
        """The group's shared base map (read-only for users: the group writes it)."""
        return self._group.base

    def extra_disks(self) -> list[tuple[Disk, float]] | None:
        """``(disk, t)`` of the scans it has beyond the group's base (outside their disks the
        map equals the base), or None if it is not a member."""
        return None if self._extra is None else list(self._extra.values())

    # --- writes -----------------------------------------------------------------------------

    def stamp(self, d: Disk, t: float) -> None:
        if self._extra is None or d.key is None:
            self._leave()
            return super().stamp(d, t)
        if self._changes is not None:
            self._changed(d.iy0, d.iy1, d.ix0, d.ix1)
        self._writes += 1
        self._group.stamped(self._extra, (d.key, t), d, t)

    def scan_disk(self, d: Disk, t: float) -> int:
        self._leave()
        return super().scan_disk(d, t)

    def cover(self, d: Disk, t: float) -> int:
        self._leave()
        return super().cover(d, t)

    def merge(self, other: UncertaintyMap | np.ndarray) -> None:
        self._leave()
        super().merge(other)

    def _leave(self) -> None:
        if self._extra is not None:
            self._group.release(self)

    def detach(self) -> None:
        """Stop being a member: build the cells into an array of its own (from then on an
        ordinary map). The group calls this when it lets the map go (:meth:`MapGroup.release`)."""
        if self._extra is not None:
            self._own_array()
            self._extra = None

    # --- cells ------------------------------------------------------------------------------

    def _own_array(self) -> None:
        """Build the cells (base, then the extra scans) into the buffer."""
        buf = self._tiles.get(0)
        if buf is None:
            buf = self._tiles[0] = np.empty(self.grid.shape, np.float32)
        np.copyto(buf, self._group.base_cells)
        for d, t in cast("Extra", self._extra).values():  # (a member's: not None)
            view = buf[d.rows, d.cols]
            np.maximum(view, d.values(t), out=view)
        self._built = self._writes

    def _materialize(self) -> None:
        if self._extra is not None and self._built != self._writes:
            self._own_array()

    def region(self, rows: slice, cols: slice) -> np.ndarray:
        if self._extra is None or self._built == self._writes:
            return super().region(rows, cols)
        out = self._group.base_cells[rows, cols].copy()
        r0, c0 = rows.start, cols.start
        for d, t in self._extra.values():
            a, z = max(rows.start, d.iy0), min(rows.stop, d.iy1)
            b, e = max(cols.start, d.ix0), min(cols.stop, d.ix1)
            if a < z and b < e:
                view = out[a - r0 : z - r0, b - c0 : e - c0]
                np.maximum(view, d.values(t)[a - d.iy0 : z - d.iy0, b - d.ix0 : e - d.ix0], out=view)
        return out

    def _cells(self, ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
        ix, iy = np.broadcast_arrays(np.asarray(ix), np.asarray(iy))
        if (self._extra is None or self._built == self._writes or ix.ndim == 0 or ix.dtype.kind not in "iu"
                or iy.dtype.kind not in "iu" or (ix.size and (ix.min() < 0 or iy.min() < 0))):
            self._materialize()  # (whole cells for the unusual cases: index checks as usual)
            return super()._cells(ix, iy)
        seen: np.ndarray = self._group.base_cells[iy, ix]  # a new array (fancy indexing)
        for d, t in self._extra.values():
            r, c = iy - d.iy0, ix - d.ix0
            inside = (r >= 0) & (r < d.iy1 - d.iy0) & (c >= 0) & (c < d.ix1 - d.ix0)
            if inside.any():
                seen[inside] = np.maximum(seen[inside], d.values(t)[r[inside], c[inside]])
        return seen
