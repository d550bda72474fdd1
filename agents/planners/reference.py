"""What the reference planners share: Dubins paths, sampled tracks and a track follower.

The reference planners (:mod:`.lawnmower`, :mod:`.formation`, :mod:`.levy`) each fly a
*pattern*: a path that a fixed-wing UAV can fly (straight legs joined by arcs no tighter than
its turn radius at full speed, times a margin). A planner only returns the next waypoint; the
simulator's local planner (:mod:`agents.apf`) steers towards it within the airframe's limits,
and a new waypoint is asked for every ``replan_s`` or when the last one is reached. So each
planner keeps, per UAV (each UAV has its own instance), a :class:`Follower`: the pattern sampled
every ``ds`` metres (a :class:`Track`, extended on demand), the UAV's progress along it, and
the waypoint it returns, a point ``lookahead`` metres further along (pure pursuit: close enough
that the straight line to it stays within tens of metres of the pattern's arcs, far enough that
it is not reached before the next replan). A UAV found more than ``rejoin_m`` from its pattern
(pushed off it by collision or threat avoidance, or at the start) flies the shortest Dubins path
back to a point of the pattern a little ahead, and goes on from there.

Known threats (``view.knowledge.threats``, sensed or heard): where the pattern runs into a
threat's *ring* (its influence radius ``d_max`` plus a margin) the UAV follows the ring to where
the pattern comes out (:meth:`Follower.waypoint`), and it does not rejoin a part of the pattern
inside a ring; the planners finally move any waypoint still inside a ``d_max`` radially out of
it (:func:`push_out_of_threats`, up to four rounds where rings overlap), so no waypoint lies
inside one. The APF repels as well, and
its guard turns away from a threat's edge.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable

import numpy as np

from agents.knowledge import KnownThreat
from agents.planners.base import PlanView

__all__ = [
    "Follower",
    "Track",
    "dubins_length",
    "dubins_shortest",
    "inside_threat",
    "lookahead_m",
    "planning_radius",
    "push_out_of_threats",
    "spread_offsets",
    "threat_rings",
]

TWO_PI = 2.0 * math.pi
TURN_MARGIN = 1.15  # planned arcs: this times the turn radius at full speed (the APF follows)
SAMPLE_M = 50.0  # track spacing
THREAT_MARGIN_M = 150.0  # waypoints are kept this far outside a known threat's d_max


def planning_radius(view: PlanView) -> float:
    """The radius of the pattern's arcs: the turn radius at full speed, with a margin."""
    k = view.kind
    return TURN_MARGIN * k.r_min(k.speed_max)


def lookahead_m(view: PlanView, r_plan: float) -> float:
    """How far ahead along the pattern the waypoint is: a little more than one replanning step
    (so it is not reached before the next), but no more than the arcs' radius (so the straight
    line to it stays close to the arc), and at least a few hundred metres."""
    return max(200.0, min(1.2 * view.kind.speed_max * view.replan_s, r_plan))


def spread_offsets(lo: float, hi: float, spacing_max: float) -> list[float]:
    """Offsets of the fewest parallel passes at most ``spacing_max`` apart whose swaths (half
    the spacing either side) tile ``[lo, hi]``: ``m = ceil((hi - lo) / spacing_max)`` passes,
    evenly spaced, the first and last half a spacing from the edges."""
    width = hi - lo
    m = max(1, math.ceil(width / spacing_max - 1e-9))
    step = width / m
    return [lo + (j + 0.5) * step for j in range(m)]


# --- Dubins paths -------------------------------------------------------------------------------
# Shortest paths of a forward-only vehicle with a minimum turning radius between two poses
# (Dubins 1957): one of six words of arcs (L, R) and a straight (S). The closed forms are those of
# Shkel & Lumelsky (2001), in the frame where the start is at the origin and the goal on the
# +x axis, lengths in units of the radius.


def _mod2pi(a: float) -> float:
    return a - TWO_PI * math.floor(a / TWO_PI)


def _angle(a: float) -> float:
    """``a`` modulo 2 pi, with a whole turn that rounding left over read as none."""
    m = _mod2pi(a)
    return 0.0 if m > TWO_PI - 1e-9 else m


def _root(p2: float) -> float | None:
    return math.sqrt(max(p2, 0.0)) if p2 >= -1e-9 else None  # (tangent cases round either way)


def _words(alpha: float, beta: float, d: float) -> list[tuple[str, float, float, float]]:
    sa, sb, ca, cb = math.sin(alpha), math.sin(beta), math.cos(alpha), math.cos(beta)
    c_ab = math.cos(alpha - beta)
    out = []
    p = _root(2.0 + d * d - 2.0 * c_ab + 2.0 * d * (sa - sb))
    if p is not None:
        tmp = math.atan2(cb - ca, d + sa - sb)
        out.append(("LSL", _angle(tmp - alpha), p, _angle(beta - tmp)))
    p = _root(2.0 + d * d - 2.0 * c_ab + 2.0 * d * (sb - sa))
    if p is not None:
        tmp = math.atan2(ca - cb, d - sa + sb)
        out.append(("RSR", _angle(alpha - tmp), p, _angle(tmp - beta)))
    p = _root(-2.0 + d * d + 2.0 * c_ab + 2.0 * d * (sa + sb))
    if p is not None:
        tmp = math.atan2(-ca - cb, d + sa + sb) - math.atan2(-2.0, p)
        out.append(("LSR", _angle(tmp - alpha), p, _angle(tmp - beta)))
    p = _root(-2.0 + d * d + 2.0 * c_ab - 2.0 * d * (sa + sb))
    if p is not None:
        tmp = math.atan2(ca + cb, d - sa - sb) - math.atan2(2.0, p)
        out.append(("RSL", _angle(alpha - tmp), p, _angle(beta - tmp)))
    c = (6.0 - d * d + 2.0 * c_ab + 2.0 * d * (sa - sb)) / 8.0
    if abs(c) <= 1.0 + 1e-9:
        p = TWO_PI - math.acos(max(-1.0, min(1.0, c)))  # in [pi, 2 pi]
        t = _angle(alpha - math.atan2(ca - cb, d - sa + sb) + p / 2.0)
        out.append(("RLR", t, p, _angle(alpha - beta - t + p)))
    c = (6.0 - d * d + 2.0 * c_ab + 2.0 * d * (sb - sa)) / 8.0
    if abs(c) <= 1.0 + 1e-9:
        p = TWO_PI - math.acos(max(-1.0, min(1.0, c)))  # in [pi, 2 pi]
        t = _angle(-alpha - math.atan2(ca - cb, d + sa - sb) + p / 2.0)
        out.append(("LRL", t, p, _angle(beta - alpha - t + p)))
    return out


Pose = tuple[float, float, float]  # x, y, heading (radians, 0 = +x, counter-clockwise)


def dubins_shortest(q0: Pose, q1: Pose, r: float) -> tuple[str, tuple[float, float, float]]:
    """The shortest Dubins path from ``q0`` to ``q1`` with turning radius ``r``: its word
    (e.g. ``"LSR"``) and the lengths of its three segments in metres."""
    dx, dy = q1[0] - q0[0], q1[1] - q0[1]
    d = math.hypot(dx, dy) / r
    th = math.atan2(dy, dx) if d > 0.0 else 0.0
    alpha, beta = _mod2pi(q0[2] - th), _mod2pi(q1[2] - th)
    best = min(_words(alpha, beta, d), key=lambda w: w[1] + w[2] + w[3])  # LSL or RSR always exist
    return best[0], (best[1] * r, best[2] * r, best[3] * r)


def dubins_length(q0: Pose, q1: Pose, r: float) -> float:
    return sum(dubins_shortest(q0, q1, r)[1])


# --- sampled tracks -----------------------------------------------------------------------------


class Track:
    """A path sampled every ``ds`` metres of arc length: point ``k`` is ``k * ds`` from the
    start. Built by appending straights and arcs at its end (the "pen"); poses along it are
    exact (the arcs' points lie on the arcs)."""

    def __init__(self, x: float, y: float, heading: float, ds: float = SAMPLE_M):
        self.ds = ds
        self._xy = np.empty((256, 3))
        self._xy[0] = x, y, heading
        self._n = 1
        self.pen: Pose = (x, y, heading)
        self._next = ds  # arc length into the next segment at which the next point lies

    def __len__(self) -> int:
        return self._n

    def pose(self, k: int) -> Pose:
        x, y, h = self._xy[k]
        return float(x), float(y), float(h)

    def points(self, lo: int, hi: int) -> np.ndarray:
        """Rows ``(x, y, heading)`` of points ``lo .. hi - 1`` (clipped to the track)."""
        return self._xy[max(lo, 0):min(hi, self._n)]

    def _append(self, pts: np.ndarray) -> None:
        need = self._n + len(pts)
        if need > len(self._xy):
            grown = np.empty((max(need, 2 * len(self._xy)), 3))
            grown[:self._n] = self._xy[:self._n]
            self._xy = grown
        self._xy[self._n:need] = pts
        self._n = need

    def _offsets(self, length: float) -> np.ndarray:
        s = np.arange(self._next, length + 1e-9, self.ds)
        self._next = (s[-1] + self.ds - length) if len(s) else self._next - length
        return s

    def line(self, length: float) -> None:
        if length <= 0.0:
            return
        x, y, h = self.pen
        s = self._offsets(length)
        c, sn = math.cos(h), math.sin(h)
        self._append(np.column_stack([x + s * c, y + s * sn, np.full(len(s), h)]))
        self.pen = (x + length * c, y + length * sn, h)

    def arc(self, side: float, length: float, r: float) -> None:
        """Turn ``length`` metres of arc on a circle of radius ``r``: left (``side = +1``,
        counter-clockwise) or right (``-1``)."""
        if length <= 0.0:
            return
        x, y, h = self.pen
        cx, cy = x - side * r * math.sin(h), y + side * r * math.cos(h)
        s = self._offsets(length)
        hs = h + side * s / r
        self._append(np.column_stack([cx + side * r * np.sin(hs), cy - side * r * np.cos(hs), hs]))
        he = h + side * length / r
        self.pen = (cx + side * r * math.sin(he), cy - side * r * math.cos(he), math.remainder(he, TWO_PI))

    def turn_to(self, heading: float, r: float) -> None:
        """Turn the shorter way round (left on an exact reversal) until the pen has ``heading``."""
        delta = math.remainder(heading - self.pen[2], TWO_PI)
        if abs(delta) >= math.pi - 1e-12:
            delta = math.pi
        self.arc(1.0 if delta >= 0 else -1.0, abs(delta) * r, r)
        self.pen = (self.pen[0], self.pen[1], heading)

    def dubins_to(self, goal: Pose, r: float) -> None:
        """Append the shortest Dubins path from the pen to ``goal``."""
        word, lengths = dubins_shortest(self.pen, goal, r)
        for letter, length in zip(word, lengths):
            if letter == "S":
                self.line(length)
            else:
                self.arc(1.0 if letter == "L" else -1.0, length, r)
        self.pen = goal  # (the sampled points end within rounding of it)

    def nearest(self, x: float, y: float, lo: int, hi: int) -> tuple[int, float]:
        """The point of ``lo .. hi - 1`` nearest ``(x, y)`` and its distance."""
        lo = max(lo, 0)
        pts = self.points(lo, hi)
        if not len(pts):
            return lo, math.inf
        d2 = (pts[:, 0] - x) ** 2 + (pts[:, 1] - y) ** 2
        i = int(np.argmin(d2))
        return lo + i, math.sqrt(float(d2[i]))


# --- threats ------------------------------------------------------------------------------------


def push_out_of_threats(x: float, y: float, threats: Iterable[KnownThreat], from_xy: tuple[float, float],
                        margin: float = THREAT_MARGIN_M) -> tuple[float, float]:
    """``(x, y)`` moved radially out of every known threat's influence radius (plus ``margin``);
    a point at a threat's very centre goes out on the side of ``from_xy`` (the UAV)."""
    threats = list(threats)
    for _ in range(4):  # rings can overlap: a point pushed out of one may land in another
        moved = False
        for th in threats:
            dx, dy = x - th.x, y - th.y
            d = math.hypot(dx, dy)
            ring = th.d_max + margin
            if d < ring:
                if d < 1e-6:
                    dx, dy = from_xy[0] - th.x, from_xy[1] - th.y
                    d = math.hypot(dx, dy) or 1.0
                    if d == 1.0 and dx == dy == 0.0:
                        dx = 1.0
                x, y = th.x + ring * dx / d, th.y + ring * dy / d
                moved = True
        if not moved:
            break
    return x, y


def inside_threat(x: float, y: float, threats: Iterable[KnownThreat], margin: float = THREAT_MARGIN_M) -> bool:
    return any(math.hypot(x - th.x, y - th.y) < th.d_max + margin for th in threats)


# --- following a track --------------------------------------------------------------------------

Ring = tuple[float, float, float]  # a known threat's centre and the radius to keep out of (d_max + margin)


def threat_rings(threats: Iterable[KnownThreat], swap: bool = False, margin: float = THREAT_MARGIN_M) -> list[Ring]:
    """Known threats as rings to keep out of, in the frame of a planner (``swap``: x and y
    exchanged, see :class:`Follower`)."""
    return [((th.y, th.x) if swap else (th.x, th.y)) + (th.d_max + margin,) for th in threats]


def _ring_at(x: float, y: float, rings: list[Ring]) -> Ring | None:
    for ring in rings:
        if math.hypot(x - ring[0], y - ring[1]) < ring[2]:
            return ring
    return None


class Follower:
    """Pure pursuit along a pattern, with Dubins rejoins and detours around threat rings.

    ``extend(track)`` appends the pattern's next leg to ``track`` (called whenever the waypoint
    would run past its end). Coordinates are whatever frame the caller works in; poses and
    rings given to :meth:`waypoint` must be in the same frame.

    Threats: when the waypoint would lie inside a ring (a known threat's ``d_max`` plus a
    margin), the UAV detours: it follows the ring (waypoints a lookahead apart on it, the
    shorter way round) to where the pattern leaves the ring, and goes on from there. Moving the
    waypoint radially out of the ring instead stalls a UAV whose pattern runs through the
    threat's centre: every waypoint lands on the same point of the ring.
    """

    def __init__(self, track: Track, extend: Callable[[Track], None], r_plan: float, lookahead: float,
                 rejoin_m: float, join_window_m: float):
        self.track = track
        self.extend = extend
        self.r = r_plan
        self.look = lookahead
        self.lk = max(1, round(lookahead / track.ds))
        self.rejoin_m = rejoin_m
        self.window = max(2, round(join_window_m / track.ds))
        self.k = 0  # progress: the track point the UAV was last found nearest
        self.transit: Track | None = None  # a Dubins path back onto the track, if flying one
        self.kt = 0  # progress along the transit
        self.join_k = 0  # where the transit meets the track
        self.detour: tuple[Ring, float, int] | None = None  # ring, sense (+1 ccw), exit point on the track
        self.t_last: float | None = None
        self.rejoins = 0
        self.detours = 0

    def _ensure(self, k: int) -> None:
        while len(self.track) <= k:
            before = len(self.track)
            self.extend(self.track)
            if len(self.track) == before:  # a pattern that cannot grow: stop asking
                break

    def join(self, pose: Pose, start: int, window: int | None = None, slot: int | None = None) -> None:
        """Fly a Dubins path from ``pose`` to a point of the track in ``start .. start + window``:
        the shortest (ties: the earliest); with ``slot`` (a track point moving at the UAV's
        speed, see :meth:`waypoint`), the earliest that leaves the UAV within 100 m of the least
        lag behind the slot it can have on arrival."""
        window = self.window if window is None else window
        step = max(1, round(250.0 / self.track.ds))
        self._ensure(start + window)
        ks = range(max(start, 0), min(start + window, len(self.track)), step)
        costs = [dubins_length(pose, self.track.pose(k), self.r) for k in ks]
        if not costs:  # (a track that cannot grow that far)
            best_k = min(start, len(self.track) - 1)
        elif slot is not None:
            costs = [c - (k - slot) * self.track.ds for k, c in zip(ks, costs)]  # lag on arrival
            least = min(costs)
            best_k = next(k for k, c in zip(ks, costs) if c <= least + 100.0)
        else:
            best_k = ks[min(range(len(ks)), key=lambda i: (costs[i], i))]
        tr = Track(*pose, ds=self.track.ds)
        tr.dubins_to(self.track.pose(best_k), self.r)
        self.transit, self.kt, self.join_k = tr, 0, best_k
        self.rejoins += 1

    def _start_detour(self, pose: Pose, ring: Ring, k_from: int, rings: list[Ring]) -> None:
        """Detour round ``ring`` to the first track point from ``k_from`` on outside every ring,
        the way round that is shorter counting the turn onto it."""
        x, y, heading = pose
        k = k_from
        limit = k_from + round(8.0 * ring[2] / self.track.ds) + self.lk
        self._ensure(limit)
        pts = self.track.points(k_from, limit + 1)
        outside = np.ones(len(pts), dtype=bool)
        for cx, cy, rho in rings:
            outside &= (pts[:, 0] - cx) ** 2 + (pts[:, 1] - cy) ** 2 >= rho * rho
        k = k_from + int(np.argmax(outside)) if outside.any() else limit
        ex, ey, _ = self.track.pose(k)
        cx, cy, rho = ring
        a_u = math.atan2(y - cy, x - cx)
        ccw = _mod2pi(math.atan2(ey - cy, ex - cx) - a_u)  # angle to go round counter-clockwise

        def cost(sense: float) -> float:
            around = ccw if sense > 0 else TWO_PI - ccw
            onto = abs(math.remainder(a_u + sense * math.pi / 2 - heading, TWO_PI))  # turn onto the ring
            return around * rho + onto * self.r

        self.detour = (ring, 1.0 if cost(1.0) <= cost(-1.0) else -1.0, k)
        self.transit = None
        self.detours += 1

    def _detour_point(self, x: float, y: float) -> tuple[float, float] | None:
        """The next waypoint round the ring, or None when the exit is within a lookahead."""
        assert self.detour is not None
        (cx, cy, rho), sense, k_exit = self.detour
        ex, ey, _ = self.track.pose(k_exit)
        a_u = math.atan2(y - cy, x - cx)
        left = sense * math.remainder(math.atan2(ey - cy, ex - cx) - a_u, TWO_PI)
        if left < 0.0:
            left += TWO_PI if left < -math.pi / 2 else 0.0  # (a small overshoot past the exit: done)
        step = self.look / rho
        if left <= step or math.hypot(ex - x, ey - y) <= self.look:
            self.detour = None
            self.k = max(self.k, k_exit)
            return None
        a = a_u + sense * step
        return cx + rho * math.cos(a), cy + rho * math.sin(a)

    def waypoint(self, pose: Pose, t: float, speed: float, sync_k: int | None = None,
                 rings: list[Ring] | None = None) -> tuple[float, float]:
        """The next waypoint for a UAV at ``pose`` at time ``t``. ``sync_k``: a track point the
        UAV should not be behind (a formation's slot); the waypoint is ``lookahead`` past the
        later of it and the UAV's own progress. ``rings``: known threats to keep out of."""
        rings = rings or []
        x, y = pose[0], pose[1]
        dt = (t - self.t_last) if self.t_last is not None else 0.0
        self.t_last = t
        travel = max(1, round((1.5 * speed * dt) / self.track.ds)) + self.lk + 2
        if self.detour is not None:
            wp = self._detour_point(x, y)
            if wp is not None:
                return wp
        if self.transit is not None:
            tr = self.transit
            self.kt, _ = tr.nearest(x, y, self.kt, self.kt + travel)
            left = len(tr) - 1 - self.kt
            if left > self.lk:
                wx, wy, _ = tr.pose(self.kt + self.lk)
                ring = _ring_at(wx, wy, rings)
                if ring is None:
                    return wx, wy
                self._start_detour(pose, ring, self.join_k, rings)
                return self._detour_point(x, y) or self._point(self.k + self.lk)
            self.k = max(self.k, self.join_k - left)
            self.transit = None
        base = self.k if sync_k is None else max(self.k, sync_k)
        self._ensure(base + travel)
        k, d = self.track.nearest(x, y, self.k, base + travel)
        self.k = max(self.k, k)
        base = self.k if sync_k is None else max(self.k, sync_k)
        px, py, _ = self.track.pose(self.k)
        if d > self.rejoin_m and _ring_at(px, py, rings) is None:
            self.join(pose, base, slot=sync_k)
            assert self.transit is not None
            wx, wy, _ = self.transit.pose(min(self.lk, len(self.transit) - 1))
            ring = _ring_at(wx, wy, rings)
            if ring is None:
                return wx, wy
            self._start_detour(pose, ring, self.join_k, rings)  # the way back runs into a ring
            return self._detour_point(x, y) or self._point(self.k + self.lk)
        wx, wy = self._point(base + self.lk)
        ring = _ring_at(wx, wy, rings)
        if ring is not None:
            self._start_detour(pose, ring, base + self.lk, rings)
            return self._detour_point(x, y) or self._point(self.k + self.lk)
        return wx, wy

    def _point(self, k: int) -> tuple[float, float]:
        self._ensure(k)
        x, y, _ = self.track.pose(min(k, len(self.track) - 1))
        return x, y
