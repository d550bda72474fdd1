"""agents.maps.mapgroup: a map in a MapGroup has exactly the cells of a map of its own, whatever it
is sent, in whatever order, and whoever falls behind or leaves."""

from __future__ import annotations

import math

import numpy as np
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.maps.grid import Grid
from agents.maps.mapgroup import LAG_TICKS, MapGroup, maps_share
from agents.maps.umap import DENSE_MAX_CELLS, UncertaintyMap

GRID = Grid(3000.0, 2500.0, 100.0)
TAU = 1 / 600


def scan(origin: int, k: int):
    rng = np.random.default_rng(origin * 7919 + k)
    x, y = rng.uniform(-200, 3200), rng.uniform(-200, 2700)
    return GRID.disk_stamp(float(x), float(y), float(rng.uniform(120, 700)))


def same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


broadcast = st.tuples(st.just("all"), st.integers(0, 3), st.integers(0, 4), st.integers(0, 30))
ops = st.lists(st.one_of(
    # (member, origin, tick): member stamps origin's scan of that tick (some twice, some late)
    st.tuples(st.just("stamp"), st.integers(0, 3), st.integers(0, 4), st.integers(0, 30)),
    broadcast, broadcast, broadcast,  # every map hears it (mostly, in a swarm)
    st.tuples(st.just("read"), st.integers(0, 3), st.sampled_from(["dense", "cells", "region", "q", "copy"]),
              st.integers(0, 2**16)),
    st.tuples(st.just("write"), st.integers(0, 3), st.sampled_from(["scan", "cover", "merge"]), st.integers(0, 30)),
), max_size=120)


@settings(max_examples=examples(200), deadline=None)
@given(n=st.integers(1, 4), steps=ops, in_order=st.booleans())
def test_group_maps_have_the_cells_of_maps_of_their_own(n, steps, in_order):
    group = MapGroup(GRID, TAU, 1.0)
    maps = [group.new_map() for _ in range(n)]
    twins = [UncertaintyMap(GRID, TAU) for _ in range(n)]
    if in_order:  # mostly a swarm that hears itself: everyone gets every scan, ticks in order
        steps = sorted(steps, key=lambda s: s[3] if s[0] in ("stamp", "all") else -1)
    for step in steps:
        kind, i = step[0], step[1] % n
        if kind == "all":
            _, _, origin, k = step
            if (d := scan(origin, k)) is not None:
                for m, twin in zip(maps, twins):
                    m.stamp(d, float(k))
                    twin.stamp(d, float(k))
        elif kind == "stamp":
            _, _, origin, k = step
            d = scan(origin, k)
            if d is None:
                continue
            maps[i].stamp(d, float(k))
            twins[i].stamp(d, float(k))
        elif kind == "write":
            _, _, how, k = step
            d = scan(9, k)
            if d is None:
                continue
            if how == "scan":
                assert maps[i].scan_disk(d, float(k)) == twins[i].scan_disk(d, float(k))
            elif how == "cover":
                assert maps[i].cover(d, float(k)) == twins[i].cover(d, float(k))
            else:
                other = (i + 1) % n
                maps[i].merge(maps[other])
                twins[i].merge(twins[other])
        else:
            _, _, how, seed = step
            rng = np.random.default_rng(seed)
            if how == "dense":
                assert same(maps[i].to_dense(), twins[i].to_dense())
            elif how == "cells":
                ix = rng.integers(0, GRID.nx, 50)
                iy = rng.integers(0, GRID.ny, 50)
                assert same(maps[i].q_at(ix, iy, 40.0), twins[i].q_at(ix, iy, 40.0))
            elif how == "region":
                r0, c0 = int(rng.integers(0, GRID.ny)), int(rng.integers(0, GRID.nx))
                rows = slice(r0, int(rng.integers(r0 + 1, GRID.ny + 1)))
                cols = slice(c0, int(rng.integers(c0 + 1, GRID.nx + 1)))
                assert same(maps[i].region(rows, cols), twins[i].region(rows, cols))
            elif how == "q":
                assert same(maps[i].uncertainty(40.0), twins[i].uncertainty(40.0))
            else:
                assert same(maps[i].copy().to_dense(), twins[i].to_dense())
    for m, twin in zip(maps, twins):
        assert same(m.to_dense(), twin.to_dense())
    # The base holds only what every member has.
    for m in group.members:
        assert (group.base.to_dense() <= m.to_dense()).all()


def test_a_swarm_that_hears_itself_shares_all_but_this_ticks_scans():
    group = MapGroup(GRID, TAU, 1.0)
    maps = [group.new_map() for _ in range(4)]
    for k in range(30):
        for me, m in enumerate(maps):
            for origin in range(4):
                if origin != me and k > 0 and (d := scan(origin, k - 1)) is not None:
                    m.stamp(d, float(k - 1))
            if (d := scan(me, k)) is not None:
                m.stamp(d, float(k))
    assert len(group.members) == 4 and group.left == 0
    assert all(len(m.extra_disks()) <= 1 for m in maps)
    assert all(m.nbytes == GRID.nx * GRID.ny * 4 for m in maps)  # reading builds its cells


def test_a_member_that_falls_behind_leaves_and_keeps_its_cells():
    group = MapGroup(GRID, TAU, 1.0)
    a, b = group.new_map(), group.new_map()
    late = group.new_map()  # never hears anything (a UAV not yet joined, or a crashed one)
    for k in range(LAG_TICKS + 3):
        for m in (a, b):
            if (d := scan(0, k)) is not None:
                m.stamp(d, float(k))
    assert late not in group.members and group.left == 1
    assert not np.isfinite(late.to_dense()).any()
    twin = UncertaintyMap(GRID, TAU)
    for k in range(LAG_TICKS + 3):
        if (d := scan(0, k)) is not None:
            twin.stamp(d, float(k))
    assert same(a.to_dense(), twin.to_dense()) and same(b.to_dense(), twin.to_dense())
    # A map made once the base holds scans starts on its own.
    assert not hasattr(group.new_map(), "extra_disks")
    # A scan stamped again long after (a resend) is recognised as known, not as new.
    d = scan(0, 1)
    a.stamp(d, 1.0)
    assert a.extra_disks() == [] and same(a.to_dense(), twin.to_dense())


def test_a_scan_only_a_few_members_have_makes_those_few_leave():
    group = MapGroup(GRID, TAU, 1.0)
    maps = [group.new_map() for _ in range(4)]
    twins = [UncertaintyMap(GRID, TAU) for _ in range(4)]
    for k in range(LAG_TICKS + 4):
        for m, twin in zip(maps, twins):
            if (d := scan(0, k)) is not None:  # everyone hears origin 0
                m.stamp(d, float(k))
                twin.stamp(d, float(k))
        if k == 1 and (d := scan(1, k)) is not None:  # only maps[3] has this one (others lost it)
            maps[3].stamp(d, float(k))
            twins[3].stamp(d, float(k))
    assert maps[3] not in group.members and len(group.members) == 3
    for m, twin in zip(maps, twins):
        assert same(m.to_dense(), twin.to_dense())


def test_maps_share_only_where_every_scan_can_reach_every_map():
    # A dense grid without a horizon, or with one covering the area's diagonal: a group.
    assert maps_share(250_000, 50_000.0, 50_000.0, math.inf)
    assert maps_share(250_000, 30_000.0, 40_000.0, 50_000.0)
    # A horizon shorter than the diagonal (bench-dense-300: 20 km in a 30 km square), or a
    # grid too large for dense maps: every map on its own.
    assert not maps_share(90_000, 30_000.0, 30_000.0, 20_000.0)
    assert not maps_share(DENSE_MAX_CELLS + 1, 50_000.0, 50_000.0, math.inf)


def test_the_simulation_and_the_memory_estimate_follow_maps_share():
    from swarm.kernel.memory import estimate_memory
    from swarm.kernel.simulation import Simulation
    from swarm.scenario import load_scenario

    for name, shared in (("paper-fig11", True), ("bench-dense-300", False)):
        sim = Simulation(name, duration_s=1.0)
        try:
            assert (sim._map_group is not None) == shared, name
        finally:
            sim.close()
        parts = estimate_memory(load_scenario(name)).parts
        assert ("UAV maps (shared storage)" in parts) == shared, name
        assert ("UAV maps (dense, one each)" in parts) == (not shared), name
