"""``swarm.pairs.pairs_within``: numpy below ``TREE_MIN`` points, scipy's k-d tree from it on,
the same pairs either way (detect-and-avoid and the placement check use it)."""

from __future__ import annotations

import numpy as np
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from swarm.pairs import TREE_MIN, pairs_within


def _tree(xy: np.ndarray, r: float) -> set[tuple[int, int]]:
    from scipy.spatial import cKDTree

    return {(int(i), int(j)) for i, j in cKDTree(xy).query_pairs(r, output_type="ndarray")}


coords = st.floats(-5e4, 5e4, allow_nan=False, allow_infinity=False)


@settings(max_examples=examples(200))
@given(xy=st.integers(0, TREE_MIN - 1).flatmap(lambda n: arrays(np.float64, (n, 2), elements=coords)),
       r=st.floats(0.0, 3e4))
def test_below_tree_min_numpy_finds_the_pairs_the_tree_finds(xy, r):
    got = pairs_within(xy, r)
    assert got.shape[1] == 2 and got.dtype.kind == "i"
    pairs = {(int(i), int(j)) for i, j in got}
    assert len(pairs) == len(got) and all(i < j for i, j in pairs)
    assert pairs == _tree(xy, r)
    # and exactly those within r, in the arithmetic it states
    for i in range(len(xy)):
        for j in range(i + 1, len(xy)):
            dx, dy = xy[i, 0] - xy[j, 0], xy[i, 1] - xy[j, 1]
            assert ((i, j) in pairs) == (dx * dx + dy * dy <= r * r)


def test_from_tree_min_on_the_tree_finds_them():
    rng = np.random.default_rng(7)
    xy = rng.uniform(0, 20_000, (TREE_MIN + 50, 2))
    got = pairs_within(xy, 3000.0)
    assert {(int(i), int(j)) for i, j in got} == _tree(xy, 3000.0) and len(got) > 10


def test_no_points_and_one_point_have_no_pairs():
    for n in (0, 1):
        assert pairs_within(np.zeros((n, 2)), 5.0).shape == (0, 2)
