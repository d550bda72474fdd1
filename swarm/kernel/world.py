"""Ground truth: where the UAVs, targets and threats really are, and what each sensor sees.

The world moves UAVs only with commands that passed :func:`agents.dynamics.limit_command`, so
the airframe limits hold on every step; it double-checks each applied command and counts a
``dynamics`` violation if one ever does not (that would be a simulator bug). Targets follow the
UAV kinematics driven by a Wiener process on acceleration and turn rate, with speed and
acceleration limits, and reflect at the area border; in a geographic area (a polygon, issue
33) a target that would leave the polygon stays where it was and turns round instead (a vessel
turning back at the coast). Each target draws from its own stream.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.dynamics import TWO_PI, command_violates, integrate, limit_command
from agents.inputs import SensedTarget, SensedUav, SensorReading
from agents.knowledge import KnownThreat
from agents.maps.grid import Grid
from agents.types import GRAVITY, UavType
from agents.zones import Keepout
from swarm.pairs import TickPairs, pairs_within

# A UAV's state: not yet flying, flying, on the ground at its base between two sorties (issue
# 33: [endurance]; it neither flies, senses nor sends), or down for good (or until a restart).
PENDING, ALIVE, LANDED, CRASHED = "pending", "alive", "landed", "crashed"


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

# From this many targets on (measured crossover), step() moves them as numpy arrays, one operation for all (the same
# IEEE operations in the same order as the per-target loop below it, and math's cos and sin, so
# the same numbers: tests/test_many_targets.py); below it, one by one in Python floats (cheaper
# for the paper's few targets). Issue 25: 10^5 targets cost 0.3 s a tick one by one.
_VECTOR_MIN = 48

# Rows of Targets._s, the targets' state (one column per target).
_X, _Y, _V, _TH, _A, _OM, _VAL = range(7)


def _clamp_v(v: np.ndarray, lo: np.ndarray | float, hi: np.ndarray | float) -> np.ndarray:
    """:func:`agents.dynamics.clamp` element by element (the same comparisons, the same order)."""
    v = np.where(lo > v, lo, v)
    return np.where(hi < v, hi, v)


def _wrap_v(a: np.ndarray) -> np.ndarray:
    """:func:`agents.dynamics.wrap_angle` element by element (numpy's ``%`` on floats is Python's)."""
    w = (a + math.pi) % TWO_PI - math.pi
    return np.where(w >= math.pi, w - TWO_PI, w)


def _math_v(f: Callable[[float], float], a: np.ndarray) -> np.ndarray:
    """``f`` (math's cos or sin) of each element: numpy's own may differ in the last bit, and
    the UAVs' and per-target paths use math's."""
    return np.fromiter(map(f, a.tolist()), np.float64, len(a))


class _Normals:
    """A generator's standard normals, drawn ahead in blocks and handed out in order, two at a
    time (kept for reference and tests: :class:`Targets` holds the same per stream in arrays)."""

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
    """Target states, one column per target of a float64 array grown by doubling (adding a
    target is O(1): a million of them build in a second), each target with its own random stream.

    ``x``, ``y``, ``v``, ``theta``, ``a``, ``omega``, ``value``: views of the live state (numpy
    arrays; take ``.tolist()`` for Python floats). A stream is a slot: targets given the same
    generator share one (and its draws, in target order); a slot's generator may be made only
    when first drawn from (:meth:`add_many`)."""

    def __init__(self, motion: TargetMotion, boundary: Any = None):
        """``boundary``: a geographic area's polygon (shapely, local metres, prepared), inside which
        targets stay (:meth:`_turn_back`); None: the area's rectangle."""
        self.motion = motion
        self._n = 0
        self._s = np.zeros((7, 0))
        self._xy: np.ndarray | None = None  # xy, made when read after a change
        self._slot = np.zeros(0, np.int64)  # target -> its stream's slot
        self._slot_of: dict[int, int] = {}  # id(generator) -> slot (the generators are kept in _gens)
        self._gens: list[np.random.Generator | None] = []  # per slot; None: made when first drawn from
        self._makers: list[tuple[int, int, int, Callable[[int], np.random.Generator]]] = []  # (slot0, slot1, target0, make)
        self._buf = np.zeros((0, _DRAW_BLOCK))  # per slot: normals drawn ahead
        self._pos = np.zeros(0, np.int64)  # per slot: the next unused one (_DRAW_BLOCK: none left)
        self._shared = False  # some slot serves several targets (step() then goes one by one)
        # While every target i has slot i and all are at the same place in their draws (targets
        # added together: the usual), that place; _pos is then stale. None: read _pos.
        self._lock: int | None = _DRAW_BLOCK
        # (issue 33) A target inside the area polygon that would step out stays put and turns round.
        self.boundary: Any = boundary

    def __len__(self) -> int:
        return self._n

    x = property(lambda self: self._s[_X, : self._n])
    y = property(lambda self: self._s[_Y, : self._n])
    v = property(lambda self: self._s[_V, : self._n])
    theta = property(lambda self: self._s[_TH, : self._n])
    a = property(lambda self: self._s[_A, : self._n])
    omega = property(lambda self: self._s[_OM, : self._n])
    value = property(lambda self: self._s[_VAL, : self._n])

    def _reserve(self, k: int) -> None:
        """Room for ``k`` more targets and slots (capacity doubled when short)."""
        n = self._n
        if n + k > self._s.shape[1]:
            cap = max(2 * self._s.shape[1], n + k, 16)
            s = np.zeros((7, cap))
            s[:, :n] = self._s[:, :n]
            self._s = s
            self._slot = np.concatenate((self._slot[:n], np.zeros(cap - n, np.int64)))
        slots = len(self._gens)
        if slots + k > len(self._pos):
            cap = max(2 * len(self._pos), slots + k, 16)
            buf = np.zeros((cap, _DRAW_BLOCK))
            buf[:slots] = self._buf[:slots]
            self._buf = buf
            self._pos = np.concatenate((self._pos[:slots], np.full(cap - slots, _DRAW_BLOCK, np.int64)))

    def _unlock(self) -> None:
        """Targets stop moving through their draws in step: _pos becomes the truth."""
        if self._lock is not None:
            self._pos[: len(self._gens)] = self._lock
            self._lock = None

    def add(self, x: float, y: float, theta: float, v: float, value: float, rng: np.random.Generator) -> int:
        if self._lock != _DRAW_BLOCK:  # (a new stream starts with no draws: in step only at a block's end)
            self._unlock()
        self._reserve(1)
        i = self._n
        self._s[:, i] = (x, y, v, theta, 0.0, 0.0, value)
        slot = self._slot_of.get(id(rng))
        if slot is None:
            slot = self._slot_of[id(rng)] = len(self._gens)
            self._gens.append(rng)
        else:
            self._shared = True
            self._unlock()
        self._slot[i] = slot
        self._n = i + 1
        self._xy = None
        return i

    def add_many(self, x: np.ndarray, y: np.ndarray, theta: np.ndarray, v: np.ndarray, value: float,
                 make: Callable[[int], np.random.Generator]) -> range:
        """Add ``len(x)`` targets, each with a stream of its own, ``make(target id)``, made only
        if and when something draws from it. Returns their ids."""
        k = len(x)
        if self._lock != _DRAW_BLOCK:
            self._unlock()
        self._reserve(k)
        n, slot0 = self._n, len(self._gens)
        s = self._s
        s[_X, n:n + k], s[_Y, n:n + k], s[_V, n:n + k], s[_TH, n:n + k] = x, y, v, theta
        s[_A, n:n + k] = s[_OM, n:n + k] = 0.0
        s[_VAL, n:n + k] = value
        self._slot[n:n + k] = np.arange(slot0, slot0 + k)
        self._gens.extend([None] * k)
        self._makers.append((slot0, slot0 + k, n, make))
        self._n = n + k
        self._xy = None
        return range(n, n + k)

    def _refill(self, slots: list[int]) -> None:
        """Draw the next block of normals of each of these slots' streams (making the stream
        first if it was never drawn from)."""
        gens, buf = self._gens, self._buf
        for slot in slots:
            g = gens[slot]
            if g is None:
                for s0, s1, t0, make in self._makers:
                    if s0 <= slot < s1:
                        g = gens[slot] = make(t0 + slot - s0)
                        break
                assert g is not None  # (every lazy slot has its maker)
            g.standard_normal(out=buf[slot])  # (= standard_normal(_DRAW_BLOCK): the same draws)
        self._pos[slots] = 0

    def state_of(self, ids: np.ndarray) -> list[list[float]]:
        """``[x, y, v, theta, value]`` of the targets ``ids``, each a list of Python floats."""
        st = self._s
        return [st[r, ids].tolist() for r in (_X, _Y, _V, _TH, _VAL)]

    @property
    def xy(self) -> np.ndarray:
        """The targets' positions, (n, 2): a new array after each change (safe to keep)."""
        if self._xy is None:
            self._xy = np.array(self._s[_X:_Y + 1, : self._n].T)
        return self._xy

    def step(self, dt: float, grid: Grid) -> None:
        n = self._n
        if not n:
            return
        before = self._s[_X:_Y + 1, :n].copy() if self.boundary is not None else None
        if n < _VECTOR_MIN or self._shared:
            self._step_each(dt, grid)
        else:
            self._step_all(dt, grid)
        if before is not None:
            self._turn_back(before)
        self._xy = None

    def _turn_back(self, before: np.ndarray) -> None:
        """Targets that were inside the area polygon and stepped out: back where they were,
        heading turned round (their speed, acceleration and turn rate kept)."""
        import shapely

        n = self._n
        st = self._s
        out = ~shapely.contains_xy(self.boundary, st[_X, :n], st[_Y, :n])
        if not out.any():
            return
        out &= shapely.contains_xy(self.boundary, before[0], before[1])
        st[_X, :n] = np.where(out, before[0], st[_X, :n])
        st[_Y, :n] = np.where(out, before[1], st[_Y, :n])
        st[_TH, :n] = np.where(out, _wrap_v(st[_TH, :n] + math.pi), st[_TH, :n])

    def _step_each(self, dt: float, grid: Grid) -> None:
        m = self.motion
        sq = math.sqrt(dt)
        # The turn rate relaxes towards 0 (Ornstein-Uhlenbeck): a pure Wiener turn rate drifts to
        # its limit and stays there, and the target circles on the spot instead of travelling.
        keep = math.exp(-dt / m.turn_reversion_s)
        sigma_a, sigma_w = m.accel_sigma * sq, m.turn_sigma * sq
        a_max, w_max, v_max = m.accel_max, m.turn_rate_max, m.speed_max
        w, h = grid.width_m, grid.height_m
        n = self._n
        st = self._s
        state = st[_X:_OM + 1, :n].tolist()  # (one call each way: rows _X.._OM)
        xs, ys, vs, ths, accs, oms = state
        if self._shared:  # (targets sharing a stream draw from it in target order)
            slots = self._slot[:n].tolist()
            buf, pos = self._buf, self._pos
            nas, nws = [], []
            for s in slots:
                k = int(pos[s])
                if k == _DRAW_BLOCK:  # (blocks are even: pairs never straddle two)
                    self._refill([s])
                    k = 0
                pos[s] = k + 2
                nas.append(buf.item(s, k))
                nws.append(buf.item(s, k + 1))
        else:
            na_a, nw_a = self._draw_pairs()
            nas, nws = na_a.tolist(), nw_a.tolist()
        cos, sin, pi = math.cos, math.sin, math.pi
        for i in range(n):
            na, nw = nas[i], nws[i]  # = rngs[i].standard_normal(2).tolist()
            # clamp(), integrate() and wrap_angle() of agents.dynamics written out (the same
            # operations in the same order, without three calls a target).
            a = accs[i] + sigma_a * na
            a = -a_max if -a_max > a else a
            a = a_max if a_max < a else a
            om = oms[i] * keep + sigma_w * nw
            om = -w_max if -w_max > om else om
            om = w_max if w_max < om else om
            v = vs[i]
            # Keep the speed in [0, speed_max] by limiting the applied acceleration.
            lo, hi = -v / dt, (v_max - v) / dt
            a = lo if lo > a else a
            a = hi if hi < a else a
            th = ths[i]
            v_next = v + a * dt
            theta_mid = th + 0.5 * om * dt
            v_mean = 0.5 * (v + v_next)
            x = xs[i] + v_mean * cos(theta_mid) * dt
            y = ys[i] + v_mean * sin(theta_mid) * dt
            th = (th + om * dt + pi) % TWO_PI - pi
            th = th - TWO_PI if th >= pi else th
            v = v_next
            if x < 0.0:
                x, th = -x, pi - th
            elif x > w:
                x, th = 2 * w - x, pi - th
            if y < 0.0:
                y, th = -y, -th
            elif y > h:
                y, th = 2 * h - y, -th
            th = (th + pi) % TWO_PI - pi
            xs[i], ys[i], vs[i], ths[i] = x, y, v, th - TWO_PI if th >= pi else th
            accs[i], oms[i] = a, om
        st[_X:_OM + 1, :n] = state

    def _draw_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """Each target's next two normals from its stream (no stream shared: order is free)."""
        n = self._n
        buf = self._buf
        lock = self._lock
        if lock is not None:  # target i is slot i, all at draw `lock`: plain slices
            if lock == _DRAW_BLOCK:
                self._refill(list(range(n)))
                lock = 0
            self._lock = lock + 2
            return buf[:n, lock], buf[:n, lock + 1]
        slots = self._slot[:n]
        k = self._pos[slots]
        empty = k == _DRAW_BLOCK
        if empty.any():
            self._refill(slots[empty].tolist())
            k = self._pos[slots]
        self._pos[slots] = k + 2
        return buf[slots, k], buf[slots, k + 1]

    def _step_all(self, dt: float, grid: Grid) -> None:
        """:meth:`_step_each` for every target at once (each target has a stream of its own)."""
        m = self.motion
        sq = math.sqrt(dt)
        keep = math.exp(-dt / m.turn_reversion_s)
        sigma_a, sigma_w = m.accel_sigma * sq, m.turn_sigma * sq
        a_max, w_max, v_max = m.accel_max, m.turn_rate_max, m.speed_max
        w, h = grid.width_m, grid.height_m
        n = self._n
        st = self._s
        na, nw = self._draw_pairs()
        a = _clamp_v(st[_A, :n] + sigma_a * na, -a_max, a_max)
        om = _clamp_v(st[_OM, :n] * keep + sigma_w * nw, -w_max, w_max)
        v = st[_V, :n]
        a = _clamp_v(a, -v / dt, (v_max - v) / dt)
        # integrate(), term by term
        v_next = v + a * dt
        theta_mid = st[_TH, :n] + 0.5 * om * dt
        v_mean = 0.5 * (v + v_next)
        x = st[_X, :n] + v_mean * _math_v(math.cos, theta_mid) * dt
        y = st[_Y, :n] + v_mean * _math_v(math.sin, theta_mid) * dt
        th = _wrap_v(st[_TH, :n] + om * dt)
        lo, hi = x < 0.0, x > w
        x = np.where(lo, -x, np.where(hi, 2 * w - x, x))
        th = np.where(lo | hi, math.pi - th, th)
        lo, hi = y < 0.0, y > h
        y = np.where(lo, -y, np.where(hi, 2 * h - y, y))
        th = np.where(lo | hi, -th, th)
        st[_X, :n], st[_Y, :n], st[_V, :n], st[_TH, :n] = x, y, v_next, _wrap_v(th)
        st[_A, :n], st[_OM, :n] = a, om


# Up to this many (UAV, target) pairs (measured crossover), sense_many tests them in Python floats
# (_sense_few), not numpy.
_SENSE_SCALAR_MAX = 32

# Up to this many UAVs, check_safety first compares every pair itself (cheaper than a k-d tree).
_SCREEN_MAX = 16
# Up to this many pairs within detect-and-avoid range, their readings are assembled in Python
# floats (_sensed_few), not numpy: 20 -> 7 us a tick on paper-fig11 (6 UAVs, 2 readings), 92 -> 61
# on bench-100 at 20 s (4 readings); 5.5 either way with none in range (paper-case2).
_DAA_FEW_PAIRS = 32


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


# From this many UAVs on, World.fly moves them as numpy arrays (the tick plane's, issue 36; the
# same IEEE operations as apply(), math's cos and sin): below it the per-UAV calls are cheaper.
_FLY_VECTOR_MIN = 64


def _airframes(kinds: list[UavType]) -> np.ndarray:
    """Rows ``accel_max, speed_min, speed_max, GRAVITY * tan(bank_max)`` with a column per UAV
    (the last is :meth:`UavType.turn_rate_max`'s numerator, computed as it computes it)."""
    return np.array([(k.accel_max, k.speed_min, k.speed_max, GRAVITY * math.tan(k.bank_max_rad)) for k in kinds],
                    dtype=np.float64).T


def fly_arrays(airframes: np.ndarray, x: np.ndarray, y: np.ndarray, v: np.ndarray, theta: np.ndarray,
               a: np.ndarray, omega: np.ndarray, dt: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`agents.dynamics.limit_command`, :func:`~agents.dynamics.command_violates` and
    :func:`~agents.dynamics.integrate` for many UAVs at once (``airframes``: :func:`_airframes`
    of their types), element by element the same operations in the same order
    (``max``/``min``/``clamp`` as their comparisons, math's cos and sin): ``(x, y, v, theta,
    violates)`` after ``dt``."""
    acc, vmin, vmax, gtan = airframes
    # limit_command
    a = np.where(np.isfinite(a), a, 0.0)
    omega = np.where(np.isfinite(omega), omega, 0.0)
    lo, hi = -acc, acc
    slow, fast = (vmin - v) / dt, (vmax - v) / dt
    lo = np.where(slow > lo, slow, lo)
    hi = np.where(fast < hi, fast, hi)
    clamped = np.where(lo > a, lo, a)
    clamped = np.where(hi < clamped, hi, clamped)
    a = np.where(lo <= hi, clamped, np.where(v > vmax, -acc, acc))
    v_next = v + a * dt
    vm = np.where(v_next > v, v_next, v)
    w_max = gtan / np.where(1e-6 > vm, 1e-6, vm)
    omega = np.where(-w_max > omega, -w_max, omega)
    omega = np.where(w_max < omega, w_max, omega)
    # command_violates (tol 1e-9; the command is finite by now)
    tol = 1e-9
    bad = (~(np.isfinite(a) & np.isfinite(omega)) | (np.abs(a) > acc * (1 + tol) + tol)
           | (v_next < vmin * (1 - tol) - tol) | (v_next > vmax * (1 + tol) + tol)
           | (np.abs(omega) > w_max * (1 + tol) + tol))
    # integrate
    theta_mid = theta + 0.5 * omega * dt
    v_mean = 0.5 * (v + v_next)
    x = x + v_mean * _math_v(math.cos, theta_mid) * dt
    y = y + v_mean * _math_v(math.sin, theta_mid) * dt
    return x, y, v_next, _wrap_v(theta + omega * dt), bad


class World:
    def __init__(self, grid: Grid, targets: Targets, threats: list[KnownThreat],
                 zones: list[Keepout] | None = None, pairs: TickPairs | None = None, vector_physics: bool = False):
        """``pairs``: the tick plane's one pair query a tick, which detect-and-avoid and the safety
        check share with the radio (None: each makes its own). ``vector_physics`` (the tick
        plane's, issue 36): :meth:`fly` moves a large swarm as arrays; False: one :meth:`apply`
        per UAV (the oracle)."""
        self.grid = grid
        self.vector_physics = vector_physics
        self._fly_kinds: list[UavType] = []  # fly(): the types its airframe rows are of
        self._ids_in_order = True  # uavs (a dict) holds the UAVs in id order
        self._fly_airframes = np.zeros((4, 0))
        self.uavs: dict[int, UavBody] = {}
        self.targets = targets
        self.threats = threats
        self.violations = {"separation": 0, "threat": 0, "dynamics": 0}
        # Polygon no-fly zones (issue 26, agents.zones.Keepout; none in a metric scenario).
        self.zones: list[Keepout] = zones if zones is not None else []
        # The wind of this tick (issue 26, swarm.kernel.mission; None: still air): every UAV drifts with it.
        self.wind: tuple[float, float] | None = None
        # uid -> [count, first t, last t] of its dynamics violations (they are counted, not logged)
        self.dynamics_by_uav: dict[int, list[float]] = {}
        self.pairs = pairs

    def add_uav(self, body: UavBody) -> None:
        uavs = self.uavs
        if uavs and body.uid not in uavs and body.uid < next(reversed(uavs)):
            self._ids_in_order = False  # (added out of id order: alive_ids() sorts)
        uavs[body.uid] = body

    def alive_ids(self) -> list[int]:
        """The flying UAVs' ids, in id order."""
        if self._ids_in_order:  # (the usual: UAVs added with increasing ids, the dict in id order)
            return [u for u, b in self.uavs.items() if b.state == ALIVE]
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
        inside: list[list[SensedTarget]] = [[] for _ in ids]
        if len(tg) and ids:
            if xy is None:
                xy = self.positions(ids)
            if len(ids) * len(tg) <= _SENSE_SCALAR_MAX:
                self._sense_few(bodies, xy, inside)
            else:
                self._sense_many_targets(bodies, xy, inside)
        daa = self._detect_and_avoid(ids, bodies, xy)
        if not self.threats:  # (most scenarios: no threat to test each UAV against)
            return [SensorReading(t, b.x, b.y, b.v, b.theta, seen, [], d) for b, seen, d in zip(bodies, inside, daa)]
        readings = []
        for k, (b, seen) in enumerate(zip(bodies, inside)):
            r = b.kind.detect_radius
            threats = [th for th in self.threats if math.hypot(th.x - b.x, th.y - b.y) - th.radius <= r]
            readings.append(SensorReading(t, b.x, b.y, b.v, b.theta, seen, threats, daa[k]))
        return readings

    def _sense_many_targets(self, bodies: list[UavBody], xy: np.ndarray, inside: list[list[SensedTarget]]) -> None:
        """sense_many's targets: every (UAV, target) distance tested with numpy."""
        tg = self.targets
        txy = tg.xy
        r2 = np.array([b.kind.detect_radius for b in bodies]) ** 2
        # Row k: the squared distances of every target from UAV k, (target - UAV)**2 per axis;
        # UAVs in chunks of at most about 4M pairs (bounded memory with many targets).
        chunk = max(1, (1 << 22) // len(txy))
        for k0 in range(0, len(bodies), chunk):
            d2 = (txy[:, 0] - xy[k0:k0 + chunk, 0:1]) ** 2 + (txy[:, 1] - xy[k0:k0 + chunk, 1:2]) ** 2
            rows, cols = (d2 <= r2[k0:k0 + chunk, None]).nonzero()  # row-major: targets in id order
            if not len(cols):
                continue
            # (Python floats, as the targets' lists gave them before: the state read once)
            st = tg.state_of(cols)
            for k, i, x, y, v, th, value in zip((rows + k0).tolist(), cols.tolist(), *st):
                inside[k].append(SensedTarget(i, x, y, v * math.cos(th), v * math.sin(th), value))

    def _sense_few(self, bodies: list[UavBody], xy: np.ndarray, inside: list[list[SensedTarget]]) -> None:
        """sense_many's targets for a few (UAV, target) pairs: the same squared distances and
        test in Python floats (numpy's calls cost more than the arithmetic here), the same
        readings in the same order."""
        tg = self.targets
        txs, tys = tg.x.tolist(), tg.y.tolist()
        ks: list[int] = []
        hits: list[int] = []
        for k, ((ux, uy), b) in enumerate(zip(xy.tolist(), bodies)):
            r = b.kind.detect_radius
            r2 = r * r  # (= numpy's r ** 2, a square)
            for i, (tx, ty) in enumerate(zip(txs, tys)):
                dx, dy = tx - ux, ty - uy
                if dx * dx + dy * dy <= r2:
                    ks.append(k)
                    hits.append(i)
        if hits:
            for k, i, x, y, v, th, value in zip(ks, hits, *tg.state_of(np.array(hits))):
                inside[k].append(SensedTarget(i, x, y, v * math.cos(th), v * math.sin(th), value))

    def _detect_and_avoid(self, ids: list[int], bodies: list[UavBody], xy: np.ndarray | None) -> list[list[SensedUav] | None]:
        """Each UAV's detect-and-avoid reading: every other flying UAV within its type's
        ``daa_range`` (true position and velocity, in id order), or None for a UAV without the
        sensor (range 0). One pair query over the flying UAVs for all of them: the tick's, shared
        with the radio and the safety check (:class:`~swarm.pairs.TickPairs`, the tick plane), or
        its own."""
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
        tick = self.pairs
        if tick is not None and pxy is xy and rmax <= tick.reach_m:
            # The tick's pairs (tick plane), squared distances included (the same numbers).
            i, j, d2 = tick.of(pop, pxy).within(rmax)
            if not len(i):
                return out
            if len(i) <= _DAA_FEW_PAIRS:
                self._sensed_few(ids, pop, pxy, i.tolist(), j.tolist(), d2.tolist(), out)
                return out
            a, b, d2 = np.concatenate((i, j)), np.concatenate((j, i)), np.concatenate((d2, d2))
        else:
            # (The candidates' reach a hair beyond the range; the test below is exact.)
            pairs = pairs_within(pxy, rmax * (1.0 + 1e-9) + 1e-6)
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

    def _sensed_few(self, ids: list[int], pop: list[int], pxy: np.ndarray, i: list[int], j: list[int],
                    d2: list[float], out: list[list[SensedUav] | None]) -> None:
        """_detect_and_avoid's readings from a few pairs ``(i, j, d2)`` (indices into ``pop``,
        the tick's squared distances), assembled in Python floats (numpy's calls cost more than
        the arithmetic here): the same test (``d2 <= r * r``, r the observer's range), the same
        readings in the same order (by observer, then the sensed UAV's id)."""
        uavs = self.uavs
        r2 = [uavs[u].kind.daa_range ** 2 for u in pop]  # (as numpy squares the ranges)
        hits = sorted([(a, b) for a, b, d in zip(i, j, d2) if d <= r2[a]]
                      + [(b, a) for a, b, d in zip(i, j, d2) if d <= r2[b]])
        if not hits:
            return
        row_of = {u: k for k, u in enumerate(ids)}
        pts = pxy.tolist()
        vel: dict[int, tuple[float, float]] = {}
        for a, b in hits:
            k = row_of.get(pop[a], -1)
            lst = out[k] if k >= 0 else None
            if lst is None:
                continue
            v = vel.get(b)
            if v is None:
                body = uavs[pop[b]]
                v = vel[b] = (body.v * math.cos(body.theta), body.v * math.sin(body.theta))
            x, y = pts[b]
            lst.append((pop[b], x, y, v[0], v[1]))

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

    def fly(self, ids: list[int], commands: list[tuple[float, float]], dt: float, t: float = math.nan) -> None:
        """:meth:`apply` of each ``(a, omega)`` of ``commands`` to its UAV of ``ids``, in order;
        with :attr:`vector_physics` and from :data:`_FLY_VECTOR_MIN` UAVs on, all at once
        (:func:`fly_arrays`: the same numbers)."""
        if not self.vector_physics or len(ids) < _FLY_VECTOR_MIN:
            for uid, (a, omega) in zip(ids, commands):
                self.apply(uid, a, omega, dt, t)
            return
        uavs = self.uavs
        bodies = [uavs[u] for u in ids]
        kinds = [b.kind for b in bodies]
        if kinds != self._fly_kinds:  # (the swarm's types, in this order: as last tick, mostly)
            self._fly_kinds, self._fly_airframes = kinds, _airframes(kinds)
        x, y, v, th = np.array([(b.x, b.y, b.v, b.theta) for b in bodies], dtype=np.float64).T
        a, omega = np.array(commands, dtype=np.float64).T
        x, y, v, th, bad = fly_arrays(self._fly_airframes, x, y, v, th, a, omega, dt)
        if bad.any():
            for k in np.flatnonzero(bad).tolist():
                self.violations["dynamics"] += 1
                seen = self.dynamics_by_uav.setdefault(ids[k], [0, t, t])
                seen[0] += 1
                seen[2] = t
        wind = self.wind
        for b, bx, by, bv, bth in zip(bodies, x.tolist(), y.tolist(), v.tolist(), th.tolist()):
            if wind is not None:
                bx += wind[0] * dt
                by += wind[1] * dt
            b.x, b.y, b.v, b.theta = bx, by, bv, bth

    def check_safety(self, ids: list[int], xy: np.ndarray, min_sep: float) -> list[tuple[str, int, int]]:
        """Count separation and threat-clearance violations now; returns them for the log."""
        found: list[tuple[str, int, int]] = []
        tick = self.pairs
        if len(ids) < 2 or _all_far_apart(xy, min_sep):
            pass
        elif tick is not None and min_sep <= tick.reach_m:
            # The tick's pairs (tick plane), in (i, j) order, judged at min_sep exactly.
            near_i, near_j, _d2 = tick.of(ids, xy).within(min_sep)
            found += [("separation", ids[a], ids[b]) for a, b in zip(near_i.tolist(), near_j.tolist())]
        else:
            from scipy.spatial import cKDTree  # (imported the first time two UAVs come near)

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
