"""The geographic tables of a scenario (issue 26): ``[geo]`` (the area as a polygon in a CRS,
inline or from a GeoJSON file beside the scenario) and ``[[no_fly]]`` (polygon no-fly zones),
and how lon/lat positions become the run's local metres.

Nothing here runs for a scenario without ``[geo]`` and ``[[no_fly]]`` (and pyproj and shapely
are not imported): :func:`resolve_geography` returns such a document untouched.

With ``[geo]``:

* the area's ``width_m`` and ``height_m`` come from the polygon (its bounding box in the local
  frame, :mod:`swarm.geo.frame`, rounded up to whole cells): giving them is an error;
* ``[[uavs]]``, ``[[targets.placed]]`` and ``[[threats]]`` may give ``lon`` and ``lat`` (in the
  ``[geo] crs``: for a projected CRS its easting and northing) instead of ``x_m`` and ``y_m``;
  they are converted when the scenario loads, so the loaded scenario (``scenario.json``) holds
  metres, as every scenario does, plus the polygon that defines the frame;
* ``[[no_fly]] polygon`` is in the ``[geo] crs``; without ``[geo]`` it is in local metres;
* ``file``: a GeoJSON FeatureCollection (path relative to the scenario file) whose features
  carry a ``role`` property: one ``"area"`` Polygon, any number of ``"no_fly"`` Polygons (an
  optional ``influence_m`` property each). It is read when the scenario loads and inlined.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from pydantic import Field

from swarm.scenario.fields import Num, Problem, Str, Table, num_field

__all__ = ["GeoSettings", "NoFlySpec", "geo_problems", "resolve_geography"]

_PAIRS = "an array of [x, y] pairs: a closed ring ([lon, lat] in [geo] crs, else metres)"


class GeoSettings(Table):
    """The search area as a polygon in a coordinate reference system (see the module docstring)."""

    crs: Str = Field(default="EPSG:4326", description="a CRS pyproj knows, e.g. \"EPSG:4326\" (lon/lat, the default)")
    area: list[list[Num]] | None = Field(default=None, description="the search area: " + _PAIRS)
    file: Str | None = Field(default=None, description="a GeoJSON FeatureCollection's path, relative to the scenario file")


class NoFlySpec(Table):
    """A polygon no-fly zone: UAVs keep out (APF repulsion within ``influence_m`` of its edge,
    the threat guard, the threat invariant), as they keep out of a circular ``[[threats]]`` zone."""

    name: Str = Field(default="", description="a string (shown in outputs)")
    polygon: list[list[Num]] = Field(..., description=_PAIRS)
    influence_m: Num = num_field(3000.0, gt=0, note="m beyond the edge where its repulsion acts (as a threat's 3 km)")


class _Bad(Exception):
    def __init__(self, problems: list[Problem]):
        self.problems = problems


def _read_collection(path: Path, key: tuple[str | int, ...]) -> tuple[list[Any] | None, list[dict[str, Any]]]:
    """The area ring and the no-fly zones of a GeoJSON FeatureCollection."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise _Bad([Problem(key, str(path), "a readable GeoJSON file (a FeatureCollection)",
                            found=f"{str(path)!r}, which cannot be read as JSON ({exc})")]) from None
    if not isinstance(doc, dict) or doc.get("type") != "FeatureCollection":
        raise _Bad([Problem(key, str(path), "a GeoJSON FeatureCollection (\"type\": \"FeatureCollection\")",
                            found=f"{str(path)!r}, which is not a FeatureCollection")])
    area = None
    zones: list[dict[str, Any]] = []
    for i, feat in enumerate(doc.get("features") or []):
        props = (feat or {}).get("properties") or {}
        geom = (feat or {}).get("geometry") or {}
        role = props.get("role")
        if role not in ("area", "no_fly"):
            continue
        if geom.get("type") != "Polygon" or not geom.get("coordinates"):
            raise _Bad([Problem(key, str(path), f"features with role {role!r} to be Polygons",
                                found=f"feature {i} of {str(path)!r}: a {geom.get('type')!r} geometry")])
        ring = geom["coordinates"][0]
        if role == "area":
            if area is not None:
                raise _Bad([Problem(key, str(path), "one feature with role \"area\"",
                                    found=f"{str(path)!r}, with several area features (the second is feature {i})")])
            area = ring
        else:
            zone: dict[str, Any] = {"polygon": ring, "name": str(props.get("name", ""))}
            if "influence_m" in props:
                zone["influence_m"] = props["influence_m"]
            zones.append(zone)
    return area, zones


def _has_lonlat(item: Any) -> bool:
    return isinstance(item, dict) and ("lon" in item or "lat" in item)


def _lonlat_items(data: dict[str, Any]) -> list[tuple[tuple[str | int, ...], dict[str, Any]]]:
    out: list[tuple[tuple[str | int, ...], dict[str, Any]]] = []
    for table in ("uavs", "threats"):
        items = data.get(table)
        if isinstance(items, list):
            out += [((table, i), item) for i, item in enumerate(items) if _has_lonlat(item)]
    if _has_lonlat(data.get("endurance")):  # the home base
        out.append((("endurance",), data["endurance"]))
    targets = data.get("targets")
    placed = targets.get("placed") if isinstance(targets, dict) else None
    if isinstance(placed, list):
        out += [(("targets", "placed", i), item) for i, item in enumerate(placed) if _has_lonlat(item)]
    return out


def resolve_geography(data: Any, context: dict[str, Any] | None) -> Any:
    """The document with its geography resolved (a before-validator of the Scenario): the GeoJSON
    file read and inlined, the area's size from its polygon, lon/lat positions in metres.
    Raises :class:`swarm.scenario.fields.Invalid` with the key path of what is wrong."""
    from swarm.scenario.fields import raise_if

    if not isinstance(data, dict):
        return data
    geo = data.get("geo")
    items = _lonlat_items(data)
    if geo is None:
        raise_if([Problem((*path, "lon" if "lon" in item else "lat"), item.get("lon", item.get("lat")),
                          "x_m and y_m in metres (lon and lat need a [geo] table that says where the area is)")
                  for path, item in items[:1]])
        return data
    if not isinstance(geo, dict):
        return data  # (the table's own type error)
    try:
        return _resolve(data, dict(geo), items, context or {})
    except _Bad as bad:
        raise_if(bad.problems)
    return data


def _resolve(data: dict[str, Any], geo: dict[str, Any], items: list[Any], context: dict[str, Any]) -> dict[str, Any]:
    from swarm.geo.frame import GeoProblem, frame_for

    data = dict(data)
    if geo.get("file") is not None and isinstance(geo["file"], str):
        source = context.get("source") or ""
        base = Path(source).parent if source and not source.startswith("<") and Path(source).suffix else Path.cwd()
        area, zones = _read_collection(base / geo["file"], ("geo", "file"))
        if area is not None and geo.get("area") is None:
            geo["area"] = area
        data["no_fly"] = [*(data.get("no_fly") or []), *zones]
        geo["file"] = None  # (read: the scenario now holds its polygons itself)
    data["geo"] = geo
    if geo.get("area") is None:
        raise _Bad([Problem(("geo", "area"), None, "the search area: " + _PAIRS + ", or a file with an \"area\" feature",
                            found="nothing (the key is missing)")])
    area_doc: dict[str, Any] = data["area"] if isinstance(data.get("area"), dict) else {}
    cell = area_doc.get("cell_m", 100.0)
    if isinstance(cell, bool) or not isinstance(cell, (int, float)) or not cell > 0 or not math.isfinite(cell):
        return data  # (the table's own error)
    crs = geo.get("crs", "EPSG:4326")
    if not isinstance(crs, str):
        return data
    try:
        frame = frame_for(crs, geo["area"], float(cell))
    except GeoProblem as p:
        raise _Bad([Problem(("geo", *p.key), p.found, p.expected, hint=p.hint)]) from None
    # The size is derived from the polygon. A document may still carry it, as every written
    # scenario.json does (the scenario that ran, derived values included), if it is the size the
    # polygon gives: a run folder reads back as itself. A different size is a contradiction.
    derived = {"width_m": frame.width_m, "height_m": frame.height_m}
    for key, value in derived.items():
        if key in area_doc and not _same_size(area_doc[key], value):
            raise _Bad([Problem(("area", key), area_doc[key],
                                "to be left out with [geo] area (the area's size is its polygon's bounding box in the "
                                f"local frame: {frame.width_m:g} x {frame.height_m:g} m)")])
    data["area"] = {**area_doc, "width_m": frame.width_m, "height_m": frame.height_m}
    # lon/lat positions -> metres (in copies of the tables that hold them)
    if items:
        copies: dict[tuple[str | int, ...], dict[str, Any]] = {}
        for table in ("uavs", "threats"):
            if isinstance(data.get(table), list):
                data[table] = [dict(x) if isinstance(x, dict) else x for x in data[table]]
        if isinstance(data.get("endurance"), dict):
            data["endurance"] = dict(data["endurance"])
        if isinstance(data.get("targets"), dict):
            data["targets"] = dict(data["targets"])
            if isinstance(data["targets"].get("placed"), list):
                data["targets"]["placed"] = [dict(x) if isinstance(x, dict) else x for x in data["targets"]["placed"]]
        for path, _ in items:
            obj: Any = data
            for part in path:
                obj = obj[part]
            copies[path] = obj
        for path, item in copies.items():
            lon, lat = item.pop("lon", None), item.pop("lat", None)
            for key, value in (("lon", lon), ("lat", lat)):
                if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                    raise _Bad([Problem((*path, key), value, "a number (with lon and lat both given, in [geo] crs)")])
            swapped = _swapped(geo, crs, (float(lon), float(lat)))
            if swapped:
                raise _Bad([Problem((*path, "lon"), lon, swapped, found=f"lon = {lon!r}, lat = {lat!r}",
                                    hint="lon and lat look swapped: GeoJSON's order is longitude first")])
            x, y = frame.to_local([lon], [lat])
            if not (math.isfinite(float(x[0])) and math.isfinite(float(y[0]))):
                raise _Bad([Problem((*path, "lon"), lon, f"a point {crs} can place on the Earth",
                                    found=f"lon = {lon!r}, lat = {lat!r}")])
            item["x_m"], item["y_m"] = float(x[0]), float(y[0])
    return data


def _same_size(given: Any, derived: float) -> bool:
    """A written size read back: equal to the derived one up to float noise (JSON keeps it exact)."""
    if isinstance(given, bool) or not isinstance(given, (int, float)):
        return False
    return math.isclose(float(given), derived, rel_tol=1e-9, abs_tol=1e-6)


def _swapped(geo: dict[str, Any], crs: str, point: tuple[float, float]) -> str:
    """What was expected, when a geographic point lies outside the area's lon/lat bounding box
    (or off the globe) and the same point with its two numbers swapped lies inside it; else ""."""
    from swarm.geo.frame import is_geographic

    if not is_geographic(crs):
        return ""
    ring = [p for p in geo["area"] if isinstance(p, (list, tuple)) and len(p) == 2]
    if not ring:
        return ""
    lons, lats = [float(p[0]) for p in ring], [float(p[1]) for p in ring]

    def inside(lon: float, lat: float) -> bool:
        return min(lons) <= lon <= max(lons) and min(lats) <= lat <= max(lats)

    a, b = point
    if inside(a, b) or not inside(b, a):
        return ""
    return (f"a point in the area (lon in [{min(lons):g}, {max(lons):g}], lat in [{min(lats):g}, {max(lats):g}]); "
            f"as lon = {b!r}, lat = {a!r} it would be")


def geo_problems(sc: Any) -> list[Problem]:
    """Checks of a validated scenario's geography: no-fly polygons closed and simple (where
    things are: :func:`swarm.scenario.placement.placement_problems`)."""
    from swarm.geo.frame import GeoProblem, check_simple, frame_for
    from swarm.geo.geography import local_ring

    problems: list[Problem] = []
    frame = frame_for(sc.geo.crs, sc.geo.area, sc.area.cell_m) if sc.geo is not None else None
    for i, z in enumerate(sc.no_fly):
        if sc.geo is not None and z.polygon and all(
                len(p) == 2 and _swapped({"area": sc.geo.area}, sc.geo.crs, (float(p[0]), float(p[1]))) for p in z.polygon):
            problems.append(Problem(("no_fly", i, "polygon"), z.polygon, "a ring of [lon, lat] pairs near the area",
                                    hint="lon and lat look swapped: every corner would lie in the area's lon/lat box "
                                         "the other way round (GeoJSON's order is longitude first)"))
            continue
        try:
            ring = local_ring(frame, z.polygon, ("polygon",))
            check_simple(ring, ("polygon",), z.polygon, "a no-fly zone")
        except GeoProblem as p:
            problems.append(Problem(("no_fly", i, *p.key), p.found, p.expected, hint=p.hint))
    return problems
