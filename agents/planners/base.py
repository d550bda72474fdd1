"""The one small interface every planner implements.

A planner is asked for a :class:`Plan` (next waypoint, mode, watched target) every
``replan_s`` seconds or when the UAV reaches its waypoint. It sees only a :class:`PlanView`:
the UAV's own pose and type, its own map and knowledge, its own random stream. Nothing about
the ground truth or other UAVs' internals reaches a planner.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from agents.knowledge import Knowledge
from agents.maps.grid import Grid
from agents.maps.umap import UncertaintyMap
from agents.types import UavType
from comms.errors import SwarmError
from comms.messages import MODE_SEARCH, NO_TARGET

__all__ = ["Plan", "PlanView", "Planner", "PlannerContext", "PlannerError"]


class PlannerError(SwarmError, RuntimeError):
    """A planner could not plan: it raised, or returned something that is not a :class:`Plan`."""


@dataclass(frozen=True, slots=True)
class Plan:
    wx: float
    wy: float
    mode: int = MODE_SEARCH
    target: int = NO_TARGET


@dataclass(slots=True)
class PlanView:
    t: float
    uav: int
    kind: UavType
    x: float
    y: float
    v: float
    theta: float
    umap: UncertaintyMap
    knowledge: Knowledge
    rng: np.random.Generator
    grid: Grid
    replan_s: float
    surveillance: bool  # False: a sighting ends interest in a target (search only)
    plan: Plan | None  # the current plan, if any


class Planner(Protocol):
    @property
    def name(self) -> str: ...

    def plan(self, view: PlanView) -> Plan: ...


@dataclass(frozen=True)
class PlannerContext:
    """What a planner may know before the run starts, given to ``from_context``.

    The area and map geometry, the UAV it plans for (id, name, type, and its rank among the
    UAVs of its type when it was added: an a-priori assignment such as a lawnmower strip can
    come from these alone), and the swarm's UAV types. Nothing about other UAVs' states: during
    the run a planner sees only its :class:`~agents.planners.base.PlanView`.
    """

    uav: int
    name: str
    type: str
    type_index: int  # 0 for the first UAV of its type, 1 for the second, ...
    type_count: int  # UAVs of its type in the scenario (at least type_index + 1)
    area_m: tuple[float, float]  # width, height
    cell_m: float
    levels: int  # map pyramid levels (map.levels)
    speed_max_by_type: dict[str, float]
    detect_radius_by_type: dict[str, float]
    settings: Any = None  # the scenario's [planner] table (built-ins read their own sub-table)
