"""Tests for agents.dynamics (limit_command, integrate, command_violates, wrap_angle) and
agents.types.UavType (turn_rate_max, r_min).

The turn-radius property is checked in its physical form: for every speed ``u`` the UAV flies
at during the step (from ``v`` to ``v_next``), ``u / |omega| >= r_min(u) = u^2 / (g tan phi)``;
this is the same as ``|omega| <= turn_rate_max(max(v, v_next))``, which is what
:func:`limit_command` enforces.
"""

from __future__ import annotations

import math

import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.dynamics import command_violates, integrate, limit_command, wrap_angle
from agents.types import GRAVITY, UavType

REL = 1e-9

# ---------------------------------------------------------------------------------------------
# strategies
# ---------------------------------------------------------------------------------------------


@st.composite
def uav_types(draw) -> UavType:
    smin = draw(st.floats(1.0, 60.0))
    smax = smin + draw(st.one_of(st.just(0.0), st.floats(0.0, 150.0)))
    return UavType(
        name="T",
        speed_min=smin,
        speed_max=smax,
        accel_max=draw(st.floats(0.05, 30.0)),
        bank_max_rad=draw(st.floats(math.radians(2.0), math.radians(80.0))),
        detect_radius=500.0,
        w_t=1.0,
        w_r=1.0,
        influence_radius=1000.0,
    )


dts = st.sampled_from([0.01, 0.1, 0.25, 0.5, 1.0, 2.0]) | st.floats(1e-3, 5.0)
huge = st.floats(allow_nan=False)  # includes +-inf and +-1.8e308
commands = st.one_of(st.floats(-50.0, 50.0), huge, st.sampled_from([0.0, -0.0, 1e300, -1e300]))


@st.composite
def speeds_inside(draw, k: UavType) -> float:
    return draw(st.one_of(st.sampled_from([k.speed_min, k.speed_max]), st.floats(k.speed_min, k.speed_max)))


@st.composite
def speeds_outside(draw, k: UavType, dt: float) -> float:
    """Slightly outside the range: some recoverable in one step, some not."""
    reach = 3.0 * k.accel_max * dt
    if draw(st.booleans()):
        return k.speed_max + draw(st.floats(1e-9, reach))
    return k.speed_min - draw(st.floats(1e-9, min(reach, 0.9 * k.speed_min)))


@st.composite
def cases(draw, inside: bool = True):
    k = draw(uav_types())
    dt = draw(dts)
    v = draw(speeds_inside(k)) if inside else draw(speeds_outside(k, dt))
    return k, v, draw(commands), draw(commands), dt


def turn_radius_ok(k: UavType, u: float, omega: float) -> bool:
    if omega == 0.0:
        return True
    return u / abs(omega) >= k.r_min(u) * (1 - REL)


# ---------------------------------------------------------------------------------------------
# UavType
# ---------------------------------------------------------------------------------------------


def test_turn_rate_and_r_min_reference_values():
    k = UavType("B", 25.0, 50.0, 2.0, math.radians(45.0), 500.0, 1.0, 1.0, 1000.0)
    assert k.r_min(30.0) == pytest.approx(900.0 / GRAVITY)
    assert k.turn_rate_max(30.0) == pytest.approx(GRAVITY / 30.0)
    # at the turn-rate limit the turn radius is exactly r_min
    assert 30.0 / k.turn_rate_max(30.0) == pytest.approx(k.r_min(30.0))
    # v = 0 does not divide by zero
    assert math.isfinite(k.turn_rate_max(0.0)) and k.turn_rate_max(0.0) > 0


# ---------------------------------------------------------------------------------------------
# limit_command
# ---------------------------------------------------------------------------------------------


@settings(deadline=None, max_examples=examples(300))
@given(cases(inside=True))
def test_limited_command_never_violates_when_speed_in_range(case):
    k, v, a, omega, dt = case
    a2, w2 = limit_command(k, v, a, omega, dt)
    assert math.isfinite(a2) and math.isfinite(w2)
    assert not command_violates(k, v, a2, w2, dt)
    assert abs(a2) <= k.accel_max
    v_next = v + a2 * dt
    assert k.speed_min * (1 - REL) <= v_next <= k.speed_max * (1 + REL)
    assert abs(w2) <= k.turn_rate_max(max(v, v_next))
    # the sign of a command is never flipped, only its magnitude limited (0 is in [lo, hi] here)
    assert a2 == 0.0 or math.copysign(1.0, a2) == math.copysign(1.0, a) or a == 0.0
    assert w2 == 0.0 or math.copysign(1.0, w2) == math.copysign(1.0, omega)


@settings(deadline=None, max_examples=examples(300))
@given(cases(inside=True))
def test_turn_radius_holds_throughout_the_step(case):
    k, v, a, omega, dt = case
    a2, w2 = limit_command(k, v, a, omega, dt)
    _, _, v_next, _ = integrate(0.0, 0.0, v, 0.0, a2, w2, dt)
    u_max = max(v, v_next)
    for u in (v, v_next, 0.5 * (v + v_next), u_max):
        assert turn_radius_ok(k, u, w2), (u, w2, k.r_min(u))
    # in particular at the larger speed, where the constraint is tightest
    if w2 != 0.0:
        assert u_max / abs(w2) >= k.r_min(u_max) * (1 - REL)


@settings(deadline=None, max_examples=examples(300))
@given(cases(inside=False))
def test_speed_slightly_outside_the_range_is_pulled_back(case):
    k, v, a, omega, dt = case
    a2, w2 = limit_command(k, v, a, omega, dt)
    assert abs(a2) <= k.accel_max * (1 + REL)
    v_next = v + a2 * dt
    if v > k.speed_max:
        assert v_next < v  # never accelerates further out of range
        recoverable = v - k.speed_max <= k.accel_max * dt
    else:
        assert v_next > v
        recoverable = k.speed_min - v <= k.accel_max * dt
    if recoverable:
        assert k.speed_min * (1 - REL) - REL <= v_next <= k.speed_max * (1 + REL) + REL
        assert not command_violates(k, v, a2, w2, dt)
    else:  # full brake / full throttle
        assert abs(a2) == pytest.approx(k.accel_max, rel=1e-12)
    # the turn radius constraint holds regardless
    for u in (v, v_next):
        assert turn_radius_ok(k, u, w2)
    assert abs(w2) <= k.turn_rate_max(max(v, v_next)) * (1 + REL)


@settings(deadline=None, max_examples=examples(200))
@given(cases(inside=True))
def test_limit_command_is_idempotent_and_keeps_valid_commands(case):
    k, v, a, omega, dt = case
    a2, w2 = limit_command(k, v, a, omega, dt)
    assert limit_command(k, v, a2, w2, dt) == (a2, w2)


@settings(deadline=None)
@given(uav_types(), dts, st.data())
def test_command_within_limits_is_unchanged(k, dt, data):
    v = data.draw(speeds_inside(k))
    lo = max(-k.accel_max, (k.speed_min - v) / dt)
    hi = min(k.accel_max, (k.speed_max - v) / dt)
    a = data.draw(st.floats(lo, hi))
    w_max = k.turn_rate_max(max(v, v + a * dt))
    omega = data.draw(st.floats(-w_max, w_max))
    assert limit_command(k, v, a, omega, dt) == (a, omega)


def test_limit_command_concrete_values():
    k = UavType("A", 20.0, 40.0, 2.0, math.radians(30.0), 500.0, 1.0, 1.0, 1000.0)
    # huge acceleration is clipped to accel_max, huge turn to the rate at the faster speed
    a, w = limit_command(k, 30.0, 1e300, 1e300, 0.5)
    assert a == 2.0
    assert w == pytest.approx(GRAVITY * math.tan(math.radians(30.0)) / 31.0)
    # near speed_max the acceleration is clipped so v_next == speed_max
    a, _ = limit_command(k, 39.5, 2.0, 0.0, 0.5)
    assert a == pytest.approx(1.0)
    # near speed_min braking is clipped so v_next == speed_min
    a, _ = limit_command(k, 20.25, -2.0, 0.0, 0.5)
    assert a == pytest.approx(-0.5)
    # far above speed_max: full brake whatever was asked
    assert limit_command(k, 45.0, 2.0, 0.0, 0.5)[0] == -2.0
    # far below speed_min: full throttle whatever was asked
    assert limit_command(k, 15.0, -2.0, 0.0, 0.5)[0] == 2.0


def test_command_violates_detects_each_limit():
    k = UavType("A", 20.0, 40.0, 2.0, math.radians(30.0), 500.0, 1.0, 1.0, 1000.0)
    assert not command_violates(k, 30.0, 0.0, 0.0, 0.5)
    assert command_violates(k, 30.0, 2.1, 0.0, 0.5)  # acceleration
    assert command_violates(k, 39.5, 2.0, 0.0, 0.5)  # speed above max after the step
    assert command_violates(k, 20.5, -2.0, 0.0, 0.5)  # speed below min after the step
    w = k.turn_rate_max(30.0)
    assert not command_violates(k, 30.0, 0.0, w, 0.5)
    assert command_violates(k, 30.0, 0.0, w * 1.001, 0.5)
    assert command_violates(k, 30.0, 0.0, -w * 1.001, 0.5)
    # the rate is judged at the faster of the two speeds
    assert command_violates(k, 30.0, 2.0, w, 0.5)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_commands_are_sanitised_and_flagged(bad):
    """Regression: NaN used to pass through limit_command and was not flagged as a violation."""
    k = UavType("A", 20.0, 40.0, 2.0, math.radians(30.0), 500.0, 1.0, 1.0, 1000.0)
    for a_in, w_in in ((bad, 0.1), (0.5, bad), (bad, bad)):
        a, w = limit_command(k, 30.0, a_in, w_in, 0.5)
        assert math.isfinite(a) and math.isfinite(w)
        assert not command_violates(k, 30.0, a, w, 0.5)
        x, y, v, th = integrate(0.0, 0.0, 30.0, 0.0, a, w, 0.5)
        assert all(math.isfinite(z) for z in (x, y, v, th))
    # the world's check flags a non-finite command that bypassed the limiter
    assert command_violates(k, 30.0, bad, 0.0, 0.5)
    assert command_violates(k, 30.0, 0.0, bad, 0.5)
    # a non-finite request means "hold": no acceleration, no turn
    assert limit_command(k, 30.0, bad, bad, 0.5) == (0.0, 0.0)


# ---------------------------------------------------------------------------------------------
# integrate
# ---------------------------------------------------------------------------------------------


@settings(deadline=None, max_examples=examples(300))
@given(cases(inside=True), st.floats(-1e4, 1e4), st.floats(-1e4, 1e4), st.floats(-math.pi, math.pi))
def test_speed_after_integrate_stays_in_range(case, x, y, theta):
    k, v, a, omega, dt = case
    a2, w2 = limit_command(k, v, a, omega, dt)
    x2, y2, v2, th2 = integrate(x, y, v, theta, a2, w2, dt)
    assert k.speed_min * (1 - REL) <= v2 <= k.speed_max * (1 + REL)
    assert -math.pi <= th2 <= math.pi
    # the step is never longer than the fastest speed times dt
    assert math.hypot(x2 - x, y2 - y) <= max(v, v2) * dt * (1 + 1e-9) + 1e-9
    # heading changed by omega*dt (mod 2 pi)
    d = th2 - (theta + w2 * dt)
    assert math.isclose(math.cos(d), 1.0, abs_tol=1e-9)


@settings(deadline=None, max_examples=examples(300))
@given(
    st.floats(-1e5, 1e5),
    st.floats(-1e5, 1e5),
    st.floats(0.0, 300.0),
    st.floats(-10 * math.pi, 10 * math.pi),
    st.floats(-20.0, 20.0),
    dts,
)
def test_straight_line_when_omega_is_zero(x, y, v, theta, a, dt):
    v_next = v + a * dt
    x2, y2, v2, th2 = integrate(x, y, v, theta, a, 0.0, dt)
    assert v2 == v_next
    dist = 0.5 * (v + v_next) * dt
    assert x2 == pytest.approx(x + dist * math.cos(theta), abs=1e-9 * (1 + abs(x) + abs(dist)))
    assert y2 == pytest.approx(y + dist * math.sin(theta), abs=1e-9 * (1 + abs(y) + abs(dist)))
    # on the line through (x, y) with heading theta: cross product ~ 0, dot product = dist
    dx, dy = x2 - x, y2 - y
    scale = 1e-9 * (1 + abs(x) + abs(y) + abs(dist))
    assert abs(dx * math.sin(theta) - dy * math.cos(theta)) <= scale
    assert dx * math.cos(theta) + dy * math.sin(theta) == pytest.approx(dist, abs=scale)
    # heading unchanged, only wrapped
    assert math.isclose(math.cos(th2 - theta), 1.0, abs_tol=1e-9)
    assert -math.pi <= th2 <= math.pi


def test_integrate_concrete_values():
    # east at 10 m/s, accelerating 2 m/s^2 for 1 s: mean speed 11 m/s
    x, y, v, th = integrate(0.0, 0.0, 10.0, 0.0, 2.0, 0.0, 1.0)
    assert (x, y, v, th) == (11.0, 0.0, 12.0, 0.0)
    # north
    x, y, v, th = integrate(5.0, 5.0, 10.0, math.pi / 2, 0.0, 0.0, 2.0)
    assert x == pytest.approx(5.0) and y == pytest.approx(25.0) and v == 10.0
    # a turn uses the mid-point heading
    x, y, v, th = integrate(0.0, 0.0, 10.0, 0.0, 0.0, 0.2, 1.0)
    assert x == pytest.approx(10.0 * math.cos(0.1)) and y == pytest.approx(10.0 * math.sin(0.1))
    assert th == pytest.approx(0.2)


def test_integrate_full_circle_returns_near_the_start():
    """At the turn-rate limit for 2 pi / omega seconds the UAV closes a circle of radius r_min."""
    k = UavType("A", 20.0, 40.0, 2.0, math.radians(30.0), 500.0, 1.0, 1.0, 1000.0)
    v = 30.0
    w = k.turn_rate_max(v)
    n = 2000
    dt = (2 * math.pi / w) / n
    x = y = th = 0.0
    max_dist = 0.0
    for _ in range(n):
        a, omega = limit_command(k, v, 0.0, 10.0, dt)
        assert (a, omega) == (0.0, w)
        x, y, v, th = integrate(x, y, v, th, a, omega, dt)
        max_dist = max(max_dist, math.hypot(x, y))
    assert math.hypot(x, y) < 1e-3
    assert max_dist == pytest.approx(2 * k.r_min(30.0), rel=1e-4)  # diameter


# ---------------------------------------------------------------------------------------------
# wrap_angle
# ---------------------------------------------------------------------------------------------


@settings(deadline=None, max_examples=examples(500))
@given(st.one_of(st.floats(-1e6, 1e6), st.floats(-10.0, 10.0),
                 st.sampled_from([0.0, math.pi, -math.pi, 2 * math.pi, -2 * math.pi, 3 * math.pi])))
def test_wrap_angle_range_and_equivalence(a):
    w = wrap_angle(a)
    assert -math.pi <= w <= math.pi
    assert math.isclose(math.cos(w), math.cos(a), abs_tol=1e-9 * (1 + abs(a)))
    assert math.isclose(math.sin(w), math.sin(a), abs_tol=1e-9 * (1 + abs(a)))
    # angles already in [-pi, pi) are returned as they are (up to rounding)
    if -math.pi <= a < math.pi:
        assert w == pytest.approx(a, abs=1e-15)
    # idempotent (up to rounding; +pi, where it occurs, maps to -pi)
    w2 = wrap_angle(w)
    assert w2 == pytest.approx(w, abs=1e-15) or (w == math.pi and w2 == -math.pi)


def test_wrap_angle_concrete_values():
    assert wrap_angle(0.0) == 0.0
    assert wrap_angle(math.pi) == -math.pi
    assert wrap_angle(-math.pi) == -math.pi
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert wrap_angle(-3 * math.pi / 2) == pytest.approx(math.pi / 2)
    assert wrap_angle(7.0) == pytest.approx(7.0 - 2 * math.pi)


@pytest.mark.parametrize("k", [0, 1, -1, 5, -5])
def test_wrap_angle_is_half_open(k):
    """Regression: a just below -pi (mod 2 pi) used to give +pi, outside [-pi, pi)."""
    for a in (math.nextafter(-math.pi, -math.inf) + k * 2 * math.pi, math.pi + k * 2 * math.pi):
        w = wrap_angle(a)
        assert -math.pi <= w < math.pi
        assert math.isclose(math.cos(w), math.cos(a), abs_tol=1e-12)


@settings(deadline=None, max_examples=examples(300))
@given(st.floats(-1e6, 1e6))
def test_wrap_angle_never_returns_pi(a):
    assert -math.pi <= wrap_angle(a) < math.pi
