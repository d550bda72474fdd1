"""Tests for agents.maps.tiles: copy-on-write map tiles shared by identity (issue 36, T8).

Maps on a grid with the tick plane (``Grid.set_tick_plane(True)``) share tile objects through the
grid's :class:`~agents.maps.tiles.TileShare`; twin maps on a grid without it keep tiles of their
own (the plain code). The property: any sequence of writes (stamps of memoised disks, the same
scan stamped onto several maps, resent scans, scans, covers, merges, copies) and tick boundaries
leaves every shared map with its twin's cells, its twin's tiles allocated and its twin's changed
boxes, after every step. The unit tests show that sharing does happen (same objects), that a
write to a shared tile leaves the other maps' cells alone, and that a tile nobody else took is
written in place again after the tick.
"""

from __future__ import annotations

import numpy as np
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.maps.grid import Grid
from agents.maps.umap import UncertaintyMap

W, H, CELL, TILE = 40.0, 30.0, 1.0, 8  # 5 x 4 tiles of 8 x 8 cells (edge tiles partly outside)


def _pair() -> tuple[Grid, Grid]:
    shared, plain = Grid(W, H, CELL), Grid(W, H, CELL)
    shared.set_tick_plane(True)
    plain.set_tick_plane(False)
    assert shared.tile_share is not None and plain.tile_share is None
    return shared, plain


scans = st.tuples(st.integers(-2, 42).map(float), st.integers(-2, 32).map(float),
                  st.sampled_from([0.4, 1.5, 3.0, 6.0, 11.0]), st.integers(0, 12).map(float))
ops = st.one_of(
    st.tuples(st.just("stamp"), scans, st.lists(st.integers(0, 3), min_size=1, max_size=4)),  # one scan, several maps
    st.tuples(st.just("once"), scans, st.integers(0, 3)),
    st.tuples(st.just("scan"), scans, st.integers(0, 3)),
    st.tuples(st.just("cover"), scans, st.integers(0, 3)),
    st.tuples(st.just("merge"), st.integers(0, 3), st.integers(0, 3)),
    st.tuples(st.just("copy"), st.integers(0, 3), st.integers(0, 3)),
    st.tuples(st.just("tick")),
)


@settings(deadline=None, max_examples=examples(300))
@given(st.lists(ops, max_size=40))
def test_shared_maps_equal_their_own_tiled_twins(steps):
    shared_grid, plain_grid = _pair()
    maps = [UncertaintyMap(shared_grid, 0.01, tile=TILE) for _ in range(4)]
    twins = [UncertaintyMap(plain_grid, 0.01, tile=TILE) for _ in range(4)]
    for m in maps + twins:
        m.track_changes()
    for op in steps:
        kind = op[0]
        if kind == "stamp":
            (x, y, r, t), which = op[1], op[2]
            for g, ms in ((shared_grid, maps), (plain_grid, twins)):
                d = g.disk_stamp(x, y, r)
                if d is not None:
                    for i in which:
                        ms[i].stamp(d, t)
        elif kind in ("once", "scan", "cover"):
            (x, y, r, t), i = op[1], op[2]
            for g, m in ((shared_grid, maps[i]), (plain_grid, twins[i])):
                if kind == "once":
                    m.stamp_once(x, y, r, t)
                    continue
                d = g.disk_stamp(x, y, r)
                if d is not None:
                    got = m.scan_disk(d, t) if kind == "scan" else m.cover(d, t)
                    if m is maps[i]:
                        mine = got
                    else:
                        assert got == mine
        elif kind == "merge":
            maps[op[1]].merge(maps[op[2]])
            twins[op[1]].merge(twins[op[2]])
        elif kind == "copy":
            maps[op[1]] = maps[op[2]].copy()
            twins[op[1]] = twins[op[2]].copy()
            maps[op[1]].track_changes()
            twins[op[1]].track_changes()
        else:
            shared_grid.new_tick()
        for m, twin in zip(maps, twins):
            assert np.array_equal(m.to_dense(), twin.to_dense())
            assert m.written_boxes() == twin.written_boxes()
            assert m.take_changes() == twin.take_changes()


def test_receivers_of_one_scan_share_the_resulting_tile():
    grid, _ = _pair()
    a, b, c = (UncertaintyMap(grid, 0.01, tile=TILE) for _ in range(3))
    d = grid.disk_stamp(12.0, 12.0, 3.0)  # inside tile (1, 1)
    assert d is not None
    for m in (a, b, c):
        m.stamp(d, 1.0)
    key = 1 * 5 + 1
    tile = a.tile(key)
    assert tile is not None and b.tile(key) is tile and c.tile(key) is tile
    share = grid.tile_share
    assert share is not None and share.made == 1 and share.stamps == 3
    # b hears one more scan: it gets a tile of its own; a and c keep theirs, cells unchanged.
    before = a.to_dense()
    d2 = grid.disk_stamp(13.0, 11.0, 2.0)
    assert d2 is not None
    b.stamp(d2, 2.0)
    assert b.tile(key) is not tile and a.tile(key) is tile and c.tile(key) is tile
    assert np.array_equal(a.to_dense(), before) and np.array_equal(c.to_dense(), before)
    assert b.to_dense()[11, 13] == np.float32(2.0)


def test_a_tile_nobody_took_is_written_in_place_after_the_tick():
    grid, _ = _pair()
    a, b = UncertaintyMap(grid, 0.01, tile=TILE), UncertaintyMap(grid, 0.01, tile=TILE)
    d = grid.disk_stamp(12.0, 12.0, 3.0)
    assert d is not None
    a.stamp(d, 1.0)
    mine = a.tile(6)
    assert mine is not None
    grid.new_tick()  # nobody took it: a's own again
    d2 = grid.disk_stamp(11.0, 13.0, 2.0)
    assert d2 is not None
    a.stamp(d2, 2.0)
    assert a.tile(6) is mine  # written in place
    b.stamp(d, 1.0)
    assert b.tile(6) is not mine  # (a new tile: the memo of the last tick is gone)
    assert a.to_dense()[13, 11] == np.float32(2.0) and b.to_dense()[13, 11] == np.float32(1.0)
