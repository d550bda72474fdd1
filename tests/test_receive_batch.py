"""The receive service's batch steps against the per-item code they replace (issue 36, T4):
its three passes against the per-actor oracle, tick by tick;
:meth:`ScanLog.add_ticks` against :meth:`ScanLog.add_tick` one scan at a time, and the knowledge
horizon of every (receiver, scan) pair of a tick (:func:`swarm.kernel.receiving.within_horizons`)
against the formula :meth:`agents.inbox.Inbox.merge` applies to each, ``(x - hx) ** 2 + (y - hy)
** 2 <= H^2``, including centres within a few ulp of the horizon (where numpy's ``d * d`` and
Python's ``d ** 2`` may round differently)."""

from __future__ import annotations

import math
from unittest.mock import patch

import pytest
from budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_tick_plane import lockstep_documents

from agents.maps.scanlog import ScanLog
from swarm import Simulation
from swarm.kernel import receiving
from swarm.kernel.receiving import SMALL_PAIRS, within_horizons
from swarm.scenario import parse_scenario
from swarm.testing.oracle import assert_lockstep

_origin = st.integers(0, 40)
# A tick's heard scans: (origin, ticks back from the clock), repeats within a batch and across
# batches, some far back (before what the log keeps), some ahead (the ring grows).
_batch = st.lists(st.tuples(_origin, st.integers(-300, 400) | st.integers(0, 12)), max_size=60)


@settings(max_examples=examples(200), deadline=None)
@given(dt=st.sampled_from([1.0, 0.5]), horizon_s=st.sampled_from([math.inf, 20.0, 100.0]),
       steps=st.lists(st.tuples(st.integers(0, 90), st.booleans(), _batch), min_size=1, max_size=12))
def test_a_batch_insert_is_the_inserts_one_by_one(dt: float, horizon_s: float,
                                                   steps: list[tuple[int, bool, list[tuple[int, int]]]]) -> None:
    batch, single = ScanLog(dt, horizon_s), ScanLog(dt, horizon_s)
    now = 400
    for advance, forget, heard in steps:
        now += advance
        if forget:
            batch.forget_before(now * dt)
            single.forget_before(now * dt)
        items = [(o, k, (k * dt, 10.0 * o + k % 7, -3.0 * k, 5.0), (0.0, 0.0, 5.0))
                 for o, back in heard if (k := now - back) >= 0]
        assert batch.add_ticks(items) == [single.add_tick(o, k, scan) for o, k, scan, _ in items]
        assert batch.count == single.count
        assert list(batch.scans()) == list(single.scans())
        t_cut = (now - 3) * dt
        assert batch.digest(t_cut) == single.digest(t_cut)
        assert list(batch.missing(0, 0, 2**31 - 1, (), t_cut, 1000)) == list(single.missing(0, 0, 2**31 - 1, (), t_cut, 1000))


def _scalar(centres: list[float], here: list[tuple[float, float, float]], counts: list[int]) -> list[bool]:
    out = []
    j = 0
    for (hx, hy, h2), c in zip(here, counts):
        for _ in range(c):
            out.append((centres[j] - hx) ** 2 + (centres[j + 1] - hy) ** 2 <= h2)
            j += 2
    return out


_coord = st.floats(-5e4, 5e4, allow_nan=False)


@st.composite
def _ticks(draw: st.DrawFn) -> tuple[list[float], list[tuple[float, float, float]], list[int]]:
    """Receivers, each with its place, horizon and heard scans; many centres placed on the
    horizon's circle (cos/sin of an angle, then nudged by a few ulp), the rest anywhere."""
    centres: list[float] = []
    here: list[tuple[float, float, float]] = []
    counts: list[int] = []
    for _ in range(draw(st.integers(1, 8))):
        hx, hy = draw(_coord), draw(_coord)
        h = draw(st.sampled_from([2.5e4, 3e4, 1234.5678, 1e-3]) | st.floats(1.0, 1e5))
        n = draw(st.integers(0, 3 * SMALL_PAIRS // 4))
        for _ in range(n):
            if draw(st.booleans()):
                a = draw(st.floats(0.0, 2 * math.pi))
                x, y = hx + h * math.cos(a), hy + h * math.sin(a)
                for _ in range(draw(st.integers(0, 3))):
                    x = math.nextafter(x, draw(st.sampled_from([math.inf, -math.inf])))
                    y = math.nextafter(y, draw(st.sampled_from([math.inf, -math.inf])))
            else:
                x, y = draw(_coord), draw(_coord)
            centres += [x, y]
        here.append((hx, hy, h * h))
        counts.append(n)
    return centres, here, counts


@settings(max_examples=examples(100), deadline=None)
@given(_ticks())
def test_the_horizon_of_every_pair_at_once_is_the_scalar_test_of_each(tick) -> None:
    centres, here, counts = tick
    got = within_horizons(centres, here, counts)
    assert got == _scalar(centres, here, counts)
    assert all(type(v) is bool for v in got)


def test_the_array_path_decides_the_edge_as_the_scalar_test():
    """Above SMALL_PAIRS pairs the arrays decide: centres on the circle, a few ulp in or out,
    among them some where the products alone (numpy's ``d * d``) would decide otherwise than
    the scalar test (``d ** 2``): the band around the horizon is what keeps them equal."""
    hx, hy, h = 1234.5, -987.25, 25000.0
    n = 40000
    centres: list[float] = []
    for i in range(n):
        a = 2 * math.pi * i / n
        x, y = hx + h * math.cos(a), hy + h * math.sin(a)
        for _ in range(i % 5):
            x = math.nextafter(x, math.inf if i % 2 else -math.inf)
        centres += [x, y]
    here, counts = [(hx, hy, h * h)], [n]
    want = _scalar(centres, here, counts)
    assert within_horizons(centres, here, counts) == want
    assert 0 < sum(want) < n  # both sides of the edge
    products = [(x - hx) * (x - hx) + (y - hy) * (y - hy) <= h * h for x, y in zip(centres[::2], centres[1::2])]
    assert products != want  # (this edge has pairs the products alone would get wrong)


# --- the three passes of the receive service against the oracle -----------------------------------

def _three_passes():
    """Every tick of every size through Receiving.receive's three passes, the horizon as arrays."""
    return patch.multiple(receiving, SMALL_SWARM=0, DENSE_FRAMES=0, SMALL_PAIRS=0)


@settings(max_examples=examples(20), deadline=None, suppress_health_check=list(HealthCheck))
@given(lockstep_documents(max_uavs=6, max_duration_s=40))
def test_the_three_passes_are_the_oracle_tick_by_tick(doc):
    """The tick plane with the receive service's three passes forced (bench-dense-300's path:
    the bench cases above 16 UAVs hear too few frames a receiver to take it) against the
    per-actor oracle, every tick, over generated scenarios with every fault kind."""
    with _three_passes():
        assert_lockstep(parse_scenario(doc))


@pytest.mark.slow  # two runs of 100 UAVs for 30 s, states compared every tick: about 12 s of CPU
def test_bench_100_in_lockstep_through_the_three_passes():
    """Tiled maps, a knowledge horizon and resends through the three passes: the run must take
    the horizon's both sides for the test to count."""
    seen: dict[str, int] = {}

    def count(sim: Simulation, tick: int) -> None:
        cs = [a.counters for a in sim.actors.values()]
        seen.update(heard=sum(c.delivered for c in cs), beyond=sum(c.scans_beyond for c in cs))

    with _three_passes():
        assert_lockstep("bench-100", planner="greedy", duration_s=30, seed=0, tamper=count)
    assert seen["heard"] > 0 and seen["beyond"] > 0, seen


class _DeafInbox:
    """In place of an actor's Inbox (as tests/test_stateful.py plants one): drained, unread."""

    digests = ()
    horizon2 = None

    def take(self, frames, *state):
        return []


def test_an_inbox_of_another_type_is_merged_in_its_turn():
    """The three passes call an actor whose inbox is not an Inbox through its own receive."""
    with _three_passes(), Simulation("paper-case1", duration_s=20, seed=0) as sim:
        sim.actors[1].inbox = _DeafInbox()  # type: ignore[assignment]
        sim.run()
        heard = {uid: a.counters.delivered for uid, a in sim.actors.items()}
        left = {uid: len(a.mailbox) for uid, a in sim.actors.items()}
    assert heard[1] == 0 and all(n > 0 for uid, n in heard.items() if uid != 1), heard
    assert left[1] <= max(left.values())  # (its mailbox drained like the others')
