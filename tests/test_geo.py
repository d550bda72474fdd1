"""Geographic scenarios and polygon no-fly zones (issue 26, items 1, 2 and 5): the local frame,
polygon geometry, validation with key paths, runs that keep inside the area and out of the
zones, coverage counted inside the polygon, and the GeoJSON outputs."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from agents.zones import Keepout
from swarm import Simulation
from swarm.errors import ScenarioError
from swarm.scenario import load_scenario, parse_scenario
from swarm.testing.invariants import check_events

pytest.importorskip("pyproj")
pytest.importorskip("shapely")

# A concave (C-shaped, opening east) coastal area of about 22 x 22 km at 54 N, in lon/lat.
CONCAVE = [[10.0, 54.0], [10.33, 54.0], [10.33, 54.06], [10.12, 54.07], [10.12, 54.13],
           [10.33, 54.14], [10.33, 54.2], [10.0, 54.2], [10.0, 54.0]]
# A no-fly polygon (concave: an L) inside, and one touching the area's south edge.
L_ZONE = [[10.03, 54.15], [10.09, 54.15], [10.09, 54.165], [10.05, 54.165], [10.05, 54.19], [10.03, 54.19], [10.03, 54.15]]
EDGE_ZONE = [[10.2, 54.0], [10.26, 54.0], [10.26, 54.025], [10.2, 54.025], [10.2, 54.0]]


def geo_doc(**over) -> dict:
    doc = {
        "name": "geo-test", "duration_s": 400.0, "seed": 2,
        "geo": {"area": CONCAVE},
        "area": {"cell_m": 200.0},
        "uavs": [{"type": "B", "lon": 10.03, "lat": 54.03, "heading_deg": 90.0},
                 {"type": "B", "lon": 10.06, "lat": 54.1, "heading_deg": 0.0},
                 {"type": "A", "lon": 10.2, "lat": 54.03, "heading_deg": 0.0}],
        "targets": {"count": 3, "speed_max": 5.0},
        "no_fly": [{"polygon": L_ZONE, "name": "L"}, {"polygon": EDGE_ZONE, "name": "edge", "influence_m": 1500.0}],
    }
    doc.update(over)
    return doc


def test_frame_is_a_local_transverse_mercator_with_tiny_distortion():
    from swarm.geo.frame import frame_for

    f = frame_for("EPSG:4326", CONCAVE, 200.0)
    assert "+proj=tmerc" in f.proj4 and f.lon0 == pytest.approx(10.165) and f.lat0 == pytest.approx(54.1)
    lon, lat = f.to_lonlat(*f.to_local([10.1, 10.3], [54.05, 54.19]))
    assert np.allclose(lon, [10.1, 10.3], atol=1e-10) and np.allclose(lat, [54.05, 54.19], atol=1e-10)
    d = f.distortion()
    assert d["scale_error_max"] < 5e-6 and d["angular_distortion_deg_max"] < 1e-4
    # 0.33 degrees of longitude at 54 N is about 21.6 km
    assert 21_000 < f.width_m < 22_000 and f.width_m % 200 == 0
    assert min(x for x, _ in f.area) == 0.0 and min(y for _, y in f.area) == 0.0


def test_keepout_concave_clearance_and_normals():
    ring = [(0, 0), (1000, 0), (1000, 1000), (600, 1000), (600, 400), (0, 400), (0, 0)]  # an L
    z = Keepout(0, ring, 500.0)
    assert z.contains(100, 100) and not z.contains(100, 800)  # the notch is outside
    rho, ux, uy = z.clearance(100, 800)
    assert rho == pytest.approx(400.0) and (ux, uy) == pytest.approx((0.0, 1.0))
    rho, ux, uy = z.clearance(300, 350)  # inside, 50 m from the top edge of the foot
    assert rho == pytest.approx(-50.0) and (ux, uy) == pytest.approx((0.0, 1.0))
    area = Keepout(-1, ring, 500.0, inverted=True)
    rho, ux, uy = area.clearance(300, 350)
    assert rho == pytest.approx(50.0) and (ux, uy) == pytest.approx((0.0, -1.0))  # back into the area
    assert np.allclose(z.clearance_many(np.array([100.0, 300.0]), np.array([800.0, 350.0])), [400.0, -50.0])


@pytest.mark.parametrize("change, key, words", [
    ({"geo": {"area": CONCAVE[:-1]}}, "geo.area", "closed ring"),
    ({"geo": {"area": [[10.0, 54.0], [10.3, 54.2], [10.3, 54.0], [10.0, 54.2], [10.0, 54.0]]}}, "geo.area", "simple polygon"),
    ({"geo": {"area": CONCAVE, "crs": "EPSG:999999"}}, "geo.crs", "pyproj knows"),
    ({"geo": {"area": [[54.0, 100.0], [54.3, 100.0], [54.3, 100.2], [54.0, 54.0]]}}, "geo.area", "closed ring"),
    ({"area": {"cell_m": 200.0, "width_m": 20000.0}}, "area.width_m", "left out"),
    ({"uavs": [{"type": "B", "lon": 10.3, "lat": 54.1}]}, "uavs[0].x_m", "inside the area polygon"),
    ({"no_fly": [{"polygon": [[10.1, 54.1], [10.2, 54.15], [10.2, 54.1], [10.1, 54.15], [10.1, 54.1]]}]},
     "no_fly[0].polygon", "simple polygon"),
    ({"no_fly": [{"polygon": [[10.1, 54.1], [10.2, 54.15], [10.2, 54.1]]}]}, "no_fly[0].polygon", "closed ring"),
])
def test_validation_names_the_key(change, key, words):
    with pytest.raises(ScenarioError) as err:
        parse_scenario(geo_doc(**change), "geo.toml")
    assert err.value.key == key and words in str(err.value), str(err.value)
    assert "\n" not in str(err.value)


def test_lonlat_without_geo_is_an_error():
    with pytest.raises(ScenarioError) as err:
        parse_scenario({"uavs": [{"type": "B", "lon": 10.0, "lat": 54.0}]}, "m.toml")
    assert err.value.key == "uavs[0].lon" and "[geo]" in str(err.value)


def test_geojson_file_beside_the_scenario(tmp_path):
    fc = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"role": "area"}, "geometry": {"type": "Polygon", "coordinates": [CONCAVE]}},
        {"type": "Feature", "properties": {"role": "no_fly", "name": "L", "influence_m": 2000},
         "geometry": {"type": "Polygon", "coordinates": [L_ZONE]}},
        {"type": "Feature", "properties": {"role": "other"}, "geometry": {"type": "Point", "coordinates": [10.1, 54.1]}}]}
    (tmp_path / "coast.geojson").write_text(json.dumps(fc))
    (tmp_path / "s.toml").write_text('[geo]\nfile = "coast.geojson"\n[area]\ncell_m = 200\n'
                                     '[[uavs]]\ntype = "B"\nlon = 10.03\nlat = 54.03\n')
    sc = load_scenario(tmp_path / "s.toml")
    assert sc.geo.area == CONCAVE and sc.geo.file is None
    assert [z.name for z in sc.no_fly] == ["L"] and sc.no_fly[0].influence_m == 2000
    again = sc.with_overrides(seed=3)  # the resolved scenario validates again on its own
    assert again.area == sc.area and again.uavs[0].x_m == sc.uavs[0].x_m


def test_geo_scenario_round_trips_through_overrides():
    sc = parse_scenario(geo_doc(), "geo.toml")
    again = sc.with_overrides(**{"area.cell_m": 100.0})
    assert again.area.width_m >= sc.area.width_m - 200 and again.area.cell_m == 100.0


def _run(planner: str, doc: dict, duration: float = 600.0):
    sc = parse_scenario(doc, "geo.toml")
    with Simulation(sc, planner=planner, duration_s=duration) as sim:
        result = sim.run()
        return sim, result


@pytest.mark.slow
@pytest.mark.parametrize("planner", ["dacmp", "greedy"])
def test_concave_area_with_polygon_zones_runs_clean(planner):
    sim, result = _run(planner, geo_doc())
    m = result.metrics
    assert m["violations"] == {"separation": 0, "threat": 0, "dynamics": 0}
    geo = sim._geography
    # no UAV outside the area polygon by more than its turn radius at full speed
    for name, rows in result.paths.items():
        kind = sim._types[result.uav_types[name]]
        assert geo.area.clearance_many(rows[:, 1], rows[:, 2]).min() > -kind.r_min(kind.speed_max), name
        for z in geo.zones:
            assert z.clearance_many(rows[:, 1], rows[:, 2]).min() > 0.0, (name, z.zone)
    # coverage counts the cells inside the polygon only
    seen = np.isfinite(result.union_last_seen)
    assert m["coverage"] == pytest.approx((seen & geo.inside).sum() / geo.inside.sum())
    assert m["geo"]["cells_inside"] == int(geo.inside.sum()) < geo.inside.size
    # the invariant checkers agree (the threat checker reads the polygons)
    violations = check_events(result.events, sim.scenario)
    assert [str(v) for v in violations] == []


def test_outside_cells_read_as_nothing_to_search():
    sim, _ = _run("dacmp", geo_doc(), duration=3.0)
    geo = sim._geography
    for actor in sim.actors.values():
        q = actor.umap.uncertainty(sim.now - sim.dt)
        assert np.all(q[~geo.inside] <= 1e-6)  # stamped as seen every tick
        assert q[geo.inside].max() == pytest.approx(1.0)  # the inside is still to search


@pytest.mark.slow
def test_geo_rectangle_matches_the_metric_rectangle():
    """The same area given as a lon/lat rectangle (its corners from the frame) and as a metric
    rectangle: coverage within a few percent (the geo one's boundary repulsion and its slightly
    non-rectangular projection aside), every cell inside."""
    from swarm.geo.frame import GeoFrame

    f = GeoFrame("EPSG:4326", 10.0, 54.0, 0.0, 0.0, 0.0, 0.0, 200.0, ())
    w = h = 16_000.0
    lon, lat = f.to_lonlat([-w / 2, w / 2, w / 2, -w / 2, -w / 2], [-h / 2, -h / 2, h / 2, h / 2, -h / 2])
    ring = [[float(a), float(b)] for a, b in zip(lon, lat)]
    uavs = [{"type": "B", "x_m": 2000.0, "y_m": 2000.0 + 4000.0 * k, "heading_deg": 0.0} for k in range(3)]
    metric = {"name": "m", "duration_s": 600.0, "area": {"width_m": w, "height_m": h, "cell_m": 200.0}, "uavs": uavs}
    geo = {"name": "g", "duration_s": 600.0, "geo": {"area": ring}, "area": {"cell_m": 200.0}, "uavs": uavs}
    _, rm = _run("dacmp", metric)
    sim, rg = _run("dacmp", geo)
    assert sim._grid.width_m == pytest.approx(w, abs=200.0)
    assert abs(rg.metrics["coverage"] - rm.metrics["coverage"]) < 0.06, (rg.metrics["coverage"], rm.metrics["coverage"])


@pytest.mark.slow
def test_geojson_outputs_open_and_lie_inside(tmp_path):
    import shapely

    from swarm.outputs import write_run

    sim, result = _run("greedy", geo_doc(), duration=300.0)
    write_run(result, tmp_path)
    paths = json.loads((tmp_path / "paths.geojson").read_text())
    zones = json.loads((tmp_path / "zones.geojson").read_text())
    targets = json.loads((tmp_path / "targets.geojson").read_text())
    assert paths["type"] == zones["type"] == targets["type"] == "FeatureCollection"
    area = shapely.geometry.shape(next(f["geometry"] for f in zones["features"] if f["properties"]["role"] == "area"))
    assert area.exterior.is_ccw  # RFC 7946: exterior rings counter-clockwise
    assert {f["properties"]["role"] for f in zones["features"]} == {"area", "no_fly"}
    # [lon, lat] order, and every UAV's track within the area (buffered by a turn radius, ~0.03 degrees)
    for feat in paths["features"]:
        line = shapely.geometry.shape(feat["geometry"])
        assert 9.9 < line.bounds[0] and line.bounds[3] < 54.3
        assert area.buffer(0.03).contains(line), feat["properties"]["name"]
    assert len(targets["features"]) == 3
    for feat in targets["features"]:
        assert area.buffer(1e-6).contains(shapely.geometry.shape(feat["geometry"]).representative_point())
    assert math.isfinite(json.loads((tmp_path / "metrics.json").read_text())["geo"]["scale_error_max"])


def test_geo_coast_has_what_the_issue_asks():
    sc = load_scenario("geo-coast")
    assert 15 <= len(sc.geo.area) - 1 <= 40 and sc.geo.crs == "EPSG:4326"
    assert len(sc.no_fly) == 1 and "Holtenau" in sc.no_fly[0].name
    assert sc.wind is not None and sc.wind.gust_sigma_mps > 0
    assert sc.endurance is not None and set(sc.endurance.types) == {"A", "B"}
    assert {u.type for u in sc.uavs} == {"A", "B"} and sc.planner.surveillance
    assert {f.kind for f in sc.faults} == {"battery", "crash"}


@pytest.mark.slow
def test_swarm_run_geo_coast_exits_0(tmp_path):
    import subprocess
    import sys

    out = tmp_path / "coast"
    proc = subprocess.run([sys.executable, "-m", "swarm", "run", "geo-coast", "--duration", "300", "--no-figures",
                           "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    for name in ("paths.geojson", "targets.geojson", "zones.geojson", "metrics.json"):
        assert (out / name).is_file(), name
    m = json.loads((out / "metrics.json").read_text())
    assert m["violations"]["threat"] == 0 and m["faults_applied"].get("battery", 0) == 0  # (at 1200 s: not yet)
