"""Faults that act on UAVs' ticks while their window is open: the engine.

:class:`TickFaults` holds the tick faults (:class:`TickFault`: pause, clock_skew,
nav_error, sensor, liar, and any kind defined like them) between their ``start_s`` and
``end_s`` clock events and, tick by tick, lets each act on the readings and actors of the live
UAVs it concerns, in the kinds' ``tick_order`` (what is sensed, then where the UAV believes it
is, then its clock, then what its actor does), schedule order within a kind.

Every random draw comes from the fault's own stream, ``("fault", kind, index, uav name)``
(``index``: the fault's place in the schedule), so a fault never shifts any other stream and a
run without these faults draws exactly what it drew before. Nothing here runs when no such
fault is active: the tick's fast path is one test of an empty list.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from agents.actor import UavActor
from agents.inputs import SensorReading
from faults.base import FaultEvents, FaultHost, Windowed

Stream = Callable[..., np.random.Generator]


class TickFault(Windowed):
    """A windowed fault that acts on its UAVs' ticks: its window opens and closes on the clock,
    and :meth:`on_tick` runs for each of its live UAVs in between (:class:`TickFaults`)."""

    # Whether it stops acting on a UAV that goes down (with no event: the process is gone).
    ends_with_process: ClassVar[bool] = False
    # The order tick faults act in within a tick (what is sensed, then where the UAV believes
    # it is, then its clock, then what its actor does).
    tick_order: ClassVar[int] = 100

    def install(self, host: FaultHost, index: int) -> None:
        if self.end_s <= host.now:
            return  # a window wholly in the past does nothing
        host.at(max(self.start_s, host.now), lambda: host.open_window(index, self))
        if math.isfinite(self.end_s):
            host.at(self.end_s, lambda: host.close_window(index, self))

    def on_tick(self, faults: TickFaults, index: int, uid: int) -> None:
        """What it does to UAV ``uid``'s tick while its window is open."""

    def tick_uavs(self, alive: Sequence[int], ids: Mapping[str, int]) -> list[int]:
        """The live UAVs its tick behaviour acts on (its ``uav``, its ``uavs`` or all)."""
        uav: str | None = getattr(self, "uav", None)
        if uav is not None:
            uid = ids[uav]
            return [uid] if uid in alive else []
        uavs = getattr(self, "uavs", ())
        if not uavs:
            return list(alive)
        scope = {ids[n] for n in uavs}
        return [u for u in alive if u in scope]

    def ended(self, events: FaultEvents, t: float, uid: int) -> None:
        """Write that it stopped acting on ``uid`` (its window closed at ``t``)."""
        events.fault_off(t=t, fault=self.kind, uav=uid)


class TickFaults:
    """The open tick faults of one simulation, and what they did this tick."""

    def __init__(self, stream: Stream, names: Mapping[str, int], area: tuple[float, float], dt: float,
                 events: FaultEvents):
        self._stream_of = stream
        self.events = events  # where the faults write their events (fault_on, pause, ...)
        self.names = names
        self.area = area
        self.dt = dt
        # (schedule index, fault) between its start and end events, in the order they began.
        self.active: list[tuple[int, TickFault]] = []
        self._streams: dict[tuple[int, int], np.random.Generator] = {}
        self._applied: set[tuple[int, int]] = set()  # (index, uid): the fault has acted on the UAV
        self._serials: dict[str, int] = {}  # made-up ids handed out so far, per series
        self.carry: dict[tuple[Any, ...], float] = {}  # rates owed across ticks (fractions)
        # What this tick's faults did, read by the simulation's later phases:
        self.paused: set[int] = set()  # UAVs not woken (they fly their last command)
        self.truth: dict[int, list[int]] = {}  # sensed target ids before a sensing fault changed them
        self.detected: dict[int, list[int]] | None = None  # real target ids the sensor reported
        # This tick's inputs, for the faults' on_tick:
        self.t = 0.0
        self.readings: dict[int, SensorReading] = {}
        self.actors: Mapping[int, UavActor] = {}
        self.pausable: Callable[[int], bool] = lambda uid: False
        self.fired: Callable[[str, int], None] = lambda kind, n: None

    def stream(self, index: int, kind: str, uid: int) -> np.random.Generator:
        """Fault ``index``'s own stream for UAV ``uid``."""
        g = self._streams.get((index, uid))
        if g is None:
            g = self._streams[(index, uid)] = self._stream_of("fault", kind, index, self.actors[uid].name)
        return g

    def first(self, index: int, uid: int) -> bool:
        """True the first time fault ``index`` acts on UAV ``uid`` (it fired)."""
        key = (index, uid)
        if key in self._applied:
            return False
        self._applied.add(key)
        return True

    def forget(self, index: int, uid: int) -> bool:
        """The fault's window ended or the UAV went down: True if it had acted on the UAV."""
        if (index, uid) in self._applied:
            self._applied.discard((index, uid))
            return True
        return False

    def serial(self, series: str, base: int, span: int) -> int:
        """The next made-up id of ``series`` (phantom targets): ``base`` + a count modulo ``span``."""
        k = self._serials.get(series, 0)
        self._serials[series] = k + 1
        return base + k % span

    def owed(self, key: tuple[Any, ...], rate_per_s: float) -> int:
        """Whole events owed this tick at ``rate_per_s``, the fractions carried over."""
        c = self.carry.get(key, 0.0) + rate_per_s * self.dt
        n = int(c)
        self.carry[key] = c - n
        return n

    # --- the clock's events ------------------------------------------------------------------

    def open(self, index: int, fault: TickFault) -> None:
        self.active.append((index, fault))

    def close(self, index: int, fault: TickFault, t: float, uids: Sequence[int]) -> None:
        """Fault ``index``'s window closed at ``t``: write that it stopped acting on those of
        ``uids`` it had acted on (:meth:`TickFault.ended`)."""
        self.active = [(i, f) for i, f in self.active if i != index]
        for uid in uids:
            if self.forget(index, uid):
                fault.ended(self.events, t, uid)

    def node_down(self, uid: int) -> None:
        """UAV ``uid`` went down: the faults that end with its process forget it (no event)."""
        for index, f in self.active:
            if f.ends_with_process:
                self.forget(index, uid)

    # --- the tick ------------------------------------------------------------------------------

    def reset(self) -> None:
        """No tick fault is active: clear what the last one left."""
        if self.paused or self.detected is not None or self.truth:
            self.paused, self.truth, self.detected = set(), {}, None

    def apply(self, t: float, alive: list[int], readings: dict[int, SensorReading],
              actors: Mapping[int, UavActor], pausable: Callable[[int], bool],
              fired: Callable[[str, int], None]) -> None:
        """Let the active faults act on this tick's readings (in place) and actors."""
        self.paused = set()
        self.truth = {}
        self.detected = None
        self.t, self.readings, self.actors = t, readings, actors
        self.pausable, self.fired = pausable, fired
        alive_set = set(alive)
        for index, f in sorted(self.active, key=lambda p: (p[1].tick_order, p[0])):
            for uid in f.tick_uavs(alive, self.names):
                if uid in alive_set:
                    f.on_tick(self, index, uid)
