"""q and the first two pyramid levels of the maps planned in one tick, computed once.

The UAVs that replan in the same tick usually hold nearly the same map: in a swarm that hears
itself well, every map has every scan up to the previous tick, and each adds its own scan of
this tick. Their q (``1 - exp(-tau (t - last_seen))``) and their pyramid levels G_1, G_2 then
differ only around those few disks, yet computing them is most of a plan's map work (a pass of
``exp`` over every cell and a 5 x 5 blur of the whole map).

:class:`FirstLevels` computes one *reference* map in full, the shared base of the UAVs'
:class:`~agents.maps.mapgroup.MapGroup`, and keeps its q and the intermediates of its pyramid steps
(row pass, its transpose). Each member map differs from the base only inside the disks of its
extra scans, which the group lists; for it, FirstLevels recomputes only where an input changed:

* q on the rows that differ (plus the rows the row pass reads around them);
* the row pass's output rows that read a changed row (each output row reads five input rows);
* the column pass's output rows (the level's columns) that read a changed column, on the
  reference's transposed row pass with the new rows written in;

and copies everything else from the reference; G_2 likewise from G_1. The numbers are exactly
those of computing the map alone: q is element-wise, and numpy gives an element the same value
in any array or slice (tested); each pyramid output row is the same BLAS call on the same five
input rows whatever rows are computed with it (:func:`agents.planners.dacmp.pyramid.reduce_rows`). Maps outside
a group (tiled maps, maps that left theirs) and members whose extra scans span many rows are
computed in full. (Comparing maps outside a group with the reference cell by cell to patch them
too cost about what it saved when they were alike, and more when they were not.)
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, TypeVar, cast

import numpy as np

from agents.maps.grid import Disk
from agents.maps.umap import UncertaintyMap
from agents.planners.dacmp.pyramid import SCALE, Scratch, pyr_down_stack, reduce_rows

if TYPE_CHECKING:
    from agents.maps.mapgroup import GroupMap

# A map is patched when at most this share of its rows differ from the reference's; beyond
# that, recomputing the patched rows and columns costs about what the whole map costs.
MAX_CHANGED_ROWS = 0.35
# Runs of changed rows closer than this are patched as one band (the row-pass output rows
# they touch would overlap).
_MERGE_GAP = 8
# Maps smaller than this (rows or columns) are always computed in full.
_MIN_SIDE = 16
# A group member with more extra scans than this is computed in full.
MAX_EXTRA = 64

T = TypeVar("T")

# FirstLevels' reference: (base map, t, (ny, nx), q, row pass transposed, G_1).
_Reference = tuple[UncertaintyMap, float, tuple[int, int], np.ndarray, np.ndarray, np.ndarray]


class _Band:
    """Rows ``r0:r1`` of a map that may differ from the reference's, within columns ``c0:c1``;
    its q on rows ``qa:qa + len(q)`` and row-pass output rows ``i_lo..i_hi``."""

    __slots__ = ("r0", "r1", "c0", "c1", "qa", "q", "i_lo", "i_hi", "rows")
    # Set as the band is processed (_band_q, _patch_level).
    qa: int
    q: np.ndarray
    i_lo: int
    i_hi: int
    rows: np.ndarray

    def __init__(self, r0: int, r1: int, c0: int, c1: int):
        self.r0, self.r1, self.c0, self.c1 = r0, r1, c0, c1


def _disk_bands(disks: list[Disk], ny: int) -> list[_Band] | None:
    """Bands covering these disks (each disk's box; boxes less than :data:`_MERGE_GAP` rows
    apart merged), or None if they span too many rows to be worth patching."""
    bands: list[_Band] = []
    for d in sorted(disks, key=lambda d: d.iy0):
        b = bands[-1] if bands else None
        if b is not None and d.iy0 <= b.r1 + _MERGE_GAP:
            b.r1, b.c0, b.c1 = max(b.r1, d.iy1), min(b.c0, d.ix0), max(b.c1, d.ix1)
        else:
            bands.append(_Band(d.iy0, d.iy1, d.ix0, d.ix1))
    if sum(b.r1 - b.r0 for b in bands) > MAX_CHANGED_ROWS * ny:
        return None
    return bands


def _row_reads(b: _Band, n: int) -> tuple[int, int, int, int]:
    """The row-pass output rows ``i_lo..i_hi`` that read a row of band ``b`` of an ``n``-row
    input (output row i reads input rows 2i - 2 .. 2i + 2, clipped), and the input rows
    ``a:z`` they read."""
    i_lo, i_hi = max(0, (b.r0 - 1) // 2), min((n + 1) // 2 - 1, (b.r1 + 1) // 2)
    return i_lo, i_hi, max(0, 2 * i_lo - 2), min(n, 2 * i_hi + 3)


def _patch_level(ref_rows_t: np.ndarray, ref_out: np.ndarray, out: np.ndarray, bands: list[_Band],
                 rows_of: Callable[[_Band, int, int], np.ndarray], n: int, ncols: int) -> list[_Band]:
    """One pyramid step of a map that differs from the reference map only inside ``bands`` (of
    an ``n x ncols`` input): ``out`` = the reference's output ``ref_out``, recomputed where an
    input changed. ``ref_rows_t``: the reference's row pass, transposed; ``rows_of(band, a, b)``:
    this map's input rows ``a:b`` (every row the band's row-pass outputs read; the band's
    changed cells must be right in it). Returns the bands of the output that changed."""
    m, mw = (n + 1) // 2, (ncols + 1) // 2
    np.copyto(out, ref_out)
    # Row pass: only the output rows that read a changed row.
    for b in bands:
        b.i_lo, b.i_hi, a, z = _row_reads(b, n)
        b.rows = np.empty((1, b.i_hi - b.i_lo + 1, ncols), out.dtype)
        reduce_rows(rows_of(b, a, z)[None], b.rows, n=n, row0=a, lo=b.i_lo, hi=b.i_hi)
    # Column pass (on the transpose): output column j reads row-pass columns 2j - 2 .. 2j + 2.
    changed: list[_Band] = []
    for b in bands:
        j_lo, j_hi = max(0, (b.c0 - 1) // 2), min(mw - 1, (b.c1 + 1) // 2)
        ca, cb = max(0, 2 * j_lo - 2), min(ncols, 2 * j_hi + 3)
        cols_t = ref_rows_t[ca:cb].copy()  # the reference's row pass, transposed, ...
        for other in bands:  # ... with this map's new rows written in
            cols_t[:, other.i_lo : other.i_hi + 1] = other.rows[0, :, ca:cb].T
        out_t = np.empty((1, j_hi - j_lo + 1, m), out.dtype)
        reduce_rows(cols_t[None], out_t, n=ncols, row0=ca, lo=j_lo, hi=j_hi)
        np.multiply(out_t[0].T, out.dtype.type(SCALE), out=out[:, j_lo : j_hi + 1])
        changed.append(_Band(b.i_lo, b.i_hi + 1, j_lo, j_hi + 1))
    return changed


class FirstLevels:
    """q, G_1 and G_2 of a planning call's maps (see the module docstring). Keeps its buffers
    from call to call; :meth:`start` begins a call, :meth:`compute` does one map's q and G_1
    (a patched G_1 is written by :meth:`finish`), :meth:`reduce_g1` every map's G_2."""

    def __init__(self, reuse: bool = True) -> None:
        self.reuse = reuse  # False: every map in full (the same numbers; for tests and benchmarks)
        self._ref_work = Scratch()  # the reference's q and pyramid intermediates
        self._other_work = Scratch()  # maps computed in full
        self._g2_work = Scratch()  # the reference's second pyramid step (reduce_g1)
        self.patched = 0  # maps computed by patching (for tests and benchmarks)
        self.full = 0
        self.start()

    def start(self) -> None:
        """A new planning call: the reference is chosen afresh."""
        self._ref: _Reference | None = None
        # Per map computed (in order): where its G_1 differs from the reference's (bands of
        # G_1), or None if it was computed in full.
        self._slots: list[list[_Band] | None] = []
        self._pending: list[tuple[int, np.ndarray, list[_Band]]] = []  # G_1 patches to do (finish)

    def compute(self, umap: UncertaintyMap, t: float, g1: np.ndarray, use: Callable[[np.ndarray], T]) -> T:
        """Write the map's G_1 at ``t`` into ``g1`` and return ``use(q)``, ``q`` the map's q
        (valid only during the call: it may be the reference's, patched for the call)."""
        ny, nx = umap.grid.shape
        extra = umap.extra_disks() if hasattr(umap, "extra_disks") else None  # a MapGroup member's
        if self.reuse and extra is not None and len(extra) <= MAX_EXTRA and min(ny, nx) >= _MIN_SIDE:
            base = cast("GroupMap", umap).base  # (a member: it has extra_disks)
            ref = self._ref
            if ref is None:
                ref = self._set_reference(base, t)
            bands = _disk_bands([d for d, _ in extra], ny) if ref[0] is base and ref[1] == t else None
            if bands is not None:
                self.patched += 1
                self._band_q(umap, t, bands)
                # G_1 is patched later (finish()): q, which the user reads now, stays in cache.
                self._pending.append((len(self._slots), g1, bands))
                self._slots.append(None)
                return self._use_patched(bands, use)
        self.full += 1
        self._slots.append(None)
        work = self._other_work
        q = work.get("q", (1, ny, nx))
        umap.uncertainty(t, out=q[0])
        pyr_down_stack(q, g1[None], work)
        return use(q[0])

    def _set_reference(self, base: UncertaintyMap, t: float) -> _Reference:
        """Compute a group's base's q and G_1 at ``t`` in full and make it the reference (returned)."""
        ny, nx = base.grid.shape
        m, mw = (ny + 1) // 2, (nx + 1) // 2
        work = self._ref_work
        q = work.get("q", (1, ny, nx))
        base.uncertainty(t, out=q[0])
        g1 = work.get("g1", (m, mw))
        pyr_down_stack(q, g1[None], work)
        # pyr_down_stack's intermediates, left in the scratch: row pass, its transpose.
        bt = work.get("pyr_rows_t", (1, nx, m), q.dtype)
        ref = self._ref = (base, t, (ny, nx), q[0], bt[0], g1)
        return ref

    def reduce_g1(self, g1: np.ndarray, g2: np.ndarray, scratch: Scratch) -> bool:
        """G_2 of every map of the call (after all of them were computed), ``g1`` and ``g2``
        ``(maps, h, w)`` in :meth:`compute`'s order: ``pyr_down_stack(g1, g2)``, with the
        patched maps patched from the reference's G_2 (the same numbers). False, doing nothing,
        when no map was patched."""
        self.finish()
        slots = self._slots
        if self._ref is None or len(slots) != len(g1) or all(b is None for b in slots):
            return False
        ref_g1 = self._ref[5]
        n, ncols = ref_g1.shape
        work = self._g2_work
        ref_g2 = work.get("g2", (1, (n + 1) // 2, (ncols + 1) // 2))
        pyr_down_stack(ref_g1[None], ref_g2, work)
        ref_rows_t = work.get("pyr_rows_t", (1, ncols, (n + 1) // 2), ref_g1.dtype)[0]
        for i, bands in enumerate(slots):
            if bands is None:
                pyr_down_stack(g1[i : i + 1], g2[i : i + 1], scratch)
            else:
                lower = g1[i]
                # (the lambda is called within this iteration: it reads this iteration's lower)
                _patch_level(ref_rows_t, ref_g2[0], g2[i], bands, lambda b, a, z: lower[a:z], n, ncols)  # noqa: B023
        return True

    def _use_patched(self, bands: list[_Band], use: Callable[[np.ndarray], T]) -> T:
        """``use(q)`` of a patched map: the reference's q with this map's changed cells written
        in for the call (they are few; copying the whole map would cost more)."""
        ref_q = cast("_Reference", self._ref)[3]  # (set: a patched map is a reference's)
        saved = []
        try:
            for b in bands:
                rows, cols = slice(b.r0, b.r1), slice(b.c0, b.c1)
                saved.append((rows, cols, ref_q[rows, cols].copy()))
                ref_q[rows, cols] = b.q[0, b.r0 - b.qa : b.r1 - b.qa, cols]
            return use(ref_q)
        finally:
            for rows, cols, old in reversed(saved):
                ref_q[rows, cols] = old

    def _band_q(self, umap: UncertaintyMap, t: float, bands: list[_Band]) -> None:
        """The q of the rows each band's row pass reads, into the band: the reference's except
        in the band's columns (bands are far enough apart that no band's rows reach another's
        changes)."""
        _, _, (ny, nx), ref_q, _, _ = cast("_Reference", self._ref)  # (set: see compute)
        for b in bands:
            _, _, b.qa, qb = _row_reads(b, ny)
            b.q = ref_q[None, b.qa : qb].copy()
            umap.q_into(t, umap.region(slice(b.qa, qb), slice(b.c0, b.c1)), b.q[0, :, b.c0 : b.c1])

    def finish(self) -> None:
        """Write the G_1 of the maps patched so far (compute() leaves it pending): call before
        reading any map's G_1."""
        if not self._pending:
            return
        _, _, (ny, nx), _, ref_bt, ref_g1 = cast("_Reference", self._ref)  # (set: patches are against it)
        for slot, g1, bands in self._pending:
            self._slots[slot] = _patch_level(ref_bt, ref_g1, g1, bands, lambda b, a, z: b.q[0, a - b.qa : z - b.qa], ny, nx)
        self._pending = []
