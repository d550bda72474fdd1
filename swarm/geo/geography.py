"""What a run builds from a scenario's ``[geo]`` and ``[[no_fly]]`` (issue 26).

* the polygon no-fly zones in local metres, as :class:`agents.zones.Keepout` (ids after the
  circular threats'), for the UAVs' APF, the world's threat check and the threat invariant;
* the area's boundary as an inverted :class:`~agents.zones.Keepout` (UAVs keep inside: the
  APF repels within :data:`AREA_REACH_M` of it and the threat guard turns them away from it);
* which cells lie inside the area polygon (a cell counts when its centre does), with shapely 2
  over every cell centre at once (``shapely.contains_xy``): the metrics count coverage and
  certainty over those cells only, and the cells outside are one mask (a
  :class:`agents.maps.grid.Disk` over the whole grid) that every UAV stamps into its map as
  seen at every tick, so ``q = 0`` there at planning time: nothing to search, for DACMP's map,
  pyramid and guide points and for every other planner alike.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.maps.grid import Disk, Grid
from agents.zones import Keepout
from swarm.geo.frame import GeoFrame, GeoProblem, _ring, frame_for

__all__ = ["AREA_REACH_M", "Geography", "geography", "local_ring", "zone_keepouts"]

# The area boundary's repulsion reaches this far inside (m): enough to turn a UAV before the
# guard must, short enough that the cells along the edge are still searched.
AREA_REACH_M = 1000.0


def local_ring(frame: GeoFrame | None, polygon: Sequence[Sequence[float]], key: tuple[str | int, ...]) -> np.ndarray:
    """A closed ring in the scenario's CRS (or in metres without a frame) as local metres."""
    pts = _ring(polygon, key, "a no-fly zone")
    if frame is None:
        return np.asarray(pts, dtype=np.float64)
    return frame.ring_to_local(pts)


def zone_keepouts(sc: Any, frame: GeoFrame | None) -> list[Keepout]:
    """The scenario's polygon no-fly zones in local metres (ids after the circular threats')."""
    base = len(sc.threats)
    return [Keepout(base + j, local_ring(frame, z.polygon, ("no_fly", j, "polygon")), z.influence_m)
            for j, z in enumerate(sc.no_fly)]


@dataclass
class Geography:
    frame: GeoFrame | None
    zones: list[Keepout]  # polygon no-fly zones
    area: Keepout | None  # the area's boundary (inverted), or None for a rectangle
    inside: np.ndarray | None  # (ny, nx) bool: cells whose centre is inside the area polygon
    outside: Disk | None  # the cells outside, as one mask over the grid (stamped as seen)
    # The area polygon as a prepared shapely polygon (local metres), or None for a rectangle:
    # what the cells and the targets (swarm.kernel.world.Targets, issue 33) are tested against.
    polygon: Any = None

    @property
    def keepouts(self) -> tuple[Keepout, ...]:
        """What the APF steers clear of: the no-fly polygons, then the area's boundary."""
        return tuple(self.zones) + ((self.area,) if self.area is not None else ())


def geography(sc: Any, grid: Grid) -> Geography | None:
    """The run's geography, or None for a scenario without ``[geo]`` or ``[[no_fly]]``."""
    if sc.geo is None and not sc.no_fly:
        return None
    frame = None
    if sc.geo is not None:
        try:
            frame = frame_for(sc.geo.crs, sc.geo.area, sc.area.cell_m)
        except GeoProblem as p:  # (validated when it loaded: only a hand-built scenario gets here)
            raise ValueError(f"geo.{'.'.join(map(str, p.key))}: {p.expected}") from None
    zones = zone_keepouts(sc, frame)
    area = inside = outside = poly = None
    if frame is not None:
        import shapely

        area = Keepout(-1, frame.area, AREA_REACH_M, inverted=True)
        poly = shapely.Polygon(frame.area)
        shapely.prepare(poly)
        cx = (np.arange(grid.nx) + 0.5) * grid.cell_m
        cy = (np.arange(grid.ny) + 0.5) * grid.cell_m
        gx, gy = np.meshgrid(cx, cy)
        inside = shapely.contains_xy(poly, gx, gy)
        if not inside.all():
            outside = Disk(0, grid.ny, 0, grid.nx, ~inside, (0, 0), key=(-1.0, -1.0, -1.0))
    return Geography(frame, zones, area, inside, outside, poly)
