"""The simulation's side of the fault kinds: what they may do to a run, and when.

:class:`RunFaults` is the :class:`faults.base.FaultHost` a fault kind installs itself on (the
clock, the UAVs' lifecycle, the tick faults' windows) and the :class:`faults.base.RadioHost`
a transmitting fault sends through. It holds the run's fault injector (frame copies) and its
tick faults (readings and actors). The simulation calls it at three points of a tick (begin,
sense, transmit) and never names a fault kind: each kind's behaviour is its own
(:mod:`faults.base`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

import swarm.events as ev
from agents.inputs import SensorReading
from agents.types import UavType
from comms.radio import Delivery, Radio, RadioCounters
from faults.base import BatteryLike, FaultKind
from faults.injector import FaultInjector
from faults.registry import FaultSchedule, uav_names
from faults.tick import TickFault, TickFaults
from swarm.errors import UsageError
from swarm.kernel.clock import FAULT, Clock
from swarm.kernel.fleet import Fleet
from swarm.kernel.recorder import EventLog
from swarm.kernel.rng import RngTree
from swarm.kernel.world import World


class _FaultEvents:
    """:class:`faults.base.FaultEvents` on the run's event log, through :mod:`swarm.events`' writers."""

    def __init__(self, log: EventLog):
        self._emit = log.emit

    def fault_on(self, *, t: float, fault: str, uav: int) -> None:
        self._emit(ev.fault_on(t=t, fault=fault, uav=uav))

    def fault_off(self, *, t: float, fault: str, uav: int) -> None:
        self._emit(ev.fault_off(t=t, fault=fault, uav=uav))

    def pause(self, *, t: float, uav: int) -> None:
        self._emit(ev.pause(t=t, uav=uav))

    def resume(self, *, t: float, uav: int) -> None:
        self._emit(ev.resume(t=t, uav=uav))


class RunFaults:
    """The faults of one simulation: the injector, the tick faults, and the host they act on."""

    def __init__(self, clock: Clock, world: World, fleet: Fleet, log: EventLog, rng: RngTree,
                 names: dict[str, int], area: tuple[float, float], dt: float, latency_s: float,
                 injector: FaultInjector, radio: Radio, batteries: Callable[[int], BatteryLike | None]):
        """``injector``: the run's fault schedule and frame-copy filter (the radio sends every
        copy through it); ``batteries``: each UAV's battery (issue 33,
        :meth:`swarm.kernel.mission.Mission.battery_of`), which the battery fault acts on: None
        without [endurance]."""
        self.clock = clock
        self.world = world
        self.fleet = fleet
        self.log = log
        self.names = names  # shared with the simulation: names added later resolve
        self._area = area
        self._latency_s = latency_s
        self.injector = injector
        self.tick = TickFaults(rng.generator, names, area, dt, _FaultEvents(log))
        self.radio = radio
        self.batteries = batteries

    @property
    def schedule(self) -> FaultSchedule:
        return self.injector.schedule

    def add(self, fault: FaultKind) -> None:
        """Add a fault to the run (a clear :class:`UsageError` if it cannot be)."""
        unknown = [n for _path, n in uav_names(fault) if n not in self.names]
        if unknown:
            raise UsageError(f"fault {fault.kind} names unknown UAV(s) {unknown}; known: {', '.join(self.names)}")
        problem = fault.check(self.now)
        if problem:
            raise UsageError(problem)
        index = len(self.injector.schedule)  # its place in the schedule: names its random streams
        fault.install(self, index)
        self.injector.add(fault)

    # --- FaultHost ---------------------------------------------------------------------------

    @property
    def now(self) -> float:
        return self.clock.now

    def uid(self, name: str) -> int:
        return self.names[name]

    def at(self, t: float, action: Callable[[], None]) -> None:
        self.clock.schedule(float(max(t, self.clock.now)), action, FAULT)

    def fired(self, kind: str, n: int = 1) -> None:
        self.injector.note_fired(kind, n)

    def state(self, uid: int) -> str:
        return self.world.uavs[uid].state

    def fail_stop(self, uid: int, back_at: float | None = None) -> None:
        if self.world.uavs[uid].state == "alive":
            self.tick.node_down(uid)
        self.fleet.fail_stop(uid, self.clock.now)
        if back_at is not None:
            self.fleet.returning[uid] = back_at

    def revive(self, uid: int, key: tuple[str | int, ...]) -> None:
        self.fleet.revive(uid, self.clock.now, key)

    def set_join(self, uid: int, at_s: float) -> None:
        self.world.uavs[uid].join_s = at_s
        self.at(at_s, lambda: self._join(uid))

    def _join(self, uid: int) -> None:
        if self.fleet.join(uid, self.clock.now):
            self.fired("join")  # a late joiner

    def open_window(self, index: int, fault: FaultKind) -> None:
        assert isinstance(fault, TickFault)
        self.tick.open(index, fault)

    def close_window(self, index: int, fault: FaultKind) -> None:
        assert isinstance(fault, TickFault)
        self.tick.close(index, fault, self.clock.now, sorted(self.world.uavs))

    # --- RadioHost -----------------------------------------------------------------------------

    @property
    def area(self) -> tuple[float, float]:
        return self._area

    @property
    def latency_s(self) -> float:
        return self._latency_s

    @property
    def counters(self) -> RadioCounters:
        return self.radio.counters

    def members(self) -> list[int]:
        return sorted(self.world.uavs)

    def uav_type(self, uid: int) -> UavType:
        return self.world.uavs[uid].kind

    # --- the tick ------------------------------------------------------------------------------

    def begin_tick(self, t: float) -> None:
        """Select the link faults active at ``t``."""
        self.injector.begin_tick(t)

    def battery(self, uid: int) -> BatteryLike | None:
        """(issue 26) The UAV's battery, or None without a budget: what the battery fault acts on."""
        return self.batteries(uid)

    def sense(self, t: float, alive: list[int], readings: dict[int, SensorReading],
              pausable: Callable[[int], bool]) -> None:
        """Let the open tick faults act on this tick's readings and actors."""
        if self.tick.active:
            self.tick.apply(t, alive, readings, self.fleet.actors, pausable, self.fired)
        else:
            self.tick.reset()

    def transmit(self, t: float, dt: float, alive: list[int], xy: np.ndarray) -> list[Delivery]:
        """Who is where (jammers), then the frames of the faults that transmit this tick."""
        self.injector.set_positions(alive, xy)
        out: list[Delivery] = []
        for tx in self.injector.transmitters:
            if tx.fault.active(t):
                n = tx.transmit(self, t, dt, alive, xy, out)
                if n:
                    self.fired(tx.fault.kind, n)
        return out

