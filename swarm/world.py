"""Ground truth: where the UAVs, targets and threats really are, and what each sensor sees.

The world moves UAVs only with commands that passed :func:`agents.dynamics.limit_command`, so
the airframe limits hold on every step; it double-checks each applied command and counts a
``dynamics`` violation if one ever does not (that would be a simulator bug). Targets follow the
UAV kinematics driven by a Wiener process on acceleration and turn rate, with speed and
acceleration limits, and reflect at the area border. Each target draws from its own stream.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from agents.actor import SensedTarget, SensedUav, SensorReading
from agents.dynamics import clamp, command_violates, integrate, limit_command, wrap_angle
from agents.knowledge import KnownThreat
from agents.maps.grid import Grid
from agents.types import UavType

PENDING, ALIVE, CRASHED = "pending", "alive", "crashed"


@dataclass(slots=True)
class UavBody:
    uid: int
    name: str
    kind: UavType
    x: float
    y: float
    v: float
    theta: float
    state: str = PENDING
    join_s: float = 0.0


@dataclass(frozen=True, slots=True)
class TargetMotion:
    speed_max: float = 20.0
    accel_max: float = 0.4
    accel_sigma: float = 0.05
    turn_sigma: float = 0.002
    turn_rate_max: float = 0.1
    turn_reversion_s: float = 30.0


# Normals drawn per call from a target's stream: one numpy call per 64 steps instead of one per
# step. A Generator gives the same numbers in one call for n as in n calls for one each.
_DRAW_BLOCK = 128


class _Normals:
    """A generator's standard normals, drawn ahead in blocks and handed out in order, two at a
    time (targets sharing one generator share one of these: the same order of draws)."""

    __slots__ = ("rng", "buf", "pos")

    def __init__(self, rng: np.random.Generator):
        self.rng = rng
        self.buf: list[float] = []
        self.pos = 0

    def pair(self) -> tuple[float, float]:
        k = self.pos
        if k == len(self.buf):  # (blocks are even: pairs never straddle two)
            self.buf = self.rng.standard_normal(_DRAW_BLOCK).tolist()  # Python floats
            k = 0
        self.pos = k + 2
        return self.buf[k], self.buf[k + 1]


class Targets:
    """Target states as parallel lists (few targets; per-target random streams)."""

    def __init__(self, motion: TargetMotion):
        self.motion = motion
        self.x: list[float] = []
        self.y: list[float] = []
        self.v: list[float] = []
        self.theta: list[float] = []
        self.a: list[float] = []
        self.omega: list[float] = []
        self.value: list[float] = []
        self.rngs: list[np.random.Generator] = []
        self._normals: list[_Normals] = []  # per target, over its generator (step() draws only here)
        self._xy = np.zeros((0, 2))

    def __len__(self) -> int:
        return len(self.x)

    def add(self, x: float, y: float, theta: float, v: float, value: float, rng: np.random.Generator) -> int:
        self.x.append(x)
        self.y.append(y)
        self.v.append(v)
        self.theta.append(theta)
        self.a.append(0.0)
        self.omega.append(0.0)
        self.value.append(value)
        self.rngs.append(rng)
        self._normals.append(next((n for n in self._normals if n.rng is rng), None) or _Normals(rng))
        self._xy = np.array([self.x, self.y]).T  # (n, 2)
        return len(self.x) - 1

    @property
    def xy(self) -> np.ndarray:
        return self._xy

    def step(self, dt: float, grid: Grid) -> None:
        m = self.motion
        sq = math.sqrt(dt)
        # The turn rate relaxes towards 0 (Ornstein-Uhlenbeck): a pure Wiener turn rate drifts to
        # its limit and stays there, and the target circles on the spot instead of travelling.
        keep = math.exp(-dt / m.turn_reversion_s)
        sigma_a, sigma_w = m.accel_sigma * sq, m.turn_sigma * sq
        a_max, w_max, v_max = m.accel_max, m.turn_rate_max, m.speed_max
        w, h = grid.width_m, grid.height_m
        xs, ys, vs, ths, accs, oms = self.x, self.y, self.v, self.theta, self.a, self.omega
        for i, normals in enumerate(self._normals):
            na, nw = normals.pair()  # = rngs[i].standard_normal(2).tolist()
            a = clamp(accs[i] + sigma_a * na, -a_max, a_max)
            om = clamp(oms[i] * keep + sigma_w * nw, -w_max, w_max)
            v = vs[i]
            # Keep the speed in [0, speed_max] by limiting the applied acceleration.
            a = clamp(a, -v / dt, (v_max - v) / dt)
            x, y, v, th = integrate(xs[i], ys[i], v, ths[i], a, om, dt)
            if x < 0.0:
                x, th = -x, math.pi - th
            elif x > w:
                x, th = 2 * w - x, math.pi - th
            if y < 0.0:
                y, th = -y, -th
            elif y > h:
                y, th = 2 * h - y, -th
            xs[i], ys[i], vs[i], ths[i] = x, y, v, wrap_angle(th)
            accs[i], oms[i] = a, om
        if self.rngs:
            self._xy = np.array([xs, ys]).T


# Up to this many UAVs, check_safety first compares every pair itself (cheaper than a k-d tree).
_SCREEN_MAX = 16


def _all_far_apart(xy: np.ndarray, r: float) -> bool:
    """True if, for a small swarm, every pair of points is clearly (1%) more than ``r`` apart,
    so that the k-d tree would find no pair within ``r`` (whatever its rounding); False when
    some pair comes near ``r``, or for larger swarms (the k-d tree then decides)."""
    if len(xy) > _SCREEN_MAX:
        return False
    pts = xy.tolist()
    near = (1.01 * r) ** 2
    return not any((xa - xb) ** 2 + (ya - yb) ** 2 <= near
                   for k, (xa, ya) in enumerate(pts) for xb, yb in pts[k + 1:])


class World:
    def __init__(self, grid: Grid, targets: Targets, threats: list[KnownThreat]):
        self.grid = grid
        self.uavs: dict[int, UavBody] = {}
        self.targets = targets
        self.threats = threats
        self.violations = {"separation": 0, "threat": 0, "dynamics": 0}
        # Polygon no-fly zones (issue 26, agents.zones.Keepout; none in a metric scenario).
        self.zones: list = []
        # The wind of this tick (issue 26, swarm.mission; None: still air): every UAV drifts with it.
        self.wind: tuple[float, float] | None = None
        # uid -> [count, first t, last t] of its dynamics violations (they are counted, not logged)
        self.dynamics_by_uav: dict[int, list[float]] = {}

    def add_uav(self, body: UavBody) -> None:
        self.uavs[body.uid] = body

    def alive_ids(self) -> list[int]:
        return [u for u, b in sorted(self.uavs.items()) if b.state == ALIVE]

    def positions(self, ids: list[int]) -> np.ndarray:
        if not ids:
            return np.zeros((0, 2))
        return np.array([(self.uavs[u].x, self.uavs[u].y) for u in ids], dtype=np.float64)

    # --- sensing ----------------------------------------------------------------------------

    def sense(self, uid: int, t: float) -> SensorReading:
        return self.sense_many([uid], t)[0]

    def sense_many(self, ids: list[int], t: float, xy: np.ndarray | None = None) -> list[SensorReading]:
        """:meth:`sense` for each UAV of ``ids``, with one distance test for all of them (a
        simulation senses for its whole swarm every tick). ``xy``: ``positions(ids)`` if known."""
        uavs = self.uavs
        bodies = [uavs[u] for u in ids]
        tg = self.targets
        inside: list[list[int]] = [[] for _ in ids]
        if len(tg) and ids:
            if xy is None:
                xy = self.positions(ids)
            txy = tg.xy
            radii = np.array([b.kind.detect_radius for b in bodies])
            # Row k: the squared distances of every target from UAV k, (target - UAV)**2 per axis.
            d2 = (txy[:, 0] - xy[:, 0:1]) ** 2 + (txy[:, 1] - xy[:, 1:2]) ** 2
            rows, cols = (d2 <= (radii * radii)[:, None]).nonzero()  # row-major: targets in id order
            for k, i in zip(rows.tolist(), cols.tolist()):
                inside[k].append(i)
        daa = self._detect_and_avoid(ids, bodies, xy)
        readings = []
        for k, (b, hits) in enumerate(zip(bodies, inside)):
            r = b.kind.detect_radius
            seen: list[SensedTarget] = []
            for i in hits:
                v, th = tg.v[i], tg.theta[i]
                seen.append(SensedTarget(i, tg.x[i], tg.y[i], v * math.cos(th), v * math.sin(th), tg.value[i]))
            threats = [th for th in self.threats if math.hypot(th.x - b.x, th.y - b.y) - th.radius <= r]
            readings.append(SensorReading(t, b.x, b.y, b.v, b.theta, seen, threats, daa[k]))
        return readings

    def _detect_and_avoid(self, ids: list[int], bodies: list[UavBody], xy: np.ndarray | None) -> list[list[SensedUav] | None]:
        """Each UAV's detect-and-avoid reading: every other flying UAV within its type's
        ``daa_range`` (true position and velocity, in id order), or None for a UAV without the
        sensor (range 0). One k-d tree over the flying UAVs for all of them."""
        ranges = [b.kind.daa_range for b in bodies]
        out: list[list[SensedUav] | None] = [[] if r > 0 else None for r in ranges]
        rmax = max(ranges, default=0.0)
        if rmax <= 0:
            return out
        pop = self.alive_ids()  # who is in the air to be sensed
        if len(pop) < 2:
            return out
        uavs = self.uavs
        pxy = xy if xy is not None and pop == ids else self.positions(pop)
        # (The tree's reach a hair beyond the range; the test below is exact.)
        pairs = cKDTree(pxy).query_pairs(rmax * (1.0 + 1e-9) + 1e-6, output_type="ndarray")
        if not len(pairs):
            return out
        # Both directions of each pair: observer a senses b if b is within a's own range.
        a = np.concatenate((pairs[:, 0], pairs[:, 1]))
        b = np.concatenate((pairs[:, 1], pairs[:, 0]))
        d2 = ((pxy[a] - pxy[b]) ** 2).sum(axis=1)
        pranges = np.array([uavs[u].kind.daa_range for u in pop])
        keep = d2 <= pranges[a] ** 2
        a, b = a[keep], b[keep]
        order = np.lexsort((b, a))  # by observer, then by the sensed UAV's id (pop is in id order)
        a, b = a[order], b[order]
        # Velocities with math's cos and sin, as a Hello's receiver computes them (numpy's may
        # differ in the last bit from one CPU to another).
        vel = [(v * math.cos(th), v * math.sin(th)) for v, th in ((uavs[u].v, uavs[u].theta) for u in pop)]
        bl = b.tolist()
        sensed = ((pop[j], x, y, *vel[j]) for j, x, y in zip(bl, pxy[b, 0].tolist(), pxy[b, 1].tolist()))
        row_of = {u: k for k, u in enumerate(ids)}
        rows = [row_of.get(u, -1) for u in pop]
        for obs, s in zip(a.tolist(), sensed):
            k = rows[obs]
            if k >= 0:
                lst = out[k]
                if lst is not None:
                    lst.append(s)
        return out

    # --- motion -----------------------------------------------------------------------------

    def apply(self, uid: int, a: float, omega: float, dt: float, t: float = math.nan) -> None:
        b = self.uavs[uid]
        a, omega = limit_command(b.kind, b.v, a, omega, dt)
        if command_violates(b.kind, b.v, a, omega, dt):
            self.violations["dynamics"] += 1
            seen = self.dynamics_by_uav.setdefault(uid, [0, t, t])
            seen[0] += 1
            seen[2] = t
        b.x, b.y, b.v, b.theta = integrate(b.x, b.y, b.v, b.theta, a, omega, dt)
        if self.wind is not None:  # (issue 26) ground velocity = air velocity + wind
            b.x += self.wind[0] * dt
            b.y += self.wind[1] * dt

    def check_safety(self, ids: list[int], xy: np.ndarray, min_sep: float) -> list[tuple[str, int, int]]:
        """Count separation and threat-clearance violations now; returns them for the log."""
        found: list[tuple[str, int, int]] = []
        if len(ids) >= 2 and not _all_far_apart(xy, min_sep):
            pairs = cKDTree(xy).query_pairs(min_sep, output_type="ndarray")
            for i, j in sorted(map(tuple, pairs.tolist())):
                found.append(("separation", ids[i], ids[j]))
        for th in self.threats:
            d = np.hypot(xy[:, 0] - th.x, xy[:, 1] - th.y) if len(ids) else np.zeros(0)
            for i in np.flatnonzero(d < th.radius).tolist():
                found.append(("threat", ids[i], th.threat))
        for z in self.zones:  # (issue 26) inside a polygon: every UAV at once
            if len(ids):
                for i in np.flatnonzero(z.contains_many(xy[:, 0], xy[:, 1])).tolist():
                    found.append(("threat", ids[i], z.zone))
        for kind, _, _ in found:
            self.violations[kind] += 1
        return found
