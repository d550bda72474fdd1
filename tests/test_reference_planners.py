"""The reference planners (agents.planners.lawnmower, .formation, .levy) and their shared
machinery (agents.planners.reference): strip and band geometry as pure functions, Dubins paths
against their own end poses, short runs that keep every safety rule and replay to the same
event log, a formation that stays abreast, Lévy step lengths against their power law, and
(slow) the lawnmower covering paper-fig11 by 2000 s."""

from __future__ import annotations

import math
from itertools import islice

import numpy as np
import pytest
from budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from agents.planners import BUILTIN, resolve_planner
from agents.planners.formation import FormationPlanner, band_order, front_geometry
from agents.planners.lawnmower import LawnmowerPlanner, strip_passes
from agents.planners.levy import LevyPlanner, pareto_step
from agents.planners.reference import Track, dubins_length, dubins_shortest
from swarm import Simulation, SimulationError, load_scenario
from swarm.errors import ScenarioError
from swarm.events import read_events
from swarm.scenario import apply_overrides
from swarm.testing.invariants import DynamicsChecker, ThreatClearanceChecker, check_events
from swarm.testing.strategies import reproducible, scenarios

REFERENCE = ("lawnmower", "formation", "levy")
lengths = st.floats(1_000.0, 200_000.0)


def test_registered_built_in_searchers_with_the_shared_surveillance():
    for name, cls in zip(REFERENCE, (LawnmowerPlanner, FormationPlanner, LevyPlanner)):
        assert name in BUILTIN and resolve_planner(name) is cls
        assert cls.surveils == "shared" and cls.name == name


# --- geometry: pure functions ------------------------------------------------------------------


@given(width=lengths, height=lengths, count=st.integers(1, 24), radius=st.floats(100.0, 5_000.0),
       overlap=st.floats(0.0, 0.5))
def test_lawnmower_strips_partition_the_area_and_their_passes_cover_each_strip(width, height, count, radius, overlap):
    strips = [strip_passes((width, height), count, k, radius, overlap) for k in range(count)]
    along, across = (height, width) if height > width else (width, height)
    assert all(s.swap == (height > width) for s in strips)
    # The strips partition [0, across]: contiguous, disjoint, equal, in rank order.
    assert strips[0].lo == 0.0 and strips[-1].hi == across
    for a, b in zip(strips, strips[1:]):
        assert a.hi == b.lo
    assert all(math.isclose(s.hi - s.lo, across / count, rel_tol=1e-9) for s in strips)
    spacing_max = 2.0 * radius * (1.0 - overlap)
    for s in strips:
        p = s.passes
        spacing = (s.hi - s.lo) / len(p)
        # The fewest passes at most spacing_max apart whose swaths tile the strip.
        assert spacing <= spacing_max * (1 + 1e-9)
        assert len(p) == 1 or (s.hi - s.lo) / (len(p) - 1) > spacing_max * (1 - 1e-9)
        assert math.isclose(p[0] - s.lo, spacing / 2) and math.isclose(s.hi - p[-1], spacing / 2)
        assert all(math.isclose(b - a, spacing) for a, b in zip(p, p[1:]))
        # Every point across the strip is within R_s of a pass (the detection circle's swath)...
        assert spacing / 2 <= radius * (1 + 1e-9)
        # ...and a pass starts where the circle still reaches the swath's corner at the edge.
        assert 0.0 <= s.u_lo <= s.u_hi <= along
        if s.u_lo < along / 2:
            assert math.hypot(s.u_lo, spacing / 2) <= radius * (1 + 1e-9)
            assert math.isclose(along - s.u_hi, s.u_lo)


@given(width=lengths, height=lengths, lanes=st.integers(1, 24), radius=st.floats(100.0, 5_000.0),
       first=st.integers(0, 1000))
def test_formation_lanes_tile_the_area_and_the_bands_are_all_swept_then_swept_again(width, height, lanes, radius, first):
    fr = front_geometry((width, height), lanes, radius)
    across = width if height > width else height
    assert fr.spacing <= 2 * radius * (1 + 1e-9)
    assert math.isclose(fr.bands * lanes * fr.spacing, across)
    assert math.isclose(fr.lane_w(0, 0), fr.spacing / 2)
    assert math.isclose(fr.lane_w(fr.bands - 1, lanes - 1), across - fr.spacing / 2)
    b0 = first % fr.bands
    order = list(islice(band_order(fr.bands, b0), 4 * fr.bands + 2))
    assert order[0] == b0 and sorted(order[:fr.bands]) == list(range(fr.bands))  # each band once, first
    if fr.bands > 1:
        later = order[fr.bands:]
        assert set(later) == set(range(fr.bands))  # then again, back and forth
        assert all(abs(a - b) == 1 for a, b in zip(later, later[1:]))


poses = st.tuples(st.floats(-20_000, 20_000), st.floats(-20_000, 20_000), st.floats(-math.pi, math.pi))


@given(q0=poses, q1=poses, r=st.floats(50.0, 5_000.0))
def test_a_sampled_dubins_path_ends_at_its_goal_and_is_no_shorter_than_the_straight_line(q0, q1, r):
    word, segs = dubins_shortest(q0, q1, r)
    length = sum(segs)
    assert length >= math.hypot(q1[0] - q0[0], q1[1] - q0[1]) - 1e-6
    tr = Track(*q0, ds=25.0)
    for letter, seg in zip(word, segs):
        tr.line(seg) if letter == "S" else tr.arc(1.0 if letter == "L" else -1.0, seg, r)
    x, y, h = tr.pen
    assert math.hypot(x - q1[0], y - q1[1]) < 1e-6 * (1 + length)
    assert abs(math.remainder(h - q1[2], 2 * math.pi)) < 1e-6
    pts = tr.points(0, len(tr))  # samples 25 m apart along the path, each on it
    steps = np.hypot(np.diff(pts[:, 0]), np.diff(pts[:, 1]))
    assert len(pts) == math.floor(length / 25.0 + 1e-9) + 1 and (steps <= 25.0 + 1e-6).all()


def test_dubins_lengths_of_known_cases():
    r = 1000.0
    assert math.isclose(dubins_length((0, 0, 0), (5000, 0, 0), r), 5000)
    assert math.isclose(dubins_length((0, 0, 0), (0, 2 * r, math.pi), r), math.pi * r)  # a half turn
    assert math.isclose(dubins_length((0, 0, 0), (r, r, math.pi / 2), r), math.pi * r / 2)  # a quarter


# --- runs ---------------------------------------------------------------------------------------


@pytest.mark.slow  # whole runs or a subprocess: the full run has it, the quick loop need not
@pytest.mark.parametrize("planner", REFERENCE)
def test_a_short_run_keeps_every_safety_rule_and_replays_to_the_same_event_log(planner):
    # paper-case2: two types, four threats, UAVs on opposite edges heading at each other.
    runs = []
    for batch in (True, False):  # each UAV's planner is its own, even when planned in batches
        with Simulation("paper-case2", planner=planner, duration_s=240.0, batch_planning=batch) as sim:
            m = sim.run().metrics  # (surveillance = true: they watch through the shared logic)
        assert m["violations"] == {"separation": 0, "threat": 0, "dynamics": 0}
        assert m["planner"] == planner and m["coverage"] > 0.1
        runs.append(m["event_log_sha256"])
    assert runs[0] == runs[1]


@settings(max_examples=examples(30), suppress_health_check=[HealthCheck.too_slow])
@given(scenario=scenarios(max_uavs=4, max_duration_s=60, planners=REFERENCE))
def test_generated_runs_keep_threat_clearance_and_limits_and_batching_changes_nothing(scenario):
    """Small areas (5-15 km, strips narrower than a turn), mixed and generated types, late
    joiners, threats, faults, lossy radios."""
    with reproducible(scenario):
        with Simulation(scenario) as sim:
            result = sim.run()
        violations = check_events(list(read_events(result.events)), scenario, [ThreatClearanceChecker(), DynamicsChecker()])
        assert not violations, "\n".join(map(str, violations))
        with Simulation(scenario, batch_planning=False) as sim:
            assert sim.run().metrics["event_log_sha256"] == result.metrics["event_log_sha256"]


def test_each_uav_has_its_own_planner_and_options_reach_it():
    sc = apply_overrides(load_scenario("paper-fig11"), {"planner.name": "lawnmower", "planner.options": {"overlap": 0.4}})
    with Simulation(sc, duration_s=30.0) as sim:
        planners = [a.planner for a in sim.actors.values()]
        sim.run()
    assert len({id(p) for p in planners}) == 6 and all(p.overlap == 0.4 for p in planners)
    assert [(p.index, p.count) for p in planners] == [(k, 6) for k in range(6)]
    assert all(len(p.strip.passes) == 4 for p in planners)  # 8.33 km strips, passes <= 2.4 km apart
    with pytest.raises(ScenarioError, match="did you mean 'mu'"):
        apply_overrides(load_scenario("paper-fig11"), {"planner.name": "levy", "planner.options": {"mue": 2.0}})
    with Simulation("paper-fig11", planner="levy", duration_s=10.0) as sim:
        assert {a.planner.mu for a in sim.actors.values()} == {2.0}
    bad = apply_overrides(load_scenario("paper-fig11"), {"planner.name": "levy", "planner.options": {"mu": 0.5}})
    with pytest.raises(SimulationError, match="mu must be in"):
        Simulation(bad, duration_s=10.0)


@pytest.mark.slow  # whole runs or a subprocess: the full run has it, the quick loop need not
def test_the_formation_flies_abreast_one_lane_apart():
    with Simulation("paper-fig11", planner="formation", duration_s=900.0) as sim:
        sim.step(300)
        first = sim.snapshot().uavs
        sim.step(600)  # 900 s: through the first band's end and the turn onto the next band
        later = sim.snapshot().uavs
        fr = sim.actors[0].planner.front
    assert fr.bands == 3 and math.isclose(fr.spacing, 50_000 / 18)
    for uavs in (first, later):
        xs, ys = [u.x for u in uavs], [u.y for u in uavs]
        # Side by side: the same position along the front (+-300 m), one lane apart across it.
        assert max(xs) - min(xs) < 300.0 or max(ys) - min(ys) < 300.0
        gaps = np.diff(ys) if max(xs) - min(xs) < 300.0 else np.diff(xs)
        assert np.allclose(np.abs(gaps), fr.spacing, atol=300.0), gaps


def test_levy_step_lengths_follow_their_power_law():
    rng = np.random.default_rng(2024)
    rs, cap, mu = 2_000.0, 50_000.0, 2.0
    steps = np.array([pareto_step(rng, mu, rs, cap) for _ in range(20_000)])
    assert steps.min() >= rs and steps.max() <= cap
    # Survival (l / R_s)^-(mu - 1) below the cap: 1/2 beyond 2 R_s, 1/5 beyond 5, 1/10 beyond 10.
    for k in (2, 5, 10):
        assert abs((steps > k * rs).mean() - k ** -(mu - 1)) < 0.01
    # Tail exponent by maximum likelihood (log(l / R_s) is exponential, censored at the cap).
    censored = steps >= cap
    alpha = (~censored).sum() / np.log(steps / rs).sum()
    assert abs(alpha - (mu - 1)) < 0.03
    # Heavy: far more long steps than an exponential law with the same median would give.
    median_excess = np.median(steps) - rs
    assert (steps > rs + 10 * median_excess).mean() > 50 * 2.0 ** -10


@pytest.mark.slow  # whole runs or a subprocess: the full run has it, the quick loop need not
def test_levy_draws_only_from_the_uavs_own_stream():
    with Simulation("paper-fig11", planner="levy", duration_s=600.0) as sim:
        sim.run()
        planners = [a.planner for a in sim.actors.values()]
    for p in planners:
        assert p.steps and all(2_000.0 <= s <= 50_000.0 for s in p.steps)
    with Simulation("paper-fig11", planner="levy", duration_s=600.0) as sim:
        sim.run()
        again = [a.planner.steps for a in sim.actors.values()]
    assert again == [p.steps for p in planners] and len({tuple(s) for s in again}) == 6


@pytest.mark.slow
def test_lawnmower_covers_paper_fig11_by_2000_s():
    metrics = Simulation(load_scenario("paper-fig11"), planner="lawnmower").run().metrics
    assert metrics["coverage"] >= 0.97, metrics["coverage"]
    assert metrics["violations"] == {"separation": 0, "threat": 0, "dynamics": 0}
