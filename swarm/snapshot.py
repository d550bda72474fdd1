"""What a running simulation looks like at one instant (:meth:`swarm.simulation.Simulation.snapshot`):
plain frozen records, safe to keep, compare and send elsewhere."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from swarm.fleet import Fleet
    from swarm.metrics import Metrics
    from swarm.world import World


@dataclass(frozen=True, slots=True)
class UavSnapshot:
    uid: int
    name: str
    type: str
    state: str  # pending | alive | landed (at its base, [endurance]) | crashed
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


def take_snapshot(t: float, world: World, fleet: Fleet, metrics: Metrics, links: Iterable[tuple[int, int]]) -> Snapshot:
    """The snapshot at ``t`` of a simulation's world, actors' plans, metrics and radio links."""
    uavs = []
    for uid, b in sorted(world.uavs.items()):
        plan = fleet.plans.get(uid)
        uavs.append(UavSnapshot(uid, b.name, b.kind.name, b.state, b.x, b.y, b.v, b.theta, fleet.mode_name(uid),
                                plan.target if plan else -1, (plan.wx, plan.wy) if plan else None))
    tg = world.targets
    targets = tuple(TargetSnapshot(i, x, y, v, th, metrics.found_t.get(i))
                    for i, (x, y, v, th) in enumerate(zip(tg.x.tolist(), tg.y.tolist(), tg.v.tolist(), tg.theta.tolist())))
    return Snapshot(t, tuple(uavs), targets, metrics.coverage(), len(metrics.found_t), tuple(sorted(links)))
