"""Grid geometry shared by the agents' maps and the simulator's ground-truth maps.

A map is a 2-D array indexed ``[row, col]`` = ``[iy, ix]``; cell ``(ix, iy)`` covers
``[ix*cell, (ix+1)*cell) x [iy*cell, (iy+1)*cell)`` and its centre is at ``(ix+0.5)*cell``.
A cell is *scanned* by a sensor when its centre lies inside the detection circle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class Grid:
    width_m: float
    height_m: float
    cell_m: float

    @property
    def nx(self) -> int:
        return int(round(self.width_m / self.cell_m))

    @property
    def ny(self) -> int:
        return int(round(self.height_m / self.cell_m))

    @property
    def shape(self) -> tuple[int, int]:
        return (self.ny, self.nx)

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(ix, iy) of the cell containing a point, clipped to the grid."""
        ix = min(max(int(x // self.cell_m), 0), self.nx - 1)
        iy = min(max(int(y // self.cell_m), 0), self.ny - 1)
        return ix, iy

    def cells_of(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ix = np.clip((np.asarray(x) // self.cell_m).astype(np.int64), 0, self.nx - 1)
        iy = np.clip((np.asarray(y) // self.cell_m).astype(np.int64), 0, self.ny - 1)
        return ix, iy

    def contains(self, x: float, y: float) -> bool:
        return 0.0 <= x <= self.width_m and 0.0 <= y <= self.height_m

    def disk(self, x: float, y: float, radius: float) -> tuple[slice, slice, np.ndarray] | None:
        """The cells whose centres lie within ``radius`` of ``(x, y)``.

        Returns ``(rows, cols, mask)``: a bounding-box slice of the map and a boolean mask over
        it, or ``None`` when no cell centre is inside (disk entirely off the grid).
        """
        c = self.cell_m
        # Centres are at (i + 0.5) * c; first/last index whose centre may lie inside.
        # One spare cell each side: the box only has to contain the disk, the mask decides (a
        # rounded box edge could otherwise drop a centre lying exactly on the circle).
        ix0 = max(int(np.ceil((x - radius) / c - 0.5)) - 1, 0)
        ix1 = min(int(np.floor((x + radius) / c - 0.5)) + 1, self.nx - 1)
        iy0 = max(int(np.ceil((y - radius) / c - 0.5)) - 1, 0)
        iy1 = min(int(np.floor((y + radius) / c - 0.5)) + 1, self.ny - 1)
        if ix1 < ix0 or iy1 < iy0:
            return None
        dx = (np.arange(ix0, ix1 + 1) + 0.5) * c - x
        dy = (np.arange(iy0, iy1 + 1) + 0.5) * c - y
        mask = (dy[:, None] ** 2 + dx[None, :] ** 2) <= radius * radius
        if not mask.any():
            return None
        return slice(iy0, iy1 + 1), slice(ix0, ix1 + 1), mask
