"""The DACMP planner's fast paths give bit for bit the numbers of straightforward code.

Each reference below is the plain formulation the planner used before it was sped up (one map
at a time, whole-map sums, fresh arrays, a window of level sums). Decisions depend on exact
float comparisons, so "close" is not enough: every comparison here is on the raw bytes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.lib.stride_tricks import as_strided

from agents.knowledge import Knowledge
from agents.maps.grid import Grid
from agents.maps.umap import UncertaintyMap
from agents.planners.base import Plan, PlanView
from agents.planners.dacmp.dubins import DubinsPoses, dubins_length
from agents.planners.dacmp.planner import Batch, DacmpPlanner, Layers, UavSearch
from agents.planners.dacmp.pyramid import Scratch, gaussian_pyramid, level_index, level_shapes, pyr_down, pyr_down_stack
from agents.types import UavType
from comms.messages import MODE_SEARCH, MODE_SURVEIL, NO_TARGET


def same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


# --- references -------------------------------------------------------------------------------

def ref_reduce_rows(a: np.ndarray) -> np.ndarray:
    n, ncols = a.shape
    m = (n + 1) // 2
    out = np.empty((m, ncols), dtype=a.dtype)
    w = np.array([1.0, 4.0, 6.0, 4.0, 1.0]).astype(a.dtype)
    hi = (n - 3) // 2
    if hi >= 1:
        s0, s1 = a.strides
        view = as_strided(a, shape=(hi, ncols, 5), strides=(2 * s0, s1, s0), writeable=False)
        np.matmul(view, w, out=out[1 : hi + 1])
        border = [0, *range(hi + 1, m)]
    else:
        border = list(range(m))
    for i in border:
        j = []
        for k in range(5):
            r = (2 * i + k - 2) % (2 * n)
            j.append(2 * n - 1 - r if r >= n else r)
        out[i] = a[j[0]] + a[j[4]]
        out[i] += 4 * (a[j[1]] + a[j[3]])
        out[i] += 6 * a[j[2]]
    return out


def ref_pyr_down(a: np.ndarray) -> np.ndarray:
    b = ref_reduce_rows(np.ascontiguousarray(a))
    out = np.ascontiguousarray(ref_reduce_rows(np.ascontiguousarray(b.T)).T)
    out *= a.dtype.type(1.0 / 256.0)
    return out


def ref_level_sum(search_levels, lam, iy, ix) -> np.ndarray:
    out = np.zeros(np.broadcast_shapes(np.shape(iy), np.shape(ix)))
    for w_l, (lv, G) in zip(lam, search_levels):
        rows = np.minimum(level_index(iy, lv), G.shape[0] - 1)
        cols = np.minimum(level_index(ix, lv), G.shape[1] - 1)
        out += w_l * G[rows, cols]
    return out


def ref_guide_point(q, regions, cell_m, x, y, theta, tie_tol=0.0, tie_key=None):
    ny, nx = regions
    h, w = q.shape
    if ny < 2 and nx < 2:
        return None
    rows = np.linspace(0, h, ny + 1).round().astype(np.intp)
    cols = np.linspace(0, w, nx + 1).round().astype(np.intp)
    strips = np.stack([q[r0:r1].sum(axis=0, dtype=np.float64) for r0, r1 in zip(rows[:-1], rows[1:])])
    sums = np.add.reduceat(strips, cols[:-1], axis=1)
    means = sums / np.outer(np.diff(rows), np.diff(cols))
    ry = int(np.clip(np.searchsorted(rows, y / cell_m, side="right") - 1, 0, ny - 1))
    rx = int(np.clip(np.searchsorted(cols, x / cell_m, side="right") - 1, 0, nx - 1))
    cands = []
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            yy, xx = ry + dy, rx + dx
            if (dx or dy) and 0 <= yy < ny and 0 <= xx < nx:
                cx = 0.5 * (cols[xx] + cols[xx + 1]) * cell_m
                cy = 0.5 * (rows[yy] + rows[yy + 1]) * cell_m
                turn = abs(math.remainder(math.atan2(cy - y, cx - x) - theta, 2 * math.pi))
                key = turn if tie_key is None else float(tie_key[(dy + 1) * 3 + dx + 1])
                cands.append((float(means[yy, xx]), key, cx, cy))
    if not cands:
        return None
    best = max(c[0] for c in cands)
    _, _, cx, cy = min((c for c in cands if c[0] >= best - tie_tol), key=lambda c: c[1])
    return cx, cy


def ref_dubins(x0, y0, theta0, px, py, r):
    """One pose (scalars), points as arrays: the closed form with fresh arrays at every step."""
    dx = np.asarray(px, dtype=np.float64) - x0
    dy = np.asarray(py, dtype=np.float64) - y0
    if not r > 0.0:
        return np.hypot(dx, dy)
    c, s, inv_r = math.cos(theta0), math.sin(theta0), 1.0 / r
    x = (c * dx + s * dy) * inv_r
    y = np.abs(c * dy - s * dx) * inv_r
    t2 = x * x + y * (y - 2.0)
    inside = t2 < 0.0
    t = np.sqrt(np.maximum(t2, 0.0))
    alpha = np.arctan2(x + t * (y - 1.0), t * x + 1.0 - y)
    alpha = np.where(alpha < 0.0, alpha + 2.0 * math.pi, alpha)
    alpha = np.where((x > 0.0) & (alpha > math.pi), 0.0, alpha)
    out = np.array(alpha + t, dtype=np.float64)
    if np.any(inside):
        xi, yi = x[inside], y[inside]
        qy = yi + 1.0
        dq = np.hypot(xi, qy)
        gamma = np.arccos(np.clip((dq * dq + 3.0) / (4.0 * dq), -1.0, 1.0))
        ang_u = np.arctan2(qy, xi) - gamma
        a = np.maximum(np.mod(0.5 * math.pi - ang_u + math.pi, 2.0 * math.pi) - math.pi, 0.0)
        ux, uy = np.cos(ang_u), np.sin(ang_u)
        b = np.mod(np.arctan2(yi + 1.0 - 2.0 * uy, xi - 2.0 * ux) - np.arctan2(-uy, -ux), 2.0 * math.pi)
        b = np.where(b < 0.5 * math.pi, b + 2.0 * math.pi, b)
        out[inside] = a + b
    out *= r
    out[(dx == 0.0) & (dy == 0.0)] = 0.0
    return out


# --- inputs -----------------------------------------------------------------------------------

def q_like(rng, shape) -> np.ndarray:
    """An uncertainty map as the simulator makes them: float32 ``1 - exp(-tau age)``, with
    never-seen (1), just-scanned (0) and everything between."""
    age = rng.exponential(300.0, shape).astype(np.float32)
    age[rng.random(shape) < 0.2] = np.inf
    age[rng.random(shape) < 0.05] = 0.0
    return np.float32(1.0) - np.exp(-np.float32(1 / 600) * age)


def wide_range(rng, shape, dtype) -> np.ndarray:
    """Values over many orders of magnitude (and exact zeros): any change in the order of
    additions or in rounding shows."""
    a = rng.random(shape) * 10.0 ** rng.integers(-12, 4, shape)
    a[rng.random(shape) < 0.1] = 0.0
    return a.astype(dtype)


# --- pyramid ----------------------------------------------------------------------------------

@settings(max_examples=examples(150), deadline=None)
@given(h=st.integers(1, 70), w=st.integers(1, 70), seed=st.integers(0, 2**32 - 1),
       dtype=st.sampled_from([np.float32, np.float64]), kind=st.sampled_from(["q", "wide"]))
def test_pyramid_is_the_reference_bit_for_bit(h, w, seed, dtype, kind):
    rng = np.random.default_rng(seed)
    q = q_like(rng, (h, w)).astype(dtype) if kind == "q" else wide_range(rng, (h, w), dtype)
    pyr = gaussian_pyramid(q, 9)
    assert [g.shape for g in pyr] == level_shapes((h, w), 9)
    ref = q
    for g in pyr[1:]:
        ref = ref_pyr_down(ref)
        assert same(g, ref)


@settings(max_examples=examples(60), deadline=None)
@given(h=st.integers(1, 40), w=st.integers(1, 40), k=st.integers(1, 5), seed=st.integers(0, 2**32 - 1))
def test_stacked_maps_each_get_their_own_numbers(h, w, k, seed):
    rng = np.random.default_rng(seed)
    a = np.stack([q_like(rng, (h, w)) for _ in range(k)])
    scratch = Scratch()
    out = np.empty((k, (h + 1) // 2, (w + 1) // 2), np.float32)
    for _ in range(2):  # the second time through reused scratch buffers
        pyr_down_stack(a, out, scratch)
        for i in range(k):
            assert same(out[i], ref_pyr_down(a[i]))
            assert same(out[i], pyr_down(a[i]))


def test_paper_sized_pyramid_is_the_reference():
    q = q_like(np.random.default_rng(1), (500, 500))
    ref = q
    for g in gaussian_pyramid(q, 8)[1:]:
        ref = ref_pyr_down(ref)
        assert same(g, ref)


def test_scratch_reuses_and_grows():
    s = Scratch()
    a = s.get("x", (4, 5))
    assert a.shape == (4, 5) and a.dtype == np.float32 and a.flags["C_CONTIGUOUS"]
    b = s.get("x", (2, 3), np.float64)
    assert b.dtype == np.float64 and np.shares_memory(a, b)
    c = s.get("x", (100,))
    assert c.shape == (100,)


# --- the planner's guide point (its layers: tests/test_maintained_pyramid.py) ------------------

@settings(max_examples=examples(300), deadline=None)
@given(h=st.integers(1, 60), w=st.integers(1, 60), ny=st.integers(1, 6), nx=st.integers(1, 6),
       seed=st.integers(0, 2**32 - 1), tie_tol=st.sampled_from([0.02, 0.0]), keyed=st.booleans(),
       dtype=st.sampled_from([np.float32, np.float64]))
def test_guide_point_is_the_reference(h, w, ny, nx, seed, tie_tol, keyed, dtype):
    ny, nx = min(ny, h), min(nx, w)
    rng = np.random.default_rng(seed)
    q = wide_range(rng, (h, w), dtype)
    x, y = rng.uniform(-50.0, w * 10.0 + 50.0), rng.uniform(-50.0, h * 10.0 + 50.0)
    key = rng.random(9) if keyed else None
    got = DacmpPlanner.guide_point(q, (ny, nx), 10.0, x, y, 0.7, tie_tol=tie_tol, tie_key=key)
    assert got == ref_guide_point(q, (ny, nx), 10.0, x, y, 0.7, tie_tol=tie_tol, tie_key=key)


# --- Dubins -----------------------------------------------------------------------------------

coord = st.floats(-5e4, 5e4, allow_nan=False)


@settings(max_examples=examples(200), deadline=None)
@given(poses=st.lists(st.tuples(coord, coord, st.floats(-7.0, 7.0), st.floats(-10.0, 3e3)), min_size=1, max_size=6),
       seed=st.integers(0, 2**32 - 1), m=st.integers(1, 40))
def test_dubins_is_the_reference(poses, seed, m):
    rng = np.random.default_rng(seed)
    x0, y0, th, r = (np.array(col) for col in zip(*poses))
    scale = np.maximum(np.abs(r), 1.0)[:, None]
    px = x0[:, None] + rng.normal(0.0, 1.0, (len(poses), m)) * scale * rng.choice([0.5, 3.0, 30.0])
    py = y0[:, None] + rng.normal(0.0, 1.0, (len(poses), m)) * scale * rng.choice([0.5, 3.0, 30.0])
    px[:, 0], py[:, 0] = x0, y0  # at the start
    with np.errstate(all="ignore"):  # extreme radii overflow, in the reference too
        ref = np.stack([ref_dubins(*p[:3], px[i], py[i], p[3]) for i, p in enumerate(poses)])
        assert same(dubins_length(x0[:, None], y0[:, None], th, px, py, r[:, None]), ref)
        d = np.stack([px - x0[:, None], py - y0[:, None]])
        assert same(DubinsPoses(th, r[:, None]).lengths(d), ref)
        assert same(DubinsPoses(th, r[:, None], shape=px.shape).lengths(d), ref)  # terms stored repeated
        for i, p in enumerate(poses):
            assert same(dubins_length(*p[:3], px[i], py[i], p[3]), ref[i])


def test_dubins_scalar_point_stays_0d():
    out = dubins_length(0.0, 0.0, 0.0, 5.0, 0.0, 1.0)
    assert isinstance(out, np.ndarray) and out.shape == () and float(out) == pytest.approx(5.0)
    assert same(dubins_length(1.0, 2.0, 0.3, 0.5, 0.4, 0.7), ref_dubins(1.0, 2.0, 0.3, 0.5, 0.4, 0.7))


def test_clip_to_unit_by_maximum_minimum_is_np_clip():
    """The planner and the Dubins CC branch clip cosines to [-1, 1] by maximum then minimum
    (np.clip's Python wrapper costs more than the clip): the same bytes, signed zeros and NaN
    included (ties only at the non-zero bounds)."""
    x = np.array([-np.inf, -2.0, -1.0, -1.0 + 1e-16, -0.0, 0.0, 5e-324, 0.3, 1.0, 1.0 + 2e-16, np.inf, np.nan])
    y = x.copy()
    np.maximum(y, -1.0, out=y)
    np.minimum(y, 1.0, out=y)
    assert same(y, np.clip(x, -1.0, 1.0))


# --- the particle swarm's fitness, particle bound and loop (issue 36: their temporaries updated
# in place) against the formulas written out with fresh arrays, as they were -------------------

def ref_fitness(batch, z, kept=False):
    planner, g = batch.planner, batch.grid
    cells = (z // g.cell_m).astype(np.int64)
    idx = batch.layers.row_part.take(cells[1], axis=1, mode="clip")
    idx += batch.layers.col_part.take(cells[0], axis=1, mode="clip")
    idx += batch.layer_base
    terms = batch.layers.flat.take(idx).astype(np.float64) * batch.layer_weights
    p_sum = batch.layers.lam_total - np.add.reduce(terms, axis=0, initial=0.0) * batch.layer_scale
    d = z - batch.p0
    dub = batch.dubins.lengths(d)
    R = batch.R
    f_sl = p_sum / (1.0 + ((dub - R) / R) ** 2)
    if batch.crowding is not None:
        f_sl *= batch.crowding(z)
    if batch.guided:
        dot = batch.guide_dir * d
        cosang = np.clip((dot[0] + dot[1]) / np.maximum(batch.g_norm * np.hypot(d[0], d[1]), 1e-9), -1.0, 1.0)
        f_sg = 1.0 / (1.0 + np.exp(np.arccos(cosang) / math.pi))
        if len(batch.guided) < len(batch.uavs):
            f_sg = np.where(batch.has_guide, f_sg, 0.5)
    else:
        f_sg = np.full(p_sum.shape, 0.5)
    f_s = planner.eta * f_sl + (1.0 - planner.eta) * f_sg
    if kept and not batch.with_targets and not batch.with_threats:
        return f_s, f_s, np.zeros(p_sum.shape)
    f_t = np.zeros(p_sum.shape)
    inside = (z >= 0) & (z <= batch.area)
    ok = inside[0] & inside[1]
    unit = planner.field_unit_m
    for i, u in batch.with_targets:
        u.target_terms(z[0, i], z[1, i], f_t[i], unit, g.cell_m / unit)
    for i, u in batch.with_threats:
        for th in u.threats:
            ok[i] &= np.hypot(z[0, i] - th.x, z[1, i] - th.y) > th.radius + planner.threat_margin_m
    return np.where(ok, f_s + f_t, -np.inf), f_s, f_t


def ref_keep_near(batch, z):
    d = z - batch.p0
    dist = np.hypot(d[0], d[1])
    scale = np.where(dist > batch.r_max, batch.r_max / np.maximum(dist, 1e-9), 1.0)
    return np.clip(batch.p0 + d * scale, 0.0, batch.area)


def ref_pso(planner, uavs, g, layers):
    """DacmpPlanner._pso with fresh arrays at every step and the reference fitness and bound."""
    U, M, n_it = len(uavs), planner.particles, planner.iterations
    batch = Batch(planner, uavs, g, layers, M)
    rows = np.arange(U)
    radius = np.abs(np.stack([u.ring_radius for u in uavs]))
    angle = np.stack([u.ring_angle for u in uavs])
    z = ref_keep_near(batch, batch.p0 + radius * np.stack([np.cos(angle), np.sin(angle)]))
    v = np.zeros((2, U, M))
    bf = ref_fitness(batch, z, kept=True)[0].copy()
    best_z = z.copy()
    gi = np.argmax(bf, axis=1)
    draws = np.repeat(np.stack([u.pso_draws for u in uavs], axis=2)[:, :, None], 2, axis=2)
    for it in range(n_it):
        frac = it / (n_it - 1) if n_it > 1 else 1.0
        w = planner.w_start + (planner.w_end - planner.w_start) * frac
        c1 = planner.c1_start + (planner.c1_end - planner.c1_start) * frac
        c2 = planner.c2_start + (planner.c2_end - planner.c2_start) * frac
        g_best = best_z[:, rows, gi][:, :, None]
        v = w * v + (c1 * draws[it, 0]) * (best_z - z) + (c2 * draws[it, 1]) * (g_best - z)
        z = ref_keep_near(batch, z + v * draws[it, 2])
        f = ref_fitness(batch, z, kept=True)[0]
        better = f > bf
        best_z = np.where(better, z, best_z)
        bf = np.where(better, f, bf)
        gi = bf.argmax(axis=1)
    wz, best = best_z[:, rows, gi][:, :, None], bf[rows, gi]
    f_s = ref_fitness(batch, np.repeat(wz, M, axis=2), kept=True)[1]
    unit = planner.field_unit_m
    return [Plan(g.width_m / 2, g.height_m / 2) if not np.isfinite(best[i])
            else u.decide(float(wz[0, i, 0]), float(wz[1, i, 0]), f_s[i, 0], unit, g.cell_m / unit)
            for i, u in enumerate(uavs)]


_KINDS = [UavType("B", 20.0, 40.0, 3.0, math.radians(30), 1500.0, 5.0, 5.1, 10_000.0),
          UavType("A", 10.0, 20.0, 2.0, math.radians(30), 2000.0, 2.0, 2.1, 4_000.0)]


@st.composite
def swarms(draw):
    """Two to five UAVs on one map: own scans, targets, threats, peers' intents, surveillance."""
    grid = Grid(draw(st.sampled_from([900.0, 8_000.0, 20_000.0])), draw(st.sampled_from([700.0, 16_000.0])), 100.0)
    t = draw(st.floats(10.0, 2000.0))
    views = []
    for uav in range(draw(st.integers(1, 5))):
        kind = draw(st.sampled_from(_KINDS))
        x, y = draw(st.floats(0.0, grid.width_m)), draw(st.floats(0.0, grid.height_m))
        umap = UncertaintyMap(grid, 1.0 / 400.0)
        for _ in range(draw(st.integers(0, 5))):
            umap.scan(draw(st.floats(0.0, grid.width_m)), draw(st.floats(0.0, grid.height_m)),
                      draw(st.floats(200.0, 3000.0)), draw(st.floats(0.0, t)))
        k = Knowledge()
        for tid in range(draw(st.integers(0, 3))):
            k.see_target(tid, draw(st.floats(0.0, grid.width_m)), draw(st.floats(0.0, grid.height_m)),
                         draw(st.floats(-15.0, 15.0)), draw(st.floats(-15.0, 15.0)), t - draw(st.floats(0.0, 30.0)), 1.0)
        for th in range(draw(st.integers(0, 2))):
            r = draw(st.floats(200.0, 3000.0))
            k.add_threat(th, draw(st.floats(0.0, grid.width_m)), draw(st.floats(0.0, grid.height_m)), r, r + 3000.0)
        for other in range(draw(st.integers(0, 2))):
            p = k.peer(100 + other)
            p.type, p.x, p.y, p.t_pose = "A", x + 1000.0, y, t - 1.0
            p.wx, p.wy, p.t_intent = draw(st.floats(0.0, grid.width_m)), draw(st.floats(0.0, grid.height_m)), t - 2.0
            p.mode, p.target = draw(st.sampled_from([(MODE_SEARCH, NO_TARGET), (MODE_SURVEIL, 0), (MODE_SURVEIL, 1)]))
        v, theta = draw(st.floats(kind.speed_min, kind.speed_max)), draw(st.floats(-math.pi, math.pi))
        rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
        views.append(PlanView(t, uav, kind, x, y, v, theta, umap, k, rng, grid, 10.0, draw(st.booleans()), None))
    return views


@settings(max_examples=examples(60), deadline=None)
@given(views=swarms(), particles=st.integers(1, 30), iterations=st.integers(1, 8), levels=st.integers(0, 7),
       eta=st.sampled_from([0.0, 0.5, 1.0]), seed=st.integers(0, 2**32 - 1))
def test_fitness_bound_and_particle_swarm_are_the_plain_formulas(views, particles, iterations, levels, eta, seed):
    """Batch.fitness, Batch.keep_near and DacmpPlanner._pso, whose temporaries are updated in
    place, give the bytes of the formulas with fresh arrays: the bound of points anywhere
    (outside the area, at the UAV itself, beyond r_max), the fitness at points it bounded and at
    the targets, and whole particle swarms."""
    planner = DacmpPlanner(particles=particles, iterations=iterations, levels=levels, eta=eta)
    g = views[0].grid
    uavs = [UavSearch.build(planner, v, slot) for slot, v in enumerate(views)]
    layers = Layers(planner, uavs)
    for u in uavs:
        u.draw(planner)
    rng = np.random.default_rng(seed)
    batch = Batch(planner, uavs, g, layers, particles)
    z = batch.p0 + rng.normal(0.0, 1.0, batch.p0.shape) * rng.choice([10.0, 3000.0, 30_000.0], (1, len(uavs), 1))
    z[:, :, 0] = batch.p0[:, :, 0]  # at the UAV
    with np.errstate(all="ignore"):
        kept = batch.keep_near(z)
        assert same(kept, ref_keep_near(batch, z))
        # The fitness reads the map near each UAV (Layers' windows): the kept points, and with
        # targets (DacmpPlanner.keep scores a target where it is) the targets.
        free = kept.copy()
        for i, u in enumerate(uavs):
            for j, (_tid, tx, ty, _v) in enumerate(u.targets[:particles]):
                free[:, i, j] = tx, ty
        for points, is_kept in ((free, False), (kept, True)):
            for got, want in zip(batch.fitness(points, kept=is_kept), ref_fitness(batch, points, kept=is_kept)):
                assert same(got, want)
        assert planner._pso(uavs, g, layers) == ref_pso(planner, uavs, g, layers)
