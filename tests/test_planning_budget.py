"""DACMP's planning budget settings (issue 36; docs/planners.md, "Planning budget").

* ``planner.dacmp.map_refresh_s``: a UAV's map pyramid is brought up to date with its map at a
  plan only when its last update is at least that old (or its base time moved); in between a
  plan reads the map as it was at that update, aged to the plan's time. Checked bit for bit
  against a pyramid computed from scratch from a copy of the map taken at the last update.
* ``planner.dacmp.member_map``: with ``"base"`` a map-group member plans on the group base's
  pyramid (one for the group), a map outside a group on its own.
* Both are validated like every scenario key, and their old values are the defaults.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.maps.grid import Grid
from agents.maps.mapgroup import MapGroup
from agents.maps.umap import UncertaintyMap
from agents.planners.dacmp.maintained import SPAN, MaintainedPyramid, base_time
from agents.planners.dacmp.planner import DacmpPlanner
from swarm.errors import ScenarioError
from swarm.scenario import apply_overrides, load_scenario


def _same_state(a: MaintainedPyramid, b: MaintainedPyramid) -> bool:
    """Levels 1..L and the guide's sums: what a plan reads. (``E`` of a tiled map is not stored
    but read from the map itself: :class:`agents.planners.dacmp.maintained.SeenPlane`.)"""
    planes = zip(a.planes, b.planes, strict=True) if a.umap.dense else zip(a.planes[1:], b.planes[1:], strict=True)
    for pa, pb in planes:
        h, w = pa.shape
        if pa.read(0, h, 0, w).tobytes() != pb.read(0, h, 0, w).tobytes():
            return False
    return a.block_means().tobytes() == b.block_means().tobytes()


@settings(max_examples=examples(40), deadline=None)
@given(dense=st.booleans(), nx=st.integers(4, 60), ny=st.integers(4, 60), levels=st.integers(1, 6),
       tau=st.sampled_from([0.005, 0.05]), refresh=st.sampled_from([0.0, 5.0, 20.0, 1e9]),
       steps=st.lists(st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.floats(0.0, 1.0),
                                st.floats(0.0, 30.0)), min_size=1, max_size=20))
def test_a_pyramid_refreshed_every_so_often_reads_the_map_of_its_last_update(dense, nx, ny, levels, tau,
                                                                            refresh, steps):
    grid = Grid(nx * 100.0, ny * 100.0, 100.0)
    umap = UncertaintyMap(grid, tau) if dense else UncertaintyMap(grid, tau, tile=(8, 8))
    planner = DacmpPlanner(levels=levels, map_refresh_s=refresh)
    pyr = planner.planning_pyramid(umap)
    t = 0.0
    snapshot, last = umap.copy(), None
    for a, b, c, dt in steps:
        disk = grid.disk_stamp(a * grid.width_m, b * grid.height_m, 50.0 + c * 1500.0)
        if disk is not None:
            umap.stamp(disk, t)  # a scan now; the plan comes dt later
        t += dt
        planner.refresh([pyr], [t])
        due = last is None or t - last >= refresh or base_time(t, tau) != base_time(last, tau)
        if due:
            snapshot, last = umap.copy(), t
        assert pyr.refreshed == last
        assert pyr.s == math.exp(-tau * (t - base_time(t, tau)))
        fresh = MaintainedPyramid(snapshot.copy(), levels)
        fresh.update(last)
        assert fresh.age(t) == pyr.s  # (same base time: the state at last, s at t)
        assert _same_state(pyr, fresh)
    if refresh == 0.0:  # the default: every plan reads the map as it is
        fresh = MaintainedPyramid(umap.copy(), levels)
        fresh.update(t)
        assert _same_state(pyr, fresh)


def test_a_pyramid_is_refreshed_when_its_base_time_moves_whatever_the_budget():
    grid = Grid(2000.0, 2000.0, 100.0)
    tau = 0.05
    umap = UncertaintyMap(grid, tau)
    planner = DacmpPlanner(levels=3, map_refresh_s=1e9)
    pyr = planner.planning_pyramid(umap)
    planner.refresh([pyr], [1.0])
    umap.stamp(grid.disk_stamp(1000.0, 1000.0, 500.0), 2.0)
    planner.refresh([pyr], [3.0])
    assert pyr.refreshed == 1.0  # aged only: the scan at 2 s is not read
    assert pyr.block_means().min() == 1.0
    later = SPAN / tau + 1.0  # the next base span: rebuilt from the map
    planner.refresh([pyr], [later])
    assert pyr.refreshed == later and pyr.block_means().min() < 1.0


def test_group_members_plan_on_the_base_pyramid_with_member_map_base():
    grid = Grid(3000.0, 3000.0, 100.0)
    group = MapGroup(grid, 0.005, 1.0)
    a, b = group.new_map(), group.new_map()
    alone = UncertaintyMap(grid, 0.005)
    base = DacmpPlanner(levels=3, member_map="base")
    own = DacmpPlanner(levels=3)
    assert base.planning_pyramid(a) is base.planning_pyramid(b) is MaintainedPyramid.of(group.base, 3)
    assert base.planning_pyramid(alone) is MaintainedPyramid.of(alone, 3)
    assert own.planning_pyramid(a) is not own.planning_pyramid(b)
    assert own.planning_pyramid(a) is MaintainedPyramid.of(a, 3)
    # A scan only a has is in a's own pyramid, not in the base's it plans on with "base".
    a.stamp(grid.disk_stamp(1500.0, 1500.0, 600.0), 10.0)
    pb, pa = base.planning_pyramid(a), own.planning_pyramid(a)
    base.refresh([pb, pb], [20.0, 20.0])  # (one pyramid for two UAVs: updated once)
    own.refresh([pa], [20.0])
    assert pb.block_means().min() == 1.0 and pa.block_means().min() < 1.0
    # A member that leaves the group plans on its own map again.
    a.scan_disk(grid.disk_stamp(500.0, 500.0, 300.0), 15.0)
    assert a.extra_disks() is None and base.planning_pyramid(a) is MaintainedPyramid.of(a, 3)


def test_the_old_values_are_the_defaults_and_bad_values_are_one_error():
    dacmp = load_scenario("paper-fig11").planner.dacmp
    assert (dacmp.member_map, dacmp.map_refresh_s) == ("own", 0.0)
    s = apply_overrides(load_scenario("paper-fig11"), {"planner.dacmp.member_map": "base",
                                                       "planner.dacmp.map_refresh_s": 30})
    assert (s.planner.dacmp.member_map, s.planner.dacmp.map_refresh_s) == ("base", 30.0)
    for key, value, words in [("member_map", "shared", "one of: own, base"), ("map_refresh_s", -1, ">= 0"),
                              ("iterations", 0, ">= 1")]:
        with pytest.raises(ScenarioError) as info:
            apply_overrides(load_scenario("paper-fig11"), {f"planner.dacmp.{key}": value})
        assert info.value.key == f"planner.dacmp.{key}"
        assert words in info.value.expected
        assert "\n" not in str(info.value)


def test_the_budget_settings_reach_the_planner():
    s = apply_overrides(load_scenario("paper-fig11"), {"planner.dacmp.member_map": "base",
                                                       "planner.dacmp.map_refresh_s": 30,
                                                       "planner.dacmp.iterations": 8})
    p = DacmpPlanner.from_settings(s.planner, s.map.levels)
    assert (p.member_map, p.map_refresh_s, p.iterations) == ("base", 30.0, 8)
    assert np.isfinite(p.map_refresh_s)


@pytest.mark.parametrize("settings", [{"planner.dacmp.member_map": "base"}, {"planner.dacmp.map_refresh_s": 20.0},
                                      {"planner.dacmp.iterations": 8}])
def test_a_budget_run_batched_has_the_one_by_one_event_log_and_differs_from_the_paper(settings):
    """With the tick plane (every actor merges its frames before anyone plans) a budget's plans
    do not depend on whether UAVs plan together or one by one; and each budget does change the
    plans (else its study would measure nothing)."""
    from swarm import Simulation

    scenario = apply_overrides(load_scenario("paper-fig11"), settings)
    logs = []
    for sc, batch in ((scenario, True), (scenario, False), (load_scenario("paper-fig11"), True)):
        with Simulation(sc, planner="dacmp", duration_s=150.0, seed=1, batch_planning=batch) as sim:
            logs.append(sim.run().metrics["event_log_sha256"])
    assert logs[0] == logs[1]
    assert logs[0] != logs[2]
