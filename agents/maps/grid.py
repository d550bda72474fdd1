"""Grid geometry shared by the agents' maps and the simulator's ground-truth maps.

A map is a 2-D array indexed ``[row, col]`` = ``[iy, ix]``; cell ``(ix, iy)`` covers
``[ix*cell, (ix+1)*cell) x [iy*cell, (iy+1)*cell)`` and its centre is at ``(ix+0.5)*cell``.
A cell is *scanned* by a sensor when its centre lies inside the detection circle.

Scanning is the simulator's hottest operation: every scan record a UAV makes is applied to its
own map, to the ground-truth map and to the map of every UAV that hears it, each time with the
same ``(x, y, radius)``. :meth:`Grid.disk_stamp` therefore memoises the disk geometry (bounding
box and mask, the scan's values ``where(mask, t, -inf)`` and their split over map tiles) per
exact ``(x, y, radius)`` in a small first-in-first-out cache owned by the grid, and
:meth:`Grid.prefetch_disks` builds many at once. The cache is a pure memo of :meth:`Grid.disk`:
hits, misses and prefetched disks give the same cells, so it can never change a result.

The tick plane (issue 36; :meth:`Grid.set_tick_plane`, on unless a simulation runs with
``tick_plane=False``) builds a tick's disks in one batch (near the grid's edges too), and keeps
their cells, bit-packed, in a :class:`DiskArchive` for as long as anti-entropy may resend their
scans: a resent scan (:meth:`UncertaintyMap.stamp_once`) then finds its cells there instead of
computing them. Off, the per-object code it replaces runs: kept as the oracle its property tests
compare it with (``tests/test_tick_geometry.py``), bit for bit.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import Enum
from itertools import islice
from typing import Final, Protocol, TypeVar, cast

import numpy as np

from agents.maps.tiles import TileShare

# Disks remembered per grid by default (about 10 KB each for a 2 km radius on 100 m cells). A
# record is reused within a few ticks (own scan, ground truth, every receiver); a simulation
# sizes the cache to its swarm (set_disk_cache_size). A miss only costs recomputing the disk.
DISK_CACHE_SIZE = 1024
# Fewer disks than this are cheaper one by one (numpy call overhead of the batch): a simulation
# builds the tick's disks together (Grid.prefetch_disks) from this many live UAVs. (Measured with
# the tick plane's batch too: 6 disks cost about twice as much batched as one by one.)
PREFETCH_MIN = 16

DiskKey = tuple[float, float, float]  # (x, y, radius) of a scan: what a Disk is memoised by
# Disk.stamps(): (tile_key, start, stop, values); Disk.pieces(): (tile_key, rows_in_tile,
# cols_in_tile, mask_piece, box_slices).
Stamp = tuple[int, int, int, np.ndarray]
Piece = tuple[int, slice, slice, np.ndarray, tuple[slice, slice]]
# Disk.stamps_memo before the first stamps(): its t (NaN) equals no t, so it never hits.
_NO_STAMPS: Final[tuple[tuple[int, int], float, list[Stamp]]] = ((0, 0), math.nan, [])


class Missing(Enum):
    MISSING = 0


MISSING: Final = Missing.MISSING  # a memo miss (None is a memoised value: a disk off the grid)

_T = TypeVar("_T")


class DiskLookup(Protocol):
    """:meth:`Grid.disk_lookup`: ``lookup(key, default)`` is the memoised disk or ``default``."""

    def __call__(self, key: DiskKey, default: _T, /) -> Disk | None | _T: ...


class _GridCache:
    __slots__ = ("disks", "centres", "size", "nx", "ny", "plane", "archive", "share")

    def __init__(self) -> None:
        self.nx: int | None = None
        self.ny: int | None = None
        self.disks: dict[DiskKey, Disk | None] = {}
        self.centres: tuple[np.ndarray, np.ndarray] | None = None
        self.size = DISK_CACHE_SIZE
        # (issue 36) True: the tick plane's geometry (batched disks, the resend archive); False:
        # the per-object code it replaces, kept as the oracle (Grid.set_tick_plane).
        self.plane = True
        self.archive: DiskArchive | None = None
        # (issue 36, T8) Copy-on-write tiles shared between the tiled maps of this grid made
        # after set_tick_plane(True) (agents.maps.tiles); None: every map keeps its own tiles.
        self.share: TileShare | None = None


_NEVER_BITS = np.uint32(0xFF800000)  # float32 -inf
_F32_PACK = struct.Struct("<f").pack
_F32_BITS = struct.Struct("<I").unpack


def where_seen(mask: np.ndarray, t: float) -> np.ndarray:
    """``np.where(mask, float32(t), -inf)`` (float32, a new array), bit for bit, by integer
    arithmetic on the bits (about 4x cheaper on a batch of disks): ``-inf``'s bits plus
    ``mask`` times the difference to ``float32(t)``'s, modulo 2**32. (``struct``'s ``"f"``
    rounds a float to float32 as numpy does: to nearest, ties to even.)"""
    try:
        bits = _F32_BITS(_F32_PACK(t))[0]
    except OverflowError:  # (beyond float32: numpy rounds it to inf)
        with np.errstate(over="ignore"):
            bits = int(np.float32(t).view(np.uint32))
    delta = np.uint32((bits - 0xFF800000) & 0xFFFFFFFF)
    v = np.multiply(mask, delta, dtype=np.uint32)
    v += _NEVER_BITS
    out: np.ndarray = v.view(np.float32)
    return out


class Disk:
    """The cells of one detection disk: bounding box ``[iy0:iy1, ix0:ix1]`` and a mask over it.

    Immutable once built (the mask is read-only); shared by every map that applies the same
    scan. ``pieces(tile_h, tile_w, ntx)`` splits it over tiles of a tiled map (memoised).
    """

    __slots__ = ("iy0", "iy1", "ix0", "ix1", "rows", "cols", "mask", "_near", "_pieces", "values_memo", "stamps_memo",
                 "key")

    def __init__(self, iy0: int, iy1: int, ix0: int, ix1: int, mask: np.ndarray,
                 near: tuple[int, int] | tuple[np.ndarray, np.ndarray], key: DiskKey | None = None):
        self.iy0, self.iy1, self.ix0, self.ix1 = iy0, iy1, ix0, ix1  # half-open bounds
        # The (x, y, radius) it was built for (disk_stamp, prefetch_disks): names its cells.
        self.key = key
        # Box row/column whose centre is nearest the disk's centre (least dy**2, dx**2), for
        # splitting over tiles: (row, col), or the (dy**2, dx**2) arrays to find them in.
        self._near: tuple[int, int] | tuple[np.ndarray, np.ndarray] = near
        self.rows = slice(iy0, iy1)
        self.cols = slice(ix0, ix1)
        mask.flags.writeable = False
        self.mask = mask
        self._pieces: dict[tuple[int, int], list[Piece]] = {}
        # Memos, each one tuple replaced whole (never seen half-updated): values_memo is
        # (t, values(t)) of the last values() call ((None, None) before it), stamps_memo
        # (tile shape, t, stamps(...)) of the last stamps() call. t as given: a float compares
        # fast, float32(t) is derived. Public, not to be written (keep_values() seeds the first):
        # a map applying a heard scan reads them to skip the call when they match (the
        # per-receiver hot path, UncertaintyMap.stamp).
        self.values_memo: tuple[float, np.ndarray] | tuple[None, None] = (None, None)
        self.stamps_memo: tuple[tuple[int, int], float, list[Stamp]] = _NO_STAMPS

    def _nearest(self) -> tuple[int, int]:
        near = self._near
        if not isinstance(near[0], int):
            near = self._near = (int(near[0].argmin()), int(near[1].argmin()))
        return near

    def values(self, t: float) -> np.ndarray:
        """``where(mask, float32(t), -inf)`` over the box (float32, read-only): ``maximum(box,
        values(t))`` is the scan. Memoised for the last ``t`` (a record is applied by many maps
        at its own t)."""
        memo = self.values_memo
        if memo[0] == t and memo[1] is not None:
            return memo[1]
        # = np.where(mask, float32(t), -inf), built by filling: about a third cheaper on a box
        # this small (each UAV's scan builds one every tick).
        v = np.empty(self.mask.shape, dtype=np.float32)
        v.fill(-np.inf)
        v[self.mask] = t
        v.flags.writeable = False
        self.values_memo = (t, v)
        return v

    def keep_values(self, t: float, values: np.ndarray) -> None:
        """Remember ``values`` (read-only, made elsewhere: :meth:`Grid.prefetch_disks`) as
        :meth:`values` at ``t``."""
        self.values_memo = (t, values)

    def stamps(self, th: int, tw: int, ntx: int, t: float, bands: np.ndarray | None = None) -> list[Stamp]:
        """The scan at ``t`` for a map of flat ``th * tw`` tiles: ``[(tile_key, start, stop,
        values), ...]`` with ``maximum(tile[start:stop], values)`` the scan's effect on the tile.
        Each piece spans whole tile rows (contiguous memory, one fast 1-D ``maximum``); cells of
        those rows outside the disk get ``-inf`` (no change). Memoised for the last tile shape
        and ``t`` (a record is applied by many maps at its own t). ``bands`` (from
        :meth:`Grid.prefetch_disks`): the values already laid out over the touched tile columns."""
        memo = self.stamps_memo
        if memo[1] == t and memo[0] == (th, tw):
            return memo[2]
        iy0, iy1, ix0, ix1 = self.iy0, self.iy1, self.ix0, self.ix1
        tx0, tx1 = ix0 // tw, (ix1 - 1) // tw
        if bands is None:
            # The box's rows over the full width of each tile column it touches.
            v = self.values(t)
            bands = np.empty((tx1 - tx0 + 1, iy1 - iy0, tw), dtype=np.float32)
            bands.fill(-np.inf)
            for b in range(tx1 - tx0 + 1):
                tx = tx0 + b
                c0, c1 = max(ix0, tx * tw), min(ix1, (tx + 1) * tw)
                bands[b, :, c0 - tx * tw : c1 - tx * tw] = v[:, c0 - ix0 : c1 - ix0]
            bands.flags.writeable = False
        # A tile holds a cell of the disk iff its cell nearest the disk's centre does (see pieces()).
        near_r, near_c = self._nearest()
        item = self.mask.item
        st: list[Stamp] = []
        for ty in range(iy0 // th, (iy1 - 1) // th + 1):
            r0, r1 = max(iy0, ty * th) - iy0, min(iy1, (ty + 1) * th) - iy0
            nr = min(max(near_r, r0), r1 - 1)
            base = iy0 - ty * th
            for b in range(tx1 - tx0 + 1):
                tx = tx0 + b
                c0, c1 = max(ix0, tx * tw) - ix0, min(ix1, (tx + 1) * tw) - ix0
                if item(nr, min(max(near_c, c0), c1 - 1)):
                    st.append((ty * ntx + tx, (r0 + base) * tw, (r1 + base) * tw, bands[b, r0:r1].reshape(-1)))
        self.stamps_memo = ((th, tw), t, st)
        return st

    def pieces(self, th: int, tw: int, ntx: int) -> list[Piece]:
        """``[(tile_key, rows_in_tile, cols_in_tile, mask_piece, box_slices), ...]`` for tiles of
        ``th x tw`` cells, ``tile_key = ty * ntx + tx``, ``box_slices`` the piece within the
        disk's box; tiles the disk touches without covering any cell centre are left out (so
        they are never allocated)."""
        key = (th, tw)
        p = self._pieces.get(key)
        if p is not None:
            return p
        p = []
        mask = self.mask
        iy0, iy1, ix0, ix1 = self.iy0, self.iy1, self.ix0, self.ix1
        ty0, tx0 = iy0 // th, ix0 // tw
        if ty0 == (iy1 - 1) // th and tx0 == (ix1 - 1) // tw:  # inside one tile (a disk is never empty)
            p.append((ty0 * ntx + tx0, slice(iy0 - ty0 * th, iy1 - ty0 * th), slice(ix0 - tx0 * tw, ix1 - tx0 * tw),
                      mask, (slice(0, iy1 - iy0), slice(0, ix1 - ix0))))
            self._pieces[key] = p
            return p
        # A piece holds a cell of the disk iff its cell nearest the disk's centre does: dx**2 and
        # dy**2 (as computed, rounding included) grow monotonically away from the nearest
        # row/column, and so does their sum. One lookup instead of scanning the piece.
        near_r, near_c = self._nearest()
        item = mask.item
        for ty in range(iy0 // th, (iy1 - 1) // th + 1):
            r0, r1 = max(iy0, ty * th) - iy0, min(iy1, (ty + 1) * th) - iy0
            nr = min(max(near_r, r0), r1 - 1)
            for tx in range(ix0 // tw, (ix1 - 1) // tw + 1):
                c0, c1 = max(ix0, tx * tw) - ix0, min(ix1, (tx + 1) * tw) - ix0
                if item(nr, min(max(near_c, c0), c1 - 1)):
                    box = (slice(r0, r1), slice(c0, c1))
                    p.append((ty * ntx + tx, slice(r0 + iy0 - ty * th, r1 + iy0 - ty * th),
                              slice(c0 + ix0 - tx * tw, c1 + ix0 - tx * tw), mask[box], box))
        self._pieces[key] = p
        return p


# The most disks a DiskArchive keeps however long its horizon (the oldest go first): about 150 MB
# of 2 km disks on 100 m cells. bench-1000's 600 s horizon would need 600 000: the last 524 s are
# kept, where nearly all resent scans lie (bench-100 over 600 s: ages 197 s median, 543 s 99th
# percentile).
ARCHIVE_MAX_ROWS = 1 << 19


class DiskArchive:
    """The geometry of the disks :meth:`Grid.prefetch_disks` built in the last ``keep_s``
    seconds, compact, for the scans anti-entropy resends (:meth:`UncertaintyMap.stamp_once`).

    A resent scan is up to ``radio.sync_horizon_s`` old, long out of :meth:`Grid.disk_stamp`'s
    memo, and usually goes to one UAV: building a :class:`Disk` and its tile bands for it costs
    several times the stamp. The archive keeps, per exact ``(x, y, radius)``, the disk's box, the
    row and column nearest its centre and its mask as bits (about 230 bytes for a 2 km radius on
    100 m cells), in a ring of rows oldest first, dropped once older than ``keep_s`` (or beyond
    :data:`ARCHIVE_MAX_ROWS`). No Python object per disk (the garbage collector would walk them
    all): rows are found by the key's ``hash`` and checked against the stored ``(x, y,
    radius)``. A pure memo: :meth:`get` gives exactly :meth:`Grid.disk`'s cells, and a miss (a
    hash collision included) only costs computing them.
    """

    __slots__ = ("keep_s", "rows", "meta", "xyr", "bits", "when", "hashes", "head", "count")

    def __init__(self, keep_s: float):
        self.keep_s = float(keep_s)
        self.rows: dict[int, int] = {}  # hash(key) -> its newest row
        cap = 1024
        # Per row: iy0, ix0, h, w (the box), the packed mask's row length, nearest row, column.
        self.meta = np.zeros((cap, 7), np.int32)
        self.xyr = np.zeros((cap, 3))  # the key
        self.bits = np.zeros((cap, 8), np.uint8)
        self.when = np.zeros(cap)  # the time of the batch that built it
        self.hashes = [0] * cap
        self.head = 0  # the next row written
        self.count = 0  # rows held: the oldest is head - count (mod capacity)

    def __len__(self) -> int:
        return self.count

    def add(self, keys: list[DiskKey], xyr: tuple[np.ndarray | float, ...], meta: tuple[np.ndarray | int, ...],
            bits: np.ndarray, t: float) -> None:
        """Archive the disks ``keys`` of a batch at ``t``: ``xyr`` the keys' columns, ``meta``
        the ring's seven columns, ``bits`` the packed masks, one row per key (a number stands
        for a column of it); drops what is older than ``t - keep_s`` first."""
        cap = len(self.hashes)
        rows, hashes, when = self.rows, self.hashes, self.when
        cut = t - self.keep_s
        m = len(keys)
        while self.count:
            old = (self.head - self.count) % cap
            if when[old] >= cut and self.count + m <= ARCHIVE_MAX_ROWS:
                break
            h = hashes[old]
            if rows.get(h) == old:  # (not re-archived since)
                del rows[h]
            self.count -= 1
        if self.count + m > cap or bits.shape[1] > self.bits.shape[1]:
            self._grow(self.count + m, bits.shape[1])
            cap, rows, hashes, when = len(self.hashes), self.rows, self.hashes, self.when
        new = [hash(k) for k in keys]
        head = self.head
        at: slice | np.ndarray = slice(head, head + m) if head + m <= cap else (head + np.arange(m)) % cap
        for j, col in enumerate(meta):
            self.meta[at, j] = col
        for j, key_col in enumerate(xyr):
            self.xyr[at, j] = key_col
        self.bits[at, : bits.shape[1]] = bits
        when[at] = t
        if isinstance(at, slice):
            hashes[at] = new
            rows.update(zip(new, range(head, head + m)))
        else:
            for h, row in zip(new, at.tolist()):
                rows[h] = row
                hashes[row] = h
        self.head = (head + m) % cap
        self.count += m

    def _grow(self, need: int, width: int) -> None:
        """Room for ``need`` rows of ``width`` mask bytes: the rows laid out afresh, oldest first."""
        cap = len(self.hashes)
        new_cap = cap
        while new_cap < need:
            new_cap *= 2
        n = self.count
        order = (self.head - n + np.arange(n)) % cap
        meta, xyr = np.zeros((new_cap, 7), np.int32), np.zeros((new_cap, 3))
        bits = np.zeros((new_cap, max(width, self.bits.shape[1])), np.uint8)
        when = np.zeros(new_cap)
        meta[:n], xyr[:n], when[:n] = self.meta[order], self.xyr[order], self.when[order]
        bits[:n, : self.bits.shape[1]] = self.bits[order]
        hashes = [self.hashes[i] for i in order.tolist()] + [0] * (new_cap - n)
        self.meta, self.xyr, self.bits, self.when, self.hashes = meta, xyr, bits, when, hashes
        self.rows = {h: i for i, h in enumerate(hashes[:n])}  # (later rows win: the newest)
        self.head = n % new_cap

    def get(self, key: DiskKey) -> tuple[int, int, int, int, np.ndarray, int, int] | None:
        """``(iy0, iy1, ix0, ix1, mask, near_row, near_col)`` of an archived disk (half-open
        bounds; the mask over the box), or None if it is not archived."""
        row = self.rows.get(hash(key))
        if row is None or tuple(self.xyr[row].tolist()) != key:
            return None
        iy0, ix0, h, w, rw, nr, nc = self.meta[row].tolist()
        mask = np.unpackbits(self.bits[row], count=h * rw).view(np.bool_).reshape(h, rw)[:, :w]
        return iy0, iy0 + h, ix0, ix0 + w, mask, nr, nc


@dataclass(frozen=True, slots=True)
class Grid:
    width_m: float
    height_m: float
    cell_m: float
    # Memo of disk_stamp() and the cell centres; not part of the grid's value (equality, hash, repr).
    _cache: _GridCache = field(default_factory=lambda: _GridCache(), init=False, repr=False, compare=False, hash=False)

    @property
    def nx(self) -> int:
        c = self._cache
        if c.nx is None:
            c.nx = int(round(self.width_m / self.cell_m))
        return c.nx

    @property
    def ny(self) -> int:
        c = self._cache
        if c.ny is None:
            c.ny = int(round(self.height_m / self.cell_m))
        return c.ny

    @property
    def shape(self) -> tuple[int, int]:
        return (self.ny, self.nx)

    def cells_of(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ix = np.clip((np.asarray(x) // self.cell_m).astype(np.int64), 0, self.nx - 1)
        iy = np.clip((np.asarray(y) // self.cell_m).astype(np.int64), 0, self.ny - 1)
        return ix, iy

    def contains(self, x: float, y: float) -> bool:
        return 0.0 <= x <= self.width_m and 0.0 <= y <= self.height_m

    def _disk_bounds(self, x: float, y: float, radius: float
                     ) -> tuple[int, int, int, int, np.ndarray, np.ndarray, np.ndarray] | None:
        """``(iy0, iy1, ix0, ix1, mask, dy**2, dx**2)`` (inclusive bounds) or ``None``."""
        c = self.cell_m
        # Centres are at (i + 0.5) * c; first/last index whose centre may lie inside.
        # One spare cell each side: the box only has to contain the disk, the mask decides (a
        # rounded box edge could otherwise drop a centre lying exactly on the circle).
        # (math.ceil/floor equal int(np.ceil/np.floor(...)) for every float, errors included.)
        ix0 = math.ceil((x - radius) / c - 0.5) - 1
        ix1 = math.floor((x + radius) / c - 0.5) + 1
        iy0 = math.ceil((y - radius) / c - 0.5) - 1
        iy1 = math.floor((y + radius) / c - 0.5) + 1
        # Clipped to the grid (conditional expressions: max()/min() would cost more than the
        # arithmetic; every UAV's scan builds a disk every tick).
        nx1, ny1 = self.nx - 1, self.ny - 1
        ix0, iy0 = (ix0 if ix0 > 0 else 0), (iy0 if iy0 > 0 else 0)
        ix1, iy1 = (ix1 if ix1 < nx1 else nx1), (iy1 if iy1 < ny1 else ny1)
        if ix1 < ix0 or iy1 < iy0:
            return None
        # (arange(i0, i1 + 1) + 0.5) * c, the cell centres, computed once per grid.
        centres_x, centres_y = self._centres()
        dx2 = (centres_x[ix0 : ix1 + 1] - x) ** 2
        dy2 = (centres_y[iy0 : iy1 + 1] - y) ** 2
        mask = np.add.outer(dy2, dx2) <= radius * radius  # = dy[:, None]**2 + dx[None, :]**2 <= r**2
        # A centre inside the area with radius >= one cell always covers the centre of the cell
        # it lies in (at most cell * sqrt(2) / 2 away): only other disks need the check.
        if not (radius >= c and 0.0 <= x <= self.width_m and 0.0 <= y <= self.height_m) and not mask.any():
            return None
        return iy0, iy1, ix0, ix1, mask, dy2, dx2

    def disk_box(self, x: float, y: float, radius: float
                 ) -> tuple[int, int, int, int, np.ndarray, np.ndarray, np.ndarray] | None:
        """``(iy0, iy1, ix0, ix1, mask, dy**2, dx**2)`` of the disk (inclusive bounds; the mask
        over the box), or None: the geometry of :meth:`disk_stamp` without a shared
        :class:`Disk` (for a scan applied once, :meth:`UncertaintyMap.stamp_once`)."""
        return self._disk_bounds(x, y, radius)

    def _centres(self) -> tuple[np.ndarray, np.ndarray]:
        cache = self._cache
        if cache.centres is None:
            cache.centres = ((np.arange(self.nx) + 0.5) * self.cell_m, (np.arange(self.ny) + 0.5) * self.cell_m)
        return cache.centres

    def disk(self, x: float, y: float, radius: float) -> tuple[slice, slice, np.ndarray] | None:
        """The cells whose centres lie within ``radius`` of ``(x, y)``.

        Returns ``(rows, cols, mask)``: a bounding-box slice of the map and a boolean mask over
        it, or ``None`` when no cell centre is inside (disk entirely off the grid).
        """
        b = self._disk_bounds(x, y, radius)
        if b is None:
            return None
        iy0, iy1, ix0, ix1, mask = b[:5]
        return slice(iy0, iy1 + 1), slice(ix0, ix1 + 1), mask

    def disk_stamp(self, x: float, y: float, radius: float) -> Disk | None:
        """:meth:`disk` as a shared, read-only :class:`Disk`, memoised per exact ``(x, y, radius)``."""
        key = (x, y, radius)
        c = self._cache
        cache = c.disks
        d = cache.get(key, MISSING)  # (not try/except: each UAV's own scan is a miss, every tick)
        if d is not MISSING:
            return d
        b = self._disk_bounds(x, y, radius)
        d = None if b is None else Disk(b[0], b[1] + 1, b[2], b[3] + 1, b[4], (b[5], b[6]), key)
        if len(cache) >= c.size:
            for k in list(islice(cache, max(1, c.size // 4))):  # oldest first (insertion order)
                del cache[k]
        cache[key] = d
        return d

    def disk_lookup(self) -> DiskLookup:
        """The memo of :meth:`disk_stamp` as a ``get``: ``lookup((x, y, radius), default)`` is the
        memoised disk (``None``: off the grid) or ``default``; for hot loops, which fall back on
        :meth:`disk_stamp` when it gives ``default``."""
        return self._cache.disks.get

    def prefetch_disks(self, xs: Iterable[float], ys: Iterable[float], radii: Iterable[float], t: float | None = None,
                       tiles: tuple[int, int] | None = None) -> None:
        """Build the disks of many scans at once (vectorised) into :meth:`disk_stamp`'s memo.

        Exactly what :meth:`disk_stamp` would build for each ``(x, y, radius)``: the same
        element-wise arithmetic, only batched (a simulation prefetches the scans of all its
        UAVs at the start of a tick). With ``t``, each disk's :meth:`Disk.values` for ``t`` is
        prepared too, and with ``tiles=(th, tw)`` its :meth:`Disk.stamps` for maps of such
        tiles. With the tick plane (:meth:`set_tick_plane`) every disk is built in the batch
        (:meth:`_build_batch`) and archived for resends; without it (the oracle), disks near the
        grid's edge, already known, or smaller than a cell are left to :meth:`disk_stamp`.
        Batches of fewer than :data:`PREFETCH_MIN` new disks are left to it either way.
        """
        cache = self._cache
        disks = cache.disks
        todo = [(x, y, r) for x, y, r in zip(xs, ys, radii) if (x, y, r) not in disks]
        if len(todo) < PREFETCH_MIN:
            return
        if cache.plane:
            self._build_batch(todo, t, tiles)
            return
        c = self.cell_m
        a = np.array(todo, dtype=np.float64)
        x, y, r = a[:, 0], a[:, 1], a[:, 2]
        # The scalar path's bounds, element-wise (same float operations; ceil/floor are exact).
        ix0 = np.ceil((x - r) / c - 0.5) - 1
        ix1 = np.floor((x + r) / c - 0.5) + 1
        iy0 = np.ceil((y - r) / c - 0.5) - 1
        iy1 = np.floor((y + r) / c - 0.5) + 1
        ok = ((r >= c) & (x >= 0.0) & (x <= self.width_m) & (y >= 0.0) & (y <= self.height_m)
              & (ix0 >= 0) & (iy0 >= 0) & (ix1 <= self.nx - 1) & (iy1 <= self.ny - 1))
        if not ok.any():
            return
        ix0, ix1, iy0, iy1 = (np.where(ok, v, 0.0).astype(np.int64) for v in (ix0, ix1, iy0, iy1))
        groups: dict[tuple[float, int, int], list[int]] = {}
        okl = np.flatnonzero(ok)
        for i, r_i, h_i, w_i in zip(okl.tolist(), r[okl].tolist(), (iy1 - iy0 + 1)[okl].tolist(),
                                    (ix1 - ix0 + 1)[okl].tolist()):
            groups.setdefault((r_i, h_i, w_i), []).append(i)
        centres_x, centres_y = self._centres()
        t32 = None if t is None else np.float32(t)
        ntx = -(-self.nx // tiles[1]) if tiles is not None else 0
        for (radius, h, w), members in groups.items():
            idx = np.array(members)
            dx2 = (centres_x[ix0[idx][:, None] + np.arange(w)] - x[idx][:, None]) ** 2
            dy2 = (centres_y[iy0[idx][:, None] + np.arange(h)] - y[idx][:, None]) ** 2
            mask = (dy2[:, :, None] + dx2[:, None, :]) <= radius * radius
            near_r = dy2.argmin(axis=1).tolist()
            near_c = dx2.argmin(axis=1).tolist()
            mask.flags.writeable = False
            values = None
            if t32 is not None:
                values = np.where(mask, t32, np.float32(-np.inf))
                values.flags.writeable = False
            if values is not None and tiles is not None:
                self._prefetch_stamps(todo, members, cast(float, t), tiles, ntx,
                                      ix0[idx], iy0[idx], h, w, mask, values, near_r, near_c)
                continue
            for k, i in enumerate(members):
                d = Disk(int(iy0[i]), int(iy1[i]) + 1, int(ix0[i]), int(ix1[i]) + 1, mask[k], (near_r[k], near_c[k]),
                         todo[i])
                if values is not None:
                    d.keep_values(cast(float, t), values[k])  # (t is not None: values were made for it)
                disks[todo[i]] = d
        if len(disks) > cache.size:
            for old in list(islice(disks, len(disks) - cache.size)):  # oldest first
                del disks[old]

    def _prefetch_stamps(self, todo: list[DiskKey], members: list[int], t: float, tiles: tuple[int, int], ntx: int,
                         ix0: np.ndarray, iy0: np.ndarray, h: int, w: int, mask: np.ndarray, values: np.ndarray,
                         near_r: list[int], near_c: list[int]) -> None:
        """prefetch_disks' disks of one (radius, h, w) group, with their values and their
        :meth:`Disk.stamps` for maps of ``tiles``, all made at once: the tiles each disk holds a
        cell of are found by stamps()'s nearest-cell test for all disks together, listed in
        stamps()'s order (issue 25: splitting each disk in its own loop was most of a disk's
        20 us)."""
        th, tw = tiles
        m = len(members)
        tx0 = ix0 // tw
        # Each disk's values over the full width of the tile columns it touches: column j of the
        # box goes to band (a + j) // tw, column (a + j) % tw.
        pos = (ix0 % tw)[:, None] + np.arange(w)
        nc = int(pos.max()) // tw + 1
        bands = np.empty((m, nc, h, tw), dtype=np.float32)
        bands.fill(-np.inf)
        bands[np.arange(m)[:, None], pos // tw, :, pos % tw] = np.swapaxes(values, 1, 2)
        bands.flags.writeable = False
        # Candidate pieces (disk, tile row j, tile column b): rows r0:r1 and columns c0:c1 of the box.
        ty0 = iy0 // th
        nr = int(((iy0 + h - 1) // th - ty0).max()) + 1
        ty = ty0[:, None] + np.arange(nr)  # (m, nr)
        r0 = np.maximum(iy0[:, None], ty * th) - iy0[:, None]
        r1 = np.minimum(iy0[:, None] + h, (ty + 1) * th) - iy0[:, None]
        tx = tx0[:, None] + np.arange(nc)  # (m, nc)
        c0 = np.maximum(ix0[:, None], tx * tw) - ix0[:, None]
        c1 = np.minimum(ix0[:, None] + w, (tx + 1) * tw) - ix0[:, None]
        nrr = np.clip(np.asarray(near_r)[:, None], r0, r1 - 1)
        ncc = np.clip(np.asarray(near_c)[:, None], c0, c1 - 1)
        valid = (r1 > r0)[:, :, None] & (c1 > c0)[:, None, :]
        kk = np.arange(m)[:, None, None]
        hit = valid & mask[kk, np.clip(nrr, 0, h - 1)[:, :, None], np.clip(ncc, 0, w - 1)[:, None, :]]
        hk, hj, hb_a = np.nonzero(hit)  # (row-major: per disk, by tile row then column)
        hb = hb_a.tolist()
        keys = (ty[hk, hj] * ntx + tx[hk, hb_a]).tolist()
        base = iy0[hk] - ty[hk, hj] * th
        starts = ((r0[hk, hj] + base) * tw).tolist()
        stops = ((r1[hk, hj] + base) * tw).tolist()
        rr0, rr1 = r0[hk, hj].tolist(), r1[hk, hj].tolist()
        per_disk = np.bincount(hk, minlength=m).tolist()
        disks = self._cache.disks
        shape = (th, tw)
        p = 0
        for k, i in enumerate(members):
            key = todo[i]
            ix = int(ix0[k])
            d = Disk(int(iy0[k]), int(iy0[k]) + h, ix, ix + w, mask[k], (near_r[k], near_c[k]), key)
            d.keep_values(t, values[k])
            bk = bands[k]
            st: list[Stamp] = []
            for q in range(p, p + per_disk[k]):
                st.append((keys[q], starts[q], stops[q], bk[hb[q], rr0[q]:rr1[q]].reshape(-1)))
            p += per_disk[k]
            d.stamps_memo = (shape, t, st)
            disks[key] = d

    def _build_batch(self, todo: list[DiskKey], t: float | None, tiles: tuple[int, int] | None) -> None:
        """The tick plane's :meth:`prefetch_disks`: every disk of ``todo`` (not yet known) built
        at once, exactly as :meth:`disk_stamp` builds it one by one (the same element-wise float
        operations), with its values at ``t`` and its :meth:`Disk.stamps` for maps of ``tiles``,
        into the memo and (for tiled maps, the only ones stamping resends apart) the resend
        archive. The bounds of all at once, then the rest per radius (:meth:`_build_group`)."""
        cache = self._cache
        c = self.cell_m
        nx, ny = self.nx, self.ny
        a = np.array(todo, dtype=np.float64)
        x, y, r = a[:, 0], a[:, 1], a[:, 2]
        with np.errstate(invalid="ignore", over="ignore"):
            # _disk_bounds' bounds, element-wise (same float operations; ceil/floor are exact),
            # then clipped to the grid.
            fx0 = np.maximum(np.ceil((x - r) / c - 0.5) - 1, 0.0)
            fx1 = np.minimum(np.floor((x + r) / c - 0.5) + 1, nx - 1.0)
            fy0 = np.maximum(np.ceil((y - r) / c - 0.5) - 1, 0.0)
            fy1 = np.minimum(np.floor((y + r) / c - 0.5) + 1, ny - 1.0)
            # Numbers no arithmetic here holds exactly are left to disk_stamp (none are honest).
            ok = (np.abs(a).max(axis=1) < 1e15) & (r >= 0.0)
        disks = cache.disks
        empty = ok & ((fx1 < fx0) | (fy1 < fy0))
        if empty.any():
            ok &= ~empty
            for i in np.flatnonzero(empty).tolist():
                disks[todo[i]] = None
        if not ok.all():
            if not ok.any():
                return
            sel = np.flatnonzero(ok)
            todo = [todo[i] for i in sel.tolist()]
            x, y, r, fx0, fx1, fy0, fy1 = x[sel], y[sel], r[sel], fx0[sel], fx1[sel], fy0[sel], fy1[sel]
        ix0, iy0 = fx0.astype(np.int64), fy0.astype(np.int64)
        ws, hs = fx1.astype(np.int64) + 1 - ix0, fy1.astype(np.int64) + 1 - iy0
        # _disk_bounds checks the mask for a cell only when the centre may cover none.
        check = ~((r >= c) & (x >= 0.0) & (x <= self.width_m) & (y >= 0.0) & (y <= self.height_m))
        radii, which = np.unique(r, return_inverse=True)
        for g in range(len(radii)):
            idx = np.flatnonzero(which == g) if len(radii) > 1 else None
            if idx is None:
                self._build_group(todo, x, y, float(radii[g]), ix0, iy0, hs, ws, check, t, tiles)
            else:
                self._build_group([todo[i] for i in idx.tolist()], x[idx], y[idx], float(radii[g]), ix0[idx], iy0[idx],
                                  hs[idx], ws[idx], check[idx], t, tiles)
        if len(disks) > cache.size:
            for old in list(islice(disks, len(disks) - cache.size)):  # oldest first
                del disks[old]

    def _build_group(self, todo: list[DiskKey], x: np.ndarray, y: np.ndarray, radius: float, ix0: np.ndarray,
                     iy0: np.ndarray, hs: np.ndarray, ws: np.ndarray, check: np.ndarray, t: float | None,
                     tiles: tuple[int, int] | None) -> None:
        """:meth:`_build_batch`'s disks of one radius (boxes ``[iy0:iy0+hs, ix0:ix0+ws]``, on the
        grid). They share one padded ``(H, W)`` box (the largest): a disk's mask, values and
        squared distances are its top-left ``(h, w)`` corner (cells beyond it are never read)."""
        cache = self._cache
        disks = cache.disks
        m = len(todo)
        nx, ny = self.nx, self.ny
        H, W = int(hs.max()), int(ws.max())
        ch, cw = np.arange(H), np.arange(W)
        centres_x, centres_y = self._centres()
        # (cx[ix0:ix1+1] - x) ** 2 per disk; beyond its own width +inf (outside the mask, never
        # the nearest column).
        dx2 = (centres_x[np.minimum(ix0[:, None] + cw, nx - 1)] - x[:, None]) ** 2
        dy2 = (centres_y[np.minimum(iy0[:, None] + ch, ny - 1)] - y[:, None]) ** 2
        if W > int(ws.min()):
            dx2[cw >= ws[:, None]] = np.inf
        if H > int(hs.min()):
            dy2[ch >= hs[:, None]] = np.inf
        mask = (dy2[:, :, None] + dx2[:, None, :]) <= radius * radius
        keep = (~check | mask.reshape(m, -1).any(axis=1)) if check.any() else None
        near_r = dy2.argmin(axis=1)
        near_c = dx2.argmin(axis=1)
        mask.flags.writeable = False
        values = None
        stamps: list[list[Stamp]] | None = None
        if t is not None:
            values = where_seen(mask, t)
            values.flags.writeable = False
            if tiles is not None:
                stamps = self._batch_stamps(tiles, ix0, iy0, hs, ws, H, mask, values, near_r, near_c)
        archive = cache.archive
        if archive is not None and t is not None and tiles is not None:  # (only tiled maps stamp_once)
            if keep is None:
                archive.add(todo, (x, y, radius), (iy0, ix0, hs, ws, W, near_r, near_c),
                            np.packbits(mask.reshape(m, -1), axis=1), t)
            elif keep.any():
                kk = np.flatnonzero(keep)
                archive.add([todo[k] for k in kk.tolist()], (x[kk], y[kk], radius),
                            (iy0[kk], ix0[kk], hs[kk], ws[kk], W, near_r[kk], near_c[kk]),
                            np.packbits(mask[kk].reshape(len(kk), -1), axis=1), t)
        kept = [True] * m if keep is None else keep.tolist()
        for k, (key, y0, x0, h, w, nr, nc) in enumerate(zip(todo, iy0.tolist(), ix0.tolist(), hs.tolist(), ws.tolist(),
                                                             near_r.tolist(), near_c.tolist())):
            if not kept[k]:
                disks[key] = None
                continue
            d = Disk(y0, y0 + h, x0, x0 + w, mask[k, :h, :w], (nr, nc), key)
            if values is not None:
                d.values_memo = (cast(float, t), values[k, :h, :w])
                if stamps is not None:
                    d.stamps_memo = (cast(tuple[int, int], tiles), cast(float, t), stamps[k])
            disks[key] = d

    def _batch_stamps(self, tiles: tuple[int, int], ix0: np.ndarray, iy0: np.ndarray, hs: np.ndarray, ws: np.ndarray,
                      H: int, mask: np.ndarray, values: np.ndarray, near_r: np.ndarray, near_c: np.ndarray
                      ) -> list[list[Stamp]]:
        """:meth:`Disk.stamps` of a group's disks of one padded ``(H, W)`` box (:meth:`_build_group`),
        all made at once: each disk's values laid over the full width of the tile columns it
        touches, and the tiles holding a cell of it found by stamps()'s nearest-cell test for all
        disks together, listed in stamps()'s order; each piece a slice of the disk's flat bands."""
        th, tw = tiles
        m, _, W = mask.shape
        ntx = -(-self.nx // tw)
        # Each disk's values over the full width of the tile columns it touches (rows of the
        # padded box; -inf outside the disk): column j of the box goes to band (a + j) // tw,
        # column (a + j) % tw, a = ix0 % tw.
        pos = (ix0 % tw)[:, None] + np.arange(W)
        nc = int(pos[:, -1].max()) // tw + 1
        bands = np.empty((m, nc, H, tw), dtype=np.float32)
        bands.fill(-np.inf)
        bands[np.arange(m)[:, None], pos // tw, :, pos % tw] = np.swapaxes(values, 1, 2)
        bands.flags.writeable = False
        # Candidate pieces (disk, tile row j, tile column b): rows r0:r1 and columns c0:c1 of the box.
        tx0, ty0 = ix0 // tw, iy0 // th
        nr = int(((iy0 + hs - 1) // th - ty0).max()) + 1
        ty = ty0[:, None] + np.arange(nr)  # (m, nr)
        r0 = np.maximum(iy0[:, None], ty * th) - iy0[:, None]
        r1 = np.minimum((iy0 + hs)[:, None], (ty + 1) * th) - iy0[:, None]
        tx = tx0[:, None] + np.arange(nc)  # (m, nc)
        c0 = np.maximum(ix0[:, None], tx * tw) - ix0[:, None]
        c1 = np.minimum((ix0 + ws)[:, None], (tx + 1) * tw) - ix0[:, None]
        nrr = np.clip(near_r[:, None], r0, r1 - 1)
        ncc = np.clip(near_c[:, None], c0, c1 - 1)
        valid = (r1 > r0)[:, :, None] & (c1 > c0)[:, None, :]
        kk = np.arange(m)[:, None, None]
        hit = valid & mask[kk, np.clip(nrr, 0, H - 1)[:, :, None], np.clip(ncc, 0, W - 1)[:, None, :]]
        hk, hj, hb = np.nonzero(hit)  # (row-major: per disk, by tile row then column)
        rr0, rr1 = r0[hk, hj], r1[hk, hj]
        base = iy0[hk] - ty[hk, hj] * th
        # Per piece: tile key, start and stop in the tile, start and stop in the disk's flat bands.
        pieces = np.stack([ty[hk, hj] * ntx + tx[hk, hb], (rr0 + base) * tw, (rr1 + base) * tw,
                           (hb * H + rr0) * tw, (hb * H + rr1) * tw], axis=1).tolist()
        flat = bands.reshape(m, -1)
        out: list[list[Stamp]] = []
        p = 0
        for k, n in enumerate(np.bincount(hk, minlength=m).tolist()):
            fk = flat[k]
            out.append([(key, start, stop, fk[a0:a1]) for key, start, stop, a0, a1 in pieces[p : p + n]])
            p += n
        return out

    def set_tick_plane(self, on: bool, resend_keep_s: float = 0.0) -> None:
        """(issue 36) ``on``: the tick plane's disk geometry: :meth:`prefetch_disks` builds every
        disk of a tick in one batch, and with ``resend_keep_s > 0`` keeps their cells that long
        in a :class:`DiskArchive` for anti-entropy resends (:meth:`UncertaintyMap.stamp_once`);
        and tiled maps made on the grid from then on share tiles copy-on-write
        (:mod:`agents.maps.tiles`; the simulation calls :meth:`new_tick` every tick). Off: the
        per-object code it replaces (the oracle), every map with tiles of its own. The same
        cells either way."""
        cache = self._cache
        cache.plane = bool(on)
        cache.archive = DiskArchive(resend_keep_s) if on and resend_keep_s > 0 else None
        cache.share = TileShare() if on else None

    @property
    def tick_plane(self) -> bool:
        return self._cache.plane

    @property
    def tile_share(self) -> TileShare | None:
        """(issue 36, T8) The copy-on-write tile sharing of the tiled maps made on this grid
        from now on (:mod:`agents.maps.tiles`): on with :meth:`set_tick_plane`, else None."""
        return self._cache.share

    def new_tick(self) -> None:
        """A simulation's tick begins: the tile sharing's memo of the last tick is flushed
        (:meth:`agents.maps.tiles.TileShare.flush`). Changes no map's cells."""
        share = self._cache.share
        if share is not None:
            share.flush()

    def disk_cells(self, x: float, y: float, radius: float) -> tuple[int, int, int, int, np.ndarray, int, int] | None:
        """``(iy0, iy1, ix0, ix1, mask, near_row, near_col)`` of the disk of ``(x, y, radius)``
        (half-open bounds, the mask over the box, the box row and column nearest the centre), or
        None when no cell centre is inside: from the resend archive when it holds the disk, else
        computed (:meth:`disk_box`). For a scan applied once (:meth:`UncertaintyMap.stamp_once`)."""
        archive = self._cache.archive
        if archive is not None:
            got = archive.get((x, y, radius))
            if got is not None:
                return got
        b = self._disk_bounds(x, y, radius)
        if b is None:
            return None
        iy0, iy1, ix0, ix1, mask, dy2, dx2 = b
        return iy0, iy1 + 1, ix0, ix1 + 1, mask, int(dy2.argmin()), int(dx2.argmin())

    def set_disk_cache_size(self, n: int) -> None:
        """How many disks :meth:`disk_stamp` remembers (a simulation sizes it to its swarm)."""
        self._cache.size = max(1, int(n))
