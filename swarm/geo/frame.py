"""The local metric frame of a geographic scenario.

A geographic area is given as a polygon in some CRS (EPSG:4326 longitude/latitude by default,
GeoJSON's axis order: ``[lon, lat]``). The simulation flies in metres, x east and y north,
origin at the south-west corner of the area's bounding box, as every scenario does. The frame
between the two is a **Transverse Mercator projection centred on the area** (``+proj=tmerc``,
``lat_0``/``lon_0`` the centre of the area's longitude/latitude bounding box, scale 1 on the
central meridian, WGS84). Why that one:

* it is **conformal**: angles and so headings, turn rates and turn radii are the same in the
  frame as on the ground; circles (detection discs, radio ranges) stay circles;
* its **scale error** grows with the square of the distance from the central meridian:
  ``k - 1 ~ x^2 / (2 R^2)``: 3e-6 at 10 km, 7.7e-6 at 25 km, 3.1e-5 at 50 km, so a
  50 km-wide area is off by at most about 1.5 m over 50 km (:meth:`GeoFrame.distortion` measures
  it at the area's vertices and corners with pyproj's own factors, and ``metrics.json`` reports it);
* grid north is true north on the central meridian and within a fraction of a degree of it
  over such an area (the meridian convergence, ``~ dlon * sin(lat)``).

UTM would do as well inside one zone, but an area straddling a zone boundary would sit on its
edge; an azimuthal equidistant projection keeps distances from the centre but not angles. A
local TM centred on the area has neither problem.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["GeoFrame", "GeoProblem", "frame_for", "is_geographic"]


class GeoProblem(ValueError):
    """A geographic input that cannot be used: ``key`` (relative to ``[geo]``) and what was expected."""

    def __init__(self, key: tuple[str | int, ...], found: Any, expected: str, hint: str = ""):
        self.key, self.found, self.expected, self.hint = key, found, expected, hint
        super().__init__(f"{key}: {expected}")


def _crs(crs: str) -> Any:
    from pyproj import CRS
    from pyproj.exceptions import CRSError

    try:
        return CRS.from_user_input(crs)
    except CRSError as exc:
        raise GeoProblem(("crs",), crs, "a coordinate reference system pyproj knows, e.g. \"EPSG:4326\" "
                                       "(longitude/latitude, WGS84) or \"EPSG:32633\" (UTM 33N)",
                         hint=str(exc).split("\n")[0][:120]) from None


@functools.lru_cache(maxsize=32)
def is_geographic(crs: str) -> bool:
    """Whether ``crs`` is a geographic (longitude/latitude) CRS."""
    return bool(_crs(crs).is_geographic)


@dataclass(frozen=True)
class GeoFrame:
    """Coordinates between a scenario's CRS, longitude/latitude and the run's local metres."""

    crs: str
    lon0: float
    lat0: float
    x0: float  # projected easting of the local origin (the area's bounding box's west edge)
    y0: float  # projected northing of the local origin (its south edge)
    width_m: float
    height_m: float
    cell_m: float
    area: tuple[tuple[float, float], ...]  # the area's ring in local metres (closed)

    @property
    def proj4(self) -> str:
        return (f"+proj=tmerc +lat_0={self.lat0!r} +lon_0={self.lon0!r} +k=1 +x_0=0 +y_0=0 "
                f"+datum=WGS84 +units=m +no_defs")

    def to_local(self, a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points in the scenario's CRS (``[lon, lat]`` for EPSG:4326) as local metres."""
        x, y = _transformer(self.crs, self.proj4).transform(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
        return np.asarray(x) - self.x0, np.asarray(y) - self.y0

    def to_lonlat(self, x: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Local metres as longitude/latitude (EPSG:4326, RFC 7946's axis order)."""
        lon, lat = _transformer(self.proj4, "EPSG:4326").transform(np.asarray(x, dtype=np.float64) + self.x0,
                                                                   np.asarray(y, dtype=np.float64) + self.y0)
        return np.asarray(lon), np.asarray(lat)

    def lonlat_to_local(self, lon: float, lat: float) -> tuple[float, float]:
        """A longitude/latitude (EPSG:4326, degrees) as local metres."""
        x, y = _transformer("EPSG:4326", self.proj4).transform(np.asarray([lon], dtype=np.float64),
                                                                np.asarray([lat], dtype=np.float64))
        return float(np.asarray(x)[0]) - self.x0, float(np.asarray(y)[0]) - self.y0

    def ring_to_local(self, ring: Sequence[Sequence[float]] | np.ndarray) -> np.ndarray:
        pts = np.asarray(ring, dtype=np.float64).reshape(-1, 2)
        x, y = self.to_local(pts[:, 0], pts[:, 1])
        return np.column_stack([x, y])

    def distortion(self) -> dict[str, float]:
        """The projection's distortion over the area (pyproj's factors at its vertices and the
        corners of its bounding box): the largest ``|k - 1|`` of the meridional and parallel
        scales, the largest angular distortion (degrees: 0 for a conformal projection), and the
        largest meridian convergence (degrees: how far grid north is from true north)."""
        from pyproj import Proj

        ring = np.asarray(self.area)
        corners = np.array([[0, 0], [self.width_m, 0], [self.width_m, self.height_m], [0, self.height_m]], dtype=np.float64)
        pts = np.vstack([ring, corners])
        lon, lat = self.to_lonlat(pts[:, 0], pts[:, 1])
        f = Proj(self.proj4).get_factors(lon, lat)
        scale = np.maximum(np.abs(np.asarray(f.meridional_scale) - 1.0), np.abs(np.asarray(f.parallel_scale) - 1.0))
        return {"scale_error_max": float(scale.max()), "angular_distortion_deg_max": float(np.abs(f.angular_distortion).max()),
                "meridian_convergence_deg_max": float(np.abs(f.meridian_convergence).max())}

    def describe(self) -> dict[str, Any]:
        """What ``metrics.json`` says of the frame."""
        lon, lat = self.to_lonlat([0.0], [0.0])
        return {"crs": self.crs, "projection": self.proj4, "origin_lonlat": [float(lon[0]), float(lat[0])],
                **self.distortion()}


@functools.lru_cache(maxsize=32)
def _transformer(src: str, dst: str) -> Any:
    from pyproj import Transformer

    return Transformer.from_crs(src, dst, always_xy=True)


def _ring(value: Any, key: tuple[str | int, ...], what: str) -> list[tuple[float, float]]:
    """A closed ring of ``[a, b]`` pairs, checked: at least 4 points (3 distinct), closed."""
    ok = isinstance(value, (list, tuple)) and all(
        isinstance(p, (list, tuple)) and len(p) == 2 and all(isinstance(c, (int, float)) and not isinstance(c, bool)
                                                             and math.isfinite(c) for c in p) for p in value)
    if not ok:
        raise GeoProblem(key, value, f"{what}: an array of [x, y] pairs ([lon, lat] in a geographic CRS)")
    pts = [(float(a), float(b)) for a, b in value]
    if len(pts) < 4:
        raise GeoProblem(key, value, f"{what}: a closed ring of at least 4 points (3 corners, then the first again)")
    if pts[0] != pts[-1]:
        raise GeoProblem(key, value, f"{what}: a closed ring (the last point equal to the first, as GeoJSON has it)",
                         hint=f"add {list(pts[0])} at the end")
    if len(set(pts[:-1])) < 3:
        raise GeoProblem(key, value, f"{what}: a ring of at least 3 distinct corners")
    return pts


def check_simple(xy: np.ndarray, key: tuple[str | int, ...], value: Any, what: str) -> None:
    """Raise :class:`GeoProblem` unless the ring ``xy`` (local metres) is a valid simple polygon
    (shapely 2: not crossing itself, not collapsed)."""
    import shapely

    poly = shapely.Polygon(xy)
    if not poly.is_valid or poly.area <= 0.0:
        why = shapely.is_valid_reason(poly)
        raise GeoProblem(key, value, f"{what}: a simple polygon (its edges may not cross or touch each other)",
                         hint=f"shapely says: {why}")


def frame_for(crs: str, ring: Any, cell_m: float) -> GeoFrame:
    """The frame of an area given as ``ring`` (a closed ring in ``crs``), with ``cell_m`` cells.
    Raises :class:`GeoProblem` (keys relative to ``[geo]``) for an unknown CRS or a bad ring."""
    pts = _ring(ring, ("area",), "the search area")
    return _frame(crs, tuple(pts), float(cell_m))


@functools.lru_cache(maxsize=16)
def _frame(crs: str, pts: tuple[tuple[float, float], ...], cell_m: float) -> GeoFrame:
    c = _crs(crs)
    a = np.array([p[0] for p in pts])
    b = np.array([p[1] for p in pts])
    if c.is_geographic:
        if not (np.all(np.abs(a) <= 180.0) and np.all(np.abs(b) <= 90.0)):
            raise GeoProblem(("area",), [list(p) for p in pts], "the search area: [lon, lat] pairs with lon in "
                             "[-180, 180] and lat in [-90, 90] (GeoJSON's order: longitude first)")
        lon, lat = a, b
    else:
        lon, lat = _transformer(crs, "EPSG:4326").transform(a, b)
    lon0 = round(float((np.min(lon) + np.max(lon)) / 2.0), 9)
    lat0 = round(float((np.min(lat) + np.max(lat)) / 2.0), 9)
    probe = GeoFrame(crs, lon0, lat0, 0.0, 0.0, 0.0, 0.0, cell_m, ())
    X, Y = probe.to_local(a, b)
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(Y))):
        raise GeoProblem(("area",), [list(p) for p in pts], f"the search area: points {crs} can place on the Earth")
    x0, y0 = float(np.min(X)), float(np.min(Y))
    width = math.ceil((float(np.max(X)) - x0) / cell_m - 1e-9) * cell_m
    height = math.ceil((float(np.max(Y)) - y0) / cell_m - 1e-9) * cell_m
    ring = tuple((float(x) - x0, float(y) - y0) for x, y in zip(X, Y))
    check_simple(np.array(ring), ("area",), [list(p) for p in pts], "the search area")
    return GeoFrame(crs, lon0, lat0, x0, y0, max(width, cell_m), max(height, cell_m), cell_m, ring)
