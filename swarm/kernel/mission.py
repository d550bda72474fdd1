"""The mission phase of a tick (issues 26 and 33): wind, and energy with return to base, relief
on station, landing, turnaround and relaunch. The simulation's side of ``[wind]`` and
``[endurance]`` (:mod:`swarm.scenario.mission`); :func:`mission` returns None for a scenario
with neither, and then nothing here runs.

The simulation calls it at two points of a tick: :meth:`Mission.begin_tick` right after the
faults' tick start (the last tick's drain, homecomings, landings, launches; this tick's wind),
and :meth:`Mission.sense` after the tick faults have acted on the readings (each UAV's energy
reading). It acts on the fleet only through :meth:`swarm.kernel.fleet.Fleet.land`,
:meth:`~swarm.kernel.fleet.Fleet.launch` and :meth:`~swarm.kernel.fleet.Fleet.fail_stop`.

Wind. ``w(t) = mean + g(t)``, uniform over the area; each gust component an
Ornstein-Uhlenbeck process with standard deviation ``sigma`` and time constant ``tau``, stepped
exactly once per tick from the run's ``("wind",)`` stream (``g' = g e^{-dt/tau} + sigma
sqrt(1 - e^{-2 dt/tau}) N(0, 1)``, starting from its stationary law), so gusts are reproducible
by seed. Every flying UAV drifts by ``w(t) dt`` over the tick (:attr:`swarm.kernel.world.World.wind`):
its ground velocity is its air velocity plus the wind; its speed, heading, turn rate and the
airframe limits stay air-relative (the dynamics invariant reads the tick's ``wind`` event).

Energy. A UAV of a type with an energy budget drains ``P(v) dt`` a tick at its airspeed ``v``
(times a battery fault's drain factor), never below zero: a UAV that reaches zero in flight is
lost (``energy_out`` once, then a crash). Each tick it is told (:class:`agents.inputs.EnergyReading`)
the way home to its pad (:mod:`swarm.kernel.homeway`: round the no-fly zones, inside the area), the
energy that way takes at its minimum-power speed against the mean wind plus ``reserve_frac``
of its capacity (when it has no more it must go: ``must_go``), and, for rule 6's reckoning,
what it has beyond the way with the worst turn onto it as seconds of flight at the most power
its type draws (``spare_s``) and what a metre farther from home takes of them
(``home_s_per_m``). A watcher asks for relief early enough that a relief can arrive before
its energy says go (docs/modelling.md, "Assignment rules", rule 6;
:meth:`agents.relief.Relief.home`): the ``relief`` events say when it asked and, if it had
to leave unrelieved, that it did.

Base. Each UAV with a budget has its own pad, ``pad_spacing_m`` apart in a row east-west through
the base. A returning UAV lands within ``land_radius_m`` of its pad (``landed``: it no longer
flies, senses or sends), is turned around in ``turnaround_s`` (a full battery) and launches
again from its pad towards the area's centre, with its memory, in the first launch slot: at
least ``launch_spacing_s`` after the base's last launch, and only while no flying UAV is within
``pad_spacing_m`` of the pad. A UAV that crashes while landed stays crashed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import swarm.events as ev
from agents.actor import UavActor
from agents.inputs import EnergyReading, SensorReading
from swarm.kernel.fleet import Fleet
from swarm.kernel.homeway import HomeWay, leg_energy_wh
from swarm.kernel.recorder import EventLog
from swarm.kernel.world import ALIVE, CRASHED, LANDED, World
from swarm.scenario import Scenario
from swarm.scenario.mission import EnduranceSettings, EnergySpec, min_power_speed, power_w

__all__ = ["Battery", "Mission", "WindField", "mission"]

# A UAV's endurance state (metrics.json endurance.per_uav.state).
FLYING, HOMEBOUND = "flying", "homebound"
# How often a UAV's way home is planned afresh (s): it changes little between two.
_REROUTE_S = 5.0


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
    pad: tuple[float, float]
    state: str = FLYING  # flying, homebound, landed, crashed
    landed_at: float = 0.0
    sorties: int = 1
    on_station_s: float = 0.0
    rtb_needed: float = 0.0
    way: list[tuple[float, float]] = field(default_factory=list)  # the way home planned at way_t
    way_t: float = -math.inf
    asked: int = -1  # the target it asked relief for (logged), -1: none


class Mission:
    """A run's wind and endurance (module docstring)."""

    def __init__(self, world: World, fleet: Fleet, log: EventLog, dt: float, area: tuple[float, float],
                 wind: WindField | None, endurance: EnduranceSettings | None, homeway: HomeWay | None):
        self.world = world
        self.fleet = fleet
        self.log = log
        self.dt = dt
        self.area = area
        self.wind = wind
        self.settings = endurance
        self.homeway = homeway
        self.uavs: dict[int, _Uav] = {}
        self.lost_to_energy = 0
        self.wind_now: tuple[float, float] = (0.0, 0.0)
        self._flew: list[int] = []  # who flew the last tick (drained at the next one's start)
        self._last_launch = -math.inf

    @property
    def mean_wind(self) -> tuple[float, float]:
        return self.wind.mean if self.wind is not None else (0.0, 0.0)

    # --- set-up --------------------------------------------------------------------------------
    def equip(self) -> None:
        """Each UAV of the scenario its battery and pad, once all of them are placed (the pads
        are spaced by their count); a UAV added later gets its own when first asked."""
        for uid in self.world.uavs:
            self.battery_of(uid)

    def battery_of(self, uid: int) -> Battery | None:
        """The UAV's battery, or None when its type has no budget (what the battery fault acts on)."""
        u = self.uavs.get(uid)
        if u is None and self.settings is not None:
            s = self.settings
            b = self.world.uavs[uid]
            spec = s.types.get(b.kind.name)
            if spec is None:
                return None
            v_mp = min_power_speed(spec, b.kind.speed_min, b.kind.speed_max)
            k = len(self.uavs)
            pad = (s.x_m + (k - 0.5 * (self._budgeted() - 1)) * s.pad_spacing_m, s.y_m)
            u = self.uavs[uid] = _Uav(Battery(spec, v_mp, spec.capacity_wh, spec.capacity_wh), pad)
        return u.battery if u is not None else None

    def _budgeted(self) -> int:
        s = self.settings
        assert s is not None
        return sum(1 for b in self.world.uavs.values() if b.kind.name in s.types)

    # --- the tick -----------------------------------------------------------------------------
    def way_home(self, uid: int, t: float, x: float, y: float) -> list[tuple[float, float]]:
        """The points of the UAV's way home to its pad from ``(x, y)`` (planned afresh every
        few seconds; the points already passed are dropped)."""
        u = self.uavs[uid]
        if self.homeway is None:
            return [u.pad]
        if t - u.way_t >= _REROUTE_S - 1e-9 or not u.way:
            u.way, u.way_t = self.homeway.route((x, y), u.pad), t
        elif len(u.way) > 1 and math.hypot(u.way[0][0] - x, u.way[0][1] - y) < 300.0:
            u.way = u.way[1:]
        return u.way

    def needed_home_wh(self, uid: int, t: float) -> tuple[float, float]:
        """Energy (Wh) to fly home from where the UAV is: the turn onto its way at its present
        speed (an arc of its turn radius through the heading change, plus a turn diameter it
        may have to come back), then its way (:mod:`swarm.kernel.homeway`) at the minimum-power speed
        against the mean wind. Also the most it can take from here: the same with the
        heading the farthest from the way's (a half turn), what a watcher circling its target
        may face at any moment."""
        b = self.world.uavs[uid]
        bat = self.uavs[uid].battery
        way = self.way_home(uid, t, b.x, b.y)
        wind = self.mean_wind
        total = 0.0
        px, py = b.x, b.y
        for qx, qy in way:
            total += leg_energy_wh(px, py, qx, qy, bat.power_w(bat.v_mp), bat.v_mp, wind)
            px, py = qx, qy
        v = max(b.v, 1.0)
        r = b.kind.r_min(max(b.v, b.kind.speed_min))
        per_m = bat.power_w(v) / max(v - math.hypot(*wind), 1.0) / 3600.0  # (Wh a metre of turn)
        worst = total + per_m * (math.pi * r + 2.0 * r)
        qx, qy = way[0]
        off = abs(math.remainder(math.atan2(qy - b.y, qx - b.x) - b.theta, 2 * math.pi))
        if off > 1e-3:
            arc = off * r + 2.0 * r * min(off / (math.pi / 2), 1.0)
            total += bat.power_w(v) * arc / max(v - math.hypot(*wind), 1.0) / 3600.0
        return total, worst

    def sense(self, t: float, alive: list[int], readings: dict[int, SensorReading]) -> None:
        """Tell each flying UAV with a budget where it stands (before the actors wake)."""
        self._flew = alive
        s = self.settings
        if s is None:
            return
        wind = math.hypot(*self.mean_wind)
        for uid in alive:
            u = self.uavs.get(uid)
            if u is None:  # (a UAV a host added since: its battery now, full, if its type has a budget)
                if self.battery_of(uid) is None:
                    continue
                u = self.uavs[uid]
            b = self.world.uavs[uid]
            bat = u.battery
            home, worst = self.needed_home_wh(uid, t)
            reserve = s.reserve_frac * bat.capacity_wh
            need = home + reserve
            left = bat.left_wh
            u.rtb_needed = need
            # The spare flight as rule 6 reckons it: at the most power its type can draw, and
            # with the worst turn onto the way home; and what a metre farther from home costs
            # of it (the way home's energy a metre against the mean wind).
            p = max(bat.power_w(b.kind.speed_min), bat.power_w(b.kind.speed_max)) * bat.drain_factor
            spare_s = max(left - worst - reserve, 0.0) * 3600.0 / p if p > 0 else math.inf
            s_per_m = bat.power_w(bat.v_mp) / max(bat.v_mp - wind, 1.0) / p if p > 0 else 0.0
            wx, wy = u.way[0] if u.way else u.pad
            readings[uid].energy = EnergyReading(u.pad[0], u.pad[1], wx, wy, left <= need, bat.v_mp,
                                                 spare_s, s.handover_s, wind, s_per_m)

    def begin_tick(self, t: float) -> None:
        """At the start of the tick at ``t`` (before anyone senses): the energy the last tick's
        flight drained, relief asked, homecomings, landings and launches; then this tick's wind."""
        if self.settings is not None:
            self._energy(t - self.dt)
            self._launches(t)
        if self.wind is not None:
            self.wind_now = self.wind.advance(t, self.dt)
            self.world.wind = self.wind_now
            self.log.emit(ev.wind(t=t, wx=self.wind_now[0], wy=self.wind_now[1]))

    def _energy(self, t: float) -> None:
        """The last tick's (at ``t``) flight: energy drained; relief asked; homecomings, landings."""
        s = self.settings
        assert s is not None
        dt = self.dt
        world, fleet = self.world, self.fleet
        flew, self._flew = self._flew, []
        landed: list[tuple[int, float]] = []  # (logged after the tick's own events: the log stays in time order)
        for uid in flew:
            u = self.uavs.get(uid)
            b = world.uavs[uid]
            if u is None or b.state != ALIVE:
                continue
            actor: UavActor = fleet.actors[uid]
            u.battery.left_wh = max(u.battery.left_wh - u.battery.power_w(b.v) * dt / 3600.0 * u.battery.drain_factor,
                                    0.0)
            ask = actor.relief.asked
            if ask is not None and ask[0] != u.asked and u.state == FLYING:
                u.asked = ask[0]
                self.log.emit(ev.relief(t=t, uav=uid, target=ask[0], by=ask[1], status="asked"))
            if actor.relief.homebound and u.state == FLYING:
                u.state = HOMEBOUND
                relief = actor.relief
                if relief.handed_target >= 0 and not relief.relieved:
                    self.log.emit(ev.relief(t=t, uav=uid, target=relief.handed_target, by=t, status="unrelieved"))
                self.log.emit(ev.rtb(t=t, uav=uid, energy_wh=u.battery.left_wh, needed_wh=u.rtb_needed,
                                     target=relief.handed_target))
            if u.state == FLYING:
                u.on_station_s += dt
            if u.battery.left_wh <= 0.0:
                self.lost_to_energy += 1
                u.state = CRASHED
                self.log.emit(ev.energy_out(t=t, uav=uid))
                fleet.fail_stop(uid, t + dt)
                continue
            if u.state == HOMEBOUND and math.hypot(b.x - u.pad[0], b.y - u.pad[1]) <= s.land_radius_m:
                u.state, u.landed_at = LANDED, t + dt
                fleet.land(uid)
                landed.append((uid, u.battery.left_wh))
        for uid, left in landed:
            self.log.emit(ev.landed(t=t + dt, uav=uid, energy_wh=left))

    def _launches(self, t: float) -> None:
        """Turned-around UAVs launch, one per slot (module docstring); a crashed one never."""
        s = self.settings
        assert s is not None
        flying = [b for b in self.world.uavs.values() if b.state == ALIVE]
        for uid, u in self.uavs.items():
            b = self.world.uavs[uid]
            if b.state == CRASHED:
                u.state = CRASHED  # (wherever it crashed: in flight, or on the ground)
                continue
            if u.state != LANDED or t + 1e-9 < u.landed_at + s.turnaround_s:
                continue
            if t + 1e-9 < self._last_launch + s.launch_spacing_s:
                continue
            px, py = u.pad
            if any(math.hypot(o.x - px, o.y - py) < s.pad_spacing_m for o in flying):
                continue
            u.battery.left_wh = u.battery.capacity_wh
            u.state = FLYING
            u.sorties += 1
            u.way, u.way_t = [], -math.inf
            u.asked = -1
            self._last_launch = t
            theta = math.atan2(self.area[1] / 2 - py, self.area[0] / 2 - px)
            fleet = self.fleet
            fleet.launch(uid, px, py, b.kind.speed_min, theta)
            self.log.emit(ev.launched(t=t, uav=uid, x=px, y=py))
            flying.append(b)

    # --- results ------------------------------------------------------------------------------
    def metrics(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.settings is not None:
            names = self.world.uavs
            out["endurance"] = {
                "sorties": sum(u.sorties for u in self.uavs.values()),
                "lost_to_energy": self.lost_to_energy,
                "per_uav": {names[uid].name: {"sorties": u.sorties, "time_on_station_s": u.on_station_s,
                                              "energy_left_wh": u.battery.left_wh,
                                              "state": CRASHED if names[uid].state == CRASHED else u.state}
                            for uid, u in sorted(self.uavs.items())},
                "time_on_station_s": sum(u.on_station_s for u in self.uavs.values()),
            }
        if self.wind is not None:
            out["wind"] = {"mean_mps": list(self.wind.mean), "last_mps": list(self.wind_now)}
        return out


def homeway(sc: Scenario, zones: list[Any], area_ring: np.ndarray | None, area: tuple[float, float]) -> HomeWay | None:
    """The routes home round the scenario's no-fly zones (circles and polygons) inside its area,
    or None when there is nothing to route round (a rectangle and no zone)."""
    rings: list[tuple[np.ndarray, float]] = []
    for th in sc.threats:
        a = np.linspace(0.0, 2 * math.pi, 16, endpoint=False)
        rings.append((np.stack([th.x_m + th.radius_m * np.cos(a), th.y_m + th.radius_m * np.sin(a)], axis=1),
                      max(th.d_max - th.radius_m, 0.0)))
    for z in zones:
        rings.append((z.vertices, z.reach_m))
    if not rings and area_ring is None:
        return None
    return HomeWay(rings, area_ring, area)


def mission(sc: Scenario, world: World, fleet: Fleet, log: EventLog, dt: float, area: tuple[float, float],
            wind_rng: np.random.Generator, zones: list[Any], area_ring: np.ndarray | None) -> Mission | None:
    """The run's wind and endurance, or None for a scenario without ``[wind]`` and ``[endurance]``."""
    if sc.wind is None and sc.endurance is None:
        return None
    wind = None
    if sc.wind is not None:
        w = sc.wind
        wind = WindField(w.mean, w.gust_sigma_mps, w.gust_tau_s, wind_rng)
    e = sc.endurance
    way = homeway(sc, zones, area_ring, area) if e is not None else None
    return Mission(world, fleet, log, dt, area, wind, e, way)
