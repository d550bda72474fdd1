"""agents.planners.dacmp.pyramid_reuse: maps of a MapGroup, patched from the group's base, get exactly the q,
G_1 and G_2 they get computed alone, whatever scans they hold beyond the base."""

from __future__ import annotations

import numpy as np
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.maps.grid import Grid
from agents.maps.mapgroup import MapGroup
from agents.maps.umap import UncertaintyMap
from agents.planners.dacmp.pyramid import Scratch, pyr_down_stack, reduce_rows
from agents.planners.dacmp.pyramid_reuse import FirstLevels

TAU = 1 / 600


def same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def alone(umap: UncertaintyMap, t: float) -> tuple[np.ndarray, np.ndarray]:
    """q and G_1 of one map computed on its own (the planner's path before reuse)."""
    ny, nx = umap.grid.shape
    q = umap.uncertainty(t)[None]
    g1 = np.empty((1, (ny + 1) // 2, (nx + 1) // 2), np.float32)
    pyr_down_stack(np.ascontiguousarray(q), g1, Scratch())
    return q[0], g1[0]


def assert_second_levels(levels: FirstLevels, g1: np.ndarray) -> None:
    """reduce_g1 gives every map the G_2 it gets alone (or leaves it to the caller)."""
    h, w = g1.shape[1:]
    g2 = np.full((len(g1), (h + 1) // 2, (w + 1) // 2), np.nan, np.float32)
    if not levels.reduce_g1(g1, g2, Scratch()):
        assert levels.patched == 0  # nothing to reuse: the caller reduces them all
        return
    for i in range(len(g1)):
        expected = np.empty((1,) + g2.shape[1:], np.float32)
        pyr_down_stack(np.ascontiguousarray(g1[i : i + 1]), expected, Scratch())
        assert same(g2[i], expected[0])


# A scan: (fraction of the width, of the height, radius in cells, time back from now).
scans = st.tuples(st.floats(-0.1, 1.1), st.floats(-0.1, 1.1), st.floats(0.6, 12.0), st.integers(0, 900))


@settings(max_examples=examples(80), deadline=None)
@given(h=st.integers(16, 90), w=st.integers(16, 90), common=st.lists(scans, max_size=12),
       extra=st.lists(st.lists(scans, max_size=4), min_size=1, max_size=5), plain=st.booleans())
def test_patched_maps_get_the_numbers_they_get_alone(h, w, common, extra, plain):
    t = 1000.0
    grid = Grid(w * 100.0, h * 100.0, 100.0)
    group = MapGroup(grid, TAU, 1.0)
    maps = [group.new_map() for _ in extra]

    def disk(s):
        fx, fy, r, back = s
        return grid.disk_stamp(fx * grid.width_m, fy * grid.height_m, r * 100.0), t - back

    for s in common:  # every member has these: they go to the base
        d, ts = disk(s)
        if d is not None:
            for m in maps:
                m.stamp(d, ts)
    for m, mine in zip(maps, extra):  # and each a few of its own
        for s in mine:
            d, ts = disk(s)
            if d is not None:
                m.stamp(d, ts)
    umaps = maps + ([UncertaintyMap(grid, TAU, maps[0].to_dense())] if plain else [])  # one outside the group
    levels = FirstLevels()
    g1 = np.empty((len(umaps), (h + 1) // 2, (w + 1) // 2), np.float32)
    for _ in range(2):  # a second call reuses the buffers
        levels.start()
        for i, u in enumerate(umaps):
            q = levels.compute(u, t, g1[i], np.copy)  # q as the map's user sees it
            assert same(q, alone(u, t)[0])
        levels.finish()
        for i, u in enumerate(umaps):
            assert same(g1[i], alone(u, t)[1])
        assert_second_levels(levels, g1)
        # Patching a map's q for its user left the reference's q as it was.
        assert same(levels.compute(umaps[0], t, np.empty_like(g1[0]), np.copy), alone(umaps[0], t)[0])
    assert levels.patched + levels.full == 2 * (len(umaps) + 1)
    assert levels.full >= 2 * int(plain)


def test_maps_are_patched_only_when_they_may_be():
    grid = Grid(6400.0, 6400.0, 100.0)
    group = MapGroup(grid, TAU, 1.0)
    a, b, c = group.new_map(), group.new_map(), group.new_map()
    for m in (a, b, c):
        m.stamp(grid.disk_stamp(3000.0, 3000.0, 900.0), 490.0)
    b.stamp(grid.disk_stamp(1000.0, 1200.0, 400.0), 499.0)
    for k in range(12):  # c's extra scans span most of its rows
        c.stamp(grid.disk_stamp(500.0 + 450.0 * k, 300.0 + 500.0 * k, 600.0), 480.0 + k)
    plain = UncertaintyMap(grid, TAU)
    levels = FirstLevels()
    g1 = np.empty((32, 32), np.float32)
    levels.start()
    for u in (a, b, c, plain):
        levels.compute(u, 500.0, g1, np.copy)
        levels.finish()
        assert same(g1, alone(u, 500.0)[1])
    assert (levels.patched, levels.full) == (2, 2)
    off = FirstLevels(reuse=False)
    off.start()
    for u in (a, b):
        off.compute(u, 500.0, g1, np.copy)
    assert (off.full, off.patched) == (2, 0)


@settings(max_examples=examples(60), deadline=None)
@given(n=st.integers(1, 40), ncols=st.integers(1, 9), lo=st.integers(0, 20), span=st.integers(0, 20),
       seed=st.integers(0, 2**32 - 1))
def test_part_of_a_row_reduce_is_the_whole_reduce_there(n, ncols, lo, span, seed):
    rng = np.random.default_rng(seed)
    a = rng.random((2, n, ncols)).astype(np.float32)
    m = (n + 1) // 2
    lo = min(lo, m - 1)
    hi = min(lo + span, m - 1)
    whole = np.empty((2, m, ncols), np.float32)
    reduce_rows(a, whole)
    # Only the input rows the wanted output rows read, offset.
    row0, row1 = max(0, 2 * lo - 2), min(n, 2 * hi + 3)
    part = np.empty((2, hi - lo + 1, ncols), np.float32)
    reduce_rows(np.ascontiguousarray(a[:, row0:row1]), part, n=n, row0=row0, lo=lo, hi=hi)
    assert same(part, whole[:, lo : hi + 1])


@settings(max_examples=examples(40), deadline=None)
@given(seed=st.integers(0, 2**32 - 1), late=st.lists(st.tuples(st.integers(0, 3), st.integers(0, 11)), max_size=6))
def test_group_maps_patched_from_the_base_get_the_numbers_they_get_alone(seed, late):
    """As a swarm plans: every map has the others' scans up to the last tick and its own of this
    one (plus a few scans heard late or not at all); maps in a MapGroup are patched from the
    group's base, maps that left it are computed in full."""
    rng = np.random.default_rng(seed)
    grid = Grid(12000.0, 10000.0, 100.0)
    scans = {(o, k): grid.disk_stamp(*map(float, rng.uniform(0, 10000, 2)), float(rng.uniform(150, 600)))
             for o in range(4) for k in range(12)}
    skipped = set(late)
    group = MapGroup(grid, TAU, 1.0)
    maps = [group.new_map() for _ in range(4)]
    for k in range(12):
        for me, umap in enumerate(maps):
            for o in range(4):
                if o != me and k > 0 and (me, k - 1) not in skipped:
                    umap.stamp(scans[(o, k - 1)], float(k - 1))
            umap.stamp(scans[(me, k)], float(k))
    levels = FirstLevels()
    levels.start()
    g1 = np.empty((4, 50, 60), np.float32)
    for i, umap in enumerate(maps):
        q = levels.compute(umap, 11.0, g1[i], np.copy)
        assert same(q, alone(umap, 11.0)[0])
    levels.finish()
    for i, umap in enumerate(maps):
        assert same(g1[i], alone(umap, 11.0)[1])
    assert_second_levels(levels, g1)
    if not late:  # all four still members: all patched from the base
        assert len(group.members) == 4 and levels.patched == 4
