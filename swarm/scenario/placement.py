"""Where a scenario's UAVs and base may be: inside the area (its polygon with ``[geo]``), outside
every no-fly zone (``[[threats]]`` circles and ``[[no_fly]]`` polygons), and UAVs that enter
together at least ``safety.min_separation_m`` apart (issues 32 and 33).

:class:`Site` is that space in local metres, built once from a scenario's tables;
:class:`~swarm.scenario.tables.FleetSpec` lays a ``[[fleet]]`` out in it, and
:func:`placement_problems` judges the result. A problem names the key a user wrote: the
``[[uavs]]`` entry, or the ``[[fleet]]`` table whose layout put a UAV there (once per fleet and
kind of problem, with how many of its slots it concerns: one mistake in a big fleet is one line).
Two hand-placed ``[[uavs]]`` that start too close are only a warning (:func:`close_starts`):
tests of the separation rule place them so on purpose.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from swarm.pairs import pairs_within
from swarm.scenario.fields import Problem, fmt

__all__ = ["Site", "close_starts", "placement_problems"]

Origin = tuple[str, int]  # ("uavs", i) or ("fleet", i): the table a UAV comes from


@dataclass
class Site:
    """The area and its no-fly zones in local metres (see the module docstring)."""

    width_m: float
    height_m: float
    min_separation_m: float
    polygon: np.ndarray | None = None  # the area's ring with [geo], else None (the rectangle)
    circles: list[tuple[str, float, float, float]] = field(default_factory=list)  # (label, x, y, radius)
    zones: list[tuple[str, np.ndarray]] = field(default_factory=list)  # (label, ring)
    lonlat: Any = None  # the GeoFrame, to say where a point is in lon/lat
    _cache: tuple[Any, list[tuple[str, Any]]] | None = field(default=None, repr=False)  # (shapely geometries)

    @classmethod
    def of(cls, sc: Any) -> Site:
        """The site of a validated scenario (a zone whose polygon is broken is left out: its own
        problem is reported by :func:`swarm.scenario.geo.geo_problems`)."""
        from swarm.geo.frame import GeoProblem

        frame = None
        if sc.geo is not None:
            from swarm.geo.frame import frame_for

            try:
                frame = frame_for(sc.geo.crs, sc.geo.area, sc.area.cell_m)
            except GeoProblem:
                frame = None
        site = cls(sc.area.width_m, sc.area.height_m, sc.safety.min_separation_m,
                   np.asarray(frame.area) if frame is not None else None, lonlat=frame)
        site.circles = [(f"threats[{i}]", t.x_m, t.y_m, t.radius_m) for i, t in enumerate(sc.threats)]
        if sc.no_fly:
            from swarm.geo.geography import local_ring

            for j, z in enumerate(sc.no_fly):
                try:
                    ring = local_ring(frame, z.polygon, ("polygon",))
                except GeoProblem:
                    continue
                label = f"no_fly[{j}]" + (f" ({z.name!r})" if z.name else "")
                site.zones.append((label, ring))
        return site

    # --- tests over many points at once -------------------------------------------------------
    def _shapes(self) -> tuple[Any, list[tuple[str, Any]]]:
        """The area polygon (its boundary counted inside) and the zones as prepared shapely
        geometries, made once."""
        cached = self._cache
        if cached is None:
            import shapely

            area = shapely.Polygon(self.polygon).buffer(1e-6) if self.polygon is not None else None
            zones = [(label, shapely.Polygon(ring)) for label, ring in self.zones]
            for g in [area, *(z for _l, z in zones)]:
                if g is not None:
                    shapely.prepare(g)
            cached = self._cache = (area, zones)
        return cached

    def in_area(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Inside the area (its polygon's boundary counts as inside)."""
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        ok = (x >= 0.0) & (x <= self.width_m) & (y >= 0.0) & (y <= self.height_m)
        if self.polygon is not None and ok.any():
            import shapely

            ok = ok & shapely.contains_xy(self._shapes()[0], x, y)
        return ok

    def zone_at(self, x: np.ndarray, y: np.ndarray) -> list[str | None]:
        """The label of the no-fly zone each point is inside (its interior), or None."""
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        out: list[str | None] = [None] * len(x)
        for label, cx, cy, r in self.circles:
            for k in np.flatnonzero(np.hypot(x - cx, y - cy) < r):
                out[k] = out[k] or label
        if self.zones:
            import shapely

            for label, poly in self._shapes()[1]:
                for k in np.flatnonzero(shapely.contains_xy(poly, x, y)):
                    out[k] = out[k] or label
        return out

    def free(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Inside the area and outside every no-fly zone."""
        free: np.ndarray = self.in_area(x, y) & np.array([z is None for z in self.zone_at(x, y)], dtype=bool)
        return free

    def where(self, x: float, y: float) -> str:
        """A point for a person: ``(x, y) m``, and its lon/lat in a geographic scenario."""
        text = f"({x:.0f}, {y:.0f}) m"
        if self.lonlat is not None:
            lon, lat = self.lonlat.to_lonlat([x], [y])
            text += f" (lon {float(lon[0]):.5f}, lat {float(lat[0]):.5f})"
        return text


def close_pairs(xy: np.ndarray, r: float) -> list[tuple[int, int, float]]:
    """Pairs ``(i, j, d)``, ``i < j``, of points closer than ``r``, by ``j`` then ``i``."""
    if len(xy) < 2:
        return []
    pairs = pairs_within(xy, r * (1.0 - 1e-12))
    out = [(int(min(a, b)), int(max(a, b)), float(np.hypot(*(xy[a] - xy[b])))) for a, b in pairs]
    return sorted(out, key=lambda p: (p[1], p[0]))


def placement_problems(sc: Any, origins: Sequence[Origin], starts: Sequence[float]) -> list[Problem]:
    """UAVs outside the area polygon or inside a no-fly zone, UAVs that enter at the same time
    (``starts``: each UAV's entry time) closer than the separation minimum, and a base outside
    the area polygon or inside a no-fly zone. ``origins[k]`` is the table UAV ``k`` comes from.
    (A UAV outside the area's rectangle is the rectangle's check: not repeated here.)"""
    site = Site.of(sc)
    uavs = sc.uavs
    names = [u.name for u in uavs]
    x = np.array([u.x_m for u in uavs], dtype=np.float64)
    y = np.array([u.y_m for u in uavs], dtype=np.float64)
    in_box = (x >= 0.0) & (x <= site.width_m) & (y >= 0.0) & (y <= site.height_m)
    per_origin: dict[tuple[Origin, str], list[str]] = {}
    first: dict[tuple[Origin, str], int] = {}

    def add(k: int, kind: str, words: str) -> None:
        key = (origins[k], kind)
        per_origin.setdefault(key, []).append(words)
        first.setdefault(key, k)

    outside = ~site.in_area(x, y) & in_box
    for kk in np.flatnonzero(outside).tolist():
        add(kk, "outside", f"{names[kk]} at {site.where(x[kk], y[kk])}")
    for k, zone in enumerate(site.zone_at(x, y)):
        if zone is not None and in_box[k]:
            add(k, "zone", f"{names[k]} at {site.where(x[k], y[k])}, inside {zone}")
    by_start: dict[float, list[int]] = {}
    for kk, s in enumerate(starts):
        by_start.setdefault(s, []).append(kk)
    for s, ks in sorted(by_start.items()):
        idx = np.array(ks)
        for a, b, d in close_pairs(np.column_stack([x[idx], y[idx]]), site.min_separation_m):
            i, j = int(idx[a]), int(idx[b])
            if origins[i][0] == origins[j][0] == "uavs":
                continue  # two hand-placed UAVs: a warning (close_starts), perhaps meant (a test of the rule)
            add(j, "close", f"{names[j]} {d:.0f} m from {names[i]} ({_table_words(origins[i])})"
                + (f", both entering at {fmt(s)} s" if s > 0 else ""))

    problems: list[Problem] = []
    for (origin, kind), items in sorted(per_origin.items(), key=lambda kv: first[kv[0]]):
        problems.append(_problem(origin, kind, items, uavs[first[(origin, kind)]], site))
    if sc.endurance is not None:
        e = sc.endurance
        if 0.0 <= e.x_m <= site.width_m and 0.0 <= e.y_m <= site.height_m:
            if not site.in_area(np.array([e.x_m]), np.array([e.y_m]))[0]:
                problems.append(Problem(("endurance", "x_m"), e.x_m, "a base inside the area polygon ([geo] area)",
                                        found=f"a base at {site.where(e.x_m, e.y_m)}, outside the area polygon"))
            zone = site.zone_at(np.array([e.x_m]), np.array([e.y_m]))[0]
            if zone is not None:
                problems.append(Problem(("endurance", "x_m"), e.x_m, "a base outside every no-fly zone",
                                        found=f"a base at {site.where(e.x_m, e.y_m)}, inside {zone}"))
    return problems


def close_starts(sc: Any) -> list[tuple[int, int, float, float]]:
    """Pairs ``(i, j, d, t)`` of UAVs that enter at the same time ``t`` closer than the separation
    minimum (``d`` apart), for :mod:`swarm.scenario.warnings`."""
    joins = {f.uav: f.at_s for f in sc.faults if f.kind == "join"}
    by_start: dict[float, list[int]] = {}
    for k, u in enumerate(sc.uavs):
        by_start.setdefault(joins.get(str(u.name), u.join_s or 0.0), []).append(k)
    out = []
    for t, ks in sorted(by_start.items()):
        xy = np.array([(sc.uavs[k].x_m, sc.uavs[k].y_m) for k in ks], dtype=np.float64)
        out += [(ks[a], ks[b], d, t) for a, b, d in close_pairs(xy, sc.safety.min_separation_m)]
    return out


def _table_words(origin: Origin) -> str:
    return f"{origin[0]}[{origin[1]}]"


def _problem(origin: Origin, kind: str, items: list[str], uav: Any, site: Site) -> Problem:
    table, i = origin
    more = f" (and {len(items) - 1} more of its UAVs)" if len(items) > 1 else ""
    if kind == "outside":
        expected = "a launch point inside the area polygon ([geo] area)"
        found = f"{items[0]}, outside the area polygon{more}"
    elif kind == "zone":
        expected = "a launch point outside every no-fly zone ([[threats]], [[no_fly]])"
        found = items[0] + more
    else:
        expected = (f"UAVs that start at least safety.min_separation_m = {fmt(site.min_separation_m)} m apart "
                    "(they would break the separation rule from their first tick)")
        found = items[0] + more
    if table == "fleet":
        hint = {"outside": "", "zone": "give the fleet a region clear of the zone, or fewer UAVs",
                "close": "give the fleets regions or lattices that keep their UAVs apart"}[kind]
        return Problem(("fleet", i), None, expected, hint=hint, found=f"a layout with {found}")
    return Problem(("uavs", i, "x_m"), uav.x_m, expected, found=found)


def grid_slots(n: int, region: tuple[float, float, float, float], site: Site | None) -> tuple[list[float], list[float]]:
    """A ``grid`` layout: ``n`` lattice points, row by row from the south-west corner of
    ``region``. In a rectangle, a near-square lattice of ``n`` cells, each UAV at its cell's
    centre. With an area polygon, the coarsest such lattice (``cols`` columns, as many rows as
    keep its cells near-square) with at least ``n`` cell centres inside the polygon, and the
    first ``n`` of them."""
    x0, y0, x1, y1 = region
    w, h = x1 - x0, y1 - y0
    if site is None or site.polygon is None:
        cols = max(1, min(n, math.ceil(math.sqrt(n * w / h))))
        rows = math.ceil(n / cols)
        return ([x0 + (k % cols + 0.5) * w / cols for k in range(n)],
                [y0 + (k // cols + 0.5) * h / rows for k in range(n)])
    cols = max(1, math.ceil(math.sqrt(n * w / h)))
    for _ in range(200):
        rows = max(1, round(cols * h / w))
        mx, my = np.meshgrid(x0 + (np.arange(cols) + 0.5) * w / cols, y0 + (np.arange(rows) + 0.5) * h / rows)
        gx, gy = mx.ravel(), my.ravel()
        keep = site.in_area(gx, gy)
        if int(keep.sum()) >= n:
            return gx[keep][:n].tolist(), gy[keep][:n].tolist()
        cols = max(cols + 1, math.ceil(cols * math.sqrt(n / max(int(keep.sum()), 1)) * 1.02))
        if cols * rows > 400 * n + 10_000:
            break
    raise ValueError("the region and the area polygon barely overlap")


def random_slots(n: int, region: tuple[float, float, float, float], site: Site | None, rng: np.random.Generator,
                 taken: Sequence[tuple[float, float]], headings: bool) -> tuple[list[float], list[float], list[float] | None]:
    """A ``random`` layout: ``n`` points uniform in ``region`` (and, with ``headings``, a
    uniform heading each) from ``rng``; then each point that is not in the free space (inside
    the area polygon, outside the no-fly zones) or is closer than the separation minimum to one
    before it or to ``taken`` is drawn again, in order, until it is. A layout that needed no
    redraw is the plain uniform one. Returns xs, ys and the headings (degrees) or None."""
    x0, y0, x1, y1 = region
    xs = rng.uniform(x0, x1, n)
    ys = rng.uniform(y0, y1, n)
    hd = rng.uniform(0.0, 360.0, n).tolist() if headings else None
    if site is None:
        return xs.tolist(), ys.tolist(), hd
    ok = site.free(xs, ys)
    r = site.min_separation_m
    placed = np.array(taken, dtype=np.float64).reshape(-1, 2)
    clash = {b - len(placed) for _a, b, _d in close_pairs(np.vstack([placed, np.column_stack([xs, ys])]), r)
             if b >= len(placed)}
    if ok.all() and not clash:
        return xs.tolist(), ys.tolist(), hd
    # Redraw in order, with a hash of cells of side r: a point's neighbours within r are in the
    # 3 x 3 cells around its own.
    cells: dict[tuple[int, int], list[tuple[float, float]]] = {}

    def near(px: float, py: float) -> bool:
        cx, cy = math.floor(px / r), math.floor(py / r)
        return any(math.hypot(px - qx, py - qy) < r for i in (-1, 0, 1) for j in (-1, 0, 1)
                   for qx, qy in cells.get((cx + i, cy + j), ()))

    def put(px: float, py: float) -> None:
        cells.setdefault((math.floor(px / r), math.floor(py / r)), []).append((px, py))

    for qx, qy in placed:
        put(float(qx), float(qy))
    # Redraws come in batches of 256 uniform points, the free ones used in order (a batch's
    # geometry tested at once); at most 20 n + 10 000 of them, so a region too small fails fast.
    pool: list[tuple[float, float]] = []
    drawn, budget = 0, 20 * n + 10_000

    def redraw(k: int) -> tuple[float, float]:
        nonlocal pool, drawn
        while not pool:
            if drawn > budget:
                raise ValueError(f"the free part of the region has no room for {n} UAVs {fmt(r)} m apart "
                                 f"(placed {k} after {drawn:,} redraws)")
            cx, cy = rng.uniform(x0, x1, 256), rng.uniform(y0, y1, 256)
            free = site.free(cx, cy)
            pool = [(float(a), float(b)) for a, b in zip(cx[free][::-1], cy[free][::-1])]
            drawn += 256
        return pool.pop()

    out_x, out_y = [], []
    for k in range(n):
        px, py, good = float(xs[k]), float(ys[k]), bool(ok[k])
        while not good or near(px, py):
            px, py = redraw(k)
            good = True
        put(px, py)
        out_x.append(px)
        out_y.append(py)
    return out_x, out_y, hd
