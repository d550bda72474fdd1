"""Pairs of points within a distance, for the few places that look for them among a handful of
points (detect-and-avoid, a scenario's placement check): plain numpy below :data:`TREE_MIN`
points, where testing every pair costs no more than building a k-d tree (measured: 11 vs 11 us
at 3 points, 8 vs 10 at 6, 10 vs 18 at 31) and scipy need not be imported at all; scipy's k-d
tree from it on (imported then)."""

from __future__ import annotations

import functools

import numpy as np

TREE_MIN = 32  # from this many points, a k-d tree finds the pairs


def pairs_within(xy: np.ndarray, r: float) -> np.ndarray:
    """Index pairs ``(i, j)``, ``i < j``, of the points ``xy`` (shape (n, 2)) at most ``r`` apart,
    in no particular order, as an (m, 2) integer array. The two ways may disagree on a pair whose
    distance rounds to ``r`` itself: callers ask with a margin and test exactly, or do not care
    at that precision."""
    n = len(xy)
    if n >= TREE_MIN:
        from scipy.spatial import cKDTree

        return cKDTree(xy).query_pairs(r, output_type="ndarray")
    i, j = _every_pair(n)
    x, y = xy[:, 0], xy[:, 1]
    dx, dy = x[i] - x[j], y[i] - y[j]
    near = np.flatnonzero(dx * dx + dy * dy <= r * r)
    return np.stack((i[near], j[near]), axis=1)


@functools.lru_cache(maxsize=TREE_MIN)
def _every_pair(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.triu_indices(n, 1)``, made once per ``n`` (it costs more than the test of the pairs),
    read-only."""
    i, j = np.triu_indices(n, 1)
    i.flags.writeable = False
    j.flags.writeable = False
    return i, j
