"""Real-world missions (issue 26): wind, and energy with return to base, landing, turnaround
and relaunch. The simulation's side of ``[wind]`` and ``[endurance]``
(:mod:`swarm.scenario.mission`); :func:`mission` returns None for a scenario with neither, and
then nothing here runs.

Wind. ``w(t) = mean + g(t)``, uniform over the area; each gust component an
Ornstein-Uhlenbeck process with standard deviation ``sigma`` and time constant ``tau``, stepped
exactly once per tick from the run's ``("wind",)`` stream (``g' = g e^{-dt/tau} + sigma
sqrt(1 - e^{-2 dt/tau}) N(0, 1)``, starting from its stationary law), so gusts are reproducible
by seed. Every flying UAV drifts by ``w(t) dt`` over the tick (:attr:`swarm.world.World.wind`):
its ground velocity is its air velocity plus the wind; its speed, heading, turn rate and the
airframe limits stay air-relative (the dynamics invariant reads the tick's ``wind`` event).

Energy. A UAV of a type with an energy budget drains ``P(v) dt`` a tick at its airspeed ``v``
(times a battery fault's drain factor). Each tick it is told (:class:`agents.actor.EnergyReading`)
whether its energy left is down to what it needs to fly home (at its minimum-power speed,
against the mean wind's component, plus ``reserve_frac`` of its capacity): ``must_go``; or to
that plus the energy of ``handover_s`` of flight at its speed: ``leave``, where a watcher hands
its target over first (its beacons say it searches while it keeps circling, until a peer
watches the target: :meth:`agents.actor.UavActor._energy`). Within ``land_radius_m`` of the
base a returning UAV lands (it no longer flies, senses or sends), is turned around in
``turnaround_s`` (a full battery) and launches again from the base towards the area's centre,
with its memory. A UAV whose energy runs out in flight is lost (``energy_out``, then a crash):
never without a battery fault, since it turns home with the reserve to spare.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agents.actor import EnergyReading, SensorReading
from swarm.scenario.mission import EnergySpec, min_power_speed, power_w

__all__ = ["Battery", "Mission", "WindField", "mission"]

LANDED = "landed"


class WindField:
    """The mean wind plus Ornstein-Uhlenbeck gusts (module docstring)."""

    def __init__(self, mean: tuple[float, float], sigma: float, tau: float, rng: np.random.Generator):
        self.mean = mean
        self.sigma = sigma
        self.tau = tau
        self.rng = rng
        self.gust = (sigma * rng.standard_normal(2)).tolist() if sigma > 0 else [0.0, 0.0]
        self._last_t: float | None = None

    def advance(self, t: float, dt: float) -> tuple[float, float]:
        """The wind of the tick at ``t`` (the gust stepped once per tick after the first)."""
        if self.sigma > 0 and self._last_t is not None:
            keep = math.exp(-dt / self.tau)
            n = self.rng.standard_normal(2)
            s = self.sigma * math.sqrt(1.0 - keep * keep)
            self.gust = [self.gust[0] * keep + s * float(n[0]), self.gust[1] * keep + s * float(n[1])]
        self._last_t = t
        return self.mean[0] + self.gust[0], self.mean[1] + self.gust[1]


@dataclass
class Battery:
    """One UAV's energy (Wh); what the ``battery`` fault acts on (faults.energy)."""

    spec: EnergySpec
    v_mp: float  # its minimum-power speed
    capacity_wh: float
    left_wh: float
    drain_factor: float = 1.0

    def power_w(self, v: float) -> float:
        return power_w(self.spec, self.v_mp, v)

    def lose(self, frac: float) -> None:
        """A sudden loss of ``frac`` of the energy left (a failed cell)."""
        self.left_wh *= 1.0 - frac


@dataclass
class _Uav:
    battery: Battery
    state: str = "flying"  # flying, homebound, landed
    landed_at: float = 0.0
    sorties: int = 1
    on_station_s: float = 0.0
    rtb_needed: float = 0.0


@dataclass
class Mission:
    sim: Any
    wind: WindField | None
    base: tuple[float, float] | None
    settings: Any  # EnduranceSettings or None
    uavs: dict[int, _Uav] = field(default_factory=dict)
    lost_to_energy: int = 0
    wind_now: tuple[float, float] = (0.0, 0.0)
    _flew: list[int] = field(default_factory=list)  # who flew the last tick (drained at the next one's start)

    # --- set-up --------------------------------------------------------------------------------
    def battery_of(self, uid: int) -> Battery | None:
        u = self.uavs.get(uid)
        if u is None and self.settings is not None:
            b = self.sim._world.uavs[uid]
            spec = self.settings.types.get(b.kind.name)
            if spec is None:
                return None
            v_mp = min_power_speed(spec, b.kind.speed_min, b.kind.speed_max)
            u = self.uavs[uid] = _Uav(Battery(spec, v_mp, spec.capacity_wh, spec.capacity_wh))
        return u.battery if u is not None else None

    # --- the tick -----------------------------------------------------------------------------
    def needed_home_wh(self, uid: int, x: float, y: float) -> float:
        """Energy to fly home from ``(x, y)`` at the minimum-power speed against the mean wind."""
        assert self.base is not None
        bat = self.uavs[uid].battery
        dx, dy = self.base[0] - x, self.base[1] - y
        d = math.hypot(dx, dy)
        if d < 1e-9:
            return 0.0
        ux, uy = dx / d, dy / d
        wx, wy = self.wind.mean if self.wind is not None else (0.0, 0.0)
        along, across = wx * ux + wy * uy, -wx * uy + wy * ux
        v = bat.v_mp
        ground = along + math.sqrt(max(v * v - across * across, 0.0))
        if ground <= 1e-6:
            return math.inf
        return bat.power_w(v) * d / ground / 3600.0

    def sense(self, t: float, alive: list[int], readings: dict[int, SensorReading]) -> None:
        """Tell each UAV with a budget where it stands (before the actors wake)."""
        self._flew = alive
        if self.settings is None:
            return
        s = self.settings
        for uid in alive:
            if self.battery_of(uid) is None:
                continue
            u = self.uavs[uid]
            b = self.sim._world.uavs[uid]
            reserve = s.reserve_frac * u.battery.capacity_wh
            need = self.needed_home_wh(uid, b.x, b.y) + reserve
            allowance = u.battery.power_w(b.v) * s.handover_s / 3600.0
            left = u.battery.left_wh
            u.rtb_needed = need
            readings[uid].energy = EnergyReading(s.x_m, s.y_m, left <= need + allowance, left <= need, u.battery.v_mp)

    def begin_tick(self, t: float) -> None:
        """At the start of the tick at ``t`` (before anyone senses): the energy the last tick's
        flight drained, homecomings, landings and relaunches; then this tick's wind."""
        sim = self.sim
        dt = sim.dt
        if self.settings is not None:
            self._energy(t - dt, dt)
        if self.wind is not None:
            self.wind_now = self.wind.advance(t, dt)
            sim._world.wind = self.wind_now
            sim._log.emit("wind", t, self.wind_now[0], self.wind_now[1])

    def _energy(self, t: float, dt: float) -> None:
        """The last tick's (at ``t``) flight: energy drained; its homecomings and landings."""
        sim = self.sim
        s = self.settings
        world, fleet = sim._world, sim._fleet
        flew, self._flew = self._flew, []
        for uid in flew:
            u = self.uavs.get(uid)
            b = world.uavs[uid]
            if u is None or b.state != "alive":
                continue
            actor = fleet.actors[uid]
            u.battery.left_wh -= u.battery.power_w(b.v) * dt / 3600.0 * u.battery.drain_factor
            if actor.homebound and u.state == "flying":
                u.state = "homebound"
                sim._log.emit("rtb", t, uid, u.battery.left_wh, u.rtb_needed, actor.handed_target)
            if u.state == "flying":
                u.on_station_s += dt
            if u.battery.left_wh <= 0.0:
                self.lost_to_energy += 1
                sim._log.emit("energy_out", t, uid)
                fleet.fail_stop(uid, t + dt)
                continue
            if u.state == "homebound" and math.hypot(b.x - s.x_m, b.y - s.y_m) <= s.land_radius_m:
                u.state, u.landed_at = LANDED, t + dt
                b.state = LANDED  # (not alive from the next tick: it neither flies, senses nor sends)
                fleet.plans.pop(uid, None)
                sim._log.emit("landed", t + dt, uid, u.battery.left_wh)
        for uid, u in self.uavs.items():
            if u.state == LANDED and t + dt + 1e-9 >= u.landed_at + s.turnaround_s:
                self._launch(t + dt, uid, u)

    def _launch(self, t: float, uid: int, u: _Uav) -> None:
        sim = self.sim
        s = self.settings
        b = sim._world.uavs[uid]
        u.battery.left_wh = u.battery.capacity_wh
        u.state = "flying"
        u.sorties += 1
        b.x, b.y = s.x_m, s.y_m
        b.v = b.kind.speed_min
        b.theta = math.atan2(sim._grid.height_m / 2 - s.y_m, sim._grid.width_m / 2 - s.x_m)
        b.state = "alive"
        actor = sim._fleet.actors[uid]
        for _arrival, sender, data in actor.mailbox.drain():  # (frames that reached it on the ground: lost)
            sim._fleet.lost(sender, uid, len(data), "receiver_down")
        actor.relaunch()
        sim._log.emit("launched", t, uid, b.x, b.y)

    # --- results ------------------------------------------------------------------------------
    def metrics(self, t: float) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.settings is not None:
            names = self.sim._world.uavs
            out["endurance"] = {
                "sorties": sum(u.sorties for u in self.uavs.values()),
                "lost_to_energy": self.lost_to_energy,
                "per_uav": {names[uid].name: {"sorties": u.sorties, "time_on_station_s": u.on_station_s,
                                              "energy_left_wh": u.battery.left_wh, "state": u.state}
                            for uid, u in sorted(self.uavs.items())},
                "time_on_station_s": sum(u.on_station_s for u in self.uavs.values()),
            }
        if self.wind is not None:
            out["wind"] = {"mean_mps": list(self.wind.mean), "last_mps": list(self.wind_now)}
        return out


def mission(sim: Any) -> Mission | None:
    """The run's wind and endurance, or None for a scenario without ``[wind]`` and ``[endurance]``."""
    sc = sim.scenario
    if sc.wind is None and sc.endurance is None:
        return None
    wind = None
    if sc.wind is not None:
        w = sc.wind
        wind = WindField(w.mean, w.gust_sigma_mps, w.gust_tau_s, sim._rng.generator("wind"))
    e = sc.endurance
    m = Mission(sim, wind, (e.x_m, e.y_m) if e is not None else None, e)
    for uid in sim._world.uavs:
        m.battery_of(uid)
    return m


