"""DACMP's map pyramid, updated where the map changed instead of recomputed (issue 15, point 1).

The planner reads ``q = 1 - exp(-tau (t - last_seen))`` and its Gaussian pyramid ``G_1..G_L``
(:mod:`agents.planners.dacmp.pyramid`). Their time dependence factors out::

    1 - q(t) = exp(-tau (t - t0)) * exp(-tau (t0 - last_seen)) = s(t) * E

and REDUCE is linear and keeps constants (its weights sum to one, the reflect border repeats
edge samples), so ``G_l(t) = 1 - s(t) * P_l`` with ``P_0 = E`` and ``P_l = REDUCE(P_{l-1})``.
``E`` changes only where cells were rescanned: :class:`MaintainedPyramid` keeps ``E`` and
``P_1..P_L`` of one UAV's map and, at each replanning, recomputes only what the map's writes
since the last one touched (the map records the boxes it wrote:
:meth:`agents.maps.umap.UncertaintyMap.take_changes`). A changed box of level ``l`` changes
the output rows ``(r0 - 1) // 2 .. (r1 + 1) // 2`` of level ``l + 1`` (each output reads five
inputs), and likewise for columns, so the work halves per level.

Base time and range. ``t0`` is a multiple of ``SPAN / tau`` (:func:`base_time`: the largest at
or below the planning time), so ``0 <= tau (t - t0) < SPAN`` and ``s >= exp(-SPAN)``. When a
plan's ``t`` falls in another span, the state is rebuilt for the new ``t0`` (from the map's
allocated storage: every ``SPAN / tau`` seconds of simulated time). ``E``'s exponent is clipped
to ``[-EXP_MIN, EXP_MIN]``: ``E <= exp(40)`` stays far from float32's 3.4e38 and every nonzero
level value stays a normal float32 (a level value is at least 1/256 of a nonzero input:
``exp(-40) / 256**12 > 1.2e-38``, so no slow denormals); a cell seen more than ``40 / tau``
before ``t0`` reads ``q = 1 - s exp(-40)`` instead of ``1 - s exp(-tau (t0 - last_seen))``, a
difference below ``4.3e-18``. Never-seen cells have ``E = 0`` exactly, so ``q`` (and a level
over never-seen cells only) is exactly ``1``, as before.

Exactness. Every level value is computed by one formula of its 25 inputs
(``(a0 + a4) + 4 (a1 + a3) + 6 a2`` per axis, numpy element-wise float32 operations, then the
exact ``1/256``), whatever box it is computed in, and ``E`` is element-wise in ``last_seen``
and ``t0``; so the maintained state is bit for bit the state computed from scratch from the
map at ``t0``: a plan depends on the map and ``t``, not on when or in what pieces the map was
updated. Against the old pipeline (q in float32, then BLAS reduces) the levels ``1 - s P_l``
differ by float rounding only: ``tests/test_maintained_pyramid.py`` checks ``|difference| <=
2e-6`` (q and its levels lie in [0, 1]; float32 rounding is 6e-8 per operation).

Batches. The UAVs that replan together have their pyramids updated together
(:meth:`MaintainedPyramid.update_many`), in batches of about :data:`BATCH_CELLS` changed cells:
the E of a batch's changed cells in one :func:`e_of` call, the changed boxes of a level of all
its maps stacked into one reduce. Both are element-wise, so each map's state is bit for bit
what its own update gives; what is shared is the cost of the numpy calls, which dominates the
small boxes of the upper levels.

Maps of a group. The maps of a :class:`~agents.maps.mapgroup.MapGroup` are its shared base
plus each member's few extra scans (its latest own scan, mostly), so their pyramids are nearly
the same, and updating each from its own changes did the same work once per member. A member's
pyramid instead follows one pyramid of the group's base (issue 36, T9): the base's is updated
once for all the members planning at the same base time, and each member's starts from a copy
of it and recomputes what its extra scans' boxes reach, as it would for a change of those cells
(:meth:`MaintainedPyramid._from_base`). Outside those boxes the member's cells are the base's,
so by the exactness above the result is bit for bit the state the member's own updates reach
(``tests/test_maintained_pyramid.py`` checks it against a recomputation under scans every
member has, scans one has, members leaving and plans across spans). A member that leaves the
group continues from that state with its own changes. The copy is of what is stale only: each
pyramid counts its updates (``version``) and remembers the boxes of each plane its last
:data:`HISTORY` updates rewrote, and a member copies the boxes the base rewrote since its last
copy plus its own previous extra boxes (elsewhere it holds the base's values already), or
everything when it is further behind; the same values as a full copy, without copying the
whole planes (about 1.3 MB a member on the paper's map) at every plan.

Whole levels. The small levels of dense maps computed whole (:func:`reduce_whole`: two BLAS
calls) are computed for all maps of an update together, a level at a time, the maps of one
shape stacked (:func:`reduce_whole_many`: numpy's matmul makes for each map of a stack the
call one map alone makes, so the bytes are the same).

Guide point (eq. 20). A sub-area's mean ``q`` is ``1 - s * sum(E) / cells``. The sums of ``E``
are kept per *chunk*: the sub-areas of a dense map, the pieces of the sub-areas cut at the tile
edges of a tiled one (only chunks with seen cells are listed). A changed chunk's sum is
recomputed from ``E`` (numpy's pairwise float32 sum: relative error about 1e-7), and its
sub-area's sum is the exactly rounded sum of its chunks' (``math.fsum``), so the sums are
exact functions of ``E`` too, not drifting running totals. A never-seen sub-area sums to 0
and has mean exactly 1: exact ties stay ties.

Storage. Each level is a :class:`Plane`: one dense float32 array for a dense map (``E`` too:
16/3 bytes a cell in all), else lazily allocated tiles of ``max(16, 64 >> l)`` cells a side
(absent = 0: never seen near there), and ``E`` of a tiled map is not stored but computed from
the map's last-seen times where a level update reads it (:class:`SeenPlane`). So a tiled map's
pyramid costs memory in proportion to the tiles the map has allocated (about 0.4 times them),
not to the area.

The planner reads the levels only in a window around each UAV
(:class:`agents.planners.dacmp.planner.Layers`): eq. 19 is ``sum(lambda) - s sum_l lambda_l
P_l`` at the particles' cells.
"""

from __future__ import annotations

import bisect
import functools
import math
from typing import NamedTuple, cast

import numpy as np

from agents.maps.mapgroup import GroupMap
from agents.maps.umap import NEVER, UncertaintyMap
from agents.planners.dacmp.pyramid import SCALE, level_shapes

__all__ = ["EXP_MIN", "SPAN", "MaintainedPyramid", "Plane", "base_time", "e_of", "reduce_boxes"]

SPAN = 16.0  # tau (t - t0) stays below this: s >= exp(-16)
EXP_MIN = 40.0  # E's exponent is clipped to [-EXP_MIN, EXP_MIN]
_MIN_LEVEL_TILE = 16
# Levels of a dense map with at most this many cells are recomputed whole (reduce_whole):
# cheaper than working out which of their cells changed.
WHOLE_CELLS = 1 << 12
# update_many recomputes maps together until their changed cells reach this many: enough maps to
# share the calls of their small boxes, few enough that their E and levels stay in cache.
BATCH_CELLS = 1 << 16
# A pyramid remembers what its last this many updates rewrote (for group members that copy it).
HISTORY = 8


def base_time(t: float, tau: float) -> float:
    """``t0`` for a plan at ``t``: the largest multiple of ``SPAN / tau`` at or below ``t``."""
    span = SPAN / tau
    if not math.isfinite(span) or span <= 0.0:
        return 0.0
    return math.floor(t / span) * span


def e_of(last_seen: np.ndarray, tau: float, t0: float) -> np.ndarray:
    """``E = exp(clip(tau (last_seen - t0), -EXP_MIN, EXP_MIN))`` (float32, computed in float32
    like the map's own q), exactly 0 where never seen (``last_seen = -inf``)."""
    arg = np.subtract(last_seen, np.float32(t0), dtype=np.float32)
    arg *= np.float32(tau)
    np.clip(arg, np.float32(-EXP_MIN), np.float32(EXP_MIN), out=arg)
    e: np.ndarray = np.exp(arg, out=arg)
    # Times 1 (seen: exact) or 0 (never seen: E is positive, so +0.0): cheaper than a masked
    # copy, most of a tile's cells being never seen.
    e *= last_seen != NEVER
    return e


class Plane:
    """A float32 ``shape`` array, dense or in tiles allocated on the first nonzero write (an
    absent tile reads as 0)."""

    __slots__ = ("shape", "tile", "dense", "_ntx", "_a", "_tiles")

    def __init__(self, shape: tuple[int, int], tile: tuple[int, int] | None):
        self.shape = shape
        self.dense = tile is None
        h, w = shape
        self.tile = (h, w) if tile is None else (min(tile[0], h), min(tile[1], w))
        self._ntx = -(-w // self.tile[1])
        self._a = np.zeros(shape, np.float32) if tile is None else None
        self._tiles: dict[int, np.ndarray] = {}

    @property
    def dense_array(self) -> np.ndarray | None:
        """The array of a dense plane (live), else None."""
        return self._a

    @property
    def nbytes(self) -> int:
        if self._a is not None:
            return self._a.nbytes
        return sum(t.nbytes for t in self._tiles.values())

    def clear(self) -> None:
        if self._a is not None:
            self._a.fill(0.0)
        self._tiles = {}

    def _pieces(self, r0: int, r1: int, c0: int, c1: int) -> list[tuple[int, slice, slice, slice, slice]]:
        """``(tile_key, rows, cols in the tile, rows, cols in the region)`` of each tile
        holding cells ``[r0:r1, c0:c1]`` (a list, not a generator, and conditional expressions,
        not max/min: the pieces of a few hundred boxes an update)."""
        th, tw = self.tile
        ntx = self._ntx
        out = []
        tx0, tx1 = c0 // tw, (c1 - 1) // tw + 1
        for ty in range(r0 // th, (r1 - 1) // th + 1):
            y0 = ty * th
            a = r0 if r0 > y0 else y0
            b = r1 if r1 < y0 + th else y0 + th
            rows, out_rows = slice(a - y0, b - y0), slice(a - r0, b - r0)
            for tx in range(tx0, tx1):
                x0 = tx * tw
                c = c0 if c0 > x0 else x0
                e = c1 if c1 < x0 + tw else x0 + tw
                out.append((ty * ntx + tx, rows, slice(c - x0, e - x0), out_rows, slice(c - c0, e - c0)))
        return out

    def read(self, r0: int, r1: int, c0: int, c1: int, out: np.ndarray | None = None) -> np.ndarray:
        """Cells ``[r0:r1, c0:c1]``: into ``out`` if given, else a view (dense) or a new array."""
        if self._a is not None:
            if out is None:
                return self._a[r0:r1, c0:c1]
            out[...] = self._a[r0:r1, c0:c1]
            return out
        if out is None:
            out = np.empty((r1 - r0, c1 - c0), np.float32)
        get = self._tiles.get
        for key, rows, cols, out_rows, out_cols in self._pieces(r0, r1, c0, c1):
            tile = get(key)
            if tile is None:
                out[out_rows, out_cols] = 0.0
            else:
                out[out_rows, out_cols] = tile[rows, cols]
        return out

    def sum(self, r0: int, r1: int, c0: int, c1: int) -> float:
        """``float(read(r0, r1, c0, c1).sum())`` (numpy's pairwise float32 sum of a dense
        plane's view, of a tiled one's cells as a new C-contiguous array) of cells within one
        tile, without the read's piecewise copy."""
        if self._a is not None:
            return float(self._a[r0:r1, c0:c1].sum())
        th, tw = self.tile
        ty, tx = r0 // th, c0 // tw
        tile = self._tile(ty * self._ntx + tx)
        if tile is None:
            return 0.0
        y0, x0 = ty * th, tx * tw
        return float(np.ascontiguousarray(tile[r0 - y0 : r1 - y0, c0 - x0 : c1 - x0]).sum())

    def _tile(self, key: int) -> np.ndarray | None:
        return self._tiles.get(key)

    def write(self, r0: int, c0: int, values: np.ndarray) -> None:
        """Set cells ``[r0:r0 + h, c0:c0 + w]`` to ``values`` (``(h, w)``)."""
        h, w = values.shape
        if self._a is not None:
            self._a[r0 : r0 + h, c0 : c0 + w] = values
            return
        tiles = self._tiles
        for key, rows, cols, in_rows, in_cols in self._pieces(r0, r0 + h, c0, c0 + w):
            piece = values[in_rows, in_cols]
            tile = tiles.get(key)
            if tile is None:
                if not piece.any():
                    continue  # zeros where the plane is implicitly zero
                tile = tiles[key] = np.zeros(self.tile, np.float32)
            tile[rows, cols] = piece


class SeenPlane(Plane):
    """``E`` of a tiled map, not stored: computed from the map's last-seen times (it is
    element-wise in them), so a huge map's pyramid stores only its levels.

    Within an update (:meth:`open` .. :meth:`close`, while the map does not change) the E of
    each map tile read is computed once, whole tiles at a time and many tiles in one
    :func:`e_of` call (:meth:`load`), and kept until :meth:`close`; outside one, a read
    computes the E of the cells read."""

    __slots__ = ("umap", "t0", "_open")

    def __init__(self, umap: UncertaintyMap):
        super().__init__(umap.grid.shape, umap.tile_shape)
        self.umap = umap
        self.t0 = 0.0
        self._open = False
        # While open: map tile key -> its E (th, tw), or None where the map has no tile (E = 0).
        self._tiles: dict[int, np.ndarray | None] = {}  # type: ignore[assignment]

    @property
    def nbytes(self) -> int:
        return 0

    def open(self, t0: float) -> None:
        self.t0 = t0
        self._open = True
        self._tiles = {}

    def close(self) -> None:
        self._open = False
        self._tiles = {}

    def keys(self, r0: int, r1: int, c0: int, c1: int) -> list[int]:
        """The keys of the tiles holding cells ``[r0:r1, c0:c1]``."""
        th, tw = self.tile
        ntx = self._ntx
        cols = range(c0 // tw, (c1 - 1) // tw + 1)
        return [ty * ntx + tx for ty in range(r0 // th, (r1 - 1) // th + 1) for tx in cols]

    def load(self, keys: list[int]) -> None:
        """E of these tiles, those not loaded yet, in one :func:`e_of` call (open only)."""
        SeenPlane.load_many([(self, keys)])

    @staticmethod
    def load_many(loads: list[tuple[SeenPlane, list[int]]]) -> None:
        """:meth:`load` of each plane's keys, one :func:`e_of` call for all planes of the same
        ``tau``, ``t0`` and tile shape (element-wise: each tile gets the values of its own load)."""
        Tiles = dict[int, np.ndarray | None]  # (a plane's loaded E tiles: None where the map has none)
        groups: dict[tuple[float, float, tuple[int, int]], tuple[list[tuple[Tiles, int]], list[np.ndarray]]] = {}
        for plane, keys in loads:
            tiles, tile_of = plane._tiles, plane.umap.tile
            todo, seen = groups.setdefault((plane.umap.tau, plane.t0, plane.tile), ([], []))
            for key in dict.fromkeys(keys):  # (each once, in order)
                if key not in tiles:
                    a = tile_of(key)
                    if a is None:
                        tiles[key] = None
                    else:
                        todo.append((tiles, key))
                        seen.append(a)
        for (tau, t0, shape), (todo, seen) in groups.items():
            if seen:
                e = e_of(np.stack(seen), tau, t0).reshape(len(seen), *shape)
                for (tiles, key), v in zip(todo, e):
                    tiles[key] = v

    def _tile(self, key: int) -> np.ndarray | None:
        if key not in self._tiles:
            self.load([key])
        return self._tiles[key]

    def sum(self, r0: int, r1: int, c0: int, c1: int) -> float:
        if self._open:
            return super().sum(r0, r1, c0, c1)
        return float(self.read(r0, r1, c0, c1).sum())

    def read(self, r0: int, r1: int, c0: int, c1: int, out: np.ndarray | None = None) -> np.ndarray:
        if self._open:
            self.load(self.keys(r0, r1, c0, c1))
            return super().read(r0, r1, c0, c1, out)
        e = e_of(self.umap.region(slice(r0, r1), slice(c0, c1)), self.umap.tau, self.t0)
        if out is None:
            return e
        out[...] = e
        return out

    def write(self, r0: int, c0: int, values: np.ndarray) -> None:
        raise TypeError("E of a tiled map is read from the map, not written")


@functools.lru_cache(maxsize=256)
def _reflected(lo: int, hi: int, n: int) -> tuple[np.ndarray, int, int]:
    """Indices ``lo..hi-1`` reflected into ``0..n-1`` (scipy.ndimage 'reflect', period 2n),
    less their minimum, the minimum and one past the maximum (read-only: shared)."""
    j = np.arange(lo, hi) % (2 * n)
    j = np.where(j >= n, 2 * n - 1 - j, j)
    a, b = int(j.min()), int(j.max()) + 1
    j -= a
    j.flags.writeable = False
    return j, a, b


@functools.lru_cache(maxsize=64)
def _reduce_matrix(n: int) -> np.ndarray:
    """REDUCE along one axis of ``n`` samples as a ``(ceil(n/2), n)`` float32 matrix (weights
    ``[1, 4, 6, 4, 1] / 16`` folded at the reflect border; exact in float32). Read-only."""
    m = (n + 1) // 2
    a = np.zeros((m, n), np.float64)
    for i in range(m):
        for k, wk in enumerate((1.0, 4.0, 6.0, 4.0, 1.0)):
            j = (2 * i + k - 2) % (2 * n)
            a[i, 2 * n - 1 - j if j >= n else j] += wk / 16.0
    out = a.astype(np.float32)
    out.flags.writeable = False
    return out


def reduce_whole(src: np.ndarray, dst: np.ndarray) -> None:
    """All of ``REDUCE(src)`` into ``dst`` (dense arrays), as ``A src B^T`` with the
    :func:`_reduce_matrix` of each axis: two BLAS calls, for the small levels of a dense map
    (always computed whole: a level is computed one way only, so the state stays a function of
    the map)."""
    n, w = src.shape
    np.matmul(np.matmul(_reduce_matrix(n), src), _reduce_matrix(w).T, out=dst)


def reduce_whole_many(jobs: list[tuple[np.ndarray, np.ndarray]]) -> None:
    """:func:`reduce_whole` of each ``(src, dst)``, those of one shape in two stacked BLAS
    calls (numpy's matmul makes the call a single map's makes for each map of a stack: the same
    numbers; ``tests/test_maintained_pyramid.py`` compares the bytes)."""
    shapes: dict[tuple[int, ...], list[tuple[np.ndarray, np.ndarray]]] = {}
    for job in jobs:
        shapes.setdefault(job[0].shape, []).append(job)
    for (n, w), group in shapes.items():
        if len(group) == 1:
            reduce_whole(*group[0])
            continue
        out = np.matmul(np.matmul(_reduce_matrix(n), np.stack([src for src, _ in group])), _reduce_matrix(w).T)
        for (_, dst), values in zip(group, out):
            dst[...] = values


Rect = tuple[int, int, int, int]  # rows r0:r1, columns c0:c1
Written = list[list[Rect] | None]  # per plane (P_0, P_1, ...): the boxes an update rewrote (None: all)
Reduce = tuple[Plane, Plane, Rect]  # output box of REDUCE(src) into dst: (src, dst, (i0, i1, j0, j1))


def reduce_boxes(tasks: list[tuple[Plane, Plane, list[Rect]]]) -> None:
    """For each ``(src, dst, boxes)``: output rows ``i0:i1``, columns ``j0:j1`` of ``REDUCE(src)``
    (the next level) for each box ``(i0, i1, j0, j1)``, written into ``dst``. Each output is
    ``(a0 + a4) + 4 (a1 + a3) + 6 a2`` over rows, then over columns, of its 5 x 5 inputs
    (reflected at the border), times 1/256: float32 element-wise operations, so an output's
    value does not depend on the box it is computed in nor on the boxes computed with it. The
    inputs of the boxes of all tasks (several maps' levels) are stacked (padded with zeros to a
    common shape, in groups of similar size: :func:`_stacks`) and reduced together: one set of
    array operations for all of them."""
    jobs = [(src, dst, box) for src, dst, boxes in tasks for box in boxes]
    if len(jobs) == 1:
        src, _, (i0, i1, j0, j1) = jobs[0]
        n, w = src.shape
        if i0 >= 1 and 2 * i1 + 1 <= n and j0 >= 1 and 2 * j1 + 1 <= w:  # interior: no copy, no padding
            _reduce_stack(src.read(2 * i0 - 2, 2 * i1 + 1, 2 * j0 - 2, 2 * j1 + 1)[None], jobs)
            return
    for group in _stacks(jobs):
        hh = max(2 * (i1 - i0) + 3 for _, _, (i0, i1, _, _) in group)
        ww = max(2 * (j1 - j0) + 3 for _, _, (_, _, j0, j1) in group)
        x = np.zeros((len(group), hh, ww), np.float32)
        for k, (src, _, (i0, i1, j0, j1)) in enumerate(group):
            n, w = src.shape
            rlo, rhi, clo, chi = 2 * i0 - 2, 2 * i1 + 1, 2 * j0 - 2, 2 * j1 + 1
            if rlo >= 0 and rhi <= n and clo >= 0 and chi <= w:  # interior: read in place
                src.read(rlo, rhi, clo, chi, out=x[k, : rhi - rlo, : chi - clo])
                continue
            rr, a, b = _reflected(rlo, rhi, n) if rlo < 0 or rhi > n else (None, rlo, rhi)
            cc, c, e = _reflected(clo, chi, w) if clo < 0 or chi > w else (None, clo, chi)
            piece = src.read(a, b, c, e)
            if rr is not None:
                piece = piece[rr]
            if cc is not None:
                piece = piece[:, cc]
            x[k, : rhi - rlo, : chi - clo] = piece
        _reduce_stack(x, group)


# Boxes stacked together cost their padded cells, a stack its calls: boxes join a stack while
# it computes at most twice their cells, or at most this many cells in all.
STACK_CELLS = 1 << 12


def _stacks(jobs: list[Reduce]) -> list[list[Reduce]]:
    """The boxes in groups to stack for :func:`reduce_boxes`: largest first, each joining the
    last group while the group padded to its largest height and width stays within
    :data:`STACK_CELLS` or twice the group's own cells, else starting a new group (all in one
    group when that holds for all)."""
    sizes = [(i1 - i0, j1 - j0) for _, _, (i0, i1, j0, j1) in jobs]
    if len(jobs) * max(h for h, _ in sizes) * max(w for _, w in sizes) <= max(STACK_CELLS, 2 * sum(h * w for h, w in sizes)):
        return [jobs]
    groups: list[list[Reduce]] = []
    hh = ww = cells = 0
    for job in sorted(jobs, key=lambda job: (job[2][1] - job[2][0]) * (job[2][3] - job[2][2]), reverse=True):
        i0, i1, j0, j1 = job[2]
        h, w = i1 - i0, j1 - j0
        if groups:
            nh, nw = max(hh, h), max(ww, w)
            if (len(groups[-1]) + 1) * nh * nw <= max(STACK_CELLS, 2 * (cells + h * w)):
                groups[-1].append(job)
                hh, ww, cells = nh, nw, cells + h * w
                continue
        groups.append([job])
        hh, ww, cells = h, w, h * w
    return groups


def _reduce_stack(x: np.ndarray, jobs: list[Reduce]) -> None:
    """The reduce of :func:`reduce_boxes` on the stacked inputs ``x`` ``(boxes, 2h + 3, 2w + 3)``
    of these boxes."""
    hh, ww = x.shape[1:]
    ni, nj = (hh - 3) // 2, (ww - 3) // 2
    r = x[:, 0 : 2 * ni - 1 : 2] + x[:, 4 : 2 * ni + 3 : 2]
    r += 4 * (x[:, 1 : 2 * ni : 2] + x[:, 3 : 2 * ni + 2 : 2])
    r += 6 * x[:, 2 : 2 * ni + 1 : 2]
    out = r[:, :, 0 : 2 * nj - 1 : 2] + r[:, :, 4 : 2 * nj + 3 : 2]
    out += 4 * (r[:, :, 1 : 2 * nj : 2] + r[:, :, 3 : 2 * nj + 2 : 2])
    out += 6 * r[:, :, 2 : 2 * nj + 1 : 2]
    out *= np.float32(SCALE)
    for k, (_, dst, (i0, i1, j0, j1)) in enumerate(jobs):
        dst.write(i0, j0, out[k, : i1 - i0, : j1 - j0])


def _merged(rects: list[Rect]) -> list[Rect]:
    """The rectangles with overlapping ones merged into their bounding box (when that box is
    not much larger than what it merges: an L-shaped swath stays two boxes). A cell in two
    boxes is computed twice, to the same value: merging only saves work."""
    out: list[list[int]] = []
    for r0, r1, c0, c1 in rects:
        for box in out:
            a, b, c, e = box
            if r0 <= b and a <= r1 and c0 <= e and c <= c1:
                na, nb, nc, ne = min(a, r0), max(b, r1), min(c, c0), max(e, c1)
                if (nb - na) * (ne - nc) <= 2 * ((b - a) * (e - c) + (r1 - r0) * (c1 - c0)):
                    box[0], box[1], box[2], box[3] = na, nb, nc, ne
                    break
        else:
            out.append([r0, r1, c0, c1])
    result = [(a, b, c, e) for a, b, c, e in out]
    return result if len(result) == len(rects) or len(result) <= 1 else _merged(result)


def _edges(n: int, step: int, cuts: tuple[int, ...]) -> list[int]:
    """``0, ..., n``: the multiples of ``step`` and the ``cuts``, sorted."""
    return sorted(set(range(0, n, step)) | set(cuts) | {0, n})


class MaintainedPyramid:
    """``E`` and ``P_1..P_L`` of one map, and the chunk sums of ``E`` for the guide point (see
    the module docstring). :meth:`of` gets a map's (made and attached on first use);
    :meth:`update` brings it to a planning time and returns ``s``."""

    __slots__ = ("umap", "levels", "shapes", "planes", "t0", "s", "regions", "row_edges", "col_edges",
                 "_chunk_rows", "_chunk_cols", "_chunk_sums", "_chunk_block_row", "_chunk_block_col", "_block_rows",
                 "_block_cols", "_block_sums", "_block_cells", "version", "_history", "_synced", "_own", "refreshed")

    def __init__(self, umap: UncertaintyMap, levels: int):
        self.umap = umap
        self.levels = levels
        self.shapes = level_shapes(umap.grid.shape, levels + 1)  # P_0 (= E) .. P_L
        h, w = umap.grid.shape
        if umap.dense:
            tiles: list[tuple[int, int] | None] = [None] * len(self.shapes)
            th, tw = h, w  # guide sums per sub-area (no finer chunks: one sum per changed sub-area)
        else:
            th, tw = umap.tile_shape
            tiles = [(th, tw)]
            tiles += [(max(_MIN_LEVEL_TILE, th >> l), max(_MIN_LEVEL_TILE, tw >> l)) for l in range(1, len(self.shapes))]
        self.planes = [Plane(shape, tile) for shape, tile in zip(self.shapes, tiles)]
        if not umap.dense:
            self.planes[0] = SeenPlane(umap)
        self.t0: float | None = None
        self.s = 1.0
        # The guide's sub-areas: the coarsest level with >= 4 x 4 cells (eq. 20).
        self.regions = next((s for s in reversed(self.shapes) if min(s) >= 4), self.shapes[0])
        ny, nx = self.regions
        self.row_edges = tuple(np.linspace(0, h, ny + 1).round().astype(np.intp).tolist())
        self.col_edges = tuple(np.linspace(0, w, nx + 1).round().astype(np.intp).tolist())
        self._chunk_rows = _edges(h, th, self.row_edges)
        self._chunk_cols = _edges(w, tw, self.col_edges)
        # Sums of E: per chunk (only chunks with seen cells are listed), and per sub-area the
        # exactly rounded sum of its chunks' (math.fsum: independent of order).
        self._chunk_sums: dict[tuple[int, int], float] = {}
        self._block_rows = [self._chunk_rows.index(r) for r in self.row_edges]  # chunk row of each sub-area edge
        self._block_cols = [self._chunk_cols.index(c) for c in self.col_edges]
        self._chunk_block_row = [bisect.bisect_right(self._block_rows, i) - 1 for i in range(len(self._chunk_rows) - 1)]
        self._chunk_block_col = [bisect.bisect_right(self._block_cols, j) - 1 for j in range(len(self._chunk_cols) - 1)]
        self._block_sums = np.zeros((ny, nx))
        self._block_cells = np.outer(np.diff(self.row_edges), np.diff(self.col_edges)).astype(np.float64)
        # What each update rewrote (for the members that copy this pyramid: _from_base): the
        # number of updates so far and, for the last HISTORY of them, the boxes of each plane it
        # wrote (None: all of the plane, or not known).
        self.version = 0
        self._history: list[Written] = []
        # As a group member's: the base pyramid and its version this state was copied from, and
        # the boxes of each plane where this state differs from that copy (its own extra scans').
        self._synced: tuple[MaintainedPyramid, int] | None = None
        self._own: Written | None = None
        # The time of the last plan that brought it up to date with the map (None: never).
        self.refreshed: float | None = None

    @classmethod
    def of(cls, umap: UncertaintyMap, levels: int) -> MaintainedPyramid:
        """The map's maintained pyramid of ``levels`` levels above ``G_0`` (made on first use;
        from then on the map records its writes for it)."""
        pyr = umap.derived
        if not isinstance(pyr, cls) or pyr.levels != levels:
            pyr = cls(umap, levels)
            umap.derived = pyr
            umap.track_changes()  # (drops what was recorded for another consumer: we rebuild)
        return pyr

    @property
    def nbytes(self) -> int:
        # (the chunk dict: about 100 bytes an entry)
        return sum(p.nbytes for p in self.planes) + self._block_sums.nbytes + 100 * len(self._chunk_sums)

    def update(self, t: float) -> float:
        """Bring ``E`` and the levels up to date with the map for a plan at ``t``; returns
        ``s = exp(-tau (t - t0))``."""
        return MaintainedPyramid.update_many([self], [t])[0]

    def age(self, t: float) -> float | None:
        """For a plan at ``t`` without reading the map's changes: ``s`` moved to ``t``, so the
        levels read the map as it was at the last update, aged to ``t`` (a planning budget:
        ``planner.dacmp.map_refresh_s``). None (nothing changed) when ``t`` is in another base
        span than the state's or the pyramid was never updated: then it needs :meth:`update`."""
        if self.t0 is None or self.refreshed is None or base_time(t, self.umap.tau) != self.t0:
            return None
        self.s = math.exp(-self.umap.tau * (t - self.t0))
        return self.s

    @staticmethod
    def update_many(pyramids: list[MaintainedPyramid], ts: list[float]) -> list[float]:
        """:meth:`update` of each pyramid for a plan at its ``t`` (the maps of one planning
        batch), the work of several in shared numpy calls (up to :data:`BATCH_CELLS` changed
        cells): one :func:`e_of` for the ``E`` of their maps (per ``tau``, ``t0`` and tile
        shape), one :func:`reduce_boxes` per level for the changed boxes of all of them. Every
        value is computed element-wise, by the formula an update of its map alone uses, so each
        pyramid ends bit for bit as its own update leaves it. Returns each one's ``s``."""
        if len({id(p) for p in pyramids}) < len(pyramids):  # (a pyramid listed twice: its updates in turn)
            return [MaintainedPyramid.update_many([p], [t])[0] for p, t in zip(pyramids, ts)]
        follow = MaintainedPyramid._follow_bases(pyramids, ts)
        work = [w for w in (follow[id(p)](t) if id(p) in follow else p._changed(t) for p, t in zip(pyramids, ts))
                if w is not None]
        batch: list[_Work] = []
        cells = 0
        for w in work:
            batch.append(w)
            cells += sum((r1 - r0) * (c1 - c0) for r0, r1, c0, c1 in w.boxes)
            if cells >= BATCH_CELLS or w is work[-1]:
                MaintainedPyramid._recompute(batch)
                batch, cells = [], 0
        for p, t in zip(pyramids, ts):
            p.refreshed = t
        return [p.s for p in pyramids]

    @staticmethod
    def _follow_bases(pyramids: list[MaintainedPyramid], ts: list[float]) -> dict[int, functools.partial[_Work | None]]:
        """Shared pyramids (issue 36, T9): the pyramids of maps in a
        :class:`~agents.maps.mapgroup.MapGroup` (each map the group's base plus its few extra
        scans) are brought up to date from one pyramid of the base. The base's pyramid is updated
        once, here, for all its members planning at the same base time; each member's then starts
        from a copy of it and recomputes only what its extra scans reach (:meth:`_from_base`).
        Returns, by ``id`` of each such member's pyramid, the call that does its part (the
        others update from their own map's changes: :meth:`_changed`)."""
        groups: dict[int, tuple[MaintainedPyramid, float, list[MaintainedPyramid]]] = {}
        for p, t in zip(pyramids, ts):
            umap = p.umap
            if isinstance(umap, GroupMap) and umap.extra_disks() is not None and p.planes[0].dense_array is not None:
                base = MaintainedPyramid.of(umap.base, p.levels)
                key = id(base)
                if key not in groups:
                    groups[key] = (base, t, [])
                if base_time(t, umap.tau) == base_time(groups[key][1], umap.tau):
                    groups[key][2].append(p)  # (else: from its own changes)
        if not groups:
            return {}
        MaintainedPyramid.update_many([b for b, _, _ in groups.values()], [t for _, t, _ in groups.values()])
        return {id(p): functools.partial(p._from_base, b) for b, _, members in groups.values() for p in members}

    def _from_base(self, base: MaintainedPyramid, t: float) -> _Work | None:
        """Set ``t0`` and ``s`` for a plan at ``t``, copy the state of ``base`` (the pyramid of
        this member map's group base, brought to the same ``t0``; only where this state is stale:
        :meth:`_stale`), and plan the work on the boxes
        of the map's extra scans: outside them the map's cells are the base's. Each value being
        one formula of its inputs (the module docstring), the result is bit for bit the state
        this map's own updates would reach (the boxes an update recomputes are those its
        changed cells reach: :meth:`_plan`, as for any change)."""
        umap = cast("GroupMap", self.umap)
        umap.take_changes()  # (what it wrote since: in the base or its extra scans, both read now)
        self.t0 = base.t0
        self.s = math.exp(-umap.tau * (t - cast("float", base.t0)))
        # Only where the copy is stale: where the base rewrote its planes since this state was
        # copied from it, and where this state has its own extra scans' values (everywhere else
        # it already holds the base's values; the same values, copied: bit for bit a full copy).
        stale = self._stale(base)
        for l, (mine, theirs) in enumerate(zip(self.planes, base.planes)):
            a, b = cast("np.ndarray", mine.dense_array), cast("np.ndarray", theirs.dense_array)
            boxes = stale[l] if stale is not None else None
            if boxes is None:
                np.copyto(a, b)
            else:
                for r0, r1, c0, c1 in boxes:
                    a[r0:r1, c0:c1] = b[r0:r1, c0:c1]
        self._chunk_sums = dict(base._chunk_sums)
        np.copyto(self._block_sums, base._block_sums)
        extra = umap.extra_disks() or []
        work = self._plan([(d.iy0, d.iy1, d.ix0, d.ix1) for d, _ in extra], whole=False)
        self._synced = (base, base.version)
        self._own = self._written(work) if work is not None else [[] for _ in self.planes]
        return work

    def _stale(self, base: MaintainedPyramid) -> Written | None:
        """The boxes of each plane where this member's state may differ from ``base``'s now
        (None: a plane, or all of them, to copy whole): what the base rewrote since this state
        was copied from it, and this state's own boxes (:meth:`_from_base`)."""
        if self._synced is None or self._synced[0] is not base or self._own is None:
            return None
        behind = base.version - self._synced[1]
        if behind > len(base._history):
            return None
        out: Written = [[] for _ in self.planes]
        for written in [*base._history[len(base._history) - behind:], self._own]:
            for l, boxes in enumerate(written):
                mine = out[l]
                if boxes is None or mine is None:
                    out[l] = None
                else:
                    mine += boxes
        return out

    def _written(self, work: _Work) -> Written:
        """The boxes of each plane that this work rewrites (None: the whole plane; a dense
        map's small levels above the work's plan are recomputed whole: :meth:`_recompute`)."""
        return [work.boxes, *work.plan, *([None] * (len(self.planes) - 1 - len(work.plan)))]

    def _record(self, written: Written | None) -> None:
        """Count an update that rewrote these boxes of each plane (None: all of every plane)."""
        self.version += 1
        self._history.append(written if written is not None else [None] * len(self.planes))
        if len(self._history) > HISTORY:
            del self._history[0]

    @staticmethod
    def _recompute(work: list[_Work]) -> None:
        """Do this work of several pyramids (planned by :meth:`_changed`), in shared calls."""
        tiled = [w for w in work if isinstance(w.pyr.planes[0], SeenPlane)]
        try:
            for w in tiled:
                cast("SeenPlane", w.pyr.planes[0]).open(cast("float", w.pyr.t0))
            SeenPlane.load_many([(cast("SeenPlane", w.pyr.planes[0]), w.pyr._e_keys(w)) for w in tiled])
            _write_e([w for w in work if not isinstance(w.pyr.planes[0], SeenPlane)])
            for w in work:
                w.pyr._sum_chunks(w.chunks)
            for l in range(1, max((len(w.plan) for w in work), default=0) + 1):
                reduce_boxes([(w.pyr.planes[l - 1], w.pyr.planes[l], w.plan[l - 1]) for w in work if len(w.plan) >= l])
        finally:
            for w in tiled:
                cast("SeenPlane", w.pyr.planes[0]).close()
        # The small levels above each plan, computed whole, level by level: all maps' together.
        for k in range(1, max((len(w.pyr.planes) for w in work), default=0)):
            reduce_whole_many([(cast("np.ndarray", w.pyr.planes[k - 1].dense_array),
                                cast("np.ndarray", w.pyr.planes[k].dense_array))
                               for w in work if len(w.plan) < k < len(w.pyr.planes)])
        for w in work:
            w.pyr._record(w.pyr._written(w))

    def _changed(self, t: float) -> _Work | None:
        """Set ``t0`` and ``s`` for a plan at ``t`` (clearing the state when ``t0`` moved or the
        map's changes are not known) and plan the work on what changed (None: nothing)."""
        tau = self.umap.tau
        t0 = base_time(t, tau)
        changes = self.umap.take_changes()
        self.s = math.exp(-tau * (t - t0))
        self._synced = None  # (from here on its own state, not a copy of a base's)
        if t0 != self.t0 or changes is None:
            self.t0 = t0
            self._record(None)
            for p in self.planes:
                p.clear()
            self._chunk_sums.clear()
            self._block_sums.fill(0.0)
            return self._plan(self.umap.written_boxes(), whole=self.umap.dense)
        return self._plan(changes, whole=False) if changes else None

    def _plan(self, rects: list[Rect], whole: bool) -> _Work | None:
        """The work of recomputing ``E`` on these boxes of the map, then every level output they
        reach. A level is computed whole (one box) when it is small (at most
        :data:`WHOLE_CELLS` cells) or the boxes cover a quarter of it, or everywhere with
        ``whole``."""
        h0, w0 = self.shapes[0]
        boxes = [(0, h0, 0, w0)] if whole else _merged(rects)
        if not boxes:
            return None
        # The boxes reduce_boxes computes on levels 1, 2, ...; a dense map's levels above them
        # (small ones) are computed whole by BLAS.
        dense = self.umap.dense
        plan: list[list[Rect]] = []
        level_boxes = boxes
        for m, mw in self.shapes[1:]:
            if dense and m * mw <= WHOLE_CELLS:
                break
            if whole:
                level_boxes = [(0, m, 0, mw)]
            else:
                level_boxes = _merged([(max(0, (r0 - 1) // 2), min(m, (r1 + 1) // 2 + 1),
                                        max(0, (c0 - 1) // 2), min(mw, (c1 + 1) // 2 + 1))
                                       for r0, r1, c0, c1 in level_boxes])
                if dense and 4 * sum((b - a) * (d - c) for a, b, c, d in level_boxes) >= m * mw:
                    level_boxes, whole = [(0, m, 0, mw)], True  # (and every level above it)
            plan.append(level_boxes)
        chunks: set[tuple[int, int]] = set()
        cr, ccl = self._chunk_rows, self._chunk_cols
        for r0, r1, c0, c1 in boxes:
            for i in range(bisect.bisect_right(cr, r0) - 1, bisect.bisect_left(cr, r1)):
                for j in range(bisect.bisect_right(ccl, c0) - 1, bisect.bisect_left(ccl, c1)):
                    chunks.add((i, j))
        return _Work(self, boxes, plan, chunks)

    def _e_keys(self, work: _Work) -> list[int]:
        """The map tiles whose ``E`` this work reads (the chunks', level 1's inputs)."""
        e = cast("SeenPlane", self.planes[0])
        h0, w0 = self.shapes[0]
        cr, ccl = self._chunk_rows, self._chunk_cols
        keys = [k for i, j in work.chunks for k in e.keys(cr[i], cr[i] + 1, ccl[j], ccl[j] + 1)]
        if work.plan:
            for i0, i1, j0, j1 in work.plan[0]:
                keys += e.keys(max(0, 2 * i0 - 2), min(h0, 2 * i1 + 1), max(0, 2 * j0 - 2), min(w0, 2 * j1 + 1))
        return keys

    def _sum_chunks(self, chunks: set[tuple[int, int]]) -> None:
        """Recompute the sums of ``E`` of these chunks and of their sub-areas."""
        e, cr, ccl = self.planes[0], self._chunk_rows, self._chunk_cols
        sums, blocks = self._chunk_sums, set()
        for i, j in chunks:
            v = e.sum(cr[i], cr[i + 1], ccl[j], ccl[j + 1])  # (float32, pairwise: error ~1e-7)
            if v:
                sums[i, j] = v
            else:
                sums.pop((i, j), None)
            blocks.add((self._chunk_block_row[i], self._chunk_block_col[j]))
        br, bc = self._block_rows, self._block_cols
        for bi, bj in blocks:
            self._block_sums[bi, bj] = math.fsum(sums.get((i, j), 0.0) for i in range(br[bi], br[bi + 1])
                                                 for j in range(bc[bj], bc[bj + 1]))

    # --- reads ------------------------------------------------------------------------------

    def level(self, l: int) -> np.ndarray:
        """``G_l = 1 - s P_l`` of the whole level, float64 (for tests and tools: planning reads
        windows, :meth:`read_window`)."""
        h, w = self.shapes[l]
        return 1.0 - self.s * self.planes[l].read(0, h, 0, w).astype(np.float64)

    def read_window(self, l: int, r0: int, r1: int, c0: int, c1: int, out: np.ndarray) -> None:
        """``P_l`` on rows ``r0:r1``, columns ``c0:c1``, into ``out``."""
        self.planes[l].read(r0, r1, c0, c1, out=out)

    def block_means(self) -> np.ndarray:
        """Mean ``q`` over each of the guide's sub-areas, ``(ny, nx)`` float64:
        ``1 - s sum(E) / cells``."""
        return 1.0 - self.s * (self._block_sums / self._block_cells)


class _Work(NamedTuple):
    """What one pyramid's update recomputes: ``E`` on ``boxes``, the level boxes of
    :func:`reduce_boxes` (``plan[l - 1]``: level ``l``'s), the chunk sums of ``chunks``."""

    pyr: MaintainedPyramid
    boxes: list[Rect]
    plan: list[list[Rect]]
    chunks: set[tuple[int, int]]


def _write_e(work: list[_Work]) -> None:
    """``E`` of the boxes of these dense maps, written into their ``P_0``: one :func:`e_of` call
    per ``tau`` and ``t0`` (the last-seen times of all boxes side by side in one flat array)."""
    groups: dict[tuple[float, float], list[tuple[Plane, Rect, np.ndarray]]] = {}
    for w in work:
        umap = w.pyr.umap
        group = groups.setdefault((umap.tau, cast("float", w.pyr.t0)), [])
        group += [(w.pyr.planes[0], box, umap.region(slice(box[0], box[1]), slice(box[2], box[3]))) for box in w.boxes]
    for (tau, t0), group in groups.items():
        seen = [a for _, _, a in group]
        flat = e_of(np.concatenate([a.ravel() for a in seen]) if len(seen) > 1 else seen[0], tau, t0).ravel()
        at = 0
        for plane, (r0, _, c0, _), a in group:
            plane.write(r0, c0, flat[at : at + a.size].reshape(a.shape))
            at += a.size
