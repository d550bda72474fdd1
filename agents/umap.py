"""A UAV's uncertainty map (DACMP eq. 7) as a state-based CRDT.

The state is one number per cell: the simulated time the cell was last scanned (``-inf`` if
never). Uncertainty is derived, not stored: ``q = 1 - exp(-tau * (t - last_seen))``, so a
never-seen cell has ``q = 1`` and a cell being scanned has ``q = 0``.

Everything that changes the map is a per-cell ``max``: scanning a disk at time ``t``, applying a
heard scan record, merging a whole heard map. ``max`` is commutative, associative and
idempotent, so frames lost, duplicated or reordered on the radio can delay agreement between
UAVs but never corrupt it, and a map never forgets (last-seen times never decrease).
"""

from __future__ import annotations

import numpy as np

from agents.grid import Grid

NEVER = np.float32(-np.inf)


class UncertaintyMap:
    __slots__ = ("grid", "tau", "last_seen")

    def __init__(self, grid: Grid, tau: float, last_seen: np.ndarray | None = None):
        self.grid = grid
        self.tau = float(tau)
        if last_seen is None:
            last_seen = np.full(grid.shape, NEVER, dtype=np.float32)
        elif last_seen.shape != grid.shape:
            raise ValueError(f"last_seen has shape {last_seen.shape}, expected {grid.shape}")
        self.last_seen = last_seen

    def scan(self, x: float, y: float, radius: float, t: float) -> int:
        """Mark the cells inside a detection circle as seen at ``t``; returns cells changed."""
        d = self.grid.disk(x, y, radius)
        if d is None:
            return 0
        rows, cols, mask = d
        view = self.last_seen[rows, cols]
        newer = mask & (view < t)
        view[newer] = t
        return int(np.count_nonzero(newer))

    def merge(self, other: "UncertaintyMap | np.ndarray") -> None:
        """Per-cell max with another map (in place)."""
        theirs = other.last_seen if isinstance(other, UncertaintyMap) else other
        np.maximum(self.last_seen, theirs, out=self.last_seen)

    def copy(self) -> "UncertaintyMap":
        return UncertaintyMap(self.grid, self.tau, self.last_seen.copy())

    def uncertainty(self, t: float, out: np.ndarray | None = None) -> np.ndarray:
        """q per cell at time ``t`` (float32)."""
        age = np.subtract(np.float32(t), self.last_seen, out=out, dtype=np.float32)
        np.multiply(age, np.float32(-self.tau), out=age)
        np.exp(age, out=age)
        np.subtract(np.float32(1.0), age, out=age)
        return age

    def q_at(self, ix: np.ndarray, iy: np.ndarray, t: float) -> np.ndarray:
        """q at selected cells only (cheap for a planner reading a few cells)."""
        seen = self.last_seen[iy, ix]
        return 1.0 - np.exp(-self.tau * (t - seen.astype(np.float64)))

    def seen_fraction(self) -> float:
        return float(np.count_nonzero(np.isfinite(self.last_seen))) / self.last_seen.size
