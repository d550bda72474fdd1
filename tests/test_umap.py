"""Tests for agents.maps.umap.UncertaintyMap (with agents.maps.grid.Grid.disk): the map as a CRDT.

The state is one float32 per cell (last time seen, -inf for never); merge and scan are per-cell
``max``. The brute-force reference for "which cells does a scan touch" loops over every cell of
the grid and tests its centre against the circle, independently of ``Grid.disk``'s bounding box.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from agents.maps.grid import Grid
from agents.maps.umap import NEVER, UncertaintyMap

NEG_INF = float("-inf")

# ---------------------------------------------------------------------------------------------
# strategies
# ---------------------------------------------------------------------------------------------

cell_sizes = st.sampled_from([1.0, 0.5, 2.0, 10.0, 0.3, 100.0])


@st.composite
def grids(draw, max_cells: int = 7) -> Grid:
    c = draw(cell_sizes)
    nx = draw(st.integers(1, max_cells))
    ny = draw(st.integers(1, max_cells))
    return Grid(nx * c, ny * c, c)


# last_seen values: never seen, or a float32 time (some repeated so ties are exercised)
seen_values = st.one_of(
    st.just(NEG_INF),
    st.sampled_from([0.0, 1.0, 2.5, 100.0]),
    st.floats(-1e4, 1e4, width=32),
)


def last_seen_arrays(shape):
    return hnp.arrays(np.float32, shape, elements=seen_values)


@st.composite
def grid_and_maps(draw, n: int):
    g = draw(grids())
    arrays = [draw(last_seen_arrays(g.shape)) for _ in range(n)]
    tau = draw(st.floats(1e-4, 1.0))
    return g, tau, [UncertaintyMap(g, tau, a) for a in arrays]


def merged(a: UncertaintyMap, b: UncertaintyMap) -> UncertaintyMap:
    out = a.copy()
    out.merge(b)
    return out


def same(a: UncertaintyMap, b: UncertaintyMap) -> bool:
    # array_equal treats -inf == -inf; no NaN ever appears in these maps
    return a.last_seen.dtype == b.last_seen.dtype and np.array_equal(a.last_seen, b.last_seen)


def brute_force_disk(g: Grid, x: float, y: float, r: float) -> tuple[np.ndarray, np.ndarray]:
    """(inside, on_boundary) masks over the whole grid, one cell at a time.

    ``on_boundary`` marks cells whose centre is within a rounding error of the circle, where a
    different but reasonable float formula could disagree; the property checks those cells
    separately from the others.
    """
    ny, nx = g.shape
    inside = np.zeros((ny, nx), bool)
    edge = np.zeros((ny, nx), bool)
    c = g.cell_m
    for iy in range(ny):
        for ix in range(nx):
            cx = (ix + 0.5) * c
            cy = (iy + 0.5) * c
            d2 = (cx - x) ** 2 + (cy - y) ** 2
            inside[iy, ix] = d2 <= r * r
            scale = r * r + (abs(cx) + abs(x) + abs(cy) + abs(y) + r) ** 2
            edge[iy, ix] = abs(d2 - r * r) <= 1e-9 * scale
    return inside, edge


# ---------------------------------------------------------------------------------------------
# construction
# ---------------------------------------------------------------------------------------------


def test_new_map_is_never_seen_float32():
    g = Grid(50.0, 30.0, 10.0)
    m = UncertaintyMap(g, 0.01)
    assert m.last_seen.shape == (3, 5)
    assert m.last_seen.dtype == np.float32
    assert np.all(m.last_seen == NEVER) and np.all(np.isneginf(m.last_seen))
    assert m.seen_fraction() == 0.0


def test_wrong_shape_is_rejected():
    g = Grid(50.0, 30.0, 10.0)
    with pytest.raises(ValueError, match=r"shape \(5, 3\), expected \(3, 5\)"):
        UncertaintyMap(g, 0.01, np.zeros((5, 3), np.float32))


# ---------------------------------------------------------------------------------------------
# merge: commutative, associative, idempotent, inflationary
# ---------------------------------------------------------------------------------------------


@settings(deadline=None)
@given(grid_and_maps(2))
def test_merge_commutative(gm):
    _, _, (a, b) = gm
    assert same(merged(a, b), merged(b, a))


@settings(deadline=None)
@given(grid_and_maps(3))
def test_merge_associative(gm):
    _, _, (a, b, c) = gm
    assert same(merged(merged(a, b), c), merged(a, merged(b, c)))


@settings(deadline=None)
@given(grid_and_maps(2))
def test_merge_idempotent(gm):
    _, _, (a, b) = gm
    assert same(merged(a, a), a)
    ab = merged(a, b)
    assert same(merged(ab, b), ab)
    assert same(merged(ab, a), ab)


@settings(deadline=None)
@given(grid_and_maps(2))
def test_merge_is_per_cell_max_and_never_forgets(gm):
    _, _, (a, b) = gm
    before = a.last_seen.copy()
    other = b.last_seen.copy()
    a.merge(b)
    assert np.array_equal(a.last_seen, np.maximum(before, other))
    assert np.all(a.last_seen >= before)
    assert np.all(a.last_seen >= other)
    assert np.array_equal(b.last_seen, other), "merge must not modify its argument"
    assert a.last_seen.dtype == np.float32


@settings(deadline=None)
@given(grid_and_maps(2))
def test_merge_with_raw_array_equals_merge_with_map(gm):
    _, _, (a, b) = gm
    via_array = a.copy()
    via_array.merge(b.last_seen.copy())
    assert same(via_array, merged(a, b))


def test_copy_is_independent():
    g = Grid(3.0, 3.0, 1.0)
    a = UncertaintyMap(g, 0.1)
    b = a.copy()
    b.scan(1.5, 1.5, 0.1, 5.0)
    assert np.all(np.isneginf(a.last_seen))
    assert b.last_seen[1, 1] == 5.0


# ---------------------------------------------------------------------------------------------
# scan
# ---------------------------------------------------------------------------------------------


@st.composite
def circles(draw, g: Grid):
    """Circle centres on, near and far off the grid; radii from 0 to larger than the grid.

    Half of the draws use round multiples of a twentieth of a cell, which puts cell centres
    exactly on the circle (in exact arithmetic) far more often than arbitrary floats do.
    """
    w, h = g.width_m, g.height_m
    span = max(w, h)
    if draw(st.booleans()):
        step = g.cell_m / 20.0
        n = int(span / step)
        x = draw(st.integers(-30 * n // 20 - 20, 50 * n // 20 + 20)) * step
        y = draw(st.integers(-30 * n // 20 - 20, 50 * n // 20 + 20)) * step
        r = draw(st.integers(0, 2 * n)) * step
        return x, y, r
    x = draw(st.floats(-1.5 * span, 2.5 * span))
    y = draw(st.floats(-1.5 * span, 2.5 * span))
    r = draw(st.one_of(st.just(0.0), st.floats(0.0, 2.0 * span)))
    return x, y, r


@settings(deadline=None, max_examples=examples(200))
@given(st.data())
def test_scan_touches_exactly_the_cells_whose_centres_are_in_the_circle(data):
    g = data.draw(grids())
    x, y, r = data.draw(circles(g))
    m = UncertaintyMap(g, 0.05)
    changed = m.scan(x, y, r, 7.0)
    inside, edge = brute_force_disk(g, x, y, r)
    got = m.last_seen == np.float32(7.0)
    # everything else is untouched
    assert np.all(np.isneginf(m.last_seen[~got]))
    # away from the circle's edge the float test is unambiguous ...
    assert np.array_equal(got[~edge], inside[~edge])
    # ... and on it, the map agrees with the same float test done cell by cell (a centre exactly
    # on the circle is inside)
    assert np.array_equal(got, inside)
    assert changed == int(np.count_nonzero(got))
    d = g.disk(x, y, r)
    assert (d is None) == (not inside.any())


@pytest.mark.parametrize(
    "x, y, r, expected_cells",
    [
        (-50.0, -50.0, 10.0, 0),  # entirely off the grid (below-left)
        (500.0, 15.0, 100.0, 0),  # entirely off the grid (right)
        (15.0, 15.0, 0.0, 1),  # radius 0 exactly on a cell centre
        (10.0, 10.0, 0.0, 0),  # radius 0 on a cell corner: no centre inside
        (-5.0, 25.0, 10.0, 1),  # mostly off the left edge, just reaches the centre (5, 25)
        (25.0, 25.0, 1000.0, 25),  # covers the whole grid
    ],
)
def test_scan_fixed_cases(x, y, r, expected_cells):
    g = Grid(50.0, 50.0, 10.0)
    m = UncertaintyMap(g, 0.05)
    assert m.scan(x, y, r, 3.0) == expected_cells
    inside, _ = brute_force_disk(g, x, y, r)
    assert np.array_equal(m.last_seen == 3.0, inside)
    assert int(inside.sum()) == expected_cells


def test_disk_returns_none_when_entirely_off_grid():
    g = Grid(50.0, 50.0, 10.0)
    assert g.disk(-100.0, 25.0, 50.0) is None
    assert g.disk(25.0, 25.0 + 1e6, 10.0) is None


@settings(deadline=None)
@given(st.data())
def test_scan_never_decreases_any_cell(data):
    g = data.draw(grids())
    m = UncertaintyMap(g, 0.05, data.draw(last_seen_arrays(g.shape)))
    for _ in range(data.draw(st.integers(1, 5))):
        x, y, r = data.draw(circles(g))
        t = data.draw(st.floats(-1e4, 1e4, width=32))
        before = m.last_seen.copy()
        changed = m.scan(x, y, r, t)
        assert np.all(m.last_seen >= before)
        diff = m.last_seen != before
        assert changed == int(np.count_nonzero(diff))
        # cells that changed were raised exactly to t
        assert np.all(m.last_seen[diff] == np.float32(t))


def test_scan_in_the_past_does_not_overwrite_newer_times():
    g = Grid(30.0, 30.0, 10.0)
    m = UncertaintyMap(g, 0.1)
    assert m.scan(15.0, 15.0, 100.0, 10.0) == 9
    assert m.scan(15.0, 15.0, 100.0, 4.0) == 0
    assert np.all(m.last_seen == 10.0)
    assert m.scan(15.0, 15.0, 100.0, 10.0) == 0  # same time again: nothing changes
    assert m.seen_fraction() == 1.0


records = st.lists(
    st.tuples(
        st.floats(0.0, 1000.0, width=32),  # t
        st.floats(-20.0, 80.0),  # x
        st.floats(-20.0, 80.0),  # y
        st.floats(0.0, 30.0),  # r
    ),
    min_size=0,
    max_size=8,
)


@settings(deadline=None)
@given(st.data())
def test_scan_records_in_any_order_give_identical_maps(data):
    g = data.draw(st.sampled_from([Grid(60.0, 40.0, 10.0), Grid(50.0, 50.0, 5.0), Grid(7.0, 3.0, 1.0)]))
    recs = data.draw(records)
    perm = data.draw(st.permutations(recs))
    a = UncertaintyMap(g, 0.02)
    b = UncertaintyMap(g, 0.02)
    for t, x, y, r in recs:
        a.scan(x, y, r, t)
    for t, x, y, r in perm:
        b.scan(x, y, r, t)
    assert same(a, b)
    # and applying them all twice changes nothing (idempotent delivery of duplicates)
    c = b.copy()
    for t, x, y, r in recs:
        assert c.scan(x, y, r, t) == 0
    assert same(c, b)


@settings(deadline=None)
@given(st.data())
def test_scan_then_merge_equals_merge_then_scan(data):
    """Scan records heard by another UAV reach the same state as merging its whole map."""
    g = Grid(60.0, 40.0, 10.0)
    recs_a = data.draw(records)
    recs_b = data.draw(records)
    a = UncertaintyMap(g, 0.02)
    b = UncertaintyMap(g, 0.02)
    for t, x, y, r in recs_a:
        a.scan(x, y, r, t)
    for t, x, y, r in recs_b:
        b.scan(x, y, r, t)
    via_records = a.copy()
    for t, x, y, r in recs_b:
        via_records.scan(x, y, r, t)
    assert same(via_records, merged(a, b))


# ---------------------------------------------------------------------------------------------
# uncertainty
# ---------------------------------------------------------------------------------------------


@settings(deadline=None)
@given(st.data())
def test_uncertainty_values(data):
    g = data.draw(grids())
    tau = data.draw(st.floats(1e-4, 2.0))
    t = data.draw(st.floats(0.0, 500.0, width=32))
    ages = data.draw(
        hnp.arrays(np.float64, g.shape, elements=st.one_of(st.just(math.inf), st.just(0.0), st.floats(0.0, 500.0)))
    )
    last = (np.float64(t) - ages).astype(np.float32)  # -inf where age is inf
    last = np.minimum(last, np.float32(t))  # never in the future after rounding
    m = UncertaintyMap(g, tau, last.copy())
    q = m.uncertainty(t)
    assert q.dtype == np.float32 and q.shape == g.shape
    never = np.isneginf(last)
    now = last == np.float32(t)
    assert np.all(q[never] == 1.0)
    assert np.all(q[now] == 0.0)
    other = ~never & ~now
    age = np.float64(np.float32(t)) - last[other].astype(np.float64)
    expected = 1.0 - np.exp(-tau * age)
    np.testing.assert_allclose(q[other], expected, rtol=1e-5, atol=1e-6)
    assert np.all((q >= 0.0) & (q <= 1.0))
    # the state was not modified by reading it
    assert np.array_equal(m.last_seen, last)
    # q_at agrees with the full map
    iy, ix = np.indices(g.shape)
    np.testing.assert_allclose(m.q_at(ix.ravel(), iy.ravel(), float(np.float32(t))), q.ravel(), rtol=1e-5, atol=1e-6)


def test_uncertainty_reference_values_and_out_buffer():
    g = Grid(3.0, 1.0, 1.0)
    m = UncertaintyMap(g, 0.1, np.array([[NEG_INF, 10.0, 0.0]], np.float32))
    out = np.empty(g.shape, np.float32)
    q = m.uncertainty(10.0, out=out)
    assert q is out
    assert q[0, 0] == 1.0
    assert q[0, 1] == 0.0
    assert q[0, 2] == pytest.approx(1.0 - math.exp(-1.0), rel=1e-6)


def test_uncertainty_decreases_with_scan_and_grows_with_time():
    g = Grid(20.0, 20.0, 10.0)
    m = UncertaintyMap(g, 0.05)
    assert np.all(m.uncertainty(0.0) == 1.0)
    m.scan(5.0, 5.0, 1.0, 2.0)
    q2, q5, q50 = m.uncertainty(2.0)[0, 0], m.uncertainty(5.0)[0, 0], m.uncertainty(50.0)[0, 0]
    assert q2 == 0.0 < q5 < q50 < 1.0
    assert np.all(m.uncertainty(50.0)[np.isneginf(m.last_seen)] == 1.0)


# ---------------------------------------------------------------------------------------------
# regression: Grid.disk's bounding box used to disagree with its own mask on the boundary
# ---------------------------------------------------------------------------------------------


def _exactly_inside(g: Grid, ix: int, iy: int, x: float, y: float, r: float) -> bool:
    c = Fraction(g.cell_m)
    half = Fraction(1, 2)
    dx = (ix + half) * c - Fraction(x)
    dy = (iy + half) * c - Fraction(y)
    return dx * dx + dy * dy <= Fraction(r) ** 2


@pytest.mark.parametrize(
    "grid, x, y, r",
    [
        # both centres (0.3, 0.1) and (0.5, 0.1) lie exactly on the circle; a rounded
        # ceil((x - r)/c - 0.5) once dropped the left one
        (Grid(1.0, 0.4, 0.2), 0.4, 0.1, 0.1),
        (Grid(0.30000000000000004, 0.6000000000000001, 0.1), 0.05, 0.2, 0.05),
        (Grid(0.3 * 5, 0.3 * 3, 0.3), 1.2, 0.15, 0.15),
        (Grid(0.1 * 3, 0.1 * 5, 0.1), 0.2, 0.05, 0.05),
    ],
)
def test_scan_includes_cells_exactly_on_the_circle(grid, x, y, r):
    """Cells whose centre is exactly on the circle are inside, in float and exact arithmetic."""
    g = grid
    inside, _ = brute_force_disk(g, x, y, r)
    ny, nx = g.shape
    exact = np.array([[_exactly_inside(g, ix, iy, x, y, r) for ix in range(nx)] for iy in range(ny)])
    assert np.array_equal(inside, exact) and inside.any()
    m = UncertaintyMap(g, 0.1)
    assert m.scan(x, y, r, 1.0) == int(inside.sum())
    assert np.array_equal(m.last_seen == 1.0, inside)


# ---------------------------------------------------------------------------------------------
# tiled storage: the same numbers as one dense array, whatever the tile size
# ---------------------------------------------------------------------------------------------


class DenseReference:
    """The map as it was before tiling: one float32 array, scans as boolean-mask assignments."""

    def __init__(self, g: Grid, tau: float):
        self.g, self.tau = g, tau
        self.a = np.full(g.shape, NEG_INF, np.float32)

    def scan(self, x, y, r, t) -> int:
        d = self.g.disk(x, y, r)
        if d is None:
            return 0
        rows, cols, mask = d
        view = self.a[rows, cols]
        newer = mask & (view < t)
        view[newer] = t
        return int(np.count_nonzero(newer))

    def q(self, t) -> np.ndarray:
        age = np.subtract(np.float32(t), self.a, dtype=np.float32)
        np.multiply(age, np.float32(-self.tau), out=age)
        np.exp(age, out=age)
        np.subtract(np.float32(1.0), age, out=age)
        return age


tile_args = st.one_of(st.none(), st.just("dense"), st.integers(1, 9), st.tuples(st.integers(1, 9), st.integers(1, 9)))


@st.composite
def windows(draw, g: Grid):
    ny, nx = g.shape
    ix0 = draw(st.integers(0, nx - 1))
    iy0 = draw(st.integers(0, ny - 1))
    return ix0, iy0, draw(st.integers(1, nx - ix0)), draw(st.integers(1, ny - iy0))


@settings(deadline=None, max_examples=examples(150))
@given(st.data())
def test_tiled_map_equals_dense_reference(data):
    g = data.draw(grids(max_cells=23))
    tau = data.draw(st.floats(1e-3, 0.5))
    tile = data.draw(tile_args, label="tile")
    m = UncertaintyMap(g, tau, tile=tile)
    ref = DenseReference(g, tau)
    other = UncertaintyMap(g, tau, tile=data.draw(tile_args, label="other tile"))
    other_ref = DenseReference(g, tau)
    for _ in range(data.draw(st.integers(1, 12))):
        op = data.draw(st.sampled_from(["scan", "stamp", "other", "merge_map", "merge_array", "copy"]))
        if op in ("scan", "stamp", "other"):
            x, y, r = data.draw(circles(g))
            t = data.draw(st.one_of(st.sampled_from([0.0, 1.0, 2.5, 100.0]), st.floats(-1e3, 1e3, width=32)))
            if op == "scan":
                assert m.scan(x, y, r, t) == ref.scan(x, y, r, t)
            elif op == "stamp":
                d = g.disk_stamp(x, y, r)
                if d is not None:
                    m.stamp(d, t)
                ref.scan(x, y, r, t)
            else:
                other.scan(x, y, r, t)
                other_ref.scan(x, y, r, t)
        elif op == "merge_map":
            m.merge(other)
            np.maximum(ref.a, other_ref.a, out=ref.a)
        elif op == "merge_array":
            arr = data.draw(last_seen_arrays(g.shape))
            m.merge(arr)
            np.maximum(ref.a, arr, out=ref.a)
        else:
            m = m.copy()
        assert np.array_equal(m.to_dense(), ref.a)
    t = data.draw(st.floats(0.0, 2e3, width=32))
    iy, ix = np.indices(g.shape)
    with np.errstate(over="ignore"):  # times after t (merged arrays) overflow exp: same either way
        assert np.array_equal(m.uncertainty(t), ref.q(t))
        expected = 1.0 - np.exp(-tau * (t - ref.a.astype(np.float64)))
        assert np.array_equal(m.q_at(ix, iy, t), expected)
        assert np.array_equal(m.q_at(ix.ravel()[::-1], iy.ravel()[::-1], t), expected.ravel()[::-1])
    assert m.seen_fraction() == float(np.count_nonzero(np.isfinite(ref.a))) / ref.a.size
    w = data.draw(windows(g))
    ix0, iy0, nx, ny = w
    assert np.array_equal(m.to_dense(window=w), ref.a[iy0 : iy0 + ny, ix0 : ix0 + nx])


@settings(deadline=None, max_examples=examples(100))
@given(st.data())
def test_window_read_equals_slice_of_full_map(data):
    g = data.draw(grids(max_cells=40))
    m = UncertaintyMap(g, data.draw(st.floats(1e-3, 0.5)), tile=data.draw(tile_args))
    for _ in range(data.draw(st.integers(0, 6))):
        x, y, r = data.draw(circles(g))
        m.scan(x, y, r, data.draw(st.floats(0.0, 100.0, width=32)))
    t = data.draw(st.floats(0.0, 500.0, width=32))
    full = m.uncertainty(t)
    w = data.draw(windows(g))
    ix0, iy0, nx, ny = w
    q = m.uncertainty(t, window=w)
    assert q.shape == (ny, nx) and q.dtype == np.float32
    assert np.array_equal(q, full[iy0 : iy0 + ny, ix0 : ix0 + nx])
    out = np.empty((ny, nx), np.float32)
    assert m.uncertainty(t, out=out, window=w) is out and np.array_equal(out, q)


def test_window_outside_the_grid_is_a_value_error():
    g = Grid(100.0, 50.0, 10.0)  # 10 x 5 cells
    for tile in (None, 3):
        m = UncertaintyMap(g, 0.1, tile=tile)
        assert m.uncertainty(0.0, window=(0, 0, 10, 5)).shape == (5, 10)
        for w in [(-1, 0, 2, 2), (0, -1, 2, 2), (9, 0, 2, 1), (0, 4, 1, 2), (0, 0, 0, 1), (0, 0, 1, 0), (0, 0, 11, 5)]:
            with pytest.raises(ValueError, match="window"):
                m.uncertainty(0.0, window=w)
        with pytest.raises(ValueError, match="window"):
            m.uncertainty(0.0, window=(1, 2))


def test_sparse_map_on_a_huge_grid_stays_small():
    import tracemalloc

    g = Grid(650_000.0, 650_000.0, 100.0)  # 42 M cells: 169 MB as one dense float32 array
    tracemalloc.start()
    try:
        m = UncertaintyMap(g, 0.005)
        assert not m.dense and m.tile_shape == (64, 64)
        for k in range(200):  # a 40 km track: the tiles along it, nothing else
            m.scan(100_000.0 + 200.0 * k, 300_000.0, 2000.0, float(k))
        copy = m.copy()
        copy.merge(m)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert m.tiles_allocated <= 2 * (40_000 // 6_400 + 2)
    assert m.nbytes == m.tiles_allocated * 64 * 64 * 4 < 1_000_000
    assert peak < 5_000_000, peak  # both maps and every temporary
    assert m.seen_fraction() == pytest.approx((40_000 * 4000 + math.pi * 2000**2) / 650_000**2, rel=0.05)
    # reading it back: unseen tiles are -inf, a window around the track has the scans
    w = m.to_dense(window=(900, 2900, 600, 200))  # ix 900..1499: the track ends at ix 1418
    assert np.isneginf(w[:, -1]).all() and (w[100, 100:300] >= 0).all()


def test_paper_grid_is_one_dense_tile_and_large_grids_are_tiled():
    assert UncertaintyMap(Grid(50_000.0, 50_000.0, 100.0), 0.005).dense
    big = UncertaintyMap(Grid(200_000.0, 200_000.0, 100.0), 0.005)
    assert not big.dense and big.tiles_allocated == 0 and big.nbytes == 0
    assert UncertaintyMap(Grid(200_000.0, 200_000.0, 100.0), 0.005, tile="dense").dense
    with pytest.raises(ValueError):
        UncertaintyMap(Grid(10.0, 10.0, 1.0), 0.1, tile=0)
    with pytest.raises(ValueError):
        UncertaintyMap(Grid(10.0, 10.0, 1.0), 0.1, tile="sparse")


def test_last_seen_is_a_read_only_snapshot():
    g = Grid(30.0, 30.0, 10.0)
    for tile in (None, 2):
        m = UncertaintyMap(g, 0.1, tile=tile)
        snap = m.last_seen
        with pytest.raises(ValueError):
            snap[0, 0] = 1.0
        m.scan(15.0, 15.0, 1.0, 4.0)
        assert np.isneginf(snap[1, 1]) and m.last_seen[1, 1] == 4.0
        dense = m.to_dense()
        dense[0, 0] = 99.0  # a copy: the map does not change
        assert np.isneginf(m.to_dense()[0, 0])


def test_disk_stamp_is_a_cached_disk():
    g = Grid(1000.0, 800.0, 10.0)
    d = g.disk_stamp(123.4, 567.8, 45.0)
    rows, cols, mask = g.disk(123.4, 567.8, 45.0)
    assert (d.rows, d.cols) == (rows, cols) and np.array_equal(d.mask, mask)
    assert g.disk_stamp(123.4, 567.8, 45.0) is d
    assert g.disk_stamp(-500.0, 0.0, 10.0) is None
    g.set_disk_cache_size(1)  # evictions only cost recomputation
    m1, m2 = UncertaintyMap(g, 0.1, tile=7), UncertaintyMap(g, 0.1)
    for k in range(30):
        m1.scan(17.0 * k, 23.0 * k, 35.0, float(k))
        m2.scan(17.0 * k, 23.0 * k, 35.0, float(k))
    assert np.array_equal(m1.to_dense(), m2.to_dense())


@settings(deadline=None, max_examples=examples(100))
@given(st.data())
def test_prefetched_disks_and_tile_splits_equal_the_one_by_one_ones(data):
    """Grid.prefetch_disks (vectorised) builds exactly the disks disk_stamp builds one by one,
    and a disk's split over tiles holds exactly the tiles with a cell of the disk."""
    import agents.maps.grid as grid_module

    c = data.draw(st.sampled_from([100.0, 0.3, 7.0, 1.0]))
    nx, ny = data.draw(st.integers(3, 120)), data.draw(st.integers(3, 120))
    g1, g2 = Grid(nx * c, ny * c, c), Grid(nx * c, ny * c, c)
    coords = st.integers(-20, 20 * max(nx, ny) + 20).map(lambda k: k * c / 20)  # lattice-aligned often
    n = data.draw(st.integers(grid_module.PREFETCH_MIN, grid_module.PREFETCH_MIN + 8))
    xs = [data.draw(coords) for _ in range(n)]
    ys = [data.draw(coords) for _ in range(n)]
    rs = [data.draw(st.sampled_from([0.5 * c, c, 2.5 * c, 7.0 * c, 20.0 * c])) for _ in range(n)]
    th, tw = data.draw(st.integers(1, 40)), data.draw(st.integers(1, 40))
    ntx = -(-nx // tw)
    g1.prefetch_disks(xs, ys, rs, 3.0, (th, tw))
    for x, y, r in zip(xs, ys, rs):
        a, b, ref = g1.disk_stamp(x, y, r), g2.disk_stamp(x, y, r), g2.disk(x, y, r)
        assert (a is None) == (b is None) == (ref is None)
        if a is None:
            continue
        assert (a.rows, a.cols) == (b.rows, b.cols) == ref[:2] and np.array_equal(a.mask, ref[2])
        assert np.array_equal(a.values(3.0), b.values(3.0))
        sa, sb = a.stamps(th, tw, ntx, 3.0), b.stamps(th, tw, ntx, 3.0)
        assert [p[:3] for p in sa] == [p[:3] for p in sb]
        assert all(np.array_equal(p[3], q[3]) for p, q in zip(sa, sb))
        touched = set()
        for ty in range(b.iy0 // th, (b.iy1 - 1) // th + 1):
            for tx in range(b.ix0 // tw, (b.ix1 - 1) // tw + 1):
                r0, r1 = max(b.iy0, ty * th) - b.iy0, min(b.iy1, (ty + 1) * th) - b.iy0
                c0, c1 = max(b.ix0, tx * tw) - b.ix0, min(b.ix1, (tx + 1) * tw) - b.ix0
                if b.mask[r0:r1, c0:c1].any():
                    touched.add(ty * ntx + tx)
        assert [p[0] for p in sa] == [p[0] for p in b.pieces(th, tw, ntx)] and set(p[0] for p in sa) == touched
