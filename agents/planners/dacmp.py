"""The DACMP planner (paper section 3; DACMP-SPEC.md "The planner").

Each replanning, a UAV runs a particle swarm over candidate waypoints:

* particles start in the ring just outside its detection radius (radius ~ N(1.5 R_s, 0.5 R_s),
  angle ~ N(heading, pi/2)), clipped to the area;
* PSO with inertia ``w`` and coefficients ``c1, c2`` changing linearly over the iterations and a
  random factor ``Q ~ U(0, 1)`` on each position increment (eq. 15);
* fitness ``f = f_S + f_t`` (eq. 16):

  - ``f_Sl = sum_{l=1..L} lambda_l P_l(k) / (1 + ((Dub(k) - R_s) / R_s)^2)`` (eq. 19), ``P_l``
    the Gaussian pyramid level ``l`` at the particle's cell, ``Dub`` the shortest Dubins path
    with free final heading (:mod:`agents.dubins`). As in the paper, ``L`` (``map.levels``, 7)
    counts the layers *above* the map ``G_0``: the sum starts at ``l = 1``, and the seventh layer
    of a 500 x 500 map is the 4 x 4 one the paper's global guide reads;
  - ``f_Sg = 1 / (1 + exp(theta_k / pi))`` (eq. 20), ``theta_k`` the angle at the UAV between
    the global guide point and the particle; the guide is the centre of the most uncertain of
    the (up to 8) regions around the UAV's own region on the coarsest level with >= 4x4 cells;
  - ``f_S = eta f_Sl + (1 - eta) f_Sg`` (eq. 21);
  - ``f_t``: for each known target within ``D_i`` of the particle, ``w_t value / (d v_i^2)``
    (eq. 22), minus, for each other UAV whose announced next waypoint lies within ``D_i`` of such
    a target, ``w_r / (d(k, wp_j) v_i v_j)`` (eq. 23). Distances and speeds in these two terms
    are in ``field_unit_m`` (km by default), distances floored at one cell;

* infeasible particles (outside the area, inside a known threat plus margin) score ``-inf``.

The UAV is in surveillance mode when, at the chosen waypoint, the target term dominates
(``f_t > f_S``) and a target lies within ``D_i``; the watched target is the nearest one.
With ``surveillance = false`` (paper-fig11) targets exert no pull: search only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from agents.dubins import dubins_length
from agents.planners.base import Plan, PlanView
from agents.pyramid import gaussian_pyramid, level_index
from comms.messages import MODE_SEARCH, MODE_SURVEIL, NO_TARGET

# Peers whose intent is older than this are ignored for the competing repulsion.
_INTENT_MAX_AGE_S = 15.0


@dataclass
class DacmpPlanner:
    particles: int = 40
    iterations: int = 25
    w_start: float = 0.9
    w_end: float = 0.4
    c1_start: float = 2.5
    c1_end: float = 0.5
    c2_start: float = 0.5
    c2_end: float = 2.5
    ring_mean_factor: float = 1.5
    ring_sd_factor: float = 0.5
    ring_max_factor: float = 2.5
    heading_sd_rad: float = math.pi / 2
    eta: float = 0.5
    levels: int = 7
    level_weights: tuple[float, ...] | None = None
    field_unit_m: float = 1000.0
    threat_margin_m: float = 300.0
    # Other UAVs' top speeds by type name (v_j of eq. 23); unknown types count as our own.
    speed_max_by_type: dict[str, float] = field(default_factory=dict)
    name: str = "dacmp"

    @classmethod
    def from_settings(cls, planner_settings, levels: int = 7,
                      speed_max_by_type: dict[str, float] | None = None) -> "DacmpPlanner":
        d = planner_settings.dacmp
        return cls(
            particles=d.particles, iterations=d.iterations, w_start=d.w_start, w_end=d.w_end,
            c1_start=d.c1_start, c1_end=d.c1_end, c2_start=d.c2_start, c2_end=d.c2_end,
            ring_mean_factor=d.ring_mean_factor, ring_sd_factor=d.ring_sd_factor, ring_max_factor=d.ring_max_factor,
            heading_sd_rad=d.heading_sd_rad, eta=d.eta, levels=levels,
            level_weights=tuple(d.level_weights) if d.level_weights is not None else None,
            field_unit_m=d.field_unit_m, threat_margin_m=d.threat_margin_m,
            speed_max_by_type=dict(speed_max_by_type or {}),
        )

    # --- pieces of the fitness --------------------------------------------------------------

    def _weights(self, n: int) -> np.ndarray:
        """lambda_1..lambda_n of eq. 19 (n < L when the map is too small for L layers)."""
        if self.level_weights is None:
            return np.full(n, 1.0 / n)
        w = np.asarray(self.level_weights[:n], dtype=np.float64)
        return w / w.sum()

    @staticmethod
    def guide_point(q: np.ndarray, regions: tuple[int, int], cell_m: float, x: float, y: float,
                    theta: float, tie_tol: float = 0.02, tie_key: np.ndarray | None = None) -> tuple[float, float] | None:
        """Centre of the most uncertain of the (up to 8) sub-areas adjacent to the UAV's (eq. 20).

        The paper's coarsest layer "divides the map into 4 x 4 sub-areas": ``regions`` is that
        layer's shape, and each sub-area's uncertainty is the mean of ``q`` over its block of
        cells. Blocks, not the layer's own samples: REDUCE centres coarse sample ``a`` on cell
        ``2**L a``, so the samples of a 4 x 4 layer sit at 0, 12.8, 25.6 and 38.4 km on a 50 km
        map and no guide point would ever lie in the eastern or northern strip.
        Sub-areas within ``tie_tol`` (2%) of the best count as tied (early on everything unseen
        is ~1). Among them, with ``tie_key`` (one number per neighbour, row by row) the smallest
        key wins; without it, the one closest to the UAV's heading.
        """
        ny, nx = regions
        h, w = q.shape
        if ny < 2 and nx < 2:
            return None
        rows = np.linspace(0, h, ny + 1).round().astype(np.intp)
        cols = np.linspace(0, w, nx + 1).round().astype(np.intp)
        sums = np.add.reduceat(np.add.reduceat(q, rows[:-1], axis=0, dtype=np.float64), cols[:-1], axis=1)
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

    @staticmethod
    def _keep_near(view: PlanView, zx: np.ndarray, zy: np.ndarray, r_max: float, g) -> tuple[np.ndarray, np.ndarray]:
        """Pull particles back to within ``r_max`` of the UAV, then into the area.

        A particle is a candidate *next* waypoint (``x_j(t+1)`` in eq. 23, which other UAVs read
        from the broadcast intent). Left free, PSO carries particles all the way to a target
        10 km off; the announced waypoint would then claim the target long before the UAV
        arrives, and a fast watcher would hand over to a slow UAV that is still minutes away.
        """
        dx, dy = zx - view.x, zy - view.y
        d = np.hypot(dx, dy)
        scale = np.where(d > r_max, r_max / np.maximum(d, 1e-9), 1.0)
        return (np.clip(view.x + dx * scale, 0.0, g.width_m), np.clip(view.y + dy * scale, 0.0, g.height_m))

    def plan(self, view: PlanView) -> Plan:
        k = view.kind
        g = view.grid
        rng = view.rng
        R = k.detect_radius
        t = view.t
        q = view.umap.uncertainty(t)
        pyr = gaussian_pyramid(q, self.levels + 1)  # G_0 .. G_L
        # Eq. 19 sums layers 1..L; a map too small for even one layer falls back on G_0.
        search_levels = list(enumerate(pyr))[1:] or [(0, pyr[0])]
        lam = self._weights(len(search_levels))
        coarse = next((lv for lv in reversed(pyr) if min(lv.shape) >= 4), pyr[0])
        # Ties go to a neighbour drawn from the UAV's own stream: with the heading as tie-break,
        # UAVs flying side by side all picked the same sub-area and flew on in formation.
        tie_key = rng.random(9)
        guide = self.guide_point(q, coarse.shape, g.cell_m, view.x, view.y, view.theta, tie_key=tie_key)
        r_min = k.r_min(view.v)
        unit = self.field_unit_m
        floor = g.cell_m / unit
        v_i = k.speed_max / unit

        threats = list(view.knowledge.threats.values())
        targets: list[tuple[int, float, float, float]] = []
        peers: list[tuple[float, float, float]] = []
        if view.surveillance:
            for tid, tr in sorted(view.knowledge.tracks.items()):
                tx, ty = tr.predict(t)
                if math.hypot(tx - view.x, ty - view.y) < k.influence_radius + 2 * R:
                    targets.append((tid, tx, ty, tr.value))
            if targets:
                for p in view.knowledge.recent_peers(t, _INTENT_MAX_AGE_S):
                    if p.uav != view.uav and math.isfinite(p.wx) and t - p.t_intent <= _INTENT_MAX_AGE_S:
                        vmax_j = self.speed_max_by_type.get(p.type, k.speed_max)
                        peers.append((p.wx, p.wy, vmax_j / unit))
        D = k.influence_radius

        def fitness(px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            ix, iy = g.cells_of(px, py)
            p_sum = np.zeros(px.shape)
            for w_l, (lv, G) in zip(lam, search_levels):
                rows = np.minimum(level_index(iy, lv), G.shape[0] - 1)
                cols = np.minimum(level_index(ix, lv), G.shape[1] - 1)
                p_sum += w_l * G[rows, cols]
            dub = dubins_length(view.x, view.y, view.theta, px, py, r_min)
            f_sl = p_sum / (1.0 + ((dub - R) / R) ** 2)
            if guide is not None:
                ax, ay = guide[0] - view.x, guide[1] - view.y
                bx, by = px - view.x, py - view.y
                cosang = (ax * bx + ay * by) / np.maximum(np.hypot(ax, ay) * np.hypot(bx, by), 1e-9)
                ang = np.arccos(np.clip(cosang, -1.0, 1.0))
                f_sg = 1.0 / (1.0 + np.exp(ang / math.pi))
            else:
                f_sg = np.full(px.shape, 0.5)
            f_s = self.eta * f_sl + (1.0 - self.eta) * f_sg
            f_t = np.zeros(px.shape)
            for _tid, tx, ty, value in targets:
                d = np.hypot(px - tx, py - ty)
                near = d < D
                if not near.any():
                    continue
                f_t += np.where(near, k.w_t * value / (np.maximum(d / unit, floor) * v_i * v_i), 0.0)
                for wx, wy, v_j in peers:
                    if math.hypot(wx - tx, wy - ty) < D:
                        dj = np.maximum(np.hypot(px - wx, py - wy) / unit, floor)
                        f_t -= np.where(near, k.w_r / (dj * v_i * v_j), 0.0)
            ok = (px >= 0) & (px <= g.width_m) & (py >= 0) & (py <= g.height_m)
            for th in threats:
                ok &= np.hypot(px - th.x, py - th.y) > th.radius + self.threat_margin_m
            f = np.where(ok, f_s + f_t, -np.inf)
            return f, f_s, f_t

        # Particles in the ring outside the detection radius (section 3.1).
        M = self.particles
        radius = rng.normal(self.ring_mean_factor * R, self.ring_sd_factor * R, M)
        angle = view.theta + rng.normal(0.0, self.heading_sd_rad, M)
        r_max = self.ring_max_factor * R
        zx, zy = self._keep_near(view, view.x + np.abs(radius) * np.cos(angle),
                                 view.y + np.abs(radius) * np.sin(angle), r_max, g)
        vx = np.zeros(M)
        vy = np.zeros(M)
        f, _, _ = fitness(zx, zy)
        bx, by, bf = zx.copy(), zy.copy(), f.copy()
        gi = int(np.argmax(bf))
        n_it = self.iterations
        for it in range(n_it):
            frac = it / (n_it - 1) if n_it > 1 else 1.0
            w = self.w_start + (self.w_end - self.w_start) * frac
            c1 = self.c1_start + (self.c1_end - self.c1_start) * frac
            c2 = self.c2_start + (self.c2_end - self.c2_start) * frac
            r = rng.random((3, M))
            gx, gy = bx[gi], by[gi]
            vx = w * vx + c1 * r[0] * (bx - zx) + c2 * r[1] * (gx - zx)
            vy = w * vy + c1 * r[0] * (by - zy) + c2 * r[1] * (gy - zy)
            zx, zy = self._keep_near(view, zx + vx * r[2], zy + vy * r[2], r_max, g)  # eq. 15: z += dz * Q
            f, _, _ = fitness(zx, zy)
            better = f > bf
            bx[better], by[better], bf[better] = zx[better], zy[better], f[better]
            gi = int(np.argmax(bf))
        wx, wy = float(bx[gi]), float(by[gi])
        if not np.isfinite(bf[gi]):
            # Nothing feasible (boxed in by threats or the border): head for the area centre.
            return Plan(g.width_m / 2, g.height_m / 2)
        _, f_s, f_t = fitness(np.array([wx]), np.array([wy]))
        mode, target = MODE_SEARCH, NO_TARGET
        if targets and f_t[0] > f_s[0]:
            d_best = D
            for tid, tx, ty, _v in targets:
                d = math.hypot(wx - tx, wy - ty)
                if d < d_best:
                    mode, target, d_best = MODE_SURVEIL, tid, d
        return Plan(wx, wy, mode, target)

