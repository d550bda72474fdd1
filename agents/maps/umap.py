"""A UAV's uncertainty map (DACMP eq. 7) as a state-based CRDT.

The state is one number per cell: the simulated time the cell was last scanned (``-inf`` if
never). Uncertainty is derived, not stored: ``q = 1 - exp(-tau * (t - last_seen))``, so a
never-seen cell has ``q = 1`` and a cell being scanned has ``q = 0``.

Everything that changes the map is a per-cell ``max``: scanning a disk at time ``t``, applying a
heard scan record, merging a whole heard map. ``max`` is commutative, associative and
idempotent, so frames lost, duplicated or reordered on the radio can delay agreement between
UAVs but never corrupt it, and a map never forgets (last-seen times never decrease).

Storage. The grid is cut into fixed-size tiles (64 x 64 cells by default, 16 KB of float32);
a tile is allocated the first time a cell in it is written, and a tile never written is
implicitly ``-inf`` everywhere. So a UAV's map costs memory for the tiles it (or a UAV it
heard) has scanned, not for the whole area: on a 650 km square at 100 m cells a dense map
would be 42 M cells (169 MB) per UAV. Grids of at most :data:`DENSE_MAX_CELLS` cells (the
paper's 500 x 500 is 250 000) are one tile covering the whole grid, allocated at once: the
fastest layout when every map ends up covering most of a small area anyway. Either way every
method gives exactly the numbers of one dense ``float32`` array (``to_dense()``): the layout is
invisible. Cells of edge tiles lying outside the grid stay ``-inf`` (writes are clipped to it).
Tiled maps of a simulation with the tick plane share tile objects copy-on-write
(:mod:`agents.maps.tiles`): UAVs that stamped the same scans onto a tile hold one tile for it.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import SupportsInt

import numpy as np

from agents.maps.grid import Disk, Grid, where_seen
from agents.maps.tiles import TileShare

NEVER = np.float32(-np.inf)

DEFAULT_TILE = 64
# Grids up to this many cells (4 MB of float32) are stored as one dense tile.
DENSE_MAX_CELLS = 1 << 20


# Writes recorded for take_changes() beyond this many stand for "everything" (a map written that
# often between two reads is reread from its storage).
MAX_CHANGES = 4096
_TOO_MANY: list[tuple[int, int, int, int]] = []  # (identity only: never appended to)


# The ``tile`` argument of UncertaintyMap: None, "dense", a size, or (rows, cols).
TileSpec = None | str | int | np.integer | tuple[int, int]


def _tile_shape(grid: Grid, tile: TileSpec) -> tuple[tuple[int, int], bool]:
    """``((tile_h, tile_w), dense)`` for a ``tile`` argument (see :class:`UncertaintyMap`)."""
    ny, nx = grid.shape
    if tile is None:
        if ny * nx <= DENSE_MAX_CELLS:
            return (ny, nx), True
        tile = DEFAULT_TILE
    elif isinstance(tile, str):
        if tile != "dense":
            raise ValueError(f"tile must be None, 'dense', a positive int or (rows, cols), got {tile!r}")
        return (ny, nx), True
    if isinstance(tile, (int, np.integer)):
        th = tw = int(tile)
    else:
        th, tw = (int(v) for v in tile)
    if th < 1 or tw < 1:
        raise ValueError(f"tile sizes must be >= 1, got {(th, tw)}")
    return (max(1, min(th, ny)), max(1, min(tw, nx))), False


class UncertaintyMap:
    """Per-cell last-seen times (float32) of one grid, stored in lazily allocated tiles.

    ``tile``: ``None`` (default) = one dense tile for grids of at most :data:`DENSE_MAX_CELLS`
    cells, else 64 x 64 tiles; ``"dense"`` = always one dense tile; an int ``n`` or ``(rows,
    cols)`` = tiles of that size, allocated on first write. ``last_seen`` (optional) is a full
    ``(ny, nx)`` array to start from (copied).
    """

    __slots__ = ("grid", "tau", "tile_shape", "dense", "_ntx", "_nty", "_tiles", "_own", "_share", "_changes", "derived")

    def __init__(self, grid: Grid, tau: float, last_seen: np.ndarray | None = None, *, tile: TileSpec = None):
        self.grid = grid
        self.tau = float(tau)
        ny, nx = grid.shape
        if last_seen is not None:
            last_seen = np.asarray(last_seen)
            if last_seen.shape != grid.shape:
                raise ValueError(f"last_seen has shape {last_seen.shape}, expected {grid.shape}")
        (th, tw), dense = _tile_shape(grid, tile)
        self.tile_shape = (th, tw)
        self.dense = dense
        self._nty = -(-ny // th)
        self._ntx = -(-nx // tw)
        # tile key ty * ntx + tx -> float32 cells (dense: the (ny, nx) grid; tiled: th * tw flat,
        # row-major); an absent tile is all -inf.
        self._tiles: dict[int, np.ndarray] = {}
        # (tiled maps) The keys of the tiles this map alone holds, written in place; the others
        # may be shared with other maps (never written: copy on write, agents.maps.tiles), through
        # the grid's TileShare when it has one (a simulation with the tick plane).
        self._own: set[int] = set()
        self._share: TileShare | None = None if dense else grid.tile_share
        self._changes: list[tuple[int, int, int, int]] | None = None  # track_changes()
        self.derived: object = None  # what a consumer of take_changes() keeps with the map
        if dense:
            if last_seen is not None:
                self._tiles[0] = np.array(last_seen, dtype=np.float32)
            else:
                self._tiles[0] = np.full((ny, nx), NEVER, dtype=np.float32)
        elif last_seen is not None:
            self.merge(last_seen)

    # --- storage ----------------------------------------------------------------------------

    def _materialize(self) -> None:
        """Make ``_tiles`` hold the map's cells before they are read (a map sharing storage,
        agents.maps.mapgroup.GroupMap, builds them here; an ordinary map holds them already)."""

    def _alloc(self, key: int) -> np.ndarray:
        """A new all-``-inf`` tile (tiled maps keep tiles flat: ``th * tw`` cells, row-major),
        owned by this map."""
        th, tw = self.tile_shape
        tile = self._tiles[key] = np.empty(th * tw, dtype=np.float32)
        tile.fill(NEVER)
        self._own.add(key)
        return tile

    def _writable(self, key: int) -> np.ndarray:
        """Tile ``key`` of a tiled map, to be written in place: owned by this map (a copy of it
        if it may be shared, a new one if absent)."""
        tile = self._tiles.get(key)
        if tile is None:
            return self._alloc(key)
        if key not in self._own:
            tile = self._tiles[key] = tile.copy()
            self._own.add(key)
        return tile

    def tile(self, key: int) -> np.ndarray | None:
        """The stored last-seen times of tile ``key`` (``ty * ntx + tx``), not to be written: a
        tiled map's flat ``th * tw`` cells (row-major; cells outside the grid are ``-inf``), a
        dense map's whole grid (key 0); None where never written. Live until the map's next
        write (a tile shared with other maps is replaced, not written, then)."""
        self._materialize()
        return self._tiles.get(key)

    @property
    def tiles_allocated(self) -> int:
        self._materialize()
        return len(self._tiles)

    @property
    def nbytes(self) -> int:
        """Bytes of cell storage this map holds (a tile shared with other maps counted in each)."""
        self._materialize()
        return sum(a.nbytes for a in self._tiles.values())

    # --- change tracking --------------------------------------------------------------------

    def track_changes(self) -> None:
        """From now on, record the boxes of cells every write may have changed, for
        :meth:`take_changes` (one consumer: :mod:`agents.planners.dacmp.maintained` keeps a
        pyramid updated from them in :attr:`derived`)."""
        self._changes = []

    def take_changes(self) -> list[tuple[int, int, int, int]] | None:
        """The boxes ``(r0, r1, c0, c1)`` (rows ``r0:r1``, columns ``c0:c1``) written since the
        last call (or :meth:`track_changes`), and start afresh; None when they are not known
        (not tracking, or more than :data:`MAX_CHANGES` writes: reread everything)."""
        changes = self._changes
        if changes is None:
            return None
        self._changes = []
        return None if changes is _TOO_MANY else changes

    def _changed(self, r0: int, r1: int, c0: int, c1: int) -> None:
        """Record a write of cells ``[r0:r1, c0:c1]`` (called only while tracking)."""
        changes = self._changes
        if changes is _TOO_MANY:
            return
        if len(changes) < MAX_CHANGES:  # type: ignore[arg-type]
            changes.append((r0, r1, c0, c1))  # type: ignore[union-attr]
        else:
            self._changes = _TOO_MANY

    def written_boxes(self) -> list[tuple[int, int, int, int]]:
        """Boxes covering every cell ever written: the whole grid of a dense map, else the
        allocated tiles (clipped to the grid)."""
        self._materialize()
        ny, nx = self.grid.shape
        if self.dense:
            return [(0, ny, 0, nx)]
        th, tw = self.tile_shape
        out = []
        for key in sorted(self._tiles):
            ty, tx = divmod(key, self._ntx)
            out.append((ty * th, min(ny, (ty + 1) * th), tx * tw, min(nx, (tx + 1) * tw)))
        return out

    # --- writes -----------------------------------------------------------------------------

    def scan(self, x: float, y: float, radius: float, t: float) -> int:
        """Mark the cells inside a detection circle as seen at ``t``; returns cells changed."""
        d = self.grid.disk_stamp(x, y, radius)
        if d is None:
            return 0
        return self.scan_disk(d, t)

    def scan_disk(self, d: Disk, t: float) -> int:
        """Apply a scan whose disk is ``d`` (from ``grid.disk_stamp``) at ``t``; returns cells changed."""
        t32 = np.float32(t)
        if self._changes is not None:
            self._changed(d.iy0, d.iy1, d.ix0, d.ix1)
        if self.dense:
            view = self._tiles[0][d.rows, d.cols]
            newer = d.mask & (view < t32)
            view[newer] = t32
            return int(np.count_nonzero(newer))
        th, tw = self.tile_shape
        tiles = self._tiles
        changed = 0
        own = self._own
        for key, rows, cols, mask, _box in d.pieces(th, tw, self._ntx):
            tile = tiles.get(key)
            if tile is None or key not in own:
                tile = self._writable(key)
            view = tile.reshape(th, tw)[rows, cols]
            newer = mask & (view < t32)
            view[newer] = t32
            changed += int(np.count_nonzero(newer))
        return changed

    def stamp(self, d: Disk, t: float) -> None:
        """:meth:`scan_disk` without the count: one ``maximum`` with the disk's shared
        ``where(mask, t, -inf)`` per tile piece (the fast path for heard scan records)."""
        changes = self._changes
        if changes is not None:
            if changes is not _TOO_MANY and len(changes) < MAX_CHANGES:  # = self._changed(...), inlined
                changes.append((d.iy0, d.iy1, d.ix0, d.ix1))
            else:
                self._changed(d.iy0, d.iy1, d.ix0, d.ix1)
        if self.dense:
            view = self._tiles[0][d.rows, d.cols]
            memo = d.values_memo  # = d.values(t) when it matches, without the call (the per-receiver hot path)
            np.maximum(view, memo[1] if memo[0] == t and memo[1] is not None else d.values(t), out=view)
            return
        tiles = self._tiles
        shape = self.tile_shape
        smemo = d.stamps_memo  # = d.stamps(...) when it matches, without the call (the per-receiver hot path)
        pieces = smemo[2] if smemo[1] == t and smemo[0] == shape else d.stamps(shape[0], shape[1], self._ntx, t)
        own = self._own
        share = self._share if d.key is not None else None
        size = shape[0] * shape[1]
        for key, start, stop, values in pieces:
            if key in own:
                tile = tiles[key]
            elif share is not None:  # (a tile that may be shared, or none yet: agents.maps.tiles)
                share.stamp(tiles, own, key, size, start, values)
                continue
            else:
                tile = self._writable(key)
            view = tile[start:stop]
            np.maximum(view, values, out=view)

    def stamp_once(self, x: float, y: float, radius: float, t: float) -> None:
        """:meth:`stamp` of the disk of ``(x, y, radius)`` at ``t`` on a tiled map, computing
        the disk's cells for this map alone (``grid.disk_box``) instead of building a shared
        :class:`Disk` and its tile bands: for a heard scan no other map is about to apply (an
        anti-entropy resend goes to one UAV; issue 25: 35 us a scan that way, about 15 so).
        The same cells, and the same tiles allocated (those holding a cell of the disk).

        With the tick plane (:meth:`Grid.set_tick_plane`) the disk's cells come from the grid's
        resend archive when it holds them (:meth:`Grid.disk_cells`) instead of being computed;
        without it, :meth:`_stamp_once_oracle`."""
        grid = self.grid
        if not grid.tick_plane:
            return self._stamp_once_oracle(x, y, radius, t)
        cells = grid.disk_cells(x, y, radius)
        if cells is None:
            return
        iy0, iy1, ix0, ix1, mask, near_r, near_c = cells
        changes = self._changes
        if changes is not None:
            self._changed(iy0, iy1, ix0, ix1)
        values = where_seen(mask, t)
        if self.dense:
            view = self._tiles[0][iy0:iy1, ix0:ix1]
            np.maximum(view, values, out=view)
            return
        th, tw = self.tile_shape
        tiles = self._tiles
        own = self._own
        ntx = self._ntx
        item = mask.item
        maximum = np.maximum
        for ty in range(iy0 // th, (iy1 - 1) // th + 1):
            r0, r1 = max(iy0, ty * th) - iy0, min(iy1, (ty + 1) * th) - iy0
            nr = min(max(near_r, r0), r1 - 1)
            a = iy0 - ty * th
            for tx in range(ix0 // tw, (ix1 - 1) // tw + 1):
                c0, c1 = max(ix0, tx * tw) - ix0, min(ix1, (tx + 1) * tw) - ix0
                if item(nr, min(max(near_c, c0), c1 - 1)):  # (a tile holds a cell iff its nearest does)
                    key = ty * ntx + tx
                    tile = tiles.get(key)
                    if tile is None or key not in own:
                        tile = self._writable(key)
                    cc = ix0 - tx * tw
                    view = tile.reshape(th, tw)[r0 + a:r1 + a, c0 + cc:c1 + cc]
                    maximum(view, values[r0:r1, c0:c1], out=view)

    def _stamp_once_oracle(self, x: float, y: float, radius: float, t: float) -> None:
        """:meth:`stamp_once` without the tick plane (the per-object code, kept as the oracle)."""
        b = self.grid.disk_box(x, y, radius)
        if b is None:
            return
        iy0, iy1, ix0, ix1, mask, dy2, dx2 = b
        iy1 += 1
        ix1 += 1
        changes = self._changes
        if changes is not None:
            self._changed(iy0, iy1, ix0, ix1)
        values = np.where(mask, np.float32(t), NEVER)
        if self.dense:
            view = self._tiles[0][iy0:iy1, ix0:ix1]
            np.maximum(view, values, out=view)
            return
        th, tw = self.tile_shape
        tiles = self._tiles
        ntx = self._ntx
        # A tile holds a cell of the disk iff its cell nearest the disk's centre does (Disk.pieces).
        near_r, near_c = int(dy2.argmin()), int(dx2.argmin())
        item = mask.item
        for ty in range(iy0 // th, (iy1 - 1) // th + 1):
            r0, r1 = max(iy0, ty * th) - iy0, min(iy1, (ty + 1) * th) - iy0
            nr = min(max(near_r, r0), r1 - 1)
            for tx in range(ix0 // tw, (ix1 - 1) // tw + 1):
                c0, c1 = max(ix0, tx * tw) - ix0, min(ix1, (tx + 1) * tw) - ix0
                if item(nr, min(max(near_c, c0), c1 - 1)):
                    key = ty * ntx + tx
                    tile = tiles.get(key)
                    if tile is None or key not in self._own:
                        tile = self._writable(key)
                    a, c = iy0 - ty * th, ix0 - tx * tw
                    view = tile.reshape(th, tw)[r0 + a:r1 + a, c0 + c:c1 + c]
                    np.maximum(view, values[r0:r1, c0:c1], out=view)

    def cover(self, d: Disk, t: float) -> int:
        """Like :meth:`stamp`, but returns how many of the disk's cells had never been seen."""
        if self._changes is not None:
            self._changed(d.iy0, d.iy1, d.ix0, d.ix1)
        if self.dense:
            view = self._tiles[0][d.rows, d.cols]
            new = int(np.count_nonzero(d.mask & (view == NEVER)))
            np.maximum(view, d.values(t), out=view)
            return new
        th, tw = self.tile_shape
        tiles = self._tiles
        values = d.values(t)
        new = 0
        for key, rows, cols, mask, box in d.pieces(th, tw, self._ntx):
            tile = tiles.get(key)
            if tile is None or key not in self._own:
                tile = self._writable(key)
            view = tile.reshape(th, tw)[rows, cols]
            new += int(np.count_nonzero(mask & (view == NEVER)))
            np.maximum(view, values[box], out=view)
        return new

    def merge(self, other: UncertaintyMap | np.ndarray) -> None:
        """Per-cell max with another map or a full ``(ny, nx)`` array (in place)."""
        if isinstance(other, UncertaintyMap):
            other._materialize()
            if other.grid.shape != self.grid.shape:
                raise ValueError(f"cannot merge a {other.grid.shape} map into a {self.grid.shape} map")
            if other.tile_shape == self.tile_shape and other.dense == self.dense:
                if self._changes is not None:
                    for box in other.written_boxes():
                        self._changed(*box)
                for key, theirs in list(other._tiles.items()):
                    mine = self._tiles.get(key)
                    if mine is None:
                        self._tiles[key] = theirs.copy()
                        self._own.add(key)
                    else:
                        if not self.dense and key not in self._own:
                            mine = self._writable(key)
                        np.maximum(mine, theirs, out=mine)
                return
            theirs = other.to_dense()
        else:
            theirs = np.broadcast_to(np.asarray(other), self.grid.shape)
        if self._changes is not None:
            self._changes = _TOO_MANY  # any cell may have changed
        if self.dense:
            mine = self._tiles[0]
            np.maximum(mine, theirs, out=mine)
            return
        th, tw = self.tile_shape
        ny, nx = self.grid.shape
        for ty in range(self._nty):
            r0, r1 = ty * th, min(ny, (ty + 1) * th)
            for tx in range(self._ntx):
                c0, c1 = tx * tw, min(nx, (tx + 1) * tw)
                piece = theirs[r0:r1, c0:c1]
                key = ty * self._ntx + tx
                mine = self._tiles.get(key)
                if mine is None:
                    if np.isneginf(piece).all():
                        continue  # max(-inf, -inf): nothing to store
                    mine = self._alloc(key)
                elif key not in self._own:
                    mine = self._writable(key)
                view = mine.reshape(th, tw)[: r1 - r0, : c1 - c0]
                np.maximum(view, piece, out=view)

    def copy(self) -> UncertaintyMap:
        """An ordinary map with the same cells (a map of its own, whatever this one is)."""
        self._materialize()
        new = object.__new__(UncertaintyMap)
        new.grid = self.grid
        new.tau = self.tau
        new.tile_shape = self.tile_shape
        new.dense = self.dense
        new._nty, new._ntx = self._nty, self._ntx
        new._tiles = {k: v.copy() for k, v in self._tiles.items()}
        new._own = set(new._tiles)
        new._share = self._share
        new._changes = None  # (a new map: nobody tracks it yet)
        new.derived = None
        return new

    # --- reads ------------------------------------------------------------------------------

    def _check_window(self, window: Iterable[SupportsInt]) -> tuple[int, int, int, int]:
        try:
            ix0, iy0, w, h = (int(v) for v in window)
        except (TypeError, ValueError):
            raise ValueError(f"window must be (ix0, iy0, nx, ny), got {window!r}") from None
        ny, nx = self.grid.shape
        if w < 1 or h < 1 or ix0 < 0 or iy0 < 0 or ix0 + w > nx or iy0 + h > ny:
            raise ValueError(f"window (ix0={ix0}, iy0={iy0}, nx={w}, ny={h}) is not inside the {nx} x {ny} grid")
        return ix0, iy0, w, h

    def _gather(self, ix0: int, iy0: int, w: int, h: int, out: np.ndarray | None = None) -> np.ndarray:
        """Last-seen times of cells ``[iy0:iy0+h, ix0:ix0+w]`` (a new C-contiguous array, or ``out``)."""
        if out is None:
            out = np.empty((h, w), np.float32)
        th, tw = self.tile_shape
        tiles = self._tiles
        ntx = self._ntx
        for ty in range(iy0 // th, (iy0 + h - 1) // th + 1):
            r0, r1 = max(iy0, ty * th), min(iy0 + h, (ty + 1) * th)
            for tx in range(ix0 // tw, (ix0 + w - 1) // tw + 1):
                c0, c1 = max(ix0, tx * tw), min(ix0 + w, (tx + 1) * tw)
                dst = out[r0 - iy0 : r1 - iy0, c0 - ix0 : c1 - ix0]
                tile = tiles.get(ty * ntx + tx)
                if tile is None:
                    dst.fill(NEVER)
                else:
                    dst[...] = tile.reshape(th, tw)[r0 - ty * th : r1 - ty * th, c0 - tx * tw : c1 - tx * tw]
        return out

    def to_dense(self, window: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """A new ``(ny, nx)`` float32 array of last-seen times: the whole grid, or with
        ``window=(ix0, iy0, nx, ny)`` the cells ``[iy0:iy0+ny, ix0:ix0+nx]``."""
        self._materialize()
        if window is not None:
            ix0, iy0, w, h = self._check_window(window)
            if self.dense:
                return self._tiles[0][iy0 : iy0 + h, ix0 : ix0 + w].copy()
            return self._gather(ix0, iy0, w, h)
        if self.dense:
            return self._tiles[0].copy()
        ny, nx = self.grid.shape
        return self._gather(0, 0, nx, ny)

    @property
    def last_seen(self) -> np.ndarray:
        """A read-only snapshot of the full last-seen array (compatibility; use :meth:`to_dense`)."""
        a = self.to_dense()
        a.flags.writeable = False
        return a

    def to_dense_view(self) -> np.ndarray:
        """The live ``(ny, nx)`` array of a dense map (read-only view; it changes with the map)."""
        if not self.dense:
            raise ValueError("to_dense_view() needs a dense map (tile='dense'); use to_dense()")
        self._materialize()
        v = self._tiles[0].view()
        v.flags.writeable = False
        return v

    def q_into(self, t: float, last_seen: np.ndarray, out: np.ndarray) -> np.ndarray:
        """q of the given last-seen values, written into ``out`` (the same numbers as
        :meth:`uncertainty` gives for those cells)."""
        return self._q(t, last_seen, out)

    def _q(self, t: float, last_seen: np.ndarray, out: np.ndarray | None) -> np.ndarray:
        age: np.ndarray = np.subtract(np.float32(t), last_seen, out=out, dtype=np.float32)
        np.multiply(age, np.float32(-self.tau), out=age)
        np.exp(age, out=age)
        np.subtract(np.float32(1.0), age, out=age)
        return age

    def uncertainty(self, t: float, out: np.ndarray | None = None,
                    window: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """q per cell at time ``t`` (float32): the full ``(ny, nx)`` grid, or with
        ``window=(ix0, iy0, nx, ny)`` the ``(ny, nx)`` block of cells ``[iy0:iy0+ny, ix0:ix0+nx]``
        (it must lie inside the grid, else ValueError). Same numbers either way."""
        self._materialize()
        if window is not None:
            ix0, iy0, w, h = self._check_window(window)
            if self.dense:
                return self._q(t, self._tiles[0][iy0 : iy0 + h, ix0 : ix0 + w], out)
        elif self.dense:
            return self._q(t, self._tiles[0], out)
        else:
            ix0, iy0 = 0, 0
            h, w = self.grid.shape
        if out is not None and out.dtype == np.float32 and out.shape == (h, w):
            return self._q(t, self._gather(ix0, iy0, w, h, out), out)
        return self._q(t, self._gather(ix0, iy0, w, h), out)

    def region(self, rows: slice, cols: slice) -> np.ndarray:
        """Last-seen times of cells ``[rows, cols]`` (slices with explicit start and stop,
        inside the grid): a read-only view of a dense map's cells, else a new array."""
        self._materialize()
        if self.dense:
            v = self._tiles[0][rows, cols]
            v.flags.writeable = False
            return v
        return self._gather(cols.start, rows.start, cols.stop - cols.start, rows.stop - rows.start)

    def _cells(self, ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
        """Last-seen times of cells ``(iy, ix)`` (integer arrays; 0-d ones give a numpy scalar)."""
        self._materialize()
        if self.dense:
            cells: np.ndarray = self._tiles[0][iy, ix]
            return cells
        ny, nx = self.grid.shape
        ix, iy = np.broadcast_arrays(np.asarray(ix), np.asarray(iy))
        for a, n, name in ((ix, nx, "ix"), (iy, ny, "iy")):
            if a.dtype.kind not in "iu":
                raise IndexError(f"{name} must be integers, got {a.dtype}")
            if a.size and (a.min() < -n or a.max() >= n):
                raise IndexError(f"{name} out of range for a grid of {n}")
        th, tw = self.tile_shape
        ty, ly = np.divmod(iy % ny, th)
        tx, lx = np.divmod(ix % nx, tw)
        key = ty * self._ntx + tx
        seen = np.full(key.shape, NEVER, dtype=np.float32)
        tiles = self._tiles
        flat = ly * tw + lx
        if key.ndim == 0:
            tile = tiles.get(int(key))
            return seen[()] if tile is None else tile[flat]
        for k in np.unique(key).tolist():
            tile = tiles.get(k)
            if tile is not None:
                sel = key == k
                seen[sel] = tile[flat[sel]]
        return seen

    def q_at(self, ix: np.ndarray, iy: np.ndarray, t: float) -> np.ndarray:
        """q at selected cells only (cheap for a planner reading a few cells)."""
        seen = self._cells(ix, iy)
        return 1.0 - np.exp(-self.tau * (t - seen.astype(np.float64)))

    def seen_fraction(self) -> float:
        self._materialize()
        ny, nx = self.grid.shape
        seen = sum(int(np.count_nonzero(np.isfinite(tile))) for tile in self._tiles.values())
        return float(seen) / (ny * nx)
