"""agents.station: where a watcher keeps a target (rule 5 of docs/modelling.md's assignment rules).
Here the geometry of :func:`agents.station.exit_ahead`, the point where a target lost in a no-fly
zone comes out if it keeps its course, against the closed form for a circle and by hand for a
polygon; the keeping itself runs in tests/test_assignment_rules.py (rule 5)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from agents.knowledge import KnownThreat, Track
from agents.station import exit_ahead
from agents.zones import Keepout

_CIRCLE = KnownThreat(0, 10_000.0, 10_000.0, 2000.0, 5000.0)
_SQUARE = Keepout(1, [(8000.0, 8000.0), (12_000.0, 8000.0), (12_000.0, 12_000.0), (8000.0, 12_000.0)], 3000.0)


def _track(x: float, y: float, vx: float, vy: float, t: float = 50.0) -> Track:
    return Track(0, x, y, vx, vy, t)


def test_a_target_driving_through_comes_out_on_the_far_side_when_its_speed_says():
    out = exit_ahead(_CIRCLE, _track(7500.0, 10_000.0, 5.0, 0.0))
    assert out is not None
    x, y, t = out
    assert x == pytest.approx(12_000.0, abs=1.0) and y == pytest.approx(10_000.0)
    assert t == pytest.approx(50.0 + 4500.0 / 5.0, abs=1.0 / 5.0 + 1e-6)  # (the exit: within 1 m past the edge)
    out = exit_ahead(_SQUARE, _track(9000.0, 7000.0, 0.0, 8.0))  # polygon alike: in at the south, out at the north
    assert out is not None
    assert out[0] == pytest.approx(9000.0) and out[1] == pytest.approx(12_000.0, abs=1.0)
    assert out[2] == pytest.approx(50.0 + 5000.0 / 8.0, abs=1.0 / 8.0 + 1e-6)


def test_no_exit_point_for_a_course_that_does_not_cross_the_zone():
    assert exit_ahead(_CIRCLE, _track(7500.0, 10_000.0, -5.0, 0.0)) is None  # heading away
    assert exit_ahead(_CIRCLE, _track(7500.0, 12_500.0, 5.0, 0.0)) is None  # passing by, 0.5 km off
    assert exit_ahead(_CIRCLE, _track(7500.0, 10_000.0, 0.0, 0.0)) is None  # standing still
    assert exit_ahead(_SQUARE, _track(7000.0, 7000.0, -1.0, 3.0)) is None  # passing by the polygon


@given(st.floats(0.0, 2 * math.pi), st.floats(0.0, 1990.0), st.floats(0.5, 20.0))
def test_from_inside_the_exit_is_on_the_circle_along_the_course(heading, r0, speed):
    """From any point inside, on any course: the exit is on the edge (within 1 m, outside it),
    straight ahead, and reached at the given speed."""
    x0, y0 = 10_000.0 + r0 * math.cos(heading + 1.0), 10_000.0 + r0 * math.sin(heading + 1.0)
    vx, vy = speed * math.cos(heading), speed * math.sin(heading)
    out = exit_ahead(_CIRCLE, _track(x0, y0, vx, vy))
    assert out is not None
    x, y, t = out
    assert 2000.0 <= math.hypot(x - 10_000.0, y - 10_000.0) <= 2001.0
    d = math.hypot(x - x0, y - y0)
    assert (x - x0) * vx + (y - y0) * vy == pytest.approx(d * speed, rel=1e-9)
    assert t == pytest.approx(50.0 + d / speed)
