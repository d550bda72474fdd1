"""Geographic scenarios (issue 26): areas and no-fly zones as polygons in longitude/latitude,
the local metric frame a run flies in, and results as GeoJSON.

* :mod:`.frame`: :class:`GeoFrame`, the local Transverse Mercator frame chosen from the area
  (pyproj), coordinates both ways and its distortion over the area;
* :mod:`.geography`: what a run builds from a scenario's ``[geo]`` and ``[[no_fly]]``: the zones
  the UAVs avoid (:class:`agents.zones.Keepout`), the cells inside the area (shapely 2,
  vectorised over every cell), the mask stamped into the UAVs' maps;
* :mod:`.geojson`: reading a FeatureCollection beside a scenario; writing a run's paths,
  targets and zones in lon/lat (RFC 7946).

pyproj and shapely are imported only when a scenario asks for geography: a metric scenario
never loads them.
"""
