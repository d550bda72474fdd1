"""The way home (issue 33): the route a UAV with an energy budget flies back to its base, round
the no-fly zones (polygons and circles) and inside the area polygon, and the energy it takes
against the wind.

The route is the shortest path in a visibility graph: the obstacles are the no-fly zones grown
by how far their repulsion reaches (a polygon's ``influence_m``, a circle's ``d_max``: the APF
keeps a UAV about that far off, so a route hugging the bare zone would undercount), the nodes
their grown outlines' vertices and the area polygon's; a leg is usable when it stays inside
the area and out of every grown zone. Straight home when nothing is in the way (one segment
test: the common case, every tick). Circles are polygons of 16 sides. The graph among the
nodes is built once; a query adds the UAV's position and its pad and runs Dijkstra over a few
tens of nodes.

The energy of a leg of length ``L`` heading ``u`` at airspeed ``v`` in the mean wind ``w``:
``P(v) L / g`` with ``g = w.u + sqrt(v^2 - (w x u)^2)`` the ground speed along it (infinite when
the wind is too strong to make way), summed over the route's legs.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence

import numpy as np
import shapely

__all__ = ["HomeWay", "leg_energy_wh"]

Point = tuple[float, float]


def leg_energy_wh(x0: float, y0: float, x1: float, y1: float, power_w: float, v: float, wind: Point) -> float:
    """Energy (Wh) to fly from ``(x0, y0)`` to ``(x1, y1)`` at airspeed ``v`` drawing ``power_w``
    in the steady wind ``wind`` (module docstring)."""
    dx, dy = x1 - x0, y1 - y0
    d = math.hypot(dx, dy)
    if d < 1e-9:
        return 0.0
    ux, uy = dx / d, dy / d
    along, across = wind[0] * ux + wind[1] * uy, -wind[0] * uy + wind[1] * ux
    ground = along + math.sqrt(max(v * v - across * across, 0.0))
    if ground <= 1e-6:
        return math.inf
    return power_w * d / ground / 3600.0


class HomeWay:
    """Routes round ``zones`` (rings in local metres, each with the margin to keep) inside
    ``area`` (a ring, or None for the rectangle ``bounds``)."""

    def __init__(self, zones: Sequence[tuple[np.ndarray, float]], area: np.ndarray | None,
                 bounds: tuple[float, float]):
        grown = [shapely.Polygon(ring).buffer(margin, quad_segs=4) for ring, margin in zones]
        self.blocked = shapely.union_all(grown) if grown else None
        box = shapely.Polygon(area) if area is not None else shapely.box(0.0, 0.0, *bounds)
        free = box.buffer(1.0)
        if self.blocked is not None:
            free = free.difference(self.blocked)
        self.free = free
        shapely.prepare(self.free)
        nodes: list[Point] = []
        if self.blocked is not None:
            # (a hair outside each grown zone, so a leg touching its corner is still usable)
            for poly in getattr(self.blocked.buffer(5.0, quad_segs=2), "geoms", [self.blocked.buffer(5.0, quad_segs=2)]):
                nodes += [(float(x), float(y)) for x, y in poly.exterior.coords[:-1]]
        if area is not None:
            inner = box.buffer(-5.0, join_style="mitre")
            for poly in getattr(inner, "geoms", [inner]):
                nodes += [(float(x), float(y)) for x, y in poly.exterior.coords[:-1]]
        self.nodes = [p for p in nodes if self.free.contains(shapely.Point(p))]
        n = len(self.nodes)
        self.edges: list[list[tuple[int, float]]] = [[] for _ in range(n)]
        for i in range(n):
            for j in range(i + 1, n):
                if self.visible(self.nodes[i], self.nodes[j]):
                    d = math.dist(self.nodes[i], self.nodes[j])
                    self.edges[i].append((j, d))
                    self.edges[j].append((i, d))

    @property
    def trivial(self) -> bool:
        """Nothing to route round: every way home is straight."""
        return self.blocked is None and not self.nodes

    def visible(self, a: Point, b: Point) -> bool:
        if a == b:
            return True
        return bool(self.free.contains(shapely.LineString([a, b])))

    def route(self, start: Point, goal: Point) -> list[Point]:
        """The points to fly through after ``start``, ending with ``goal`` (the straight line
        when it is usable, or when no usable route exists: the UAV is then already somewhere
        the routes do not reach, inside a grown zone or outside the area)."""
        if self.trivial or self.visible(start, goal):
            return [goal]
        nodes = self.nodes
        n = len(nodes)
        from_start = [(j, math.dist(start, p)) for j, p in enumerate(nodes) if self.visible(start, p)]
        to_goal = {j: math.dist(p, goal) for j, p in enumerate(nodes) if self.visible(p, goal)}
        if not from_start or not to_goal:
            return [goal]
        dist = [math.inf] * n
        prev = [-1] * n
        heap: list[tuple[float, int]] = []
        for j, d in from_start:
            dist[j] = d
            heapq.heappush(heap, (d, j))
        best, last = math.inf, -1
        while heap:
            d, i = heapq.heappop(heap)
            if d > dist[i] or d >= best:
                continue
            if i in to_goal and d + to_goal[i] < best:
                best, last = d + to_goal[i], i
            for j, w in self.edges[i]:
                if d + w < dist[j]:
                    dist[j] = d + w
                    prev[j] = i
                    heapq.heappush(heap, (d + w, j))
        if last < 0:
            return [goal]
        path = [goal]
        i = last
        while i >= 0:
            path.append(nodes[i])
            i = prev[i]
        path.reverse()
        return path

    def energy_wh(self, start: Point, way: Sequence[Point], power_w: float, v: float, wind: Point) -> float:
        """The energy to fly ``start`` then through ``way`` (:func:`leg_energy_wh` per leg)."""
        total = 0.0
        x, y = start
        for px, py in way:
            total += leg_energy_wh(x, y, px, py, power_w, v, wind)
            x, y = px, py
        return total
