"""Where a scenario's UAVs and base may be (issues 32 and 33, :mod:`swarm.scenario.placement`):
inside the area polygon, outside the no-fly zones (circles and polygons), fleet UAVs apart by
the separation minimum; ``[[fleet]]`` layouts inside the polygon; lon/lat that look swapped;
did-you-mean for fault kinds and UAV types. Each mistake is one problem naming its key."""

from __future__ import annotations

import numpy as np
import pytest

from swarm.errors import ScenarioError
from swarm.scenario import load_scenario, parse_scenario
from swarm.scenario.placement import Site, close_starts
from swarm.scenario.warnings import scenario_warnings

pytest.importorskip("shapely")

from test_geo import geo_doc


def problems(doc: dict) -> list[ScenarioError]:
    with pytest.raises(ScenarioError) as err:
        parse_scenario(doc, "p.toml")
    return err.value.all


def one(doc: dict) -> ScenarioError:
    found = problems(doc)
    assert len(found) == 1, [str(e) for e in found]
    assert "\n" not in str(found[0])
    return found[0]


def test_a_uav_inside_a_no_fly_polygon_or_circle():
    e = one(geo_doc(uavs=[{"type": "B", "lon": 10.04, "lat": 54.17}]))  # in the L
    assert e.key == "uavs[0].x_m" and "inside no_fly[0] ('L')" in e.found and "outside every no-fly zone" in e.expected
    assert "lon 10.04000, lat 54.17000" in e.found
    e = one({"uavs": [{"type": "B", "x_m": 5000.0, "y_m": 5000.0}],
             "threats": [{"x_m": 5500.0, "y_m": 5000.0, "radius_m": 1000.0}]})
    assert e.key == "uavs[0].x_m" and "inside threats[0]" in e.found


def test_a_uav_outside_the_polygon_but_inside_its_box():
    e = one(geo_doc(uavs=[{"type": "B", "lon": 10.3, "lat": 54.1}]))  # in the C's opening
    assert e.key == "uavs[0].x_m" and "outside the area polygon" in e.found


def test_a_base_outside_the_polygon_or_in_a_zone():
    endurance = {"lon": 10.3, "lat": 54.1, "types": {"B": {"capacity_wh": 5000.0}, "A": {"capacity_wh": 5000.0}}}
    e = one(geo_doc(endurance=endurance))
    assert e.key == "endurance.x_m" and "outside the area polygon" in e.found and "a base inside" in e.expected
    e = one(geo_doc(endurance={**endurance, "lon": 10.04, "lat": 54.17}))
    assert e.key == "endurance.x_m" and "inside no_fly[0]" in e.found


@pytest.mark.parametrize("where", ["uavs", "endurance"])
def test_lon_and_lat_swapped_is_one_line_that_says_so(where):
    if where == "uavs":
        doc = geo_doc(uavs=[{"type": "B", "lon": 54.03, "lat": 10.03}])
    else:
        doc = geo_doc(endurance={"lon": 54.03, "lat": 10.03, "types": {"B": {"capacity_wh": 5000.0}}})
    e = one(doc)
    assert e.key == f"{where}[0].lon" if where == "uavs" else e.key == "endurance.lon"
    assert "look swapped" in str(e) and "lon = 10.03, lat = 54.03" in e.expected
    assert "inf" not in str(e)


def test_a_point_off_the_globe_is_not_inf():
    e = one(geo_doc(uavs=[{"type": "B", "lon": 10.03, "lat": 95.0}]))
    assert e.key == "uavs[0].lon" and "inf" not in str(e)


def test_fleet_layouts_keep_to_the_polygon():
    for layout in ("grid", "random"):
        sc = parse_scenario(geo_doc(uavs=[], no_fly=[], fleet=[{"type": "A", "count": 40, "layout": layout}]))
        site = Site.of(sc)
        x, y = np.array([u.x_m for u in sc.uavs]), np.array([u.y_m for u in sc.uavs])
        assert len(x) == 40 and site.in_area(x, y).all(), layout
        assert not close_starts(sc)


def test_a_random_fleet_is_drawn_in_the_free_space_and_apart():
    doc = geo_doc(uavs=[], fleet=[{"type": "A", "count": 60, "layout": "random", "heading_deg": 10.0}])
    sc = parse_scenario(doc)
    x, y = np.array([u.x_m for u in sc.uavs]), np.array([u.y_m for u in sc.uavs])
    assert Site.of(sc).free(x, y).all() and not close_starts(sc)
    # In a rectangle with no zone and no clash the layout is the plain uniform one.
    plain = parse_scenario({"fleet": [{"type": "A", "count": 3, "layout": "random", "layout_seed": 4}]})
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy=4, spawn_key=(0,))))
    assert [u.x_m for u in plain.uavs] == pytest.approx(rng.uniform(0, 50_000, 3).tolist())


def test_a_grid_slot_in_a_no_fly_zone_is_one_line_for_the_fleet():
    e = one(geo_doc(uavs=[], fleet=[{"type": "A", "count": 400}]))
    assert e.key == "fleet[0]" and "inside no_fly" in e.found and "more of its UAVs" in e.found
    assert "region" in e.hint


def test_fleets_closer_than_the_separation_minimum():
    """Issue 32: two grid fleets that put each A beside the B of the same number."""
    doc = {"fleet": [{"type": "B", "count": 9, "region": [0, 0, 9000, 9000]},
                     {"type": "A", "count": 9, "region": [150, 0, 9150, 9000]}]}
    e = one(doc)
    assert e.key == "fleet[1]" and "A1 150 m from B1 (fleet[0])" in e.found and "(and 8 more" in e.found
    assert "min_separation_m = 200 m" in e.expected
    doc["fleet"][1]["join_s"] = 10.0  # entering later: not judged against the others
    assert len(parse_scenario(doc).uavs) == 18


def test_two_hand_placed_uavs_too_close_are_a_warning():
    sc = parse_scenario({"uavs": [{"type": "B", "x_m": 100.0, "y_m": 100.0}, {"type": "A", "x_m": 150.0, "y_m": 100.0}]})
    warnings = [w for w in scenario_warnings(sc) if "min_separation_m" in w]
    assert len(warnings) == 1 and "uavs[1] (A1) 50 m from uavs[0] (B1)" in warnings[0]


def test_bench_dense_300_fleets_start_apart():
    sc = load_scenario("bench-dense-300")
    assert len(sc.uavs) == 300 and not close_starts(sc)
    xy = np.array([(u.x_m, u.y_m) for u in sc.uavs])
    d = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    assert d.min() == pytest.approx(1000 * 2**0.5)


def test_every_builtin_validates_with_its_uavs_apart():
    from swarm.scenario import builtin_scenarios

    for name in builtin_scenarios():
        assert not close_starts(load_scenario(name)), name


def test_did_you_mean_for_fault_kinds_and_uav_types():
    e = problems({"uavs": [{"type": "B", "x_m": 0, "y_m": 0}], "faults": [{"kind": "crsh", "uav": "B1", "at_s": 1}]})[0]
    assert e.key == "faults[0].kind" and e.hint == "did you mean 'crash'?"
    e = one({"uavs": [{"type": "b", "x_m": 0, "y_m": 0}], "faults": [{"kind": "crash", "uav": "B1", "at_s": 1}]})
    assert e.key == "uavs[0].type" and e.hint == "did you mean 'B'?"  # (and no second line for B1)
    e = one({"fleet": [{"type": "AA", "count": 2}]})
    assert e.key == "fleet[0].type" and e.hint == "did you mean 'A'?"



def test_a_no_fly_polygon_with_lon_and_lat_swapped():
    from test_geo import L_ZONE

    e = one(geo_doc(no_fly=[{"polygon": [[lat, lon] for lon, lat in L_ZONE]}]))
    assert e.key == "no_fly[0].polygon" and "look swapped" in e.hint
