"""The tick plane's disk geometry (issue 36, T2) against the per-object code it replaces.

``Grid.set_tick_plane(True)``: :meth:`Grid.prefetch_disks` builds a tick's disks in one batch
(``Grid._build_batch``) and keeps their cells in a :class:`~agents.maps.grid.DiskArchive` for
anti-entropy resends, which :meth:`UncertaintyMap.stamp_once` then reads. ``False``: the code
kept as the oracle (the old batch, disks built one by one, ``stamp_once`` computing the disk).
Each property compares the two bit for bit over random grids, centres (on the grid, on its
edges, off it), radii (below a cell, zero, beyond the grid), tile shapes and times:

* every disk's box, mask, values and tile pieces, and the maps stamped with them;
* a resent scan stamped through the archive (hit), and one it lacks (miss), into maps holding
  earlier scans: the same cells, the same tiles allocated, the same changed boxes reported;
* ``where_seen`` (values by bit arithmetic) against ``np.where`` for every kind of float;
* the archive drops what is older than its horizon, and a hash collision is a miss;
* whole simulations: the same maps for every UAV and the same event log either way.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.maps.grid import PREFETCH_MIN, DiskArchive, Grid, where_seen
from agents.maps.umap import UncertaintyMap


def _bits(a: np.ndarray) -> bytes:
    """The exact bytes of a float32 array (NaN payloads, -0.0 and all)."""
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32).tobytes()


def _pair(nx: int, ny: int, c: float, keep_s: float = 50.0) -> tuple[Grid, Grid]:
    """The same grid twice: with the tick plane's geometry, and with the oracle's."""
    new, old = Grid(nx * c, ny * c, c), Grid(nx * c, ny * c, c)
    new.set_tick_plane(True, keep_s)
    old.set_tick_plane(False)
    return new, old


@st.composite
def scenes(draw):
    """A grid, tile shape, time and a batch of scans (lattice-aligned coordinates often, so
    cell centres fall exactly on circles), some of them off the grid or on its edges."""
    c = draw(st.sampled_from([100.0, 0.3, 7.0, 1.0]))
    nx, ny = draw(st.integers(1, 90)), draw(st.integers(1, 90))
    coords_x = st.one_of(st.integers(-40, 20 * nx + 40).map(lambda k: k * c / 20),
                         st.floats(-3.0 * nx * c, 4.0 * nx * c, allow_nan=False),
                         st.sampled_from([0.0, nx * c, -1e-9, nx * c + 1e-9]))
    coords_y = st.one_of(st.integers(-40, 20 * ny + 40).map(lambda k: k * c / 20),
                         st.floats(-3.0 * ny * c, 4.0 * ny * c, allow_nan=False),
                         st.sampled_from([0.0, ny * c]))
    radii = st.one_of(st.sampled_from([0.0, 0.3 * c, 0.5 * c, c, 2.5 * c, 7.0 * c, 20.0 * c, 150.0 * c]),
                      st.floats(0.0, 30.0 * c, allow_nan=False))
    n = draw(st.integers(PREFETCH_MIN, PREFETCH_MIN + 12))
    scans = [(draw(coords_x), draw(coords_y), draw(radii)) for _ in range(n)]
    if draw(st.booleans()):
        scans.append(scans[0])  # the same disk twice in one batch
    th, tw = draw(st.integers(1, 40)), draw(st.integers(1, 70))
    t = draw(st.one_of(st.floats(0.0, 1e6, allow_nan=False), st.sampled_from([0.0, 1.0, 3.3, 599.0])))
    return nx, ny, c, (th, tw), t, scans


@settings(deadline=None, max_examples=examples(150))
@given(scenes())
def test_batched_disks_equal_the_oracles(scene):
    """The tick plane's batch builds, for every scan, the disk the oracle builds: box, mask,
    values at t and tile pieces; maps stamped with either are the same bit for bit."""
    nx, ny, c, (th, tw), t, scans = scene
    new, old = _pair(nx, ny, c)
    xs, ys, rs = zip(*scans)
    new.prefetch_disks(xs, ys, rs, t, (th, tw))
    old.prefetch_disks(xs, ys, rs, t, (th, tw))
    ntx = -(-nx // tw)
    maps = {g: (UncertaintyMap(g, 0.01, tile=(th, tw)), UncertaintyMap(g, 0.01, tile="dense")) for g in (new, old)}
    for x, y, r in scans:
        a, b, ref = new.disk_stamp(x, y, r), old.disk_stamp(x, y, r), old.disk(x, y, r)
        assert (a is None) == (b is None) == (ref is None)
        if a is None or b is None or ref is None:
            continue
        assert (a.rows, a.cols) == (b.rows, b.cols) == ref[:2]
        assert a.mask.shape == b.mask.shape and np.array_equal(a.mask, b.mask) and np.array_equal(a.mask, ref[2])
        assert _bits(a.values(t)) == _bits(b.values(t))
        sa, sb = a.stamps(th, tw, ntx, t), b.stamps(th, tw, ntx, t)
        assert [p[:3] for p in sa] == [p[:3] for p in sb]
        assert all(_bits(p[3]) == _bits(q[3]) for p, q in zip(sa, sb))
        assert [p[:3] for p in a.pieces(th, tw, ntx)] == [p[:3] for p in b.pieces(th, tw, ntx)]
        for g, d in ((new, a), (old, b)):
            tiled, dense = maps[g]
            tiled.stamp(d, t)
            dense.stamp(d, t)
    for i in range(2):
        assert _bits(maps[new][i].to_dense()) == _bits(maps[old][i].to_dense())
    assert sorted(maps[new][0]._tiles) == sorted(maps[old][0]._tiles)  # the same tiles allocated


@settings(deadline=None, max_examples=examples(150))
@given(scenes(), st.data())
def test_resent_scans_through_the_archive_equal_the_oracles(scene, data):
    """stamp_once from the archive (scans of an earlier batch) or computing the disk (scans it
    lacks: never batched, or too old) changes the same cells as the oracle's stamp_once, into
    maps that already hold other scans; the same tiles are allocated and the same boxes
    reported as changed."""
    nx, ny, c, tiles, t0, scans = scene
    new, old = _pair(nx, ny, c, keep_s=data.draw(st.sampled_from([0.0, 5.0, 1e9])))
    xs, ys, rs = zip(*scans)
    new.prefetch_disks(xs, ys, rs, t0, tiles)  # archived (with keep_s > 0)
    old.prefetch_disks(xs, ys, rs, t0, tiles)
    later = data.draw(st.floats(0.0, 20.0))
    extra = [(x + 0.25 * c, y, r) for x, y, r in scans[:3]]  # never batched: not archived
    new.prefetch_disks([x + 1.0 for x in xs], ys, rs, t0 + later, tiles)  # (may push the first out)
    tile = data.draw(st.sampled_from([tiles, "dense", (tiles[0], 1), (1, tiles[1])]))
    m_new, m_old = UncertaintyMap(new, 0.01, tile=tile), UncertaintyMap(old, 0.01, tile=tile)
    for m in (m_new, m_old):  # earlier content, older and newer than the resends
        m.scan(xs[0], ys[0], rs[0] + c, t0 + 1.0)
        m.scan(xs[-1], ys[-1], 3 * c, t0 - 2.0)
        m.track_changes()
    order = data.draw(st.permutations(list(range(len(scans) + len(extra)))))
    every = scans + extra
    for i in order:
        x, y, r = every[i]
        when = data.draw(st.sampled_from([t0, t0 + 0.5, t0 - 1.0, 0.0]))
        m_new.stamp_once(x, y, r, when)
        m_old.stamp_once(x, y, r, when)
    assert _bits(m_new.to_dense()) == _bits(m_old.to_dense())
    assert sorted(m_new._tiles) == sorted(m_old._tiles)
    assert m_new.take_changes() == m_old.take_changes()


@pytest.mark.parametrize("t", [0.0, -0.0, 1.0, 3.3, 1e-40, 2.0**-149, 2.0**-150, 123456.789, 3.4028235e38,
                               3.4028236e38, 1e300, -1e300, math.inf, -math.inf, math.nan])
def test_where_seen_is_np_where_bit_for_bit(t):
    rng = np.random.default_rng(7)
    for shape in [(5, 7), (3, 4, 9), (0, 3), (1,)]:
        mask = rng.random(shape) < 0.5
        with np.errstate(over="ignore"):
            ref = np.where(mask, np.float32(t), np.float32(-np.inf))
        assert _bits(where_seen(mask, t)) == _bits(ref)
        assert _bits(where_seen(mask[..., ::2], t)) == _bits(ref[..., ::2])  # (a strided mask)


def test_archive_keeps_its_horizon_and_a_collision_is_a_miss():
    g = Grid(20_000.0, 20_000.0, 100.0)
    g.set_tick_plane(True, 10.0)
    archive = g._cache.archive
    assert isinstance(archive, DiskArchive)
    keys = [[(1000.0 + 37.0 * i + k, 2000.0 + 11.0 * i, 700.0 + 50.0 * (i % 3)) for i in range(PREFETCH_MIN)]
            for k in range(40)]
    for k, batch in enumerate(keys):
        g.prefetch_disks(*zip(*batch), float(k), (64, 64))
    # Batches of times 29..39 are kept (39 - 10 = 29), older ones dropped.
    assert len(archive) == 11 * PREFETCH_MIN
    for k, batch in enumerate(keys):
        for key in batch:
            got = archive.get(key)
            assert (got is not None) == (k >= 29)
            if got is not None:
                iy0, iy1, ix0, ix1, mask, nr, nc = got
                rows, cols, ref = g.disk(*key)  # type: ignore[misc]
                assert (slice(iy0, iy1), slice(ix0, ix1)) == (rows, cols) and np.array_equal(mask, ref)
                b = g._disk_bounds(*key)
                assert b is not None and (nr, nc) == (int(b[5].argmin()), int(b[6].argmin()))
    # A key whose hash finds another key's row is not that disk: a miss, then computed.
    a, b = keys[-1][0], keys[-1][1]
    archive.rows[hash(b)] = archive.rows[hash(a)]
    assert archive.get(b) is None
    got = g.disk_cells(*b)
    assert got is not None and np.array_equal(got[4], g.disk(*b)[2])  # type: ignore[index]


def test_archive_grows_without_losing_rows():
    archive = DiskArchive(1e9)
    rng = np.random.default_rng(3)
    for k in range(30):  # 30 batches of 100: past the first capacity several times, masks widening
        m = 100
        keys = [(float(x), float(y), 5.0) for x, y in rng.random((m, 2))]
        width = 8 + 4 * k
        xyr = tuple(np.array(col) for col in zip(*keys))
        archive.add(keys, xyr, (k, np.arange(m), 2, 3, 4, 0, 0), rng.integers(0, 256, (m, width), dtype=np.uint8),
                    float(k))
        got = archive.get(keys[17])
        assert got is not None and got[:4] == (k, k + 2, 17, 20)
    assert len(archive) == 3000


def test_archive_keeps_at_most_its_row_cap(monkeypatch):
    import agents.maps.grid as grid_module

    monkeypatch.setattr(grid_module, "ARCHIVE_MAX_ROWS", 5 * PREFETCH_MIN)
    g = Grid(20_000.0, 20_000.0, 100.0)
    g.set_tick_plane(True, 1e9)
    keys = [[(1000.0 + 37.0 * i + k, 2000.0 + 11.0 * i, 700.0) for i in range(PREFETCH_MIN)] for k in range(12)]
    for k, batch in enumerate(keys):
        g.prefetch_disks(*zip(*batch), float(k), (64, 64))
        archive = g._cache.archive
        assert archive is not None and len(archive) == min(k + 1, 5) * PREFETCH_MIN
    assert [archive.get(key) is not None for batch in keys for key in batch[:1]] == [False] * 7 + [True] * 5


def _maps_and_log(name: str, plane: bool, duration_s: float, seed: int, **kw: object) -> tuple[list[bytes], str]:
    from swarm import Simulation

    with Simulation(name, duration_s=duration_s, seed=seed, tick_plane=plane, **kw) as sim:  # type: ignore[arg-type]
        sim.run()
        maps = [_bits(a.umap.to_dense()) for a in sim.actors.values()]
        return maps, sim.metrics_dict()["event_log_sha256"]


@pytest.mark.slow
@pytest.mark.parametrize("name,duration_s,kw", [
    ("bench-100", 25.0, {"planner": "greedy"}),  # tiled maps, batched disks, anti-entropy resends
    ("demo-all-faults", None, {}),  # every fault kind: spoofed and lying scans, crashes, partitions
])
def test_simulations_give_the_same_maps_and_event_logs(name, duration_s, kw):
    new = _maps_and_log(name, True, duration_s, 0, **kw)
    old = _maps_and_log(name, False, duration_s, 0, **kw)
    assert new[1] == old[1]
    assert new[0] == old[0]
