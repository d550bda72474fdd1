"""``[[fleet]]``: many UAVs of one type laid out deterministically, expanded into ``uavs`` on load."""

from __future__ import annotations

import pytest

from swarm.errors import ScenarioError
from swarm.scenario import apply_overrides, load_scenario, parse_scenario


def test_grid_layout_fills_the_region_row_by_row_and_names_continue_per_type():
    s = parse_scenario({
        "area": {"width_m": 20_000.0, "height_m": 10_000.0},
        "uavs": [{"type": "B", "x_m": 1.0, "y_m": 2.0}],
        "fleet": [{"type": "B", "count": 7, "heading_deg": 90.0},
                  {"type": "A", "count": 2, "region": [0, 0, 4000, 2000], "speed": 40}],
    })
    assert s.uav_names == ["B1", "B2", "B3", "B4", "B5", "B6", "B7", "B8", "A1", "A2"]
    assert s.fleet == []  # consumed: every UAV is in uavs
    # 7 on 20 x 10 km: 4 columns x 2 rows of 5 x 5 km cells, centres, from the south-west
    assert [(u.x_m, u.y_m) for u in s.uavs[1:8]] == [
        (2500.0, 2500.0), (7500.0, 2500.0), (12500.0, 2500.0), (17500.0, 2500.0),
        (2500.0, 7500.0), (7500.0, 7500.0), (12500.0, 7500.0)]
    assert all(u.heading_deg == 90.0 and u.speed is None for u in s.uavs[1:8])
    assert [(u.x_m, u.y_m, u.speed) for u in s.uavs[8:]] == [(1000.0, 1000.0, 40.0), (3000.0, 1000.0, 40.0)]


def test_random_layout_is_fixed_by_its_layout_seed_not_the_run_seed():
    doc = {"fleet": [{"type": "A", "count": 20, "layout": "random", "region": [1000, 2000, 3000, 9000]}]}
    a = parse_scenario({**doc, "seed": 1})
    b = parse_scenario({**doc, "seed": 2})
    assert [(u.x_m, u.y_m, u.heading_deg) for u in a.uavs] == [(u.x_m, u.y_m, u.heading_deg) for u in b.uavs]
    assert all(1000 <= u.x_m <= 3000 and 2000 <= u.y_m <= 9000 and 0 <= u.heading_deg < 360 for u in a.uavs)
    c = parse_scenario({"fleet": [{**doc["fleet"][0], "layout_seed": 5}]})
    assert [u.x_m for u in c.uavs] != [u.x_m for u in a.uavs]
    assert len({(u.x_m, u.y_m) for u in a.uavs}) == 20


def test_expanded_scenario_round_trips_and_takes_overrides():
    s = load_scenario("bench-100")
    assert len(s.uavs) == 100 and sorted({u.type for u in s.uavs}) == ["A", "B"]
    assert parse_scenario(s.to_dict(), "bench-100") == s
    moved = apply_overrides(s, {"uavs[99].x_m": 5.0, "seed": 3})
    assert moved.uavs[99].x_m == 5.0 and moved.uavs[98] == s.uavs[98] and moved.seed == 3


@pytest.mark.parametrize("fleet, key, expected", [
    ({"type": "C", "count": 3}, "fleet[0].type", "a UAV type defined in [uav_types]: A, B"),
    ({"type": "B", "count": 0}, "fleet[0].count", "a whole number in [1, 100000]"),
    ({"type": "B", "count": 2.0}, "fleet[0].count", "a whole number in [1, 100000]"),
    ({"type": "B", "count": 3, "layout": "hex"}, "fleet[0].layout", "one of: grid, random"),
    ({"type": "B", "count": 3, "speed": 10}, "fleet[0].speed", "a number in [60, 90] (type B's speed range)"),
    ({"type": "B", "count": 3, "region": [0, 0, 60_000, 10]}, "fleet[0].region",
     "[x0_m, y0_m, x1_m, y1_m] with 0 <= x0 < x1 <= 50000 and 0 <= y0 < y1 <= 50000 (inside the area)"),
    ({"type": "B", "count": 3, "region": [5, 5, 1, 10]}, "fleet[0].region", None),
    ({"type": "B", "count": 3, "region": [0, 0, 10]}, "fleet[0].region", None),
])
def test_fleet_mistakes_name_the_key(fleet, key, expected):
    with pytest.raises(ScenarioError) as info:
        parse_scenario({"fleet": [fleet]}, "f.toml")
    err = info.value
    assert err.source == "f.toml" and err.key == key
    if expected is not None:
        assert err.expected == expected
    assert str(err).startswith(f"f.toml: {key}: found ")


def test_unknown_fleet_key_suggests_the_right_one():
    with pytest.raises(ScenarioError) as info:
        parse_scenario({"fleet": [{"type": "B", "cont": 3}]}, "f.toml")
    assert info.value.key == "fleet[0].cont" and "did you mean 'count'?" in str(info.value)


def test_no_uavs_at_all_is_still_missing_uavs():
    with pytest.raises(ScenarioError) as info:
        parse_scenario({"seed": 1}, "f.toml")
    assert info.value.key == "uavs" and info.value.found == "nothing (the key is missing)"
    with pytest.raises(ScenarioError) as info:
        parse_scenario({"uavs": [], "fleet": []}, "f.toml")
    assert info.value.key == "uavs"


def test_faults_can_name_fleet_uavs():
    s = parse_scenario({"fleet": [{"type": "B", "count": 3}], "faults": [{"kind": "crash", "uav": "B3", "at_s": 5}]})
    assert s.faults[0].uav == "B3"
