"""What a running simulation looks like at one instant (:meth:`swarm.simulation.Simulation.snapshot`):
plain frozen records, safe to keep, compare and send elsewhere."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class UavSnapshot:
    uid: int
    name: str
    type: str
    state: str  # pending | alive | crashed
    x: float
    y: float
    v: float
    theta: float
    mode: str
    target: int
    waypoint: tuple[float, float] | None


@dataclass(frozen=True, slots=True)
class TargetSnapshot:
    tid: int
    x: float
    y: float
    v: float
    theta: float
    found_t: float | None


@dataclass(frozen=True, slots=True)
class Snapshot:
    t: float
    uavs: tuple[UavSnapshot, ...]
    targets: tuple[TargetSnapshot, ...]
    coverage: float
    targets_found: int
    links: tuple[tuple[int, int], ...]
