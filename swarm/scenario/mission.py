"""The mission tables of a scenario (issue 26): ``[wind]`` and ``[endurance]``.

Absent (the default), nothing of them runs: no wind, no energy, no events of theirs, and the
event log is what it always was. The simulation's side is :mod:`swarm.kernel.mission`.
"""

from __future__ import annotations

import math
from typing import Any

from pydantic import Field, model_validator

from swarm.scenario.fields import Num, Problem, Str, Table, fmt, num_field, raise_if

__all__ = ["EnduranceSettings", "EnergySpec", "WindSettings", "endurance_problems", "min_power_speed"]


class WindSettings(Table):
    """A mean wind plus gusts: each horizontal gust component an Ornstein-Uhlenbeck process
    (mean 0, standard deviation ``gust_sigma_mps``, time constant ``gust_tau_s``), drawn from
    the run's own ``("wind",)`` stream. Uniform over the area. A UAV's ground velocity is its
    air velocity plus the wind."""

    speed_mps: Num = num_field(0.0, ge=0, lt=100, note="m/s, the mean wind")
    direction_deg: Num = num_field(0.0, note="degrees: where the wind blows TO, 0 = east, counter-clockwise (as heading_deg)")
    gust_sigma_mps: Num = num_field(0.0, ge=0, lt=50, note="m/s, the standard deviation of each gust component; 0 = steady")
    # Our choice: 10 s, about a Dryden turbulence length scale of 500 m crossed at 50 m/s.
    gust_tau_s: Num = num_field(10.0, gt=0, note="s, the gusts' correlation time")

    @property
    def mean(self) -> tuple[float, float]:
        a = math.radians(self.direction_deg)
        return self.speed_mps * math.cos(a), self.speed_mps * math.sin(a)


class EnergySpec(Table):
    """A UAV type's energy budget and its power against airspeed (fixed wing: induced power
    falls and parasitic power rises with speed):

        P(v) = power_min_w * (3/4 * v_mp / v + 1/4 * (v / v_mp)^3)

    the classic ``a / v + b v^3`` curve written with its minimum ``power_min_w`` at the
    minimum-power speed ``v_mp`` (``min_power_speed_mps``; default: a quarter of the way from
    the type's ``speed_min`` to its ``speed_max``)."""

    capacity_wh: Num = num_field(..., gt=0, note="Wh, a full battery")
    # Default: about a 25 kg fixed wing with L/D 12 at 40 m/s and a 70% efficient propulsion.
    power_min_w: Num = num_field(1000.0, gt=0, note="W, at the minimum-power speed")
    min_power_speed_mps: Num | None = num_field(None, gt=0, note="m/s; default speed_min + (speed_max - speed_min) / 4",
                                               optional=True)


def min_power_speed(spec: EnergySpec, speed_min: float, speed_max: float) -> float:
    return spec.min_power_speed_mps if spec.min_power_speed_mps is not None else speed_min + 0.25 * (speed_max - speed_min)


class EnduranceSettings(Table):
    """Energy budgets per UAV type and the home base they return to, land at and relaunch from."""

    x_m: Num = num_field(..., note="m, the base (or lon/lat with [geo])")
    y_m: Num = num_field(..., note="m, the base (or lon/lat with [geo])")
    types: dict[Str, EnergySpec] = Field(default_factory=dict, description="tables [endurance.types.NAME] (a UAV type's budget)")
    reserve_frac: Num = num_field(0.1, ge=0, lt=0.9, note="of the capacity, kept on arrival home")
    handover_s: Num = num_field(60.0, ge=0, note="s of loitering a watcher may spend handing its target over")
    turnaround_s: Num = num_field(300.0, ge=0, note="s on the ground between landing and relaunch")
    land_radius_m: Num = num_field(500.0, gt=0, note="m from its pad where a returning UAV lands")
    # (issue 33) Base operations: each UAV its own pad, in a row east-west through the base; a
    # launch waits for its slot (launch_spacing_s after the last one, no flying UAV within
    # pad_spacing_m of the pad), so no two UAVs come within the separation minimum at the base.
    pad_spacing_m: Num = num_field(400.0, gt=0, note="m between two pads (at least safety.min_separation_m)")
    launch_spacing_s: Num = num_field(20.0, ge=0, note="s between two launches from the base")

    @model_validator(mode="after")
    def _some_type(self) -> EnduranceSettings:
        if not self.types:
            raise_if([Problem(("types",), self.types, "at least one [endurance.types.NAME] table (a type's capacity_wh)")])
        return self


def power_w(spec: EnergySpec, v_mp: float, v: float) -> float:
    r = v / v_mp
    return spec.power_min_w * (0.75 / r + 0.25 * r * r * r)


def endurance_problems(sc: Any) -> list[Problem]:
    """A type in ``[endurance.types]`` that does not exist, a base outside the area, and a
    budget too small to reach the area and come back (the farthest launch point of its type,
    at its minimum-power speed against the mean wind, plus the reserve)."""
    e = sc.endurance
    problems: list[Problem] = []
    if e.pad_spacing_m < sc.safety.min_separation_m:
        problems.append(Problem(("endurance", "pad_spacing_m"), e.pad_spacing_m,
                                f"at least safety.min_separation_m ({fmt(sc.safety.min_separation_m)} m): two UAVs on "
                                f"neighbouring pads must not be too close"))
    if not (0.0 <= e.x_m <= sc.area.width_m and 0.0 <= e.y_m <= sc.area.height_m):
        problems.append(Problem(("endurance", "x_m"), e.x_m, f"a base inside the area ({fmt(sc.area.width_m)} x "
                                f"{fmt(sc.area.height_m)} m)", found=f"({e.x_m:.0f}, {e.y_m:.0f}) m"))
    wind = sc.wind.speed_mps + 3.0 * sc.wind.gust_sigma_mps if sc.wind is not None else 0.0
    for name, spec in e.types.items():
        t = sc.uav_types.get(name)
        if t is None:
            problems.append(Problem(("endurance", "types", name), name,
                                    f"a UAV type defined in [uav_types]: {', '.join(sc.uav_types)}",
                                    found=f"a table for {name!r}, which is not a UAV type"))
            continue
        v = min_power_speed(spec, t.speed_min, t.speed_max)
        if not t.speed_min <= v <= t.speed_max:
            problems.append(Problem(("endurance", "types", name, "min_power_speed_mps"), v,
                                    f"a speed in type {name}'s range [{fmt(t.speed_min)}, {fmt(t.speed_max)}]"))
            continue
        far = max((math.hypot(u.x_m - e.x_m, u.y_m - e.y_m) for u in sc.uavs if u.type == name), default=0.0)
        ground = v - wind
        need = math.inf if ground <= 0 else 2.0 * far / ground * power_w(spec, v, v) / 3600.0
        if need + e.reserve_frac * spec.capacity_wh >= spec.capacity_wh:
            problems.append(Problem(("endurance", "types", name, "capacity_wh"), spec.capacity_wh,
                                    f"a budget above {need / (1 - e.reserve_frac):.0f} Wh: enough to reach the farthest "
                                    f"{name} launch point ({far / 1000:.1f} km from the base) and come back against the "
                                    f"wind, with the reserve"))
    return problems
