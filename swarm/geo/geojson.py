"""A run's results as GeoJSON (issue 26, RFC 7946): ``paths.geojson`` (each UAV's track),
``targets.geojson`` (each target's track) and ``zones.geojson`` (the search area, the no-fly
polygons, the circular threats as polygons, the bases), all in longitude/latitude (WGS84,
``[lon, lat]`` order, polygons' outer rings counter-clockwise, no ``crs`` member), which a GIS
tool (QGIS, geopandas, geojson.io) opens as they are.

Written only for a scenario with ``[geo]`` (a metric scenario has no place on the Earth).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from swarm.geo.frame import GeoFrame, frame_for

__all__ = ["geojson_files", "run_frame"]

_DECIMALS = 7  # 1e-7 degrees: about 1 cm


def run_frame(scenario: Mapping[str, Any]) -> GeoFrame | None:
    """The frame of a scenario as ``scenario.json`` holds it (None without ``[geo]``)."""
    geo = scenario.get("geo")
    if not geo:
        return None
    return frame_for(geo.get("crs", "EPSG:4326"), geo["area"], float(scenario["area"]["cell_m"]))


def _coords(frame: GeoFrame, x: np.ndarray, y: np.ndarray) -> list[list[float]]:
    lon, lat = frame.to_lonlat(x, y)
    return [[round(float(a), _DECIMALS), round(float(b), _DECIMALS)] for a, b in zip(lon, lat)]


def _polygon(frame: GeoFrame, ring_xy: np.ndarray) -> dict[str, Any]:
    import shapely
    from shapely.geometry.polygon import orient

    ring = _coords(frame, ring_xy[:, 0], ring_xy[:, 1])
    if ring[0] != ring[-1]:
        ring.append(ring[0])
    poly = orient(shapely.Polygon(ring), sign=1.0)  # RFC 7946: exterior rings counter-clockwise
    return {"type": "Polygon", "coordinates": [[list(p) for p in poly.exterior.coords]]}


def _line(frame: GeoFrame, rows: np.ndarray) -> dict[str, Any]:
    pts = _coords(frame, rows[:, 1], rows[:, 2])
    if len(pts) == 1:
        return {"type": "Point", "coordinates": pts[0]}
    return {"type": "LineString", "coordinates": pts}


def _collection(features: list[dict[str, Any]]) -> bytes:
    return json.dumps({"type": "FeatureCollection", "features": features}, separators=(",", ":")).encode()


def geojson_files(result: Any, scenario: Mapping[str, Any], extra_zones: list[dict[str, Any]] | None = None) -> dict[str, bytes]:
    """``{"paths.geojson": ..., "targets.geojson": ..., "zones.geojson": ...}`` of a run, or
    ``{}`` for a scenario without ``[geo]``."""
    frame = run_frame(scenario)
    if frame is None:
        return {}
    types = getattr(result, "uav_types", {}) or {}
    paths = []
    for name, rows in result.paths.items():
        rows = np.asarray(rows)
        if len(rows) == 0:
            continue
        paths.append({"type": "Feature", "geometry": _line(frame, rows),
                      "properties": {"name": name, "type": types.get(name, ""), "t_start": float(rows[0, 0]),
                                     "t_end": float(rows[-1, 0])}})
    targets = []
    for tid, rows in sorted(result.target_paths.items()):
        rows = np.asarray(rows)
        if len(rows) == 0:
            continue
        targets.append({"type": "Feature", "geometry": _line(frame, rows),
                        "properties": {"target": int(tid), "t_start": float(rows[0, 0]), "t_end": float(rows[-1, 0])}})
    zones: list[dict[str, Any]] = [{"type": "Feature", "geometry": _polygon(frame, np.asarray(frame.area)),
                                    "properties": {"role": "area"}}]
    n_threats = len(scenario.get("threats") or [])
    for j, z in enumerate(scenario.get("no_fly") or []):
        zones.append({"type": "Feature", "geometry": _polygon(frame, frame.ring_to_local(z["polygon"])),
                      "properties": {"role": "no_fly", "zone": n_threats + j, "name": z.get("name", ""),
                                     "influence_m": z.get("influence_m")}})
    for k, th in enumerate(scenario.get("threats") or []):
        a = np.linspace(0.0, 2.0 * math.pi, 73)
        ring = np.column_stack([th["x_m"] + th["radius_m"] * np.cos(a), th["y_m"] + th["radius_m"] * np.sin(a)])
        zones.append({"type": "Feature", "geometry": _polygon(frame, ring),
                      "properties": {"role": "threat", "zone": k, "radius_m": th["radius_m"]}})
    e = scenario.get("endurance")
    if isinstance(e, dict) and e.get("x_m") is not None:  # the home base: where UAVs land and relaunch
        zones.append({"type": "Feature", "geometry": {"type": "Point", "coordinates": _coords(
            frame, np.array([float(e["x_m"])]), np.array([float(e["y_m"])]))[0]},
                      "properties": {"role": "base", "land_radius_m": e.get("land_radius_m")}})
    for feat in extra_zones or []:
        zones.append(feat)
    return {"paths.geojson": _collection(paths), "targets.geojson": _collection(targets), "zones.geojson": _collection(zones)}
