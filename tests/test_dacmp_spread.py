"""``dacmp-spread`` (agents/planners/dacmp/spread.py): DACMP plus a search-mode spacing term from
the peers' announced waypoints, a variant beyond the paper. With weight 0 it is DACMP; its term is
the share of the particle's footprint the peers' next swaths cover; batched planning still gives
the one-by-one plans; its option is checked like any planner option."""

from __future__ import annotations

import math

import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from test_batching import _with_rng_copy, situations

from agents.planners.dacmp.planner import DacmpPlanner
from agents.planners.dacmp.spread import DacmpSpreadPlanner, _Crowding
from agents.planners.registry import option_problems, resolve_planner
from swarm import Simulation
from swarm.errors import SimulationError
from swarm.scenario import apply_overrides, load_scenario

_SMALL = {"particles": 12, "iterations": 6, "levels": 5}


def test_registered_and_a_dacmp():
    assert resolve_planner("dacmp-spread") is DacmpSpreadPlanner
    assert issubclass(DacmpSpreadPlanner, DacmpPlanner) and DacmpSpreadPlanner().name == "dacmp-spread"


@settings(max_examples=examples(20), deadline=None)
@given(situations())
def test_weight_zero_is_dacmp_and_batching_is_exact(views):
    dacmp = DacmpPlanner(**_SMALL).plan_many([_with_rng_copy(v) for v in views])
    assert DacmpSpreadPlanner(spread_weight=0.0, **_SMALL).plan_many([_with_rng_copy(v) for v in views]) == dacmp
    spread = DacmpSpreadPlanner(**_SMALL)
    assert spread.plan_many([_with_rng_copy(v) for v in views]) == [spread.plan(_with_rng_copy(v)) for v in views]


def test_factor_is_the_uncovered_share_of_the_footprint():
    # One UAV, one peer flying from (0, 0) to (2000, 0), both radii 2 km (R_i + R_j = 4 km).
    seg = np.array([0.0, 0.0, 2000.0, 0.0, 4000.0]).reshape(5, 1, 1, 1)
    z = np.array([[[1000.0, 1000.0, 1000.0, 6000.0, 9000.0]], [[0.0, 2000.0, 4000.0, 0.0, 9000.0]]])
    f = _Crowding(seg, 1.0)(z)[0]
    u = 0.5  # 2 km off the segment: centres 2 km apart, half of R_i + R_j
    lens = (2 / math.pi) * (math.acos(u) - u * math.sqrt(1 - u * u))
    assert f[0] == 0.0  # on the peer's path: all of it will be scanned
    assert f[1] == pytest.approx(1 - lens)
    assert f[2] == f[3] == f[4] == 1.0  # 4 km or more from the path: no overlap
    assert list(_Crowding(seg, 2.0)(z)[0][:2]) == [0.0, pytest.approx(1 - 2 * lens)]


def test_option_is_checked():
    assert option_problems("dacmp-spread", {"spread_weight": 0.5}) == []
    (key, found, expected), = option_problems("dacmp-spread", {"spread_wieght": 0.5})
    assert key == "spread_wieght" and "did you mean 'spread_weight'" in expected
    sc = apply_overrides(load_scenario("paper-fig11"), {"planner.name": "dacmp-spread",
                                                        "planner.options": {"spread_weight": 0.5}})
    with Simulation(sc, duration_s=1.0) as sim:
        assert {a.planner.spread_weight for a in sim.actors.values()} == {0.5}
    sc = apply_overrides(sc, {"planner.options": {"spread_weight": -1.0}})
    with pytest.raises(SimulationError, match="dacmp-spread.*spread_weight must be a number >= 0"):
        Simulation(sc, duration_s=1.0)


def test_batched_run_has_the_one_by_one_event_log(small_scenario_path):
    def run(batch: bool) -> str:
        with Simulation(small_scenario_path, planner="dacmp-spread", duration_s=120.0, batch_planning=batch) as sim:
            return sim.run().metrics["event_log_sha256"]

    assert run(True) == run(False)
