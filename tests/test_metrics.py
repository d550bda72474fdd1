"""Ground-truth metrics on large areas: the block-wise certainty equals the whole-map formula."""

from __future__ import annotations

import numpy as np
import pytest

from agents.grid import Grid
from swarm.metrics import Metrics


@pytest.mark.parametrize("grid", [Grid(50_000.0, 50_000.0, 100.0), Grid(130_000.0, 110_000.0, 100.0)])
def test_certainty_and_coverage_equal_the_whole_map_formulas(grid):
    m = Metrics(grid, 0.005)
    rng = np.random.default_rng(1)
    assert m.certainty(0.0) == 0.0 and m.coverage() == 0.0
    for k in range(400):  # disks in, near and off the area, of several radii and times
        x = rng.uniform(-3000.0, grid.width_m + 3000.0)
        y = rng.uniform(-3000.0, grid.height_m + 3000.0)
        m.scan(x, y, float(rng.choice([500.0, 1500.0, 2000.0, 3100.0])), float(k % 97))
        if k % 50 == 0:
            for t in (100.0, 777.5):
                whole = 1.0 - float(np.mean(m.union.uncertainty(t), dtype=np.float64))
                assert m.certainty(t) == whole
            seen = np.isfinite(m.union.to_dense())
            assert m.coverage() == np.count_nonzero(seen) / seen.size
