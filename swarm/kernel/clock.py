"""The simulation clock: virtual time and a heap of scheduled callbacks (after SimPy's core).

Nothing here sleeps or reads the wall clock. Entries are ``(time, priority, sequence, callback)``;
the sequence number from ``itertools.count`` breaks ties so events at one instant and priority
run in the order they were scheduled, and the heap never compares callbacks. Radio deliveries,
fault events, joins and the physics tick are all just entries; the clock knows none of them.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable
from typing import Any

from swarm.errors import SimulationError

# Priorities at one instant: faults and joins first, then frames arriving, then the tick.
FAULT, DELIVERY, TICK = 0, 1, 2


class Clock:
    __slots__ = ("now", "_heap", "_seq")

    def __init__(self, start: float = 0.0):
        self.now = float(start)
        self._heap: list[tuple[float, int, int, Callable[[], Any]]] = []
        self._seq = itertools.count()

    def schedule(self, time: float, callback: Callable[[], Any], priority: int = DELIVERY) -> None:
        if time < self.now:
            raise SimulationError(f"cannot schedule at t={time} before now={self.now}")
        heapq.heappush(self._heap, (time, priority, next(self._seq), callback))

    def peek(self) -> float:
        """Time of the next entry, or +inf when nothing is scheduled."""
        return self._heap[0][0] if self._heap else float("inf")

    def pop(self) -> Callable[[], Any]:
        """Advance ``now`` to the next entry and return its callback."""
        time, _prio, _seq, callback = heapq.heappop(self._heap)
        self.now = time
        return callback

    def advance_to(self, t: float) -> None:
        """Move ``now`` forward to ``t`` (a tick boundary the host acts at: every entry before it
        has run); never backwards."""
        if t > self.now:
            self.now = float(t)

    def __len__(self) -> int:
        return len(self._heap)
