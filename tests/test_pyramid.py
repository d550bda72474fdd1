"""Tests for agents.planners.dacmp.pyramid (Gaussian map pyramid, spec eq. 17-18)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.ndimage import convolve1d

from agents.planners.dacmp.pyramid import gaussian_pyramid, level_index, pyr_down, sample_levels

KERNEL = np.array([1.0, 4.0, 6.0, 4.0, 1.0]) / 16.0


def reference_down(a: np.ndarray) -> np.ndarray:
    """Full-resolution separable blur with scipy (mode='reflect'), then keep [::2, ::2]; float64."""
    b = convolve1d(np.asarray(a, dtype=np.float64), KERNEL, axis=0, mode="reflect")
    b = convolve1d(b, KERNEL, axis=1, mode="reflect")
    return b[::2, ::2]


SHAPES = [(1, 1), (1, 2), (2, 1), (2, 2), (3, 3), (4, 5), (5, 4), (6, 7), (7, 6), (8, 8),
          (9, 9), (10, 3), (13, 16), (64, 63), (101, 100), (500, 500)]


@pytest.mark.parametrize("shape", SHAPES)
def test_pyr_down_matches_scipy_float64(shape):
    rng = np.random.default_rng(hash(shape) % 2**32)
    a = rng.random(shape)
    got = pyr_down(a)
    ref = reference_down(a)
    assert got.shape == ref.shape == (math.ceil(shape[0] / 2), math.ceil(shape[1] / 2))
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, ref, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("shape", SHAPES)
def test_pyr_down_matches_scipy_float32(shape):
    rng = np.random.default_rng(1 + hash(shape) % 2**32)
    a = rng.random(shape).astype(np.float32)
    got = pyr_down(a)
    assert got.dtype == np.float32
    # float32 arithmetic: a few ulp of the result (values in (0, 1))
    np.testing.assert_allclose(got, reference_down(a), rtol=1e-6, atol=1e-7)


@settings(max_examples=examples(60), deadline=None)
@given(h=st.integers(1, 40), w=st.integers(1, 40), seed=st.integers(0, 2**31))
def test_pyr_down_matches_scipy_any_shape(h, w, seed):
    a = np.random.default_rng(seed).normal(size=(h, w))
    np.testing.assert_allclose(pyr_down(a), reference_down(a), rtol=1e-12, atol=1e-12)


def test_pyr_down_border_is_reflect_not_other_modes():
    # A ramp distinguishes 'reflect' (d c b a | a b c d) from 'mirror', 'nearest', 'wrap', zeros.
    a = np.tile(np.arange(9, dtype=np.float64), (9, 1))
    got = pyr_down(a)[0]
    # first kept column: (1*b + 4*a + 6*a + 4*b + 1*c)/16 with a, b, c = 0, 1, 2 -> 7/16
    assert got[0] == pytest.approx(7.0 / 16.0)
    # last kept column (index 8): inputs 6, 7, 8, 8(reflect), 7(reflect)
    assert got[-1] == pytest.approx((6 + 4 * 7 + 6 * 8 + 4 * 8 + 7) / 16.0)
    # interior: a linear ramp is preserved exactly by a symmetric kernel
    np.testing.assert_allclose(got[1:-1], [2.0, 4.0, 6.0])


def test_non_contiguous_and_integer_input():
    rng = np.random.default_rng(3)
    a = rng.random((30, 41))
    np.testing.assert_allclose(pyr_down(a.T), reference_down(a.T), rtol=1e-13)
    np.testing.assert_allclose(pyr_down(a[::3, 1::2]), reference_down(a[::3, 1::2]), rtol=1e-13)
    ai = rng.integers(0, 100, (11, 12))
    got = pyr_down(ai)
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, reference_down(ai), rtol=1e-13)


def test_input_not_modified():
    a = np.random.default_rng(4).random((17, 18)).astype(np.float32)
    before = a.copy()
    gaussian_pyramid(a, 5)
    np.testing.assert_array_equal(a, before)


@pytest.mark.parametrize("value", [0.0, 1.0, 0.5, 0.37, 123.456])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_constant_map_stays_constant(value, dtype):
    q = np.full((37, 50), value, dtype=dtype)
    pyr = gaussian_pyramid(q, 8)
    for g in pyr:
        assert g.dtype == dtype
        if value in (0.0, 1.0, 0.5):  # dyadic: every step is exact
            assert np.all(g == dtype(value))
        else:
            np.testing.assert_allclose(g, value, rtol=4 * np.finfo(dtype).eps * len(pyr))


def test_level_shapes_are_ceil_chain():
    q = np.zeros((500, 500), dtype=np.float32)
    shapes = [g.shape for g in gaussian_pyramid(q, 7)]
    assert shapes == [(500, 500), (250, 250), (125, 125), (63, 63), (32, 32), (16, 16), (8, 8)]
    q = np.zeros((37, 20))
    shapes = [g.shape for g in gaussian_pyramid(q, 5)]
    assert shapes == [(37, 20), (19, 10), (10, 5), (5, 3), (3, 2)]


def test_g0_is_q_and_levels_follow_pyr_down():
    q = np.random.default_rng(5).random((40, 33)).astype(np.float32)
    pyr = gaussian_pyramid(q, 4)
    assert len(pyr) == 4
    assert pyr[0] is q
    for lo, hi in zip(pyr[:-1], pyr[1:]):
        np.testing.assert_array_equal(hi, pyr_down(lo))


def test_stops_after_first_1x1_level():
    q = np.random.default_rng(6).random((5, 3))
    pyr = gaussian_pyramid(q, 10)
    assert [g.shape for g in pyr] == [(5, 3), (3, 2), (2, 1), (1, 1)]
    assert len(gaussian_pyramid(np.ones((1, 1)), 7)) == 1
    assert len(gaussian_pyramid(q, 1)) == 1


def test_bad_arguments():
    with pytest.raises(ValueError):
        gaussian_pyramid(np.ones((4, 4)), 0)
    with pytest.raises(ValueError):
        gaussian_pyramid(np.ones((0, 4)), 3)
    with pytest.raises(ValueError):
        pyr_down(np.ones(5))


def test_float32_preserved_on_all_levels():
    q = np.random.default_rng(7).random((500, 500)).astype(np.float32)
    pyr = gaussian_pyramid(q, 7)
    assert all(g.dtype == np.float32 for g in pyr)
    assert all(g.flags["C_CONTIGUOUS"] for g in pyr)
    # the pyramid stays a weighted average: values within the input's range
    for g in pyr:
        assert g.min() >= q.min() - 1e-6 and g.max() <= q.max() + 1e-6


def test_sample_levels_picks_cells():
    # Give each level distinct, position-coded values so a wrong cell is visible.
    shapes = [(9, 12), (5, 6), (3, 3), (2, 2)]
    pyr = [np.arange(h * w, dtype=np.float64).reshape(h, w) + 1000 * l
           for l, (h, w) in enumerate(shapes)]
    ix0 = np.array([0, 11, 5, 7, 3, 100, -4])  # col
    iy0 = np.array([0, 8, 3, 6, 8, -2, 100])  # row
    got = sample_levels(pyr, ix0, iy0)
    assert got.shape == (4, 7)
    for l, g in enumerate(pyr):
        h, w = g.shape
        for n, (c, r) in enumerate(zip(ix0, iy0)):
            rr = min(level_index(max(r, 0), l), h - 1)
            cc = min(level_index(max(c, 0), l), w - 1)
            assert got[l, n] == g[rr, cc]
    # a few by hand: level 1 cell a is centred on level-0 cell 2a, so point (col 11, row 8) ->
    # nearest centres (row 4, col 6 -> clipped to 5)
    assert got[1, 1] == 1000 + 4 * 6 + 5
    # level 2, point (col 7, row 6): centres at 0, 4, 8 -> (row 2, col 2)
    assert got[2, 3] == 2000 + 2 * 3 + 2
    # level 1, point (col 5, row 3): 5 is nearer centre 6 (a = 3) than 4; 3 -> a = 2
    assert got[1, 2] == 1000 + 2 * 6 + 3
    # out-of-range indices clip to the border
    assert got[0, 5] == pyr[0][0, 11] and got[3, 6] == pyr[3][1, 0]


def test_sample_levels_on_real_pyramid_and_dtype():
    q = np.random.default_rng(8).random((64, 48)).astype(np.float32)
    pyr = gaussian_pyramid(q, 5)
    ix0 = np.array([0, 47, 13, 30])
    iy0 = np.array([0, 63, 40, 2])
    got = sample_levels(pyr, ix0, iy0)
    assert got.shape == (5, 4) and got.dtype == np.float32
    for l in range(5):
        rows = np.minimum(level_index(iy0, l), pyr[l].shape[0] - 1)
        cols = np.minimum(level_index(ix0, l), pyr[l].shape[1] - 1)
        np.testing.assert_array_equal(got[l], pyr[l][rows, cols])
    assert sample_levels(pyr, np.zeros(0, int), np.zeros(0, int)).shape == (5, 0)


def test_level_index_rounds_to_the_nearest_coarse_centre():
    # Level-l cell a is centred on level-0 cell a * 2**l: 0..1 -> 0 and 2..5 -> 1 on level 2.
    assert [level_index(i, 2) for i in range(10)] == [0, 0, 1, 1, 1, 1, 2, 2, 2, 2]
    assert [level_index(i, 0) for i in range(4)] == [0, 1, 2, 3]
    # the truncating index (i >> l) would read a coarse cell centred up to 2**l - 1 cells away
    i = np.arange(1000)
    for l in range(1, 7):
        assert np.abs((level_index(i, l) << l) - i).max() <= (1 << l) // 2
