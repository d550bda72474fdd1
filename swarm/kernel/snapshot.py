"""What a running simulation looks like at one instant (:meth:`swarm.kernel.simulation.Simulation.snapshot`):
plain frozen records, safe to keep, compare and send elsewhere."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from swarm.kernel.simulation import Simulation


@dataclass(frozen=True, slots=True)
class UavSnapshot:
    uid: int
    name: str
    type: str
    state: str  # pending | alive | homebound | landed (at its base, [endurance]) | crashed
    x: float
    y: float
    v: float
    theta: float
    mode: str  # search | surveil, or down | pending
    target: int
    waypoint: tuple[float, float] | None  # the command's waypoint (its plan's), None before any
    # The command the actor gave at its last tick (None before any): the speed its local planner
    # steers towards (m/s), the acceleration (m/s^2) and turn rate (rad/s, counter-clockwise).
    speed_cmd: float | None = None
    accel_cmd: float | None = None
    turn_rate_cmd: float | None = None
    lon: float | None = None  # geographic runs ([geo]) only
    lat: float | None = None
    energy_wh: float | None = None  # energy left, runs with [endurance] only
    controlled: bool = False  # its body is driven by the host (take_control)


@dataclass(frozen=True, slots=True)
class TargetSnapshot:
    tid: int
    x: float
    y: float
    v: float
    theta: float
    found_t: float | None
    lon: float | None = None  # geographic runs only
    lat: float | None = None


@dataclass(frozen=True, slots=True)
class Snapshot:
    t: float
    uavs: tuple[UavSnapshot, ...]
    targets: tuple[TargetSnapshot, ...]
    coverage: float
    targets_found: int
    links: tuple[tuple[int, int], ...]
    wind: tuple[float, float] | None = None  # (east, north) m/s this tick, runs with [wind] only


def take_snapshot(sim: Simulation) -> Snapshot:
    """The snapshot of a simulation now: its world, the actors' commands, metrics, radio links."""
    world, fleet, metrics, mission = sim._world, sim._fleet, sim._metrics, sim._mission
    geo = sim.geographic
    bodies = sorted(world.uavs.items())
    tg = world.targets
    if geo:
        frame = sim._frame("snapshot")
        ulon, ulat = frame.to_lonlat([b.x for _, b in bodies], [b.y for _, b in bodies])
        tlon, tlat = frame.to_lonlat(tg.x.tolist(), tg.y.tolist())
    uavs = []
    for i, (uid, b) in enumerate(bodies):
        plan = fleet.plans.get(uid)
        out = fleet.outputs.get(uid)
        m = mission.uavs.get(uid) if mission is not None else None
        state = "homebound" if b.state == "alive" and m is not None and m.state == "homebound" else b.state
        uavs.append(UavSnapshot(
            uid, b.name, b.kind.name, state, b.x, b.y, b.v, b.theta, fleet.mode_name(uid),
            plan.target if plan else -1, (plan.wx, plan.wy) if plan else None,
            None if out is None or math.isnan(out.speed) else out.speed,
            None if out is None else out.a, None if out is None else out.omega,
            float(ulon[i]) if geo else None, float(ulat[i]) if geo else None,
            m.battery.left_wh if m is not None else None, uid in sim._host.controlled))
    targets = tuple(TargetSnapshot(i, x, y, v, th, metrics.found_t.get(i),
                                   float(tlon[i]) if geo else None, float(tlat[i]) if geo else None)
                    for i, (x, y, v, th) in enumerate(zip(tg.x.tolist(), tg.y.tolist(), tg.v.tolist(), tg.theta.tolist())))
    wind = mission.wind_now if mission is not None and mission.wind is not None else None
    return Snapshot(sim.now, tuple(uavs), targets, metrics.coverage(), len(metrics.found_t),
                    tuple(sorted(sim._radio.graph.edges())), wind)
