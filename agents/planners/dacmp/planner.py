"""The DACMP planner (paper section 3; DACMP-SPEC.md "The planner").

Each replanning, a UAV runs a particle swarm over candidate waypoints:

* particles start in the ring just outside its detection radius (radius ~ N(1.5 R_s, 0.5 R_s),
  angle ~ N(heading, pi/2)), clipped to the area;
* PSO with inertia ``w`` and coefficients ``c1, c2`` changing linearly over the iterations and a
  random factor ``Q ~ U(0, 1)`` on each position increment (eq. 15);
* fitness ``f = f_S + f_t`` (eq. 16):

  - ``f_Sl = sum_{l=1..L} lambda_l P_l(k) / (1 + ((Dub(k) - R_s) / R_s)^2)`` (eq. 19), ``P_l``
    the Gaussian pyramid level ``l`` at the particle's cell, ``Dub`` the shortest Dubins path
    with free final heading (:mod:`agents.planners.dacmp.dubins`). As in the paper, ``L`` (``map.levels``, 7)
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

The UAV is in surveillance mode when, at the chosen waypoint, a target term dominates: the
target within ``D_i`` whose own pull there (its eq. 22 term less the eq. 23 terms of the UAVs
standing at it) is the strongest and above ``f_S`` is the one it watches.
With ``surveillance = false`` (paper-fig11) targets exert no pull: search only.
"""

from __future__ import annotations

import bisect
import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Protocol, cast

import numpy as np

from agents.knowledge import Knowledge, KnownThreat, Track
from agents.maps.grid import Grid
from agents.maps.mapgroup import GroupMap
from agents.maps.umap import UncertaintyMap
from agents.planners.base import Plan, PlanView
from agents.planners.dacmp.dubins import DubinsPoses
from agents.planners.dacmp.maintained import MaintainedPyramid
from agents.planners.dacmp.pyramid import Scratch, level_index, level_shapes
from agents.planners.dacmp.settings import DacmpSettings
from comms.messages import MODE_SEARCH, MODE_SURVEIL, NO_TARGET

if TYPE_CHECKING:
    from agents.planners.base import PlannerContext

# Peers whose intent is older than this are ignored for the competing repulsion.
_INTENT_MAX_AGE_S = 15.0


class PlannerTable(Protocol):
    """A scenario's ``[planner]`` table as :meth:`DacmpPlanner.from_settings` reads it: its
    ``dacmp`` table, with the fields of :class:`DacmpSettings` (arrays as lists)."""

    @property
    def dacmp(self) -> object: ...


@dataclass(frozen=True)
class DacmpPlanner(DacmpSettings):
    """The planner: its settings (:class:`DacmpSettings`, keyword arguments) and what the run
    tells it about the map and the other UAV types."""

    levels: int = 7
    # Other UAVs' top speeds by type name (v_j of eq. 23); unknown types count as our own.
    speed_max_by_type: dict[str, float] = field(default_factory=dict)
    # Other UAVs' detection radii by type name (how far their next waypoint goes); unknown: ours.
    detect_radius_by_type: dict[str, float] = field(default_factory=dict)
    name: str = "dacmp"
    # Work arrays reused from one replanning to the next (not a setting: not compared or shown).
    scratch: Scratch = field(default_factory=Scratch, init=False, repr=False, compare=False)

    @classmethod
    def from_context(cls, context: PlannerContext) -> DacmpPlanner:
        """The planner of a scenario: its settings are the ``[planner.dacmp]`` table."""
        return cls.from_settings(context.settings, context.levels, context.speed_max_by_type,
                                 context.detect_radius_by_type)

    @classmethod
    def from_settings(cls, planner_settings: PlannerTable, levels: int = 7,
                      speed_max_by_type: dict[str, float] | None = None,
                      detect_radius_by_type: dict[str, float] | None = None) -> DacmpPlanner:
        """The planner of a scenario's ``[planner]`` table: its ``dacmp`` table has the fields of
        :class:`DacmpSettings` (arrays as lists)."""
        d = planner_settings.dacmp
        settings = {f.name: getattr(d, f.name) for f in fields(DacmpSettings)}
        if settings["level_weights"] is not None:
            settings["level_weights"] = tuple(settings["level_weights"])
        return cls(
            **settings, levels=levels,
            speed_max_by_type=dict(speed_max_by_type or {}),
            detect_radius_by_type=dict(detect_radius_by_type or {}),
        )

    # --- pieces of the fitness --------------------------------------------------------------

    def search_weights(self, n: int) -> np.ndarray:
        """lambda_1..lambda_n of eq. 19 (n < L when the map is too small for L layers)."""
        if self.level_weights is None:
            return np.full(n, 1.0 / n)
        w = np.asarray(self.level_weights[:n], dtype=np.float64)
        weights: np.ndarray = w / w.sum()
        return weights

    @staticmethod
    def guide_point(q: np.ndarray, regions: tuple[int, int], cell_m: float, x: float, y: float,
                    theta: float, tie_tol: float = 0.0, tie_key: np.ndarray | None = None) -> tuple[float, float] | None:
        """Centre of the most uncertain of the (up to 8) sub-areas adjacent to the UAV's (eq. 20).

        The paper's coarsest layer "divides the map into 4 x 4 sub-areas": ``regions`` is that
        layer's shape, and each sub-area's uncertainty is the mean of ``q`` over its block of
        cells. Blocks, not the layer's own samples: REDUCE centres coarse sample ``a`` on cell
        ``2**L a``, so the samples of a 4 x 4 layer sit at 0, 12.8, 25.6 and 38.4 km on a 50 km
        map and no guide point would ever lie in the eastern or northern strip.
        The most uncertain one, as the paper says; sub-areas within ``tie_tol`` of the best count
        as tied (default 0: exact ties only, such as sub-areas nobody has seen, whose mean is
        exactly 1). Among tied ones, with ``tie_key`` (one number per neighbour, row by row) the
        smallest key wins; without it, the one closest to the UAV's heading. (A 2% tolerance
        used before picked a less uncertain sub-area in 13% of plans on paper-fig11.)
        """
        ny, nx = regions
        h, w = q.shape
        if ny < 2 and nx < 2:
            return None
        rows, cols = _sub_areas(h, w, ny, nx)
        ry, y0, y1 = _neighbour_blocks(rows, ny, y / cell_m)
        rx, x0, x1 = _neighbour_blocks(cols, nx, x / cell_m)
        # Only the UAV's sub-area and its neighbours are read (rows y0..y1-1, columns x0..x1-1
        # of sub-areas). Row blocks summed one by one (row after row, like
        # add.reduceat along axis 0 but about twice as fast: no buffered casting), then the few
        # columns; each sum is the one a sum over the whole map would give.
        c0, c1 = cols[x0], cols[x1]
        strips = np.stack([q[rows[i] : rows[i + 1], c0:c1].sum(axis=0, dtype=np.float64) for i in range(y0, y1)])
        sums = np.add.reduceat(strips, [c - c0 for c in cols[x0:x1]], axis=1)
        sizes = np.outer(np.diff(rows[y0 : y1 + 1]), np.diff(cols[x0 : x1 + 1]))
        means = np.zeros((ny, nx))
        means[y0:y1, x0:x1] = sums / sizes
        return DacmpPlanner.pick_guide(means, rows, cols, cell_m, x, y, theta, tie_tol, tie_key)

    @staticmethod
    def pick_guide(means: np.ndarray, rows: tuple[int, ...], cols: tuple[int, ...], cell_m: float, x: float, y: float,
                   theta: float, tie_tol: float = 0.0, tie_key: np.ndarray | None = None) -> tuple[float, float] | None:
        """The choice of :meth:`guide_point` from the sub-areas' mean ``q`` (``means``, ``(ny,
        nx)``; only the UAV's sub-area's neighbours are read) and their row and column edges in
        cells."""
        ny, nx = means.shape
        if ny < 2 and nx < 2:
            return None
        ry, _, _ = _neighbour_blocks(rows, ny, y / cell_m)
        rx, _, _ = _neighbour_blocks(cols, nx, x / cell_m)
        cands = []
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                yy, xx = ry + dy, rx + dx
                if (dx or dy) and 0 <= yy < ny and 0 <= xx < nx:
                    cx = 0.5 * (cols[xx] + cols[xx + 1]) * cell_m
                    cy = 0.5 * (rows[yy] + rows[yy + 1]) * cell_m
                    if tie_key is None:  # the turn towards the sub-area's centre
                        key = abs(math.remainder(math.atan2(cy - y, cx - x) - theta, 2 * math.pi))
                    else:
                        key = float(tie_key[(dy + 1) * 3 + dx + 1])
                    cands.append((float(means[yy, xx]), key, cx, cy))
        if not cands:
            return None
        best = max(c[0] for c in cands)
        _, _, cx, cy = min((c for c in cands if c[0] >= best - tie_tol), key=lambda c: c[1])
        return cx, cy

    def rivals(self, view: PlanView, targets: list[tuple[int, float, float, float]],
               D: float) -> list[tuple[float, float, float, tuple[int, ...], int]]:
        """The other UAVs of eq. 23, each once, as ``(x_j(t+1), y_j(t+1), v_j,max, scope, at)``
        in (m, m, field units / s, indices into ``targets``): ``scope`` lists the targets in
        whose scope ``j`` is (UAVs in none are left out); ``at`` is the target whose ``g_m``
        stands for ``x_j(t+1)`` (below), -1 if none.

        Eq. 23 is one sum over the other UAVs ``j``, each counted when it and the particle are
        "both in the scope of [a] target": a UAV near two known targets repels a particle near
        both once, not once per target (counted per target, a watcher of one target pushed a
        slow UAV off the next target it was taking over, or off its own). A UAV in search mode is
        in the scope of every target within ``D`` of ``x_j(t+1)`` that no UAV watches (as far as
        we know: our claim and the intents we heard); one in surveillance mode is in
        the scope of its own target only (if within ``D`` of it), and of none when that target is
        not among ``targets``: it is not competing for the others, and counted near them it kept
        a slow UAV at the edge of ``D`` from taking over a target whose fast watcher had a slow
        UAV watching another target 5 km away (paper-case2, seed 10), against eq. 25's outcome.

        ``x_j(t+1)`` is ``j``'s announced next waypoint. A UAV in surveillance mode of ``m``
        within one planning step of it (``ring_max_factor`` times its detection radius: the
        farthest a waypoint goes) announces the target itself (see ``keep``); we put that
        waypoint at our own estimate of ``g_m``. Then ``d(k, x_j) = d(k, g_m)`` and eq. 22-23
        compare only weights and speeds, which is what the paper's assignment rules (eq. 25-27)
        assume. With the announced coordinates, the 50-200 m between its estimate of the target
        and ours (track age, one-cell floor on distances) decided who keeps the target (Table 1's
        ``w_t / w_r`` differ by 2-5%), and two UAVs of one type ended up watching one target for
        minutes.

        Two UAVs of one type that both claim ``m`` (surveillance mode of ``m``) repel each other
        equally (eq. 27), so both would let go; the nearer one keeps it ("the nearest UAV could
        prioritize its own surveillance relationship", paper, Case 1): while we claim ``m``
        ourselves, a same-type rival claiming ``m`` from farther away is ignored, and one from
        nearer counts as at ``g_m`` wherever it is, so the farther of two claimants yields at
        once instead of flying on until the nearer one is one planning step from the target.
        """
        out: list[tuple[float, float, float, tuple[int, ...], int]] = []
        if not targets:
            return out
        k = view.kind
        t = view.t
        unit = self.field_unit_m
        mine = view.plan
        claim = mine.target if mine is not None and mine.mode == MODE_SURVEIL else NO_TARGET
        peers = [p for p in view.knowledge.recent_peers(t, _INTENT_MAX_AGE_S)
                 if p.uav != view.uav and math.isfinite(p.wx) and t - p.t_intent <= _INTENT_MAX_AGE_S]
        watched = {claim} | {p.target for p in peers if p.mode == MODE_SURVEIL}
        for p in peers:
            v_j = self.speed_max_by_type.get(p.type, k.speed_max) / unit
            r_j = self.detect_radius_by_type.get(p.type, k.detect_radius)
            wx, wy, at = p.wx, p.wy, -1
            if p.mode == MODE_SURVEIL:
                claimed = [(i, tx, ty) for i, (tid, tx, ty, _v) in enumerate(targets) if tid == p.target]
                if not claimed:
                    continue  # it watches a target we do not weigh
                i, tx, ty = claimed[0]
                d_j = math.hypot(p.x - tx, p.y - ty)
                rival = claim == p.target and p.type == k.name
                if rival and (d_j, p.uav) > (math.hypot(view.x - tx, view.y - ty), view.uav):
                    continue  # a same-type rival farther away: we keep the target
                # A slower UAV coming to take over the target we watch stands at it once it has
                # had the target in sight (inside its detection radius), not a planning step
                # before: until then we keep it (docs/modelling.md, "Assignment rules", rule
                # 3). Let go at one planning step, a fast watcher left a target its slow relief
                # had not yet found (paper-case2 seeds 7 and 8: 40-50 s unwatched). Its pose is
                # as heard, up to a beacon or two old: the target may have moved that long since,
                # so the radius is shrunk by that much (then it did have it in sight, then). A
                # target nobody has seen for a replanning period (kept at a no-fly zone: rule
                # 5) is in nobody's sight: we keep it.
                reach = self.ring_max_factor * r_j
                if claim == p.target and v_j < k.speed_max / unit:
                    tr = view.knowledge.tracks.get(p.target)
                    if tr is None or t - tr.t > view.replan_s:
                        reach = -1.0
                    else:
                        reach = r_j - math.hypot(tr.vx, tr.vy) * max(t - p.t_pose, 0.0)
                if rival or d_j <= reach:
                    wx, wy, at = tx, ty, i  # its next waypoint is the target
                scope: tuple[int, ...] = (i,) if math.hypot(wx - tx, wy - ty) < D else ()
            else:
                # A searching UAV competes for the free targets near its next waypoint only: one
                # that passes a target another UAV watches is not after it (counted there, a fast
                # searcher passing within D kept a slow UAV from taking a target over from a
                # fast watcher: eq. 25 weighs one watcher's repulsion, not two).
                scope = tuple(i for i, (tid, tx, ty, _v) in enumerate(targets)
                              if tid not in watched and math.hypot(wx - tx, wy - ty) < D)
            if scope:
                out.append((wx, wy, v_j, scope, at))
        return out

    def crowding(self, uavs: list[UavSearch], points: int) -> Callable[[np.ndarray], np.ndarray] | None:
        """A factor on eq. 19's ``f_Sl`` at the points ``z`` of these UAVs (``(2, UAVs, points)``
        to ``(UAVs, points)``), or None. The paper's DACMP has none; variants beyond the paper
        do (:mod:`agents.planners.dacmp.spread`)."""
        return None

    def planning_pyramid(self, umap: UncertaintyMap) -> MaintainedPyramid:
        """The maintained pyramid a UAV with map ``umap`` plans on (``member_map``): its own
        map's, or with ``member_map = "base"`` and ``umap`` a member of a map group, the group
        base's (the scans every member has; one pyramid for the whole group)."""
        if self.member_map == "base" and isinstance(umap, GroupMap) and umap.extra_disks() is not None:
            umap = umap.base
        return MaintainedPyramid.of(umap, self.levels)

    def refresh(self, pyramids: list[MaintainedPyramid], ts: list[float]) -> None:
        """Bring the pyramids the UAVs of a plan read (:meth:`planning_pyramid`; each at its
        plan's ``t``) to their plans' times: up to date with their maps in one
        :meth:`MaintainedPyramid.update_many` (a pyramid several UAVs read, once), except, with
        ``map_refresh_s``, those updated less than that long ago, which are only aged
        (:meth:`MaintainedPyramid.age`)."""
        due: list[MaintainedPyramid] = []
        due_ts: list[float] = []
        seen: dict[int, float] = {}
        for p, t in zip(pyramids, ts):
            if p.refreshed is not None and t - p.refreshed < self.map_refresh_s and p.age(t) is not None:
                continue
            if seen.get(id(p)) != t:  # (a pyramid at two times: update_many does them in turn)
                seen[id(p)] = t
                due.append(p)
                due_ts.append(t)
        if due:
            MaintainedPyramid.update_many(due, due_ts)

    def plan(self, view: PlanView) -> Plan:
        return self.plan_many([view])[0]

    def plan_many(self, views: list[PlanView]) -> list[Plan]:
        """Plans for several UAVs at once: exactly ``[plan(v) for v in views]``.

        Each UAV keeps its own map, pyramid, guide point, targets, rivals, threats and random
        stream (its draws are made from its own generator, in the order the one-UAV algorithm
        makes them); only array operations are shared: the PSO's, on arrays of shape
        ``(2, UAVs, particles)``, and the pyramid steps of the smaller levels (:class:`Layers`).
        Numpy's element-wise operations give each element the same value whatever array it sits
        in, and each pyramid row is the same BLAS call, so a UAV's decision does not depend on
        its batch (``tests/test_batching.py`` checks plans and event logs).

        Mode switching for a UAV already in surveillance mode comes first: it keeps its target
        ``m`` while its own term still dominates on the target itself (its own pull above
        ``f_S`` at ``g_m``), with ``g_m`` (pulled to within ``r_max``) as its next waypoint, and makes no
        PSO draws. It lets go when a rival's claim makes the term negative there (eq. 23, see
        :meth:`rivals`) or when the track is too old to attract. Without this, two targets a
        few kilometres apart are two equal peaks of the ``1/d`` attraction (both saturate at
        the one-cell floor) and PSO picks one at random each replanning: the UAV switched target
        every 10 s and watched neither.
        """
        if type(self).plan is not DacmpPlanner.plan:  # a subclass with its own plan(): honour it
            return [self.plan(v) for v in views]
        g = views[0].grid
        uavs = [UavSearch.build(self, v, slot) for slot, v in enumerate(views)]
        layers = Layers(self, uavs)  # (sets every UAV's guide point)
        plans: list[Plan | None] = [None] * len(uavs)
        for i, u in enumerate(uavs):
            plans[i] = self.keep(u, g, layers)
        search = [i for i, p in enumerate(plans) if p is None]
        for i in search:
            uavs[i].draw(self)
        if search:
            for i, plan in zip(search, self._pso([uavs[i] for i in search], g, layers)):
                plans[i] = plan
        return cast("list[Plan]", plans)  # every None (a UAV to plan afresh) got its PSO plan

    def keep(self, u: UavSearch, g: Grid, layers: Layers) -> Plan | None:
        """The surveillance-mode rule of :meth:`plan_many` for one UAV (None: plan afresh)."""
        mine = u.view.plan
        if mine is None or mine.mode != MODE_SURVEIL:
            return None
        for i, (tid, tx, ty, _v) in enumerate(u.targets):
            if tid == mine.target:
                z = np.array([[[tx]], [[ty]]])
                batch = Batch(self, [u], g, layers, 1)
                _, f_s, _ = batch.fitness(z)
                # This target's own term, not the whole f_t there: another target within D of
                # g_m adds its pull to f_t at g_m, and a UAV whose own target was kept by a
                # nearer UAV of its type went on claiming it, drawn by the free one beside it.
                if u.own_pull(i, tx, ty, self.field_unit_m, g.cell_m / self.field_unit_m) > f_s[0, 0]:
                    wx, wy = batch.keep_near(z)[:, 0, 0]
                    return Plan(float(wx), float(wy), MODE_SURVEIL, tid)
                return None
        return None

    def _pso(self, uavs: list[UavSearch], g: Grid, layers: Layers) -> list[Plan]:
        """Particle swarms of several UAVs in lockstep (their draws made by :meth:`UavSearch.draw`)."""
        U, M, n_it = len(uavs), self.particles, self.iterations
        batch = Batch(self, uavs, g, layers, M)
        fitness, keep_near = batch.fitness, batch.keep_near
        rows = np.arange(U)
        # Positions and velocities as (axis, UAV, particle): x and y rows share every operation.
        # Particles in the ring outside the detection radius (section 3.1). Every UAV here has
        # made its draws (UavSearch.draw), so none of these arrays is None.
        radius = np.abs(np.stack(cast("list[np.ndarray]", [u.ring_radius for u in uavs])))
        angle = np.stack(cast("list[np.ndarray]", [u.ring_angle for u in uavs]))
        z = keep_near(batch.p0 + radius * np.stack([np.cos(angle), np.sin(angle)]))
        v = np.zeros((2, U, M))
        f, _, _ = fitness(z, kept=True)
        best_z, bf = z.copy(), f.copy()
        gi = np.argmax(bf, axis=1)
        # (iteration, r1/r2/Q, axis, UAV, particle): the draws repeated for the x and y rows.
        draws = np.repeat(np.stack(cast("list[np.ndarray]", [u.pso_draws for u in uavs]), axis=2)[:, :, None], 2, axis=2)
        # The coefficients of every iteration, and c1 * r1, c2 * r2 for all of them in one go
        # (the same products as one iteration at a time).
        fracs = [it / (n_it - 1) if n_it > 1 else 1.0 for it in range(n_it)]
        ws = [self.w_start + (self.w_end - self.w_start) * frac for frac in fracs]
        c1s = np.array([self.c1_start + (self.c1_end - self.c1_start) * frac for frac in fracs])
        c2s = np.array([self.c2_start + (self.c2_end - self.c2_start) * frac for frac in fracs])
        c1r0 = c1s[:, None, None, None] * draws[:, 0]
        c2r1 = c2s[:, None, None, None] * draws[:, 1]
        for it in range(n_it):
            g_best = best_z[:, rows, gi][:, :, None]
            # v = w v + c1 r1 (best - z) + c2 r2 (g_best - z), in place, in that order.
            v *= ws[it]
            step = best_z - z
            step *= c1r0[it]
            v += step
            np.subtract(g_best, z, out=step)
            step *= c2r1[it]
            v += step
            np.multiply(v, draws[it, 2], out=step)
            step += z
            z = keep_near(step)  # eq. 15: z += dz * Q
            f, _, _ = fitness(z, kept=True)
            better = f > bf
            np.copyto(best_z, z, where=better)
            np.copyto(bf, f, where=better)
            gi = bf.argmax(axis=1)
        wz, best = best_z[:, rows, gi][:, :, None], bf[rows, gi]
        _, f_s, _ = fitness(np.repeat(wz, M, axis=2), kept=True)  # (the batch's shape: M copies)
        plans = []
        for i, u in enumerate(uavs):
            if not np.isfinite(best[i]):
                # Nothing feasible (boxed in by threats or the border): head for the area centre.
                plans.append(Plan(g.width_m / 2, g.height_m / 2))
            else:
                plans.append(u.decide(float(wz[0, i, 0]), float(wz[1, i, 0]), f_s[i, 0],
                                      self.field_unit_m, g.cell_m / self.field_unit_m))
        return plans


class Batch:
    """The fitness (eq. 16) and the particle bound of several UAVs, on ``(2, UAVs, points)``
    arrays of positions (x row, then y row), ``points`` per UAV.

    Per-UAV values are stored repeated for each point: numpy is several times faster on
    same-shape operands than when it has to broadcast a column, and the numbers are the same.
    """

    def __init__(self, planner: DacmpPlanner, uavs: list[UavSearch], grid: Grid, layers: Layers, points: int):
        self.planner, self.uavs, self.grid, self.layers = planner, uavs, grid, layers
        shape = (len(uavs), points)

        def column(values: Sequence[float]) -> np.ndarray:
            return np.repeat(np.array(values, dtype=np.float64)[:, None], points, axis=1)

        self.p0 = np.stack([column([u.view.x for u in uavs]), column([u.view.y for u in uavs])])
        self.area = np.stack([np.full(shape, grid.width_m), np.full(shape, grid.height_m)])
        self.R = column([u.R for u in uavs])
        self.r_max = column([u.r_max for u in uavs])
        self.layer_base, self.layer_weights, self.layer_scale = layers.operands([u.slot for u in uavs], points)
        self.guided = [i for i, u in enumerate(uavs) if u.guide is not None]
        gax = column([u.guide[0] - u.view.x if u.guide is not None else 0.0 for u in uavs])
        gay = column([u.guide[1] - u.view.y if u.guide is not None else 0.0 for u in uavs])
        self.guide_dir = np.stack([gax, gay])
        self.g_norm = np.hypot(gax, gay)
        self.has_guide = column([u.guide is not None for u in uavs]) > 0.5
        self.with_targets = [(i, u) for i, u in enumerate(uavs) if u.targets]
        self.with_threats = [(i, u) for i, u in enumerate(uavs) if u.threats]
        self.dubins = DubinsPoses(np.array([u.view.theta for u in uavs]), column([u.r_min for u in uavs]), shape=shape)
        self.no_targets = np.zeros(shape)  # f_t where no UAV has a target term
        self.no_targets.flags.writeable = False
        self.crowding = planner.crowding(uavs, points)  # None for DACMP itself

    def fitness(self, z: np.ndarray, kept: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(f, f_S, f_t)`` at the points ``z`` (``z[:, i]``: UAV ``i``'s ``points`` points).
        ``kept``: the points come from :meth:`keep_near`, so they lie inside the area.

        The temporaries are updated in place: the same operations on each element, in the same
        order, as the formulas in the comments (``tests/test_plan_speed.py`` compares the bytes
        with them written out)."""
        planner, g = self.planner, self.grid
        # Each point's cell, as Grid.cells_of (its clip to the grid is in level_sum's gathers).
        cells = (z // g.cell_m).astype(np.int64)
        p_sum = self.layers.level_sum(self.layer_base, self.layer_weights, self.layer_scale, cells[0], cells[1])
        d = z - self.p0  # from the UAV
        # f_Sl = p_sum / (1 + ((Dub - R) / R) ** 2), on Dub's own (fresh) array.
        f_sl = self.dubins.lengths(d)
        f_sl -= self.R
        f_sl /= self.R
        np.square(f_sl, out=f_sl)
        f_sl += 1.0
        np.divide(p_sum, f_sl, out=f_sl)
        if self.crowding is not None:
            f_sl *= self.crowding(z)
        eta = planner.eta
        f_s = np.multiply(f_sl, eta, out=f_sl)  # eta f_Sl + (1 - eta) f_Sg: this term first
        if self.guided:
            # cos = (g . d) / max(|g| |d|, 1e-9), clipped to [-1, 1]; f_Sg = 1 / (1 + exp(acos / pi)).
            dot = self.guide_dir * d
            cosang = np.add(dot[0], dot[1], out=dot[0])
            norm = np.hypot(d[0], d[1])
            np.multiply(self.g_norm, norm, out=norm)
            np.maximum(norm, 1e-9, out=norm)
            cosang /= norm
            np.maximum(cosang, -1.0, out=cosang)
            np.minimum(cosang, 1.0, out=cosang)
            f_sg = np.arccos(cosang, out=cosang)
            f_sg /= math.pi
            np.exp(f_sg, out=f_sg)
            f_sg += 1.0
            np.divide(1.0, f_sg, out=f_sg)
            if len(self.guided) < len(self.uavs):
                f_sg = np.where(self.has_guide, f_sg, 0.5)
            f_sg *= 1.0 - eta
            f_s += f_sg
        else:
            f_s += (1.0 - eta) * 0.5  # f_Sg = 0.5 everywhere (the same double product)
        if kept and not self.with_targets and not self.with_threats:
            # Nothing to add and every point feasible: f = f_S (f_S > 0, so f_S + 0.0 is f_S).
            return f_s, f_s, self.no_targets
        f_t = np.zeros(p_sum.shape)
        inside = (z >= 0) & (z <= self.area)
        ok = inside[0] & inside[1]
        px, py = z[0], z[1]
        unit = planner.field_unit_m
        floor = g.cell_m / unit
        for i, u in self.with_targets:
            u.target_terms(px[i], py[i], f_t[i], unit, floor)
        for i, u in self.with_threats:
            for th in u.threats:
                ok[i] &= np.hypot(px[i] - th.x, py[i] - th.y) > th.radius + planner.threat_margin_m
        f = np.where(ok, f_s + f_t, -np.inf)
        return f, f_s, f_t

    def keep_near(self, z: np.ndarray) -> np.ndarray:
        """Pull points back to within ``r_max`` of their UAV, then into the area.

        A particle is a candidate *next* waypoint (``x_j(t+1)`` in eq. 23, which other UAVs read
        from the broadcast intent). Left free, PSO carries particles all the way to a target
        10 km off; the announced waypoint would then claim the target long before the UAV
        arrives, and a fast watcher would hand over to a slow UAV still minutes away.
        """
        d = z - self.p0
        dist = np.hypot(d[0], d[1])
        # p0 + d * scale, scale = r_max / max(dist, 1e-9) where dist > r_max, else 1 (and
        # d * 1 is d: no product where no point is beyond r_max).
        far = dist > self.r_max
        if far.any():
            np.maximum(dist, 1e-9, out=dist)
            scale = np.divide(self.r_max, dist, out=dist)
            np.copyto(scale, 1.0, where=np.logical_not(far, out=far))
            d *= scale
        kept: np.ndarray = d
        kept += self.p0
        # = np.clip(kept, 0.0, self.area), without its Python-level overhead.
        np.maximum(kept, 0.0, out=kept)
        np.minimum(kept, self.area, out=kept)
        return kept


@dataclass
class UavSearch:
    """One UAV's share of a (batched) DACMP plan: everything that is its own."""

    view: PlanView
    R: float
    r_max: float
    r_min: float
    D: float
    v_i: float
    slot: int  # the UAV's index in the Layers of the plan_many call (its map's pyramid)
    targets: list[tuple[int, float, float, float]]
    rivals: list[tuple[float, float, float, tuple[int, ...], int]]  # DacmpPlanner.rivals
    threats: list[KnownThreat]
    guide: tuple[float, float] | None = None  # set by Layers
    ring_radius: np.ndarray | None = None  # draw(): only a UAV that runs PSO draws these
    ring_angle: np.ndarray | None = None
    pso_draws: np.ndarray | None = None  # (iterations, 3, particles): r1, r2 and Q of eq. 15

    @classmethod
    def build(cls, planner: DacmpPlanner, view: PlanView, slot: int) -> UavSearch:
        """Everything but the map work (done for the whole batch by :class:`Layers`)."""
        k = view.kind
        R = k.detect_radius
        t = view.t
        r_max = planner.ring_max_factor * R
        targets: list[tuple[int, float, float, float]] = []
        max_age = planner.track_max_age_s if planner.track_max_age_s is not None else 1.0 / view.umap.tau
        if view.surveillance:
            mine = view.plan
            watched = mine.target if mine is not None and mine.mode == MODE_SURVEIL else NO_TARGET
            for tid, tr in sorted(view.knowledge.tracks.items()):
                # Nobody has seen it for a while: g_m(t) is unknown. Except our own target last
                # seen (or predicted) inside a no-fly zone, circle or polygon, or within our
                # detection radius of one, where we, kept outside, lose sight of a target we
                # could otherwise follow: targets may enter a zone and we may not, so it is not
                # lost, and we keep it until anyone sees it again (docs/modelling.md,
                # "Assignment rules", rule 5; the actor patrols the zone's boundary), wherever
                # on that boundary we are.
                kept = tid == watched and _near_zone(view.knowledge, tr, t, R)
                if t - tr.t > max_age and not kept:
                    continue
                tx, ty = tr.predict(t)
                if kept or math.hypot(tx - view.x, ty - view.y) < k.influence_radius + 2 * R:
                    targets.append((tid, tx, ty, tr.value))
        rivals = planner.rivals(view, targets, k.influence_radius)
        return cls(view, R, r_max, k.r_min(view.v), k.influence_radius, k.speed_max / planner.field_unit_m,
                   slot, targets, rivals, list(view.knowledge.threats.values()))

    def draw(self, planner: DacmpPlanner) -> None:
        """The rest of the UAV's draws, in the one-UAV order: ring radii, ring angles, then per
        PSO iteration three rows (r1, r2, Q)."""
        rng, R, M = self.view.rng, self.R, planner.particles
        self.ring_radius = rng.normal(planner.ring_mean_factor * R, planner.ring_sd_factor * R, M)
        self.ring_angle = self.view.theta + rng.normal(0.0, planner.heading_sd_rad, M)
        self.pso_draws = rng.random((planner.iterations, 3, M))

    def target_terms(self, px: np.ndarray, py: np.ndarray, f_t: np.ndarray, unit: float, floor: float) -> None:
        """Add eq. 22 (target attraction) and eq. 23 (competing repulsion) into ``f_t``."""
        k = self.view.kind
        D, v_i = self.D, self.v_i
        near = []  # per target: the points within D of it
        for _tid, tx, ty, value in self.targets:
            d = np.hypot(px - tx, py - ty)
            near.append(d < D)
            if near[-1].any():
                f_t += np.where(near[-1], k.w_t * value / (np.maximum(d / unit, floor) * v_i * v_i), 0.0)
        for wx, wy, v_j, scope, _at in self.rivals:  # each other UAV once (see DacmpPlanner.rivals)
            shared = near[scope[0]] if len(scope) == 1 else np.logical_or.reduce([near[i] for i in scope])
            if shared.any():
                dj = np.maximum(np.hypot(px - wx, py - wy) / unit, floor)
                f_t -= np.where(shared, k.w_r / (dj * v_i * v_j), 0.0)

    def decide(self, wx: float, wy: float, f_s: float, unit: float, floor: float) -> Plan:
        """Mode switch at the chosen waypoint (spec "mode switching"): surveillance when a
        target term dominates there, of the target within ``D`` whose own pull (:meth:`own_pull`:
        its eq. 22 term less the eq. 23 terms of the UAVs that stand at it, ``at`` of
        :meth:`DacmpPlanner.rivals`) is the strongest and above ``f_S``. Not the sum ``f_t``
        over targets: with a large ``D`` a same-type UAV claiming another target nearby pushed
        the sum below ``f_S``, and a slow UAV never took a target over from a fast one. Not
        simply the nearest target either: a UAV drawn by a free target next to one that another
        UAV keeps (one of its type, or a slower one: eq. 26-27 push it off that one) declared
        the kept one, its nearest, and watched it beside its keeper."""
        mode, target = MODE_SEARCH, NO_TARGET
        best = f_s
        for i, (tid, _tx, _ty, _value) in enumerate(self.targets):
            pull = self.own_pull(i, wx, wy, unit, floor)
            if pull > best:
                mode, target, best = MODE_SURVEIL, tid, pull
        return Plan(wx, wy, mode, target)

    def own_pull(self, i: int, wx: float, wy: float, unit: float, floor: float) -> float:
        """Target ``i``'s own term at ``(wx, wy)``: its eq. 22 attraction less the eq. 23
        repulsion of the UAVs that stand at it (``at`` of :meth:`DacmpPlanner.rivals`: its
        watchers within a planning step, a nearer claimant of our type); 0 beyond ``D``.
        Attraction and those repulsions share the distance to ``g_m``. Both the mode switch
        (:meth:`decide`) and the keep rule (:meth:`DacmpPlanner.keep`) judge a target by it."""
        _tid, tx, ty, value = self.targets[i]
        d = math.hypot(wx - tx, wy - ty)
        if d >= self.D:
            return 0.0
        k, v_i = self.view.kind, self.v_i
        pull = k.w_t * value / (v_i * v_i) - sum(k.w_r / (v_i * v_j) for *_, v_j, _s, at in self.rivals if at == i)
        return pull / max(d / unit, floor)


def _near_zone(knowledge: Knowledge, track: Track, t: float, reach: float) -> bool:
    """Whether a track's last sighting or its predicted position lies inside a known no-fly
    zone (a circle or a polygon) or within ``reach`` of one."""
    if not knowledge.threats and not knowledge.no_fly:
        return False
    return (knowledge.near_no_fly(track.x, track.y, reach) is not None
            or knowledge.near_no_fly(*track.predict(t), reach) is not None)


def _neighbour_blocks(edges: tuple[int, ...], n: int, pos: float) -> tuple[int, int, int]:
    """Along one axis: the sub-area holding cell coordinate ``pos`` (clipped to ``0..n-1``) and
    the range ``lo:hi`` of it and its neighbours."""
    i = min(max(bisect.bisect_right(edges, pos) - 1, 0), n - 1)
    return i, max(i - 1, 0), min(i + 2, n)


@functools.lru_cache(maxsize=64)
def _cell_parts(ny: int, nx: int, search: tuple[int, ...], shapes: tuple[tuple[int, int], ...],
                widths: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """``Layers.row_part`` and ``col_part`` of a grid and window widths (read-only)."""
    row_part = np.stack([np.minimum(level_index(np.arange(ny), l), shapes[l][0] - 1) * wd for l, wd in zip(search, widths)])
    col_part = np.stack([np.minimum(level_index(np.arange(nx), l), shapes[l][1] - 1) for l in search])
    row_part.flags.writeable = False
    col_part.flags.writeable = False
    return row_part, col_part


@functools.lru_cache(maxsize=16)
def _sub_areas(h: int, w: int, ny: int, nx: int) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """Row and column edges of the guide's ``ny x nx`` sub-areas of an ``h x w`` map."""
    rows = np.linspace(0, h, ny + 1).round().astype(np.intp)
    cols = np.linspace(0, w, nx + 1).round().astype(np.intp)
    return tuple(rows.tolist()), tuple(cols.tolist())


class Layers:
    """The map work of one :meth:`DacmpPlanner.plan_many` call: every UAV's global guide point
    and the eq. 19 layers its particles can reach.

    Each UAV's map keeps its pyramid up to date itself (:class:`MaintainedPyramid`: ``G_l = 1 -
    s P_l``, recomputed only where the map changed since its last plan). Eq. 19 sums layers
    1..L (a map too small for even one layer falls back on G_0). For the particles, each UAV's
    ``P_l`` are copied, only in a window around the UAV (every cell within ``r_max`` of it, one
    cell of margin, and the cells of its targets, which :meth:`DacmpPlanner.keep` scores), into
    one flat float32 buffer, level by level and UAV by UAV within a level, so that the level
    sums of all particles of all UAVs are one gather (:meth:`level_sum`). The buffer is bounded
    by the windows, not by the map: a 42 M-cell map costs what a small one does.
    """

    def __init__(self, planner: DacmpPlanner, uavs: list[UavSearch]):
        views = [u.view for u in uavs]
        g = views[0].grid
        n = self.count = len(views)
        shapes = level_shapes(g.shape, planner.levels + 1)  # G_0 .. G_L
        self.search = search = list(range(1, len(shapes))) or [0]
        lam = planner.search_weights(len(search))
        self.lam = lam[:, None, None]
        self.lam_total = float(np.add.reduce(lam, initial=0.0))
        pyramids = [planner.planning_pyramid(v.umap) for v in views]
        planner.refresh(pyramids, [v.t for v in views])
        self.scale = np.array([p.s for p in pyramids], np.float64)  # s of each UAV's map
        # Window of each UAV on each search level: rows lo..hi, columns lo..hi (inclusive).
        win = np.empty((len(search), n, 4), np.int64)
        for i, (u, pyr) in enumerate(zip(uavs, pyramids)):
            view = u.view
            # Ties go to a neighbour drawn from the UAV's own stream, afresh each replanning.
            # With the heading as tie-break, UAVs flying side by side all picked the same
            # sub-area and flew on in formation, each UAV flew straight at a sub-area centre
            # rather than straight ahead, and paper-case2 found half as many targets by 200 s
            # (docs/paper.md, "Why a fast UAV misses the target straight ahead").
            tie_key = view.rng.random(9)
            u.guide = planner.pick_guide(pyr.block_means(), pyr.row_edges, pyr.col_edges, g.cell_m, view.x, view.y,
                                         view.theta, tie_key=tie_key)
            xs = [view.x - u.r_max, view.x + u.r_max] + [tx for _, tx, _, _ in u.targets]
            ys = [view.y - u.r_max, view.y + u.r_max] + [ty for _, _, ty, _ in u.targets]
            cx0, cx1 = (min(max(int(math.floor(v / g.cell_m)) + d, 0), g.nx - 1) for v, d in ((min(xs), -1), (max(xs), 1)))
            cy0, cy1 = (min(max(int(math.floor(v / g.cell_m)) + d, 0), g.ny - 1) for v, d in ((min(ys), -1), (max(ys), 1)))
            for j, l in enumerate(search):
                h, w = shapes[l]
                win[j, i] = (min(level_index(cy0, l), h - 1), min(level_index(cy1, l), h - 1),
                             min(level_index(cx0, l), w - 1), min(level_index(cx1, l), w - 1))
        heights = win[:, :, 1] - win[:, :, 0] + 1
        widths = (win[:, :, 3] - win[:, :, 2] + 1).max(axis=1)  # one width per level: one row table
        sizes = heights * widths[:, None]
        starts = np.cumsum(np.concatenate([[0], sizes.ravel()]))[:-1].reshape(sizes.shape)
        self.flat = planner.scratch.get("layers", (int(sizes.sum()),))
        for j, l in enumerate(search):
            wd = int(widths[j])
            for i, pyr in enumerate(pyramids):
                r0, r1, c0, c1 = (int(v) for v in win[j, i])
                block = self.flat[starts[j, i] : starts[j, i] + sizes[j, i]].reshape(r1 - r0 + 1, wd)
                pyr.read_window(l, r0, r1 + 1, c0, c1 + 1, block[:, : c1 - c0 + 1])
        # Flat index of a level-l cell (r, c) of UAV i's window on search level j:
        # offset[j, i] + r * widths[j] + c.
        self.offset = starts - win[:, :, 0] * widths[:, None] - win[:, :, 2]
        # Per-axis parts of it: row part (times the window width) and column part of the
        # nearest coarse cell of every level-0 row / column (rounded to the nearest centre,
        # clipped to the level: agents.planners.dacmp.pyramid.level_index).
        self.row_part, self.col_part = _cell_parts(g.ny, g.nx, tuple(search), tuple(shapes), tuple(widths.tolist()))

    def operands(self, slots: list[int], points: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(base, lam, s)`` for :meth:`level_sum` on ``(UAVs, points)`` arrays of the UAVs in
        these slots: the flat offset of each of their search levels and the levels' weights,
        both ``(levels, UAVs, points)``, and each UAV's ``s``, ``(UAVs, points)`` (full size:
        same-shape operands keep numpy on its fast path)."""
        shape = (len(self.search), len(slots), points)
        base = self.offset[:, slots][:, :, None]
        s = np.repeat(self.scale[slots][:, None], points, axis=1)
        return (np.ascontiguousarray(np.broadcast_to(base, shape)), np.ascontiguousarray(np.broadcast_to(self.lam, shape)), s)

    def level_sum(self, base: np.ndarray, lam: np.ndarray, s: np.ndarray, ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
        """``sum_l lambda_l G_l = sum_l lambda_l - s sum_l lambda_l P_l`` read at the coarse
        cells nearest level-0 cells ``(iy, ix)`` (``(UAVs, points)`` int arrays; ``base``,
        ``lam``, ``s`` from :meth:`operands`), ``P_l`` terms accumulated level by level from 0
        in float64: the numerator of eq. 19."""
        # mode="clip": cells outside the grid read its border cells (as Grid.cells_of clips).
        # (ndarray.take: np.take's Python wrapper costs more than the gather here.)
        idx = self.row_part.take(iy, axis=1, mode="clip")  # (levels, UAVs, points)
        idx += self.col_part.take(ix, axis=1, mode="clip")
        idx += base
        terms = self.flat.take(idx).astype(np.float64) * lam  # lambda_l * P_l (float64: same-type multiply)
        # A reduction over the first axis adds whole rows, one level after the other.
        p: np.ndarray = np.add.reduce(terms, axis=0, initial=0.0)
        p *= s
        np.subtract(self.lam_total, p, out=p)
        return p
