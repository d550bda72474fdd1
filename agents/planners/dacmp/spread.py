"""``dacmp-spread``: DACMP plus a search-mode spacing term from the peers' announced waypoints.

Not in the paper. The paper's DACMP keeps UAVs apart only inside a target's influence (eq. 23);
in search, eq. 19 reads the uncertainty at the particle itself, and ground a peer flying
alongside is about to scan still reads as unseen until it has scanned it. So two UAVs flying
side by side, even 1-2 km apart with their 2 km detection circles overlapping, both keep finding
unseen cells ahead, and nothing in the fitness tells them apart (paper-fig11: DACMP UAVs have a
neighbour closer than 4 km, two detection radii, about a fifth of the time).

This variant treats what the peers will scan next as scanned: each peer ``j`` heard within the
last 15 s will sweep the segment from its last heard position to its announced next waypoint
``x_j(t+1)`` (the intent every UAV broadcasts for eq. 23) with its detection circle, and eq. 19's
``f_Sl`` at a particle ``k`` is multiplied by

    max(0, 1 - spread_weight * sum_j overlap(d(k, segment_j) / (R_i + R_j)))

where ``overlap(u) = (2/pi) (acos(u) - u sqrt(1 - u^2))`` (0 for ``u >= 1``) is the share of a
circle covered by an equal circle whose centre is ``2 R u`` away: the share of UAV ``i``'s
footprint at ``k`` that peer ``j``'s footprint will scan (radii taken equal, at their mean).
Everything else is DACMP's (:class:`~agents.planners.dacmp.planner.DacmpPlanner`, the same
settings in ``[planner.dacmp]``); ``spread_weight`` is a ``[planner.options]`` key (default 1).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np

from agents.planners.dacmp.planner import _INTENT_MAX_AGE_S, DacmpPlanner

if TYPE_CHECKING:
    from agents.planners.base import PlannerContext
    from agents.planners.dacmp.planner import UavSearch

__all__ = ["DacmpSpreadPlanner"]

_FAR_M = 1e12  # a padding segment this far away overlaps nothing (overlap(1) is exactly 0)


@dataclass(frozen=True)
class DacmpSpreadPlanner(DacmpPlanner):
    """DACMP whose search term discounts ground the peers are about to scan (module docstring)."""

    spread_weight: float = 1.0
    name: str = "dacmp-spread"

    @classmethod
    def from_context(cls, context: PlannerContext, spread_weight: float = 1.0) -> DacmpSpreadPlanner:
        """DACMP's planner of the scenario (its ``[planner.dacmp]`` table), with ``spread_weight``
        from ``[planner.options]``."""
        if not (isinstance(spread_weight, (int, float)) and math.isfinite(spread_weight) and spread_weight >= 0):
            raise ValueError(f"spread_weight must be a number >= 0, got {spread_weight!r}")
        planner = cast("DacmpSpreadPlanner", super().from_context(context))  # from_settings builds cls
        return dataclasses.replace(planner, spread_weight=float(spread_weight))

    def crowding(self, uavs: list[UavSearch], points: int) -> _Crowding | None:
        """The factor on ``f_Sl`` (module docstring) for these UAVs, or None when none hears a peer."""
        if self.spread_weight == 0:
            return None
        rows: list[list[tuple[float, float, float, float, float]]] = []
        for u in uavs:
            v = u.view
            mine = []
            for p in v.knowledge.recent_peers(v.t, _INTENT_MAX_AGE_S):
                if p.uav == v.uav or not (math.isfinite(p.x) and math.isfinite(p.wx)) or v.t - p.t_intent > _INTENT_MAX_AGE_S:
                    continue
                r_j = self.detect_radius_by_type.get(p.type, v.kind.detect_radius)
                mine.append((p.x, p.y, p.wx, p.wy, u.R + r_j))
            rows.append(mine)
        n = max(len(r) for r in rows)
        if n == 0:
            return None
        # (x0, y0, x1, y1, R_i + R_j) per UAV and peer, padded with far-away segments; peers in
        # id order, so a UAV's sum is the same whatever batch it is planned in (padding adds 0).
        seg = np.empty((5, len(uavs), n, 1))
        seg[:4] = _FAR_M
        seg[4] = 1.0
        for i, mine in enumerate(rows):
            for j, row in enumerate(mine):
                seg[:, i, j, 0] = row
        return _Crowding(seg, self.spread_weight)


class _Crowding:
    """``f_Sl`` factor at points ``z`` ``(2, UAVs, points)`` from the peers' next swaths."""

    def __init__(self, seg: np.ndarray, weight: float):
        self.x0, self.y0, x1, y1, self.two_r = seg
        self.dx, self.dy = x1 - self.x0, y1 - self.y0
        self.len2 = np.maximum(self.dx * self.dx + self.dy * self.dy, 1e-9)
        self.weight = weight

    def __call__(self, z: np.ndarray) -> np.ndarray:
        px, py = z[0][:, None, :] - self.x0, z[1][:, None, :] - self.y0  # (UAVs, peers, points)
        s = np.clip((px * self.dx + py * self.dy) / self.len2, 0.0, 1.0)  # nearest point of the segment
        u = np.minimum(np.hypot(px - s * self.dx, py - s * self.dy) / self.two_r, 1.0)
        overlap = (2.0 / math.pi) * (np.arccos(u) - u * np.sqrt(1.0 - u * u))
        crowding: np.ndarray = np.maximum(1.0 - self.weight * overlap.sum(axis=1), 0.0)
        return crowding
