"""Pairs of points within a distance.

:func:`pairs_within`, for the few places that look for them among a handful of points (a
scenario's placement check, detect-and-avoid on the per-actor path): plain numpy below
:data:`TREE_MIN` points, where testing every pair costs no more than building a k-d tree
(measured: 11 vs 11 us at 3 points, 8 vs 10 at 6, 10 vs 18 at 31) and scipy need not be imported
at all; scipy's k-d tree from it on (imported then).

:class:`TickPairs` (issue 36, the tick plane): the pairs of live UAVs near each other at one
tick's positions, found once and shared by everything that needs them that tick: the radio's
links, detect-and-avoid and the safety check. Each takes the pairs within its own range
(:meth:`Near.within`), tested exactly (``dx * dx + dy * dy <= r * r``, the test the k-d tree
applies to a pair it finds).
"""

from __future__ import annotations

import functools
import math

import numpy as np

TREE_MIN = 32  # from this many points, a k-d tree finds the pairs

# The tick's query reaches this much beyond the largest range asked for (relative and absolute):
# a pair exactly at a range is then found whatever the k-d tree's rounding, and judged by the
# exact test of the range that asks.
_SLACK_REL, _SLACK_ABS = 1e-9, 1e-6


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


class Near:
    """The pairs of one set of points within a reach: index arrays ``i < j`` sorted by ``(i, j)``
    and their squared distances ``d2`` (``dx * dx + dy * dy``), read-only."""

    __slots__ = ("i", "j", "d2", "_within")

    def __init__(self, i: np.ndarray, j: np.ndarray, d2: np.ndarray):
        self.i, self.j, self.d2 = i, j, d2
        self._within: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def within(self, r: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pairs ``(i, j, d2)`` at most ``r`` apart (``d2 <= r * r``), in ``(i, j)`` order;
        ``r`` must not exceed the reach they were found at."""
        got = self._within.get(r)
        if got is None:
            if math.isinf(r):
                got = (self.i, self.j, self.d2)
            else:
                keep = np.flatnonzero(self.d2 <= r * r)
                if len(keep) == len(self.d2):
                    got = (self.i, self.j, self.d2)
                elif not len(keep):
                    got = (keep, keep, self.d2[:0])
                else:
                    got = (self.i[keep], self.j[keep], self.d2[keep])
            self._within[r] = got
        return got


class TickPairs:
    """One pair query per set of positions, up to ``reach_m`` (inf: every pair), kept until other
    positions are asked about: the radio, detect-and-avoid and the safety check of a tick all
    ask about the same live UAVs at the same positions, and share one query.

    Below :data:`TREE_MIN` points every pair is tested in numpy, from it on a k-d tree finds the
    candidates (up to the reach plus a hair); either way a pair's ``d2`` is computed here, and
    every range judges its pairs exactly on it."""

    def __init__(self, reach_m: float):
        self.reach_m = float(reach_m)
        self._ids: list[int] | None = None
        self._xy = b""  # the positions of the last query, as bytes (float64, row-major)
        self._near: Near | None = None
        self.queries = 0  # pair queries made (tests: one a tick)

    def of(self, ids: list[int], xy: np.ndarray) -> Near:
        """The pairs of points ``xy`` (rows in ``ids`` order) within the reach."""
        xy = np.asarray(xy, dtype=np.float64)
        key = xy.tobytes()  # (a copy: the caller may reuse its array; cheaper than array_equal)
        near = self._near
        if near is not None and key == self._xy and ids == self._ids:
            return near
        near = self._near = self._query(xy)
        self._ids = list(ids)
        self._xy = key
        self.queries += 1
        return near

    def _query(self, xy: np.ndarray) -> Near:
        n = len(xy)
        reach = self.reach_m
        if n < 2:
            empty = np.zeros(0, np.int64)
            return Near(empty, empty, np.zeros(0))
        x, y = xy[:, 0], xy[:, 1]
        if n < TREE_MIN or math.isinf(reach):
            i, j = _every_pair(n)
            dx, dy = x[i] - x[j], y[i] - y[j]
            d2 = dx * dx + dy * dy
            if not math.isinf(reach):
                r = reach * (1.0 + _SLACK_REL) + _SLACK_ABS
                keep = np.flatnonzero(d2 <= r * r)
                i, j, d2 = i[keep], j[keep], d2[keep]
            return Near(i, j, d2)
        from scipy.spatial import cKDTree

        pairs = cKDTree(xy).query_pairs(reach * (1.0 + _SLACK_REL) + _SLACK_ABS, output_type="ndarray")
        if not len(pairs):
            empty = np.zeros(0, np.int64)
            return Near(empty, empty, np.zeros(0))
        # (i, j) order: one key, i * n + j (i < j < n)
        pairs = pairs[np.argsort(pairs[:, 0] * n + pairs[:, 1])]
        i, j = pairs[:, 0].astype(np.int64), pairs[:, 1].astype(np.int64)
        dx, dy = x[i] - x[j], y[i] - y[j]
        return Near(i, j, dx * dx + dy * dy)
