"""swarm.kernel.clock.Clock: virtual time and a heap of callbacks ordered by (time, priority, sequence).

The simulation's determinism rests on this order: at one instant faults and joins run before
deliveries, deliveries before the tick, and entries of one priority in the order they were
scheduled. Nothing here sleeps or reads the wall clock.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from swarm.errors import SimulationError, SwarmError
from swarm.kernel.clock import DELIVERY, FAULT, TICK, Clock


def _drain(clock: Clock) -> list:
    """Pop every entry, calling each callback; returns what they returned, in order."""
    out = []
    while len(clock):
        out.append(clock.pop()())
    return out


def _tag(value):
    return lambda: value


def test_a_new_clock_is_at_its_start_and_empty():
    assert Clock().now == 0.0
    clock = Clock(start=12.5)
    assert clock.now == 12.5 and isinstance(clock.now, float)
    assert len(clock) == 0


def test_peek_on_an_empty_clock_is_infinity_and_pop_raises():
    clock = Clock()
    assert clock.peek() == math.inf
    with pytest.raises(IndexError):
        clock.pop()
    assert clock.now == 0.0  # a failed pop does not move time


def test_entries_come_out_by_time_whatever_the_scheduling_order():
    clock = Clock()
    for t in (5.0, 1.0, 3.0, 2.0, 4.0):
        clock.schedule(t, _tag(t))
    assert _drain(clock) == [1.0, 2.0, 3.0, 4.0, 5.0]


def test_at_one_instant_faults_then_deliveries_then_the_tick():
    clock = Clock()
    clock.schedule(1.0, _tag("tick"), TICK)
    clock.schedule(1.0, _tag("delivery"), DELIVERY)
    clock.schedule(1.0, _tag("fault"), FAULT)
    clock.schedule(0.5, _tag("earlier tick"), TICK)  # time first, priority second
    assert _drain(clock) == ["earlier tick", "fault", "delivery", "tick"]
    assert FAULT < DELIVERY < TICK


def test_the_default_priority_is_a_delivery():
    clock = Clock()
    clock.schedule(1.0, _tag("tick"), TICK)
    clock.schedule(1.0, _tag("default"))
    clock.schedule(1.0, _tag("fault"), FAULT)
    assert _drain(clock) == ["fault", "default", "tick"]


def test_ties_at_one_instant_and_priority_run_in_scheduling_order():
    clock = Clock()
    for i in range(50):
        clock.schedule(2.0, _tag(i), DELIVERY)
    assert _drain(clock) == list(range(50))


def test_callbacks_are_never_compared():
    """Equal (time, priority) entries are told apart by their sequence number: callbacks that
    cannot be ordered (functions, or objects whose ``<`` raises) are fine."""

    class Unorderable:
        def __init__(self, i):
            self.i = i

        def __lt__(self, other):
            raise AssertionError("the heap compared two callbacks")

        def __call__(self):
            return self.i

    clock = Clock()
    for i in range(10):
        clock.schedule(1.0, Unorderable(i), FAULT)
    assert _drain(clock) == list(range(10))


def test_pop_advances_now_to_the_entry_and_peek_does_not():
    clock = Clock()
    clock.schedule(3.0, _tag("a"))
    clock.schedule(7.5, _tag("b"))
    assert clock.peek() == 3.0 and clock.now == 0.0
    assert clock.pop()() == "a"
    assert clock.now == 3.0 and clock.peek() == 7.5 and len(clock) == 1
    assert clock.pop()() == "b"
    assert clock.now == 7.5 and clock.peek() == math.inf and len(clock) == 0


def test_scheduling_in_the_past_is_refused_and_now_is_allowed():
    clock = Clock()
    clock.schedule(5.0, _tag("a"))
    clock.pop()
    with pytest.raises(SimulationError, match=r"t=4\.0 before now=5\.0"):
        clock.schedule(4.0, _tag("too late"))
    assert len(clock) == 0  # nothing was added
    clock.schedule(5.0, _tag("now"))  # the current instant is still open
    clock.schedule(5.0 + 1e-12, _tag("just after"))
    assert _drain(clock) == ["now", "just after"]
    assert issubclass(SimulationError, SwarmError)


def test_a_clock_with_a_start_refuses_times_before_it():
    clock = Clock(start=10.0)
    with pytest.raises(SimulationError):
        clock.schedule(9.0, _tag("before the start"))


def test_callbacks_may_schedule_more_at_the_same_instant_and_they_run_after():
    """An entry added while its instant is being processed runs at that instant, after the
    entries of its priority already there (a delivery scheduled by a fault, say)."""
    clock = Clock()
    order = []

    def fault():
        order.append("fault")
        clock.schedule(clock.now, lambda: order.append("delivery added by the fault"), DELIVERY)
        clock.schedule(clock.now, lambda: order.append("fault added by the fault"), FAULT)

    clock.schedule(1.0, lambda: order.append("tick"), TICK)
    clock.schedule(1.0, lambda: order.append("delivery"), DELIVERY)
    clock.schedule(1.0, fault, FAULT)
    _drain(clock)
    assert order == ["fault", "fault added by the fault", "delivery", "delivery added by the fault", "tick"]
    assert clock.now == 1.0


@given(st.lists(st.tuples(st.integers(0, 20).map(float), st.sampled_from([FAULT, DELIVERY, TICK])), max_size=60))
def test_pop_order_is_sorted_by_time_priority_then_scheduling_order(entries):
    clock = Clock()
    for i, (t, prio) in enumerate(entries):
        clock.schedule(t, _tag(i), prio)
    got = []
    times = []
    while len(clock):
        got.append(clock.pop()())
        times.append(clock.now)
    assert got == sorted(range(len(entries)), key=lambda i: (entries[i][0], entries[i][1], i))
    assert times == sorted(times)  # now never goes back
