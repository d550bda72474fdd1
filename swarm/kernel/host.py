"""The host's side of a simulation: the lockstep contract of docs/embedding.md.

Time moves in ticks of ``dt``; the simulation stands at a *tick boundary* ``k * dt`` between
two ticks. Everything a host does takes effect at a boundary:

* the *present* is the boundary where a change made now takes effect: ``sim.now`` when the
  simulation is not inside a tick, else the end of the tick under way (``sim.now + dt``: a
  task that runs while the actors think, without waiting, acts at the next boundary);
* a change (:mod:`swarm.kernel.hostlog`) made at a boundary is applied at once; one made inside a tick
  is queued and applied at the next boundary, in call order; each is logged (``host``);
* at each boundary, before anything of the next tick (faults, frames, the tick itself), the
  simulation applies the queued changes, then serves the alarms due there in order (time,
  then registration): a ``call_at`` callback is called; a task waiting in ``wait_until`` is
  resumed and the simulation waits until it waits again or finishes, whatever it awaits in
  between (real I/O included) and however long it takes. So the changes, their order and
  their boundaries do not depend on wall time: one host gives one event log.

A boundary is served once, when the simulation first stands at it (``run_until(t)`` serves the
boundary it stops at before it returns). The host changes themselves are checked here (one
:class:`~swarm.errors.UsageError` subclass per kind of bad input, the run unchanged) and
applied by :mod:`swarm.kernel.hostlog`.
"""

from __future__ import annotations

import asyncio
import heapq
import itertools
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from faults.base import FaultKind
from faults.registry import fault_to_dict, uav_names
from swarm.errors import (
    APIMisuseError,
    BadStateError,
    NotControlledError,
    NotGeographicError,
    TimeInPastError,
    UnknownUavError,
    UsageError,
)
from swarm.kernel.hostlog import apply_change

if TYPE_CHECKING:
    from swarm.geo.geography import Geography
    from swarm.kernel.driving import LoopBinding
    from swarm.kernel.simulation import Simulation
    from swarm.kernel.world import World

# What an alarm does when its boundary comes.
_CALL, _WAKE, _REPLAY = 0, 1, 2


class Host:
    """One simulation's host side: the changes queued for the next boundary, the alarms
    (``call_at``, ``wait_until``, replayed changes), and the bodies driven from outside."""

    def __init__(self, sim: Simulation):
        self._sim = sim
        self.controlled: set[int] = set()  # UAV ids whose bodies the host flies
        self.in_tick = False  # a tick is under way (set by the simulation)
        self._queue: list[tuple[str, dict[str, Any]]] = []  # changes made inside a tick
        self._alarms: list[tuple[int, int, int, Any]] = []  # heap of (boundary, seq, what, payload)
        self._seq = itertools.count()
        self._served = -1  # the last boundary served
        self._acting: asyncio.Task[Any] | None = None  # the task resumed at this boundary
        self._acted: asyncio.Future[None] | None = None

    # --- time ---------------------------------------------------------------------------------

    def present(self) -> int:
        """The boundary (tick index) where a change made now takes effect."""
        return self._sim._tick_index + (1 if self.in_tick else 0)

    def boundary_of(self, t: float, what: str) -> int:
        """The last boundary at or before ``t`` (where ``run_until(t)`` stops); not in the past."""
        if not isinstance(t, (int, float)) or not math.isfinite(t):
            raise UsageError(f"{what}: time {t!r} is not a finite number of seconds")
        sim = self._sim
        k = math.floor(t / sim.dt + 1e-9)
        present = self.present()
        if k < present:
            raise TimeInPastError(f"{what}: t = {t:g} s is in the past (the present is {present * sim.dt:g} s, "
                                  f"the tick boundary where a change made now takes effect)")
        return k

    # --- changes --------------------------------------------------------------------------------

    def submit(self, change: str, args: dict[str, Any]) -> None:
        """Apply a checked change now (at a boundary) or at the next boundary (inside a tick)."""
        if self.in_tick:
            self._queue.append((change, args))
        else:
            apply_change(self._sim, change, args)

    def queued(self, change: str) -> list[dict[str, Any]]:
        return [a for c, a in self._queue if c == change]

    def uid(self, name: str) -> int:
        """A UAV's id by name (an added UAV still queued has none yet: use :meth:`known`)."""
        names = self._sim._names
        if name not in names:
            raise UnknownUavError(f"no UAV named {name!r}; known: {', '.join(names)}")
        return names[name]

    def known(self, name: str) -> str:
        if name not in self._sim._names and not any(a["name"] == name for a in self.queued("add_uav")):
            self.uid(name)  # (raises)
        return name

    def local(self, x: float | None, y: float | None, lon: float | None, lat: float | None,
              what: str) -> tuple[float, float]:
        """A position given in local metres or (geographic scenarios) longitude/latitude."""
        if lon is not None or lat is not None:
            if x is not None or y is not None:
                raise UsageError(f"{what}: give x and y (metres) or lon and lat, not both")
            if lon is None or lat is None:
                raise UsageError(f"{what}: give both lon and lat")
            if not self._sim.geographic:
                raise not_geographic(what)
            x, y = self._sim.to_local(lon, lat)
        if x is None or y is None:
            raise UsageError(f"{what}: give x and y (metres){' or lon and lat' if self._sim.geographic else ''}")
        return finite(x, f"{what}: x"), finite(y, f"{what}: y")

    def add_target(self, x: float, y: float, heading_deg: float, speed: float, value: float) -> int:
        sim = self._sim
        heading, speed, value = finite(heading_deg, "heading_deg"), finite(speed, "speed"), finite(value, "value")
        if not sim._grid.contains(x, y):
            raise UsageError(f"target position ({x}, {y}) is outside the area {sim._grid.width_m} x {sim._grid.height_m} m")
        if not 0.0 <= speed <= sim._targets.motion.speed_max:
            raise UsageError(f"target speed {speed} outside [0, {sim._targets.motion.speed_max}] m/s")
        tid = len(sim._targets) + len(self.queued("add_target"))
        self.submit("add_target", {"x": x, "y": y, "heading_deg": heading, "speed": speed, "value": value})
        return tid

    def add_uav(self, type: str, x: float, y: float, heading_deg: float, speed: float | None,
                name: str | None, join_s: float | None) -> str:
        sim = self._sim
        if type not in sim._types:
            raise UsageError(f"unknown UAV type {type!r}; known: {', '.join(sim._types)}")
        taken = set(sim._names) | {a["name"] for a in self.queued("add_uav")}
        if name is None:
            k = 1 + sum(1 for b in sim._world.uavs.values() if b.kind.name == type) + sum(
                1 for a in self.queued("add_uav") if a["type"] == type)
            name = f"{type}{k}"
            while name in taken:
                k += 1
                name = f"{type}{k}"
        if name in taken:
            raise UsageError(f"a UAV named {name!r} already exists")
        if not sim._grid.contains(x, y):
            raise UsageError(f"UAV position ({x}, {y}) is outside the area")
        kind = sim._types[type]
        if speed is not None:
            speed = finite(speed, "speed")
            if not kind.speed_min <= speed <= kind.speed_max:
                raise UsageError(f"speed {speed} outside type {type}'s range [{kind.speed_min}, {kind.speed_max}]")
        present = self.present() * sim.dt
        join = present if join_s is None else max(finite(join_s, "join_s"), present)
        self.submit("add_uav", {"name": name, "type": type, "x": x, "y": y,
                                "heading_deg": finite(heading_deg, "heading_deg"), "speed": speed,
                                "join_s": join})
        return name

    def add_fault(self, fault: FaultKind) -> None:
        sim = self._sim
        queued = {a["name"] for a in self.queued("add_uav")}
        unknown = [n for _path, n in uav_names(fault) if n not in sim._names and n not in queued]
        if unknown:
            raise UnknownUavError(f"fault {fault.kind} names unknown UAV(s) {unknown}; known: {', '.join(sim._names)}")
        problem = fault.check(self.present() * self._sim.dt)
        if problem:
            raise TimeInPastError(problem) if "past" in problem else UsageError(problem)
        self.submit("add_fault", {"fault": fault_to_dict(fault)})

    def take_control(self, name: str) -> None:
        self.submit("take_control", {"uav": self.known(name)})

    def release_control(self, name: str) -> None:
        if self._controlled_after_queue(name) is False:
            raise NotControlledError(f"release_control({name!r}): the host does not control {name!r}")
        self.submit("release_control", {"uav": name})

    def _controlled_after_queue(self, name: str) -> bool:
        """Whether ``name`` will be controlled once the queued changes are applied."""
        self.known(name)
        held = name in self._sim._names and self._sim._names[name] in self.controlled
        for change, a in self._queue:
            if a.get("uav") == name and change in ("take_control", "release_control"):
                held = change == "take_control"
        return held

    def set_state(self, name: str, x: float, y: float, heading_rad: float, speed_mps: float) -> None:
        sim = self._sim
        if not self._controlled_after_queue(name):
            raise NotControlledError(f"set_state({name!r}): the host does not control {name!r}; "
                                     f"call take_control({name!r}) first")
        heading, speed = finite(heading_rad, "heading_rad"), finite(speed_mps, "speed_mps")
        if speed < 0.0:
            raise BadStateError(f"set_state({name!r}): speed {speed} m/s is negative")
        if not sim._grid.contains(x, y):
            raise UsageError(f"set_state({name!r}): position ({x}, {y}) is outside the area")
        self.submit("set_state", {"uav": name, "x": x, "y": y, "heading": math.remainder(heading, math.tau),
                                  "speed": speed})

    def set_waypoint(self, name: str, x: float, y: float) -> None:
        sim = self._sim
        self.known(name)
        if not sim._grid.contains(x, y):
            raise UsageError(f"set_waypoint({name!r}): position ({x}, {y}) is outside the area")
        self.submit("set_waypoint", {"uav": name, "x": x, "y": y})

    # --- alarms ---------------------------------------------------------------------------------

    def call_at(self, t: float, fn: Callable[[], Any]) -> None:
        if not callable(fn):
            raise UsageError(f"call_at: {fn!r} is not callable")
        k = self.boundary_of(t, "call_at")
        if k == self._served and not self.in_tick and self._sim._tick_index == k:
            fn()  # (the simulation stands at that boundary: now)
            return
        heapq.heappush(self._alarms, (k, next(self._seq), _CALL, fn))

    def replay_at(self, k: int, change: str, args: dict[str, Any]) -> None:
        heapq.heappush(self._alarms, (k, next(self._seq), _REPLAY, (change, args)))

    async def wait_until(self, t: float) -> None:
        sim = self._sim
        k = self.boundary_of(t, "wait_until")
        if k > sim.n_ticks:
            raise UsageError(f"wait_until: t = {t:g} s is after the run's end ({sim.duration_s:g} s)")
        task = asyncio.current_task()
        if task is None:
            raise APIMisuseError("wait_until must be awaited from a task")
        if k == sim._tick_index and self._served == k and not self.in_tick:
            return  # (standing at that boundary, served: the caller acts now)
        woken: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        heapq.heappush(self._alarms, (k, next(self._seq), _WAKE, (woken, task)))
        if self._acting is task and self._acted is not None and not self._acted.done():
            self._acted.set_result(None)  # (it waits again: the simulation goes on)
        await woken

    async def serve(self) -> None:
        """Serve the boundary the simulation stands at (once): the queued changes, then the
        alarms due, in order."""
        sim = self._sim
        k = self._served = sim._tick_index
        if self._queue:
            queue, self._queue = self._queue, []
            for change, args in queue:
                apply_change(sim, change, args)
        alarms = self._alarms
        while alarms and alarms[0][0] <= k:
            _k, _seq, what, payload = heapq.heappop(alarms)
            if what == _CALL:
                payload()
            elif what == _REPLAY:
                apply_change(sim, *payload)
            else:
                woken, task = payload
                if not woken.done():  # (cancelled while it waited: nothing to wait for)
                    await self._let_act(woken, task)

    def due(self) -> bool:
        """Whether the boundary the simulation stands at is still to be served."""
        return self._served != self._sim._tick_index

    async def _let_act(self, woken: asyncio.Future[None], task: asyncio.Task[Any]) -> None:
        acted: asyncio.Future[None] = asyncio.get_running_loop().create_future()

        def finished(_task: asyncio.Task[Any]) -> None:
            if not acted.done():
                acted.set_result(None)

        self._acting, self._acted = task, acted
        task.add_done_callback(finished)
        woken.set_result(None)
        try:
            await acted
        finally:
            task.remove_done_callback(finished)
            self._acting = self._acted = None


def finite(value: Any, what: str) -> float:
    """``value`` as a finite float, or a :class:`BadStateError` naming it."""
    try:
        f = float(value)
    except (TypeError, ValueError):
        raise BadStateError(f"{what}: {value!r} is not a number") from None
    if not math.isfinite(f):
        raise BadStateError(f"{what}: {value!r} is not finite")
    return f


def not_geographic(what: str) -> NotGeographicError:
    return NotGeographicError(f"{what}: longitude/latitude need a geographic scenario (one with [geo]); "
                              f"this one is in metres: give x and y")


class HostApi:
    """The embedding API's calls that change a run or act at a simulated time, and the local
    frame's conversions: a part of :class:`swarm.kernel.simulation.Simulation` (it inherits them), here
    beside the contract they follow. Each checks its input and hands the change to :class:`Host`."""

    _host: Host
    _binding: LoopBinding
    _geography: Geography | None
    _world: World

    @property
    def geographic(self) -> bool:
        """Whether the scenario has a longitude/latitude frame (``[geo]``)."""
        return self._geography is not None and self._geography.frame is not None

    @property
    def controlled(self) -> tuple[str, ...]:
        """The UAVs whose bodies the host drives (``take_control``), by name."""
        return tuple(self._world.uavs[uid].name for uid in sorted(self._host.controlled))

    def to_local(self, lon: float, lat: float) -> tuple[float, float]:
        """Longitude/latitude (WGS84, degrees) as the run's local metres ``(x, y)`` (x east, y
        north, from the area's south-west corner); a :class:`NotGeographicError` without ``[geo]``."""
        frame = self._frame("to_local")
        x, y = frame.lonlat_to_local(finite(lon, "lon"), finite(lat, "lat"))
        return x, y

    def to_lonlat(self, x: float, y: float) -> tuple[float, float]:
        """Local metres as longitude/latitude (WGS84, degrees); inverse of :meth:`to_local`."""
        lon, lat = self._frame("to_lonlat").to_lonlat([finite(x, "x")], [finite(y, "y")])
        return float(lon[0]), float(lat[0])

    def _frame(self, what: str) -> Any:
        if not self.geographic:
            raise not_geographic(what)
        assert self._geography is not None
        return self._geography.frame

    # --- changing the run: checked, applied at a tick boundary, logged (swarm.kernel.hostlog) ---

    def add_target(self, x: float | None = None, y: float | None = None, heading_deg: float = 0.0, speed: float = 0.0,
                   value: float = 1.0, *, lon: float | None = None, lat: float | None = None) -> int:
        """Add a target at ``(x, y)`` (or ``lon``/``lat``); returns its id."""
        x, y = self._host.local(x, y, lon, lat, "add_target")
        return self._host.add_target(x, y, heading_deg, speed, value)

    def add_uav(self, type: str, x: float | None = None, y: float | None = None, heading_deg: float = 0.0,
                speed: float | None = None, name: str | None = None, join_s: float | None = None, *,
                lon: float | None = None, lat: float | None = None) -> str:
        """Add a UAV at ``(x, y)`` (or ``lon``/``lat``); it joins at ``join_s`` (default: the
        present). Returns its name."""
        x, y = self._host.local(x, y, lon, lat, "add_uav")
        return self._host.add_uav(type, x, y, heading_deg, speed, name, join_s)

    def add_fault(self, fault: FaultKind) -> None:
        """Add a fault (an instance of a kind of :mod:`faults.schedule`, or of one registered
        elsewhere); faults that happen at a time must not be before the present."""
        self._host.add_fault(fault)

    def take_control(self, name: str) -> None:
        """Drive UAV ``name``'s body from outside: the simulator stops integrating it (it stays
        where :meth:`set_state` last put it); its actor goes on sensing, planning and talking."""
        self._host.take_control(name)

    def release_control(self, name: str) -> None:
        """Give UAV ``name``'s body back to the simulator, which flies it on from its last state."""
        self._host.release_control(name)

    def set_state(self, name: str, x_m: float, y_m: float, heading_rad: float, speed_mps: float) -> None:
        """Put a controlled UAV's body at ``(x_m, y_m)`` with heading ``heading_rad`` (from east,
        counter-clockwise) and speed ``speed_mps``."""
        x, y = self._host.local(x_m, y_m, None, None, "set_state")
        self._host.set_state(name, x, y, heading_rad, speed_mps)

    def set_state_lonlat(self, name: str, lon: float, lat: float, heading_rad: float, speed_mps: float) -> None:
        """:meth:`set_state` with the position as longitude/latitude (geographic scenarios)."""
        x, y = self._host.local(None, None, lon, lat, "set_state_lonlat")
        self._host.set_state(name, x, y, heading_rad, speed_mps)

    def set_waypoint(self, name: str, x: float | None = None, y: float | None = None, *,
                     lon: float | None = None, lat: float | None = None) -> None:
        """An operator's waypoint: UAV ``name`` flies to it searching (no replanning on the
        way), then plans afresh."""
        x, y = self._host.local(x, y, lon, lat, "set_waypoint")
        self._host.set_waypoint(name, x, y)

    def call_at(self, t: float, fn: Callable[[], Any]) -> None:
        """Call ``fn()`` when the simulation reaches the last tick boundary at or before ``t``."""
        self._host.call_at(t, fn)

    async def wait_until(self, t: float) -> None:
        """Suspend the calling task until the simulation reaches the last tick boundary at or
        before ``t``; the simulation does not go on until the task waits again or finishes."""
        self._binding.check_host_loop()
        await self._host.wait_until(t)
