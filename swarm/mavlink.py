"""MAVLink to a ground station (extra ``mavlink``: pymavlink): each UAV is a MAVLink system.

``swarm run SCENARIO --mavlink udpout:HOST:PORT`` (or :class:`MavlinkBridge` beside
``run_until`` in your own loop) makes UAV number ``i`` (its id in the log) MAVLink system
``i + 1`` (component 1, a fixed-wing, generic autopilot). At every tick boundary each sends:

* ``HEARTBEAT``: ``custom_mode`` 0 search, 1 surveil, 2 homebound, 3 pending or landed, 4 down;
  ``system_status`` ACTIVE while flying, STANDBY pending or landed, FLIGHT_TERMINATION down;
* ``GLOBAL_POSITION_INT``: its position as latitude/longitude (the scenario's frame in a
  geographic scenario; in a scenario in metres, ``(x, y)`` put on a local tangent plane whose
  ``(0, 0)`` is :data:`ORIGIN`, PX4 SITL's default home), at :data:`ALTITUDE_M` metres, its
  ground velocity and heading;
* ``SYS_STATUS``: the battery left (percent) with ``[endurance]``, else -1 (unknown).

A ground station's reposition to one UAV, ``SET_POSITION_TARGET_GLOBAL_INT`` or
``MAV_CMD_DO_REPOSITION`` (``COMMAND_LONG`` or ``COMMAND_INT``), becomes an operator waypoint
(``sim.set_waypoint``) at the next tick boundary, recorded like any host change (so the run
replays from its folder); a command gets a ``COMMAND_ACK`` (``DENIED`` for a point outside the
area or an unknown system). Messages are read at tick boundaries only, by a task that waits
for each boundary (``wait_until``): which boundary a message lands on depends on when it
arrives, what it does there is recorded. ``pace``: simulated seconds per wall-clock second
(1.0: real time, for a person at the ground station); ``None``: as fast as it runs.
"""

from __future__ import annotations

import asyncio
import math
import time
from typing import Any

from swarm.errors import UsageError
from swarm.kernel.simulation import Simulation

__all__ = ["ALTITUDE_M", "ORIGIN", "MavlinkBridge", "lonlat_to_metres", "metres_to_lonlat", "pace"]

#: Where ``(0, 0)`` of a scenario in metres is put (lon, lat): PX4 SITL's default home, Zurich.
ORIGIN = (8.545594, 47.397742)
#: The altitude every UAV reports (m above the origin's ellipsoid height and above home).
ALTITUDE_M = 100.0
_EARTH_R = 6378137.0  # WGS84 equatorial radius (m): the tangent plane's scale

# custom_mode codes of HEARTBEAT.
_MODES = {"search": 0, "surveil": 1, "homebound": 2, "pending": 3, "landed": 3, "down": 4}


def metres_to_lonlat(x: float, y: float, origin: tuple[float, float] = ORIGIN) -> tuple[float, float]:
    """Local metres (x east, y north) on the tangent plane at ``origin`` as (lon, lat)."""
    lon0, lat0 = origin
    return (lon0 + math.degrees(x / (_EARTH_R * math.cos(math.radians(lat0)))), lat0 + math.degrees(y / _EARTH_R))


def lonlat_to_metres(lon: float, lat: float, origin: tuple[float, float] = ORIGIN) -> tuple[float, float]:
    """Inverse of :func:`metres_to_lonlat`."""
    lon0, lat0 = origin
    return (math.radians(lon - lon0) * _EARTH_R * math.cos(math.radians(lat0)), math.radians(lat - lat0) * _EARTH_R)


async def pace(sim: Simulation, factor: float, t_end: float) -> None:
    """Hold the run to ``factor`` simulated seconds per wall-clock second, up to ``t_end``."""
    if not factor > 0:
        raise UsageError(f"pace {factor!r}: expected a positive number of simulated seconds per second")
    t0, wall0 = sim.now, time.monotonic()
    t = t0
    while t <= t_end + 1e-9:
        await sim.wait_until(t)
        delay = wall0 + (t - t0) / factor - time.monotonic()
        if delay > 0:
            await asyncio.sleep(delay)
        t += sim.dt


class MavlinkBridge:
    """The swarm as MAVLink systems on one connection (a pymavlink URL, e.g.
    ``udpout:127.0.0.1:14550``)."""

    def __init__(self, sim: Simulation, url: str, *, origin: tuple[float, float] = ORIGIN):
        try:
            from pymavlink import mavutil
        except ImportError:
            raise UsageError("--mavlink needs pymavlink: pip install 'uav-swarm-sim[mavlink]'") from None
        self.sim = sim
        self.origin = origin
        self._mavutil = mavutil
        self.conn: Any = mavutil.mavlink_connection(url, source_system=1, source_component=1, dialect="common")
        self.mav = self.conn.mav
        self.received: list[tuple[float, str, str]] = []  # (t, UAV, what): repositions applied
        self._t0_wall = time.monotonic()

    def close(self) -> None:
        self.conn.close()

    # --- frames ---------------------------------------------------------------------------------

    def _lonlat(self, x: float, y: float, lon: float | None, lat: float | None) -> tuple[float, float]:
        return (lon, lat) if lon is not None and lat is not None else metres_to_lonlat(x, y, self.origin)

    def _local(self, lon: float, lat: float) -> tuple[float, float]:
        return self.sim.to_local(lon, lat) if self.sim.geographic else lonlat_to_metres(lon, lat, self.origin)

    def send(self) -> None:
        """Every UAV's HEARTBEAT, GLOBAL_POSITION_INT and SYS_STATUS, now."""
        m = self._mavutil.mavlink
        snap = self.sim.snapshot()
        boot_ms = int(round(snap.t * 1000))
        for u in snap.uavs:
            self.mav.srcSystem = u.uid + 1
            mode = u.state if u.state in ("homebound", "landed") else u.mode
            status = {"alive": m.MAV_STATE_ACTIVE, "homebound": m.MAV_STATE_ACTIVE,
                      "crashed": m.MAV_STATE_FLIGHT_TERMINATION}.get(u.state, m.MAV_STATE_STANDBY)
            self.mav.heartbeat_send(m.MAV_TYPE_FIXED_WING, m.MAV_AUTOPILOT_GENERIC,
                                    m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | m.MAV_MODE_FLAG_GUIDED_ENABLED,
                                    _MODES.get(mode, 0), status)
            lon, lat = self._lonlat(u.x, u.y, u.lon, u.lat)
            vn, ve = u.v * math.sin(u.theta), u.v * math.cos(u.theta)
            hdg = int(round((90.0 - math.degrees(u.theta)) % 360.0 * 100)) % 36000
            self.mav.global_position_int_send(boot_ms, int(round(lat * 1e7)), int(round(lon * 1e7)),
                                              int(ALTITUDE_M * 1000), int(ALTITUDE_M * 1000),
                                              int(round(vn * 100)), int(round(ve * 100)), 0, hdg)
            battery = -1
            if u.energy_wh is not None:
                cap = self.sim.scenario.endurance.types[u.type].capacity_wh if self.sim.scenario.endurance else 0.0
                battery = max(0, min(100, int(round(100 * u.energy_wh / cap)))) if cap else -1
            self.mav.sys_status_send(0, 0, 0, 0, 0, -1, battery, 0, 0, 0, 0, 0, 0)

    def poll(self) -> None:
        """Apply every reposition that has arrived (at the present tick boundary)."""
        while True:
            msg = self.conn.recv_match(blocking=False)
            if msg is None:
                return
            kind = msg.get_type()
            if kind == "SET_POSITION_TARGET_GLOBAL_INT":
                self._reposition(msg.target_system, msg.lon_int / 1e7, msg.lat_int / 1e7, None)
            elif kind == "COMMAND_LONG" and msg.command == self._mavutil.mavlink.MAV_CMD_DO_REPOSITION:
                self._reposition(msg.target_system, msg.param6, msg.param5, msg)
            elif kind == "COMMAND_INT" and msg.command == self._mavutil.mavlink.MAV_CMD_DO_REPOSITION:
                self._reposition(msg.target_system, msg.y / 1e7, msg.x / 1e7, msg)

    def _reposition(self, sysid: int, lon: float, lat: float, command: Any) -> None:
        m = self._mavutil.mavlink
        uavs = self.sim.snapshot().uavs
        result = m.MAV_RESULT_DENIED
        if 1 <= sysid <= len(uavs) and math.isfinite(lon) and math.isfinite(lat):
            name = uavs[sysid - 1].name
            x, y = self._local(lon, lat)
            try:
                self.sim.set_waypoint(name, x, y)
            except UsageError:
                pass
            else:
                result = m.MAV_RESULT_ACCEPTED
                self.received.append((self.sim.now, name, f"reposition to ({x:.0f}, {y:.0f}) m"))
        if command is not None:
            self.mav.srcSystem = sysid if 1 <= sysid <= len(uavs) else 1
            self.mav.command_ack_send(command.command, result)

    # --- the task ---------------------------------------------------------------------------------

    async def run(self, t_end: float) -> None:
        """At every tick boundary up to ``t_end``: read what arrived, then send."""
        sim = self.sim
        t = sim.now
        while t <= t_end + 1e-9:
            await sim.wait_until(t)
            self.poll()
            self.send()
            t += sim.dt
