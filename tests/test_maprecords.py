"""agents.maprecords: two maps can differ only inside the disks differences() lists."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.grid import Grid
from agents.maprecords import KEEP_TICKS, MapRecords, differences
from agents.umap import UncertaintyMap

GRID = Grid(4000.0, 4000.0, 100.0)
DT = 1.0


def scan(origin: int, k: int):
    """Origin's scan of tick k: a disk somewhere on the grid (deterministic)."""
    rng = np.random.default_rng(origin * 100_003 + k)
    x, y = rng.uniform(0, GRID.width_m, 2)
    return k * DT, GRID.disk_stamp(float(x), float(y), float(rng.uniform(150, 600)))


def fresh() -> MapRecords:
    return MapRecords(UncertaintyMap(GRID, 1 / 600), DT)


def covered(disks) -> np.ndarray:
    """Cells inside any of the disks."""
    out = np.zeros(GRID.shape, bool)
    for d in disks:
        out[d.rows, d.cols] |= d.mask
    return out


deliveries = st.lists(st.tuples(st.integers(0, 3), st.integers(0, 30)), max_size=80)


@settings(max_examples=150, deadline=None)
@given(a_scans=deliveries, b_scans=deliveries, common=st.integers(0, 25))
def test_maps_differ_only_inside_the_listed_disks(a_scans, b_scans, common):
    a, b = fresh(), fresh()
    # A common past (every origin's scans up to `common`, in order), then each its own arrivals:
    # late, repeated, out of order, missing.
    for k in range(common):
        for origin in range(4):
            t, d = scan(origin, k)
            a.stamp(origin, t, d)
            b.stamp(origin, t, d)
    for rec, scans in ((a, a_scans), (b, b_scans)):
        for origin, k in scans:
            t, d = scan(origin, k)
            rec.stamp(origin, t, d)
    disks = differences(a, b)
    if disks is None:
        return  # it could not tell: the planner compares the maps instead
    differ = a.umap.to_dense() != b.umap.to_dense()
    assert not (differ & ~covered(disks)).any()
    assert differences(b, a) is not None


def test_a_swarm_that_hears_itself_differs_by_this_ticks_own_scans():
    maps = [fresh() for _ in range(4)]
    for k in range(40):
        for me, rec in enumerate(maps):
            for origin in range(4):  # heard: every other UAV's scan of the previous tick
                if origin != me and k > 0:
                    rec.stamp(origin, *scan(origin, k - 1))
            rec.stamp(me, *scan(me, k))  # own scan of this tick
    disks = differences(maps[0], maps[1])
    assert disks is not None and len(disks) == 2
    assert {id(d) for d in disks} == {id(scan(0, 39)[1]), id(scan(1, 39)[1])}


def test_any_other_write_or_an_old_gap_makes_it_unable_to_tell():
    a, b = fresh(), fresh()
    for k in range(5):
        a.stamp(0, *scan(0, k))
        b.stamp(0, *scan(0, k))
    assert differences(a, b) == []
    a.umap.scan(100.0, 100.0, 300.0, 3.0)  # not through the summary
    assert differences(a, b) is None
    c = fresh()
    c.stamp(0, *scan(0, 0))
    for k in range(2, KEEP_TICKS + 12):
        c.stamp(0, *scan(0, k))  # tick 1 never heard: tick 2 on are outside the run
    assert differences(c, b) is not None  # still small enough to list
    d = fresh()
    for k in range(KEEP_TICKS + 5):
        d.stamp(1, *scan(1, k))
    assert differences(d, b) is None  # a whole origin b lacks, longer than the disks kept
    e = fresh()
    e.stamp(0, 0.5, scan(0, 0)[1])  # off the tick grid
    assert differences(e, b) is None
    written = UncertaintyMap(GRID, 1 / 600)
    written.scan(100.0, 100.0, 300.0, 3.0)
    assert differences(MapRecords(written, DT), b) is None
