"""Shortest Dubins path length from one pose to many points, final heading free.

This is the "relaxed Dubins" (Dubins-to-a-point) problem used by the DACMP fitness
(spec, "The planner" 3, eq. 19: ``Dub(k)``).  The vehicle starts at ``(x0, y0)`` with heading
``theta0`` (radians, 0 = +x, counter-clockwise positive), moves forward only with turning radius
at least ``r_min``, and must reach the point ``p``.  **The final heading is free**: the returned
length is the minimum over *all* final headings (not the length for the heading of the straight
line to the point).

Closed form (Bui, Soueres, Boissonnat & Laumond 1994, "Shortest path synthesis for Dubins
non-holonomic robot"; the free-terminal-heading optimal paths are of type CS or CC).
Work in the vehicle frame scaled by ``r = r_min``: the start is the origin, heading +x, and the
point is ``(x, y)``.  Because the problem is mirror symmetric, the point is reflected to
``y >= 0`` (the left side); the right side is the mirror image (swap L and R below).
The left minimum-turning circle has centre ``c_L = (0, 1)``, the right one ``c_R = (0, -1)``.
A point with ``y >= 0`` can never be strictly inside the right circle.

* **Outside (or on) the left circle**, ``|p - c_L| >= 1``: path **LS** -- turn toward the point's
  side by ``alpha`` along the circle, then go straight along the tangent to the point::

      d_c   = |p - c_L|                      (distance from the circle centre)
      t     = sqrt(d_c^2 - 1)                (tangent length)
      alpha = atan2(x + t (y - 1), t x + 1 - y)  in [0, 2 pi)
      L     = r (alpha + t)

  ``alpha`` is the heading of the tangent segment, i.e. the angle turned; it is obtained by solving
  ``p - c_L = (sin a, -cos a) + t (cos a, sin a)`` for ``a`` (the same as
  ``angle(p - c_L) + pi/2 - atan2(t, 1)`` modulo ``2 pi``).  A point straight ahead gives
  ``alpha = 0``, ``L = |p|``; a point on the circle gives ``t = 0`` (pure arc).

* **Strictly inside the left circle**, ``|p - c_L| < 1``: the point is too close on its own side
  to be reached by turning toward it, and the shortest path is **RL** (CC type): turn *away* by
  ``a`` on the right circle, then turn back by ``b`` on a left circle of centre ``c_2`` passing
  through the point.  With ``q = p - c_R`` (``1 < |q| < 3`` for such points), the second centre is
  ``c_2 = c_R + 2 u`` with ``u`` a unit vector such that ``|p - c_2| = 1``, i.e. (law of cosines)::

      angle(u) = angle(q) - gamma,   cos(gamma) = (|q|^2 + 3) / (4 |q|)
      a = pi/2 - angle(u)                      (first arc, clockwise, in [0, pi/3])
      b = (angle(p - c_2) - angle(-u)) mod 2 pi  (second arc, counter-clockwise, in (pi, 2 pi))
      L = r (a + b)

  The other root, ``angle(q) + gamma``, gives a first arc in ``[5 pi/3, 2 pi)`` and is always
  longer; the optimum has ``b > pi``, as in Bui et al.  The RS path (turn away all the way round,
  then straight) is also feasible there but never shorter.  Both claims are checked by the tests
  against a brute-force reference over all classic Dubins words and densely sampled final
  headings.

The length is discontinuous across the front arcs of the two turning circles (just outside: a
short arc; just inside: a long CC loop); that is a property of the problem, not of the code.
Points *exactly* at the start position get length 0 (the formula already gives it; it is also
guarded explicitly, for radii so small that ``1 / r`` overflows).  ``r_min <= 0`` means no
turning constraint: the Euclidean distance.

Everything is vectorised with numpy (no Python loop over points). :class:`DubinsPoses` keeps the
start poses' terms for repeated calls (a planner's particle swarm evaluates the same poses a few
dozen times per replanning).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["DubinsPoses", "dubins_length"]

_TWO_PI = 2.0 * math.pi


def dubins_length(
    x0: float | np.ndarray,
    y0: float | np.ndarray,
    theta0: float | np.ndarray,
    px: np.ndarray,
    py: np.ndarray,
    r_min: float | np.ndarray,
) -> np.ndarray:
    """Shortest forward path length from pose ``(x0, y0, theta0)`` to each point ``(px, py)``.

    Final heading free (minimum over all final headings); turning radius at least ``r_min``.
    Returns float64 with the broadcast shape of ``px`` and ``py`` (the shape of ``px`` when they
    have the same shape).  See the module docstring for the cases and formulas.

    Several start poses at once: ``x0``, ``y0``, ``r_min`` as arrays that broadcast against the
    points (e.g. shape ``(n, 1)`` for ``(n, m)`` points) and ``theta0`` as ``n`` headings, one per
    row. Each row then gets exactly the numbers of a call with that row's scalars (the heading's
    sine and cosine come from :mod:`math` either way).
    """
    px = np.asarray(px, dtype=np.float64)
    py = np.asarray(py, dtype=np.float64)
    px, py = np.broadcast_arrays(px, py)
    if np.ndim(theta0) == 0:
        dx = px - float(x0)
        dy = py - float(y0)
        r = float(r_min)
        if math.isnan(r):
            raise ValueError("r_min is NaN")
        if not r > 0.0:
            return np.hypot(dx, dy)
        # (1-d while computing: the in-place steps need arrays, and a 0-d array stays 0-d.)
        out = _lengths(np.stack([dx.reshape(-1), dy.reshape(-1)]), math.cos(theta0), math.sin(theta0), r, 1.0 / r)
        return out.reshape(dx.shape)
    poses = DubinsPoses(theta0, r_min, px.ndim)
    dx, dy = np.broadcast_arrays(px - np.asarray(x0, dtype=np.float64), py - np.asarray(y0, dtype=np.float64))
    # Offsets spanning every pose (the in-place steps keep the shape of the first product).
    shape = np.broadcast_shapes(dx.shape, poses.c.shape, poses.r.shape)
    return poses.lengths(np.broadcast_to(np.stack([dx, dy]), (2, *shape)))


class DubinsPoses:
    """``n`` start poses (headings ``theta0``, turning radii ``r_min``) whose lengths to many sets
    of points are wanted: the per-pose terms of :func:`dubins_length` computed once.

    ``lengths(d)`` takes the points as offsets from the start positions, stacked: ``d[0] = px -
    x0``, ``d[1] = py - y0`` (each with ``ndim`` dimensions, row ``i`` for pose ``i``), and returns
    exactly what :func:`dubins_length` returns for those poses and points. With ``shape`` (the
    shape of ``d[0]`` of every call) the per-pose terms are stored repeated to the shapes they
    meet (``d``'s or ``d[0]``'s): numpy is faster on same-shape operands than when it
    broadcasts, for the same numbers.
    """

    def __init__(self, theta0: float | np.ndarray, r_min: float | np.ndarray, ndim: int = 2,
                 shape: tuple[int, ...] | None = None):
        r = np.asarray(r_min, dtype=np.float64)
        if np.isnan(r).any():
            raise ValueError("r_min is NaN")
        # Poses without a turning constraint (r_min <= 0) get the straight-line distance, as a
        # single such pose would; the others are computed with radius 1 in their place.
        self.free = ~(r > 0.0) if not (r > 0.0).all() else None
        if self.free is not None:
            r = np.where(self.free, 1.0, r)
        theta = [float(a) for a in np.ravel(theta0)]
        column = (len(theta),) + (1,) * (ndim - 1)
        self.c = np.array([math.cos(a) for a in theta]).reshape(column)
        self.s = np.array([math.sin(a) for a in theta]).reshape(column)
        self.r = r
        self.inv_r = 1.0 / r
        # A point at the start needs the guard of _lengths only with a radius or an inverse that
        # is not finite (with finite ones the formula itself gives +0.0 there).
        self.guard = not (np.isfinite(r).all() and np.isfinite(self.inv_r).all())
        if shape is not None:
            def full(a: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
                return np.ascontiguousarray(np.broadcast_to(a, shape))

            self.c, self.s, self.inv_r = (full(a, (2, *shape)) for a in (self.c, self.s, self.inv_r))
            self.r = full(self.r, shape)

    def lengths(self, d: np.ndarray) -> np.ndarray:
        turning = _lengths(d, self.c, self.s, self.r, self.inv_r, self.guard)
        if self.free is None:
            return turning
        return np.where(self.free, np.hypot(d[0], d[1]), turning)


def _lengths(d: np.ndarray, c: float | np.ndarray, s: float | np.ndarray, r: float | np.ndarray,
             inv_r: float | np.ndarray, guard: bool = True) -> np.ndarray:
    """The closed form of the module docstring, for stacked offsets ``d = (dx, dy)`` (each at
    least 1-d) from the start and the start's ``cos``, ``sin``, ``r`` and ``1 / r`` (scalars, or
    arrays broadcasting into the offsets' shape). Temporaries are updated in place and the two
    coordinates share operations: the same numbers, fewer numpy calls. ``guard``: set the
    points at the start to 0 afterwards (needed only where ``r`` or ``1 / r`` is not finite:
    with finite ones the formula gives +0.0 there, whatever the signs of the zeros)."""
    # Vehicle frame, scaled by r, mirrored onto the left side (y >= 0).
    xy = c * d  # (c dx, c dy)
    sd = s * d  # (s dx, s dy)
    x: np.ndarray
    y: np.ndarray
    x, y = xy  # (views: the in-place steps below update xy)
    x += sd[1]  # c dx + s dy
    y -= sd[0]  # c dy - s dx
    np.abs(y, out=y)
    xy *= inv_r

    # |p - c_L|^2 - 1 = x^2 + (y-1)^2 - 1 = x^2 + y (y - 2)   (exact for y == 0: t == |x|)
    t2 = x * x
    w = y - 2.0
    w *= y
    t2 += w
    inside = (t2.ravel() < 0.0).nonzero()[0]  # flat indices: cheaper to gather and scatter than a mask

    # --- CS (LS) for every point; overwritten below for points inside the left circle.
    t = np.maximum(t2, 0.0, out=t2)
    np.sqrt(t, out=t)
    num = np.subtract(y, 1.0, out=w)
    num *= t
    num += x  # x + t (y - 1)
    den = t * x
    den += 1.0
    den -= y  # t x + 1 - y
    alpha = np.arctan2(num, den, out=num)
    np.add(alpha, _TWO_PI, out=alpha, where=alpha < 0.0)
    # Defensive: for x > 0 the true alpha lies in [0, pi], so a value near 2 pi there can only be a
    # rounded zero (point straight ahead).
    ahead = x > 0.0
    ahead &= alpha > math.pi
    alpha[ahead] = 0.0
    out: np.ndarray = alpha
    out += t

    # --- CC (RL) for points strictly inside the left turning circle (usually none). The x and
    # y rows of q and u share their operations (stacked: the same numbers, fewer calls).
    if inside.size:
        q = xy.reshape(2, -1).take(inside, axis=1)  # (x, y), then y + 1: q = p - c_R, c_R = (0, -1)
        xi, qy = q
        qy += 1.0  # 1 < |q| < 3 here
        dq = np.hypot(xi, qy)
        cos_gamma = dq * dq
        cos_gamma += 3.0
        cos_gamma /= 4.0 * dq  # (|q|^2 + 3) / (4 |q|)
        # Clipped to [-1, 1] (np.clip's numbers, without its Python-level overhead).
        np.maximum(cos_gamma, -1.0, out=cos_gamma)
        np.minimum(cos_gamma, 1.0, out=cos_gamma)
        gamma = np.arccos(cos_gamma, out=cos_gamma)
        ang_u = np.arctan2(qy, xi)
        ang_u -= gamma  # the root with the short first arc
        # first arc (clockwise): a = pi/2 - angle(u), in [0, pi/3]; wrap to [-pi, pi), clip rounding
        a = np.subtract(0.5 * math.pi, ang_u)
        a += math.pi
        np.mod(a, _TWO_PI, out=a)
        a -= math.pi
        np.maximum(a, 0.0, out=a)
        u = np.empty_like(q)
        np.cos(ang_u, out=u[0])
        np.sin(ang_u, out=u[1])
        # second centre c_2 = c_R + 2u; the switch point is c_R + u, seen from c_2 in direction -u
        to_p = q - 2.0 * u
        np.negative(u, out=u)
        b = np.arctan2(to_p[1], to_p[0])
        b -= np.arctan2(u[1], u[0])
        np.mod(b, _TWO_PI, out=b)
        # b lies in (pi, 2 pi): a value near 0 is 2 pi lost to rounding (point at the start)
        np.add(b, _TWO_PI, out=b, where=b < 0.5 * math.pi)
        a += b
        out.put(inside, a)

    out *= r
    # A point at the start gets +0.0 from the formula itself, but not with a radius whose
    # inverse overflows (0 * inf): guarded.
    if guard:
        zero = d == 0.0
        out[zero[0] & zero[1]] = 0.0
    return out
