"""Fixed-wing kinematics (eq. 9-10) and the hard limits on every command (eq. 11-12).

Both the world (to move UAVs) and the planners (to predict) use these functions, so a planner
can never ask for something the airframe cannot do: :func:`limit_command` is applied to every
command before integration.
"""

from __future__ import annotations

import math

from agents.types import UavType

TWO_PI = 2.0 * math.pi


def wrap_angle(a: float) -> float:
    """Angle in [-pi, pi)."""
    w = (a + math.pi) % TWO_PI - math.pi
    return w - TWO_PI if w >= math.pi else w  # the modulo can round up to exactly 2 pi


def clamp(v: float, lo: float, hi: float) -> float:
    """``min(max(v, lo), hi)``: the same comparisons in the same order, so the same result for
    every input (ties, signed zeros, NaN, ``lo > hi``), without the builtins' call overhead
    (several times the cost of the comparisons on these per-UAV, per-tick paths)."""
    v = lo if lo > v else v  # max(v, lo): the first argument wins a tie
    return hi if hi < v else v  # min(v, hi)


def limit_command(kind: UavType, v: float, a: float, omega: float, dt: float) -> tuple[float, float]:
    """Clip ``(a, omega)`` so that acceleration, speed range and turn radius all hold.

    The acceleration is limited so the speed stays in ``[speed_min, speed_max]`` after ``dt``;
    the turn rate uses the larger of the speeds before and after the step, so the turn radius
    constraint holds throughout the step.
    """
    # A non-finite request (a planner bug) must not reach the airframe: hold speed and heading.
    if not math.isfinite(a):
        a = 0.0
    if not math.isfinite(omega):
        omega = 0.0
    # Conditional expressions for max()/min() (see clamp()).
    lo, hi = -kind.accel_max, kind.accel_max
    slow, fast = (kind.speed_min - v) / dt, (kind.speed_max - v) / dt
    lo = slow if slow > lo else lo  # max(-accel_max, slow)
    hi = fast if fast < hi else hi  # min(accel_max, fast)
    if lo <= hi:
        a = clamp(a, lo, hi)
    else:  # speed outside the range and not recoverable in one step: brake/accelerate fully
        a = -kind.accel_max if v > kind.speed_max else kind.accel_max
    v_next = v + a * dt
    w_max = kind.turn_rate_max(v_next if v_next > v else v)  # max(v, v_next)
    omega = clamp(omega, -w_max, w_max)
    return a, omega


def integrate(x: float, y: float, v: float, theta: float, a: float, omega: float, dt: float) -> tuple[float, float, float, float]:
    """Advance one step (mid-point heading, mean speed): deterministic and second order."""
    v_next = v + a * dt
    theta_mid = theta + 0.5 * omega * dt
    v_mean = 0.5 * (v + v_next)
    x += v_mean * math.cos(theta_mid) * dt
    y += v_mean * math.sin(theta_mid) * dt
    return x, y, v_next, wrap_angle(theta + omega * dt)


def command_violates(kind: UavType, v: float, a: float, omega: float, dt: float, tol: float = 1e-9) -> bool:
    """True if a command that was applied breaks a hard limit (the world counts these)."""
    if not (math.isfinite(a) and math.isfinite(omega)):
        return True
    v_next = v + a * dt
    if abs(a) > kind.accel_max * (1 + tol) + tol:
        return True
    if v_next < kind.speed_min * (1 - tol) - tol or v_next > kind.speed_max * (1 + tol) + tol:
        return True
    return abs(omega) > kind.turn_rate_max(v_next if v_next > v else v) * (1 + tol) + tol  # max(v, v_next)
