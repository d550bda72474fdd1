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
    counts the layers *above* the map ``G_0``: the sum starts at ``l = 1`` and the seventh layer
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
from agents.pyramid import gaussian_pyramid, level_index, sample_levels
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
            ring_mean_factor=d.ring_mean_factor, ring_sd_factor=d.ring_sd_factor,
            heading_sd_rad=d.heading_sd_rad, eta=d.eta, levels=levels,
            level_weights=tuple(d.level_weights) if d.level_weights is not None else None,
            field_unit_m=d.field_unit_m, threat_margin_m=d.threat_margin_m,
            speed_max_by_type=dict(speed_max_by_type or {}),
        )

    # --- pieces of the fitness --------------------------------------------------------------

    def _weights(self, n: int) -> np.ndarray:
        """lambda_1..lambda_n of eq. 19 (n can be < L when the map is small), summing to 1."""
        if self.level_weights is None:
            return np.full(n, 1.0 / n)
        w = np.asarray(self.level_weights[:n], dtype=np.float64)
        total = w.sum()
        return w / total if total > 0 else np.full(n, 1.0 / n)

    @staticmethod
    def guide_point(pyramid: list[np.ndarray], cell_m: float, x: float, y: float, theta: float,
                    width: float, height: float, tie_tol: float = 0.02) -> tuple[float, float] | None:
        """Centre of the most uncertain region adjacent to the UAV's, on the coarsest level >= 4x4.

        Regions within ``tie_tol`` (2%) of the best count as tied (early on, everything unseen is ~1);
        among them the one closest to the UAV's heading wins. A fixed scan order would send every
        UAV the same way (south-west) whenever the map is uniform.
        """
        level = None
        for lv in range(len(pyramid) - 1, -1, -1):
            if min(pyramid[lv].shape) >= 4:
                level = lv
                break
        if level is None:
            return None
        g = pyramid[level]
        # Region a of this level is centred on level-0 cell a * 2**level (see level_index).
        ry = min(level_index(max(int(y // cell_m), 0), level), g.shape[0] - 1)
        rx = min(level_index(max(int(x // cell_m), 0), level), g.shape[1] - 1)
        cands = []
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                yy, xx = ry + dy, rx + dx
                if (dx or dy) and 0 <= yy < g.shape[0] and 0 <= xx < g.shape[1]:
                    cx = min(((xx << level) + 0.5) * cell_m, width)
                    cy = min(((yy << level) + 0.5) * cell_m, height)
                    turn = abs(math.remainder(math.atan2(cy - y, cx - x) - theta, 2 * math.pi))
                    cands.append((float(g[yy, xx]), turn, cx, cy))
        if not cands:
            return None
        best = max(c[0] for c in cands)
        _, _, cx, cy = min((c for c in cands if c[0] >= best - tie_tol), key=lambda c: c[1])
        return cx, cy

    def plan(self, view: PlanView) -> Plan:
        k = view.kind
        g = view.grid
        rng = view.rng
        R = k.detect_radius
        t = view.t
        q = view.umap.uncertainty(t)
        pyr = gaussian_pyramid(q, self.levels + 1)  # G_0 .. G_L
        lam = self._weights(max(len(pyr) - 1, 1))
        guide = self.guide_point(pyr, g.cell_m, view.x, view.y, view.theta, g.width_m, g.height_m)
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
            # Levels 1..L (eq. 19); a map too small to have level 1 falls back on G_0.
            upper = pyr[1:] or pyr[:1]
            p_sum = lam @ sample_levels(upper, ix, iy) if len(pyr) > 1 else lam[0] * sample_levels(pyr, ix, iy)[0]
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
        zx = np.clip(view.x + np.abs(radius) * np.cos(angle), 0.0, g.width_m)
        zy = np.clip(view.y + np.abs(radius) * np.sin(angle), 0.0, g.height_m)
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
            zx = np.clip(zx + vx * r[2], 0.0, g.width_m)  # eq. 15: z += dz * Q
            zy = np.clip(zy + vy * r[2], 0.0, g.height_m)
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

