"""Gaussian map pyramid of the DACMP planner (spec "The planner" 1, paper eq. 17-18).

``G_0 = q`` (the uncertainty map, indexed ``[row, col]``) and ``G_l = REDUCE(G_{l-1})``:
a 5x5 binomial blur with the separable kernel ``[1, 4, 6, 4, 1] / 16`` along both axes, border
mode *reflect* in scipy.ndimage's sense (``d c b a | a b c d``, the edge sample repeated), then
every other row and column is kept, starting at index 0.  A level of shape ``(h, w)`` therefore
gives ``(ceil(h/2), ceil(w/2))``.  Up to float rounding the result equals::

    b = scipy.ndimage.convolve1d(a, k, axis=0, mode="reflect")
    b = scipy.ndimage.convolve1d(b, k, axis=1, mode="reflect")
    b[::2, ::2]

but only the kept output rows/columns are computed, directly as strided sums
``out[i] = sum_k w_k * a[reflect(2i + k - 2)]``: rows first (halving the data), then columns (done
as a row pass on the transposed, re-contiguous intermediate, which is faster than column-strided
access).  Interior outputs are one BLAS matrix-vector product over a read-only strided view of the
input (no padding copy, no scipy); the one or two border rows/columns per axis use reflected
indices.  The weights are applied as integers (1, 4, 6, 4, 1) and the ``1/256`` (exact, a power of
two) once at the end.  float32 input stays float32 (computed in float32); other floating dtypes
keep their dtype; integer/bool input is computed in float64.  Results agree with the scipy
formulation to float rounding (a few ulp: BLAS may fuse multiply-adds), not bit for bit; they are
deterministic for a given machine and library build.

:func:`pyr_down_stack` reduces a stack of same-shape maps at once (one call per step for all
of them, the same BLAS call per row as for one map, so each map gets exactly its own numbers),
with its intermediates in a :class:`Scratch` that a caller keeps between calls.

The planner itself does not recompute pyramids: :mod:`agents.planners.dacmp.maintained` keeps
each map's pyramid of ``1 - q`` (times a scalar) up to date where the map changed, with the same
REDUCE; this module is the definition it is tested against.

Stopping rule of :func:`gaussian_pyramid`: ``ceil(n/2) >= 1``, so no level can ever become
smaller than 1x1; once a level is 1x1 every further level would be the same single value again
(carrying no information), so the pyramid stops after the first 1x1 level and the returned list
may then be shorter than ``levels``.  (The paper's 500x500 grid with 7 levels never gets there:
500, 250, 125, 63, 32, 16, 8.)
"""

from __future__ import annotations

import functools
import math
from typing import Any, cast, overload

import numpy as np
import numpy.typing as npt

__all__ = ["SCALE", "Scratch", "reduce_rows", "pyr_down", "pyr_down_stack", "gaussian_pyramid", "level_shapes", "level_index",
           "sample_levels"]

_WEIGHTS = np.array([1.0, 4.0, 6.0, 4.0, 1.0])  # binomial, unnormalised
SCALE = 1.0 / 256.0  # (1/16) per axis, applied once at the end (exact: a power of two)


def _reflect(j: int, n: int) -> int:
    """scipy.ndimage 'reflect' index (``d c b a | a b c d``, period 2n)."""
    j %= 2 * n
    return 2 * n - 1 - j if j >= n else j


@functools.lru_cache(maxsize=64)
def _border_rows(n: int) -> tuple[tuple[int, tuple[int, ...]], ...]:
    """``(i, five input rows)`` of each output row of a reduce over ``n`` rows that has an input
    outside ``0..n-1`` (reflected): the first and the last, or every row when ``n < 5``."""
    m = (n + 1) // 2
    hi = (n - 3) // 2  # last output row i with 2i + 2 <= n - 1 (fully interior)
    rows = [0, *range(hi + 1, m)] if hi >= 1 else range(m)
    return tuple((i, tuple(_reflect(2 * i + t - 2, n) for t in range(5))) for i in rows)


def reduce_rows(a: np.ndarray, out: np.ndarray, n: int | None = None, row0: int = 0, lo: int = 0,
                hi: int | None = None) -> None:
    """Unscaled [1,4,6,4,1] reduce along axis 1 of a C-contiguous stack ``a`` of 2-D arrays
    ``(k, rows, ncols)``, kept rows only, into ``out`` ``(k, ceil(n/2), ncols)``.

    Output row ``i`` is ``sum_k w_k * a[reflect(2i + k - 2)]``.  Rows whose five inputs are all in
    range (all but the first and the last) are one matrix-vector product per row over a read-only
    strided view ``V[s, i, c, k] = a[s, 2i + k, c]`` (no copy: BLAS gemv does the five-term sums,
    the same call for every row whatever ``k``); the one or two border rows use reflected indices.

    Part of a reduce: ``a`` may hold only input rows ``row0 ..
    row0 + rows - 1`` of an ``n``-row input (default: all of it, ``n = rows``), and only output
    rows ``lo .. hi`` (default: all) are computed, into ``out[:, : hi - lo + 1]``; ``a`` must hold
    every input row they read (``2i - 2 .. 2i + 2``, clipped to the input). Each output row gets
    the numbers of the whole reduce: the same call on the same five rows.
    """
    k, rows, ncols = a.shape
    if n is None:
        n = rows
    if hi is None:
        hi = (n + 1) // 2 - 1
    i0, i1 = max(lo, 1), min(hi, (n - 3) // 2)  # the fully interior output rows wanted
    if i1 >= i0:
        sk, s0, s1 = a.strides
        # np.ndarray over a's buffer: the same view as as_strided, at a fraction of its call cost.
        view = np.ndarray((k, i1 - i0 + 1, ncols, 5), a.dtype, a, (2 * i0 - 2 - row0) * s0, (sk, 2 * s0, s1, s0))
        view.flags.writeable = False
        np.matmul(view, _WEIGHTS.astype(a.dtype), out=out[:, i0 - lo : i1 - lo + 1])
    for i, j in _border_rows(n):  # at most two rows, or every row of a tiny array
        if lo <= i <= hi:
            r = out[:, i - lo]
            np.add(a[:, j[0] - row0], a[:, j[4] - row0], out=r)
            r += 4 * (a[:, j[1] - row0] + a[:, j[3] - row0])
            r += 6 * a[:, j[2] - row0]


class Scratch:
    """Named work arrays kept from call to call: a planner replanning every few seconds reuses
    the same memory instead of allocating (and page-faulting) megabytes each time.

    ``get(name, shape, dtype)`` returns a C-contiguous array of that shape, with undefined
    contents, backed by the name's buffer (grown when too small, never shrunk: the memory held
    is what the largest call needed). An array is valid until the next ``get`` of the same name.
    """

    def __init__(self) -> None:
        self._buffers: dict[str, np.ndarray] = {}
        # (name, shape, dtype) -> view of the buffer
        self._arrays: dict[tuple[str, tuple[int, ...], npt.DTypeLike], np.ndarray] = {}

    def get(self, name: str, shape: tuple[int, ...], dtype: npt.DTypeLike = np.float32) -> np.ndarray:
        key = (name, shape, dtype)
        a = self._arrays.get(key)
        if a is None:
            dt = np.dtype(dtype)
            nbytes = math.prod(shape) * dt.itemsize
            buf = self._buffers.get(name)
            if buf is None or buf.size < nbytes:
                buf = self._buffers[name] = np.empty(nbytes, np.uint8)
                self._arrays = {k: v for k, v in self._arrays.items() if k[0] != name}  # old buffer
            a = self._arrays[key] = buf[:nbytes].view(dt).reshape(shape)
        return a


def pyr_down_stack(a: np.ndarray, out: np.ndarray, scratch: Scratch | None = None) -> np.ndarray:
    """:func:`pyr_down` of every map of a C-contiguous float stack ``a`` ``(k, h, w)``, written
    into ``out`` ``(k, ceil(h/2), ceil(w/2))`` (same dtype).  Each map gets exactly the numbers
    :func:`pyr_down` gives it alone.  ``scratch`` supplies the intermediates (fresh arrays
    without it); they stay there until its next use: ``"pyr_rows"`` the row pass ``(k, m, w)``,
    ``"pyr_rows_t"`` its transpose ``(k, w, m)``, ``"pyr_cols_t"`` the column pass, transposed."""
    k, h, w = a.shape
    m, mw = (h + 1) // 2, (w + 1) // 2
    work = scratch if scratch is not None else Scratch()
    b = work.get("pyr_rows", (k, m, w), a.dtype)
    reduce_rows(a, b)  # rows: (ceil(h/2), w)
    bt = work.get("pyr_rows_t", (k, w, m), a.dtype)
    np.copyto(bt, b.transpose(0, 2, 1))
    out_t = work.get("pyr_cols_t", (k, mw, m), a.dtype)
    reduce_rows(bt, out_t)  # columns, on the transpose
    # Back to row-major, scaled on the way (exact: a power of two).
    np.multiply(out_t.transpose(0, 2, 1), a.dtype.type(SCALE), out=out)
    return out


def pyr_down(a: np.ndarray) -> np.ndarray:
    """One pyramid step: [1,4,6,4,1]/16 blur on both axes (reflect border), keep ``[::2, ::2]``.

    ``a`` must be 2-D and non-empty; the result has shape ``(ceil(h/2), ceil(w/2))`` and the
    dtype of ``a`` (float32 stays float32; integer/bool input gives float64).
    """
    a = np.asarray(a)
    if a.ndim != 2:
        raise ValueError(f"pyr_down expects a 2-D array, got shape {a.shape}")
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"pyr_down expects a non-empty array, got shape {a.shape}")
    if not np.issubdtype(a.dtype, np.floating):
        a = a.astype(np.float64)
    h, w = a.shape
    out = np.empty((1, (h + 1) // 2, (w + 1) // 2), a.dtype)
    down: np.ndarray = pyr_down_stack(np.ascontiguousarray(a)[None], out)[0]
    return down


def level_shapes(shape: tuple[int, int], levels: int) -> list[tuple[int, int]]:
    """Shapes of ``gaussian_pyramid(q, levels)`` for a ``q`` of this shape (same stopping rule)."""
    shapes = [cast("tuple[int, int]", tuple(shape))]
    while len(shapes) < levels and shapes[-1] != (1, 1):
        h, w = shapes[-1]
        shapes.append(((h + 1) // 2, (w + 1) // 2))
    return shapes


def gaussian_pyramid(q: np.ndarray, levels: int) -> list[np.ndarray]:
    """``[G_0, G_1, ..., G_{levels-1}]`` with ``G_0 = q`` (not copied) and ``G_l = pyr_down(G_{l-1})``.

    ``levels`` counts G_0 and must be >= 1.  Stops early after the first 1x1 level (further levels
    could not be smaller, only identical), so the list can be shorter than ``levels``.
    """
    levels = int(levels)
    if levels < 1:
        raise ValueError(f"levels must be >= 1, got {levels}")
    g = np.asarray(q)
    if g.ndim != 2 or g.shape[0] == 0 or g.shape[1] == 0:
        raise ValueError(f"q must be a non-empty 2-D array, got shape {g.shape}")
    pyr = [g]
    for _ in level_shapes(g.shape, levels)[1:]:
        pyr.append(pyr_down(pyr[-1]))
    return pyr


@overload
def level_index(i0: int, level: int) -> int: ...
@overload
def level_index(i0: npt.NDArray[np.integer[Any]], level: int) -> npt.NDArray[np.integer[Any]]: ...


def level_index(i0: int | npt.NDArray[np.integer[Any]], level: int) -> int | npt.NDArray[np.integer[Any]]:
    """Index on level ``level`` of the cell nearest to level-0 cell ``i0`` (int or int array).

    ``REDUCE`` keeps samples 0, 2, 4, ...: level-``l`` cell ``a`` is centred on level-0 cell
    ``2**l * a``, not on the middle of the block ``[2**l a, 2**l (a+1))``. Reading level ``l`` at
    ``i0 >> l`` would therefore look half a coarse cell towards the origin (3.2 km on level 6 of
    the paper's map): the planner would see every region shifted south-west of where it is.
    Rounding to the nearest centre removes that bias.
    """
    return (i0 + ((1 << level) >> 1)) >> level


def sample_levels(pyramid: list[np.ndarray], ix0: np.ndarray, iy0: np.ndarray) -> np.ndarray:
    """Values of every level at the cells nearest to level-0 cells ``(row iy0, col ix0)``.

    Returns shape ``(len(pyramid), n)`` (``n`` = number of points after broadcasting ``ix0``,
    ``iy0`` and flattening): row ``l`` is ``G_l[clip(level_index(iy0, l)), clip(level_index(ix0, l))]``,
    indices clipped to the level's shape.  The dtype is the common dtype of the levels.
    """
    ix = np.asarray(ix0).astype(np.intp, copy=False).ravel()
    iy = np.asarray(iy0).astype(np.intp, copy=False).ravel()
    ix, iy = np.broadcast_arrays(ix, iy)
    dtype = np.result_type(*pyramid) if pyramid else np.float64
    out = np.empty((len(pyramid), ix.shape[0]), dtype=dtype)
    # Negative indices clip to 0 once (rounding a non-negative index stays non-negative); the
    # upper clip is per level.
    ix = np.maximum(ix, 0)
    iy = np.maximum(iy, 0)
    for l, g in enumerate(pyramid):  # loop over levels (~7), not points
        h, w = g.shape
        r = np.minimum(level_index(iy, l), h - 1)
        c = np.minimum(level_index(ix, l), w - 1)
        r *= w
        r += c
        out[l] = np.take(g, r)  # flat (row-major) index r * w + c, any memory layout
    return out
