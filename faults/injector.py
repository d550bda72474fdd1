"""Applies a run's fault schedule to frame copies and counts what actually fired.

The injector is the radio's :class:`comms.radio.LinkFilter`. Each fault kind that acts on links
gives it a :class:`faults.base.LinkBehaviour` (:meth:`faults.base.FaultKind.link_behaviour`); each frame
copy on a directed link passes through the active ones in a fixed order of stages (the cuts:
partition and bridge, then swizzle; then jammer, drop, burst, corrupt, duplicate, delay), in
schedule order within a stage, drawing only from that link's random stream. The first that
loses the copy names the cause.

``fired`` counts, per kind, the times a fault changed something (a copy blocked, dropped,
corrupted, duplicated or delayed; a UAV crashed or joined; a spoofed frame sent), so an inert
fault shows as 0. Behaviours on nodes and ticks report through :meth:`FaultInjector.note_fired`.

Draws a fault makes for itself (a swizzle's subset and order, a spoofer's frames) come from its
own stream, ``fault_rng(kind, k)`` (the simulator's ``rng.generator("fault", kind, k)``, ``k``
the fault's index among the faults of its kind): no other stream shifts because of them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from faults.base import COPY_STAGES, Copy, FaultKind, FaultRng, LinkBehaviour, Transmitter
from faults.registry import FaultSchedule


def _default_fault_rng(kind: str, k: int) -> np.random.Generator:
    raise ValueError(f"a {kind} fault draws from its own stream: give FaultInjector a fault_rng")


class FaultInjector:
    def __init__(self, schedule: FaultSchedule, ids: Mapping[str, int], fault_rng: FaultRng | None = None):
        self.schedule = schedule
        self._ids = ids
        self._fault_rng = fault_rng or _default_fault_rng
        self.fired: dict[str, int] = {k: 0 for k in schedule.kinds()}
        self._behaviours: list[LinkBehaviour] = []
        self._by_fault: dict[int, LinkBehaviour] = {}  # id(fault) ->
        self._ranks: dict[str, int] = {}  # faults of each kind so far
        # Faults that send frames of their own (spoofers), in schedule order.
        self.transmitters: list[Transmitter] = []
        self._cuts: list[LinkBehaviour] = []  # active this tick
        self._copy: list[LinkBehaviour] = []  # active this tick
        for f in schedule.faults:
            self._register(f)

    def _register(self, f: FaultKind) -> None:
        self.fired.setdefault(f.kind, 0)
        rank = self._ranks.get(f.kind, 0)
        self._ranks[f.kind] = rank + 1
        b = f.link_behaviour(self._ids, self._fault_rng, rank)
        if b is not None:
            self._behaviours.append(b)
            self._by_fault[id(f)] = b
        tx = f.transmitter(self._fault_rng, rank)
        if tx is not None:
            self.transmitters.append(tx)

    def add(self, f: FaultKind) -> None:
        """Add a fault while the run goes on (the simulator installs its clock behaviour)."""
        self.schedule.add(f)
        self._register(f)

    def note_fired(self, kind: str, n: int = 1) -> None:
        self.fired[kind] = self.fired.get(kind, 0) + n

    def behaviour(self, f: FaultKind) -> LinkBehaviour | None:
        """The link behaviour of a fault of this injector (None: it has none)."""
        return self._by_fault.get(id(f))

    def drawn(self, f: FaultKind) -> Any:
        """What fault ``f`` drew for itself once it started (None before, or if it draws nothing)."""
        b = self._by_fault.get(id(f))
        return b.drawn() if b is not None else None

    # --- per tick ---------------------------------------------------------------------------

    def begin_tick(self, t: float) -> None:
        """Select the faults active at ``t`` (windows are half-open: ``[start, end)``)."""
        # A fixed order whatever the schedule's: a copy that is dropped is never counted as
        # corrupted, duplicated or delayed (sorted() is stable: schedule order within a stage).
        active = sorted((b for b in self._behaviours if b.fault.active(t)), key=lambda b: b.stage)
        for b in active:
            b.begin_tick(t)
        self._cuts = [b for b in active if b.stage < COPY_STAGES]
        self._copy = [b for b in active if b.stage >= COPY_STAGES]

    def set_positions(self, ids: Sequence[int], xy: np.ndarray) -> None:
        """The live UAVs' positions of this tick (``xy`` shape (n, 2), rows in ``ids`` order).
        Call after :meth:`begin_tick`, before the tick's frames are filtered."""
        if self._copy:
            pts = np.asarray(xy, dtype=float).reshape(-1, 2)
            for b in self._copy:
                b.set_positions(ids, pts)

    def _cut(self, src: int, dst: int) -> str | None:
        """Why no copy passes from ``src`` to ``dst`` this tick (a cause), or None."""
        for b in self._cuts:
            if b.cut(src, dst):
                return b.fault.kind
        return None

    def blocked(self, src: int, dst: int) -> bool:
        """Whether a cut (partition, bridge, swizzle) blocks ``src -> dst`` this tick."""
        return self._cut(src, dst) is not None

    @property
    def idle(self) -> bool:
        return not (self._cuts or self._copy)

    # --- the radio's LinkFilter -------------------------------------------------------------

    def filter(self, t: float, src: int, dst: int, data: bytes,
               rng: np.random.Generator) -> tuple[list[tuple[float, bytes]], str | None]:
        if self._cuts and self.blocked(src, dst):  # (then _cut names the cause; blocked is what a test may replace)
            cut = self._cut(src, dst) or "partition"
            self.fired[cut] += 1
            return [], cut
        if not self._copy:
            return [(0.0, data)], None
        c = Copy(data)
        fired = self.fired
        for b in self._copy:
            if b.on_copy(c, src, dst, rng):
                kind = b.fault.kind
                fired[kind] += 1
                if c.lost:
                    return [], kind
        return [(c.extra_s, c.data)] * c.copies, None
