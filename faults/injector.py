"""Applies a fault schedule on the simulation clock and counts what actually fired.

Link faults plug into the radio as its :class:`comms.radio.LinkFilter`: each frame copy on a
directed link passes through the active faults in a fixed order (partition, drop, burst,
corrupt, duplicate, delay), drawing only from that link's random stream. Node faults (crash,
join) are handed to the simulator as timed events; it reports back when one took effect.

``fired`` counts, per kind, the times a fault changed something (a copy blocked, dropped,
corrupted, duplicated or delayed; a UAV crashed or joined), so an inert fault shows as 0.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from faults.schedule import (
    Burst,
    Corrupt,
    Delay,
    Drop,
    Duplicate,
    Fault,
    FaultSchedule,
    LinkFault,
    Partition,
)

_ORDER = {"drop": 0, "burst": 1, "corrupt": 2, "duplicate": 3, "delay": 4}


class _Scope:
    """Which directed links a link fault applies to, in UAV ids."""

    __slots__ = ("uavs", "links")

    def __init__(self, fault: LinkFault, ids: Mapping[str, int]):
        self.uavs = frozenset(ids[n] for n in fault.uavs)
        self.links = frozenset((ids[a], ids[b]) for a, b in fault.links)

    def covers(self, src: int, dst: int) -> bool:
        if self.uavs and src not in self.uavs and dst not in self.uavs:
            return False
        if self.links and (src, dst) not in self.links:
            return False
        return True


class FaultInjector:
    def __init__(self, schedule: FaultSchedule, ids: Mapping[str, int]):
        self.schedule = schedule
        self._ids = ids
        self.fired: dict[str, int] = {k: 0 for k in schedule.kinds()}
        self._link: list[tuple[LinkFault, _Scope]] = []
        self._partitions: list[tuple[Partition, dict[int, int]]] = []
        self._burst_bad: dict[tuple[int, int, int], bool] = {}
        self._active: list[tuple[LinkFault, _Scope]] = []
        self._active_partitions: list[tuple[Partition, dict[int, int]]] = []
        for f in schedule.faults:
            self._register(f)

    def _register(self, f: Fault) -> None:
        self.fired.setdefault(f.kind, 0)
        if isinstance(f, Partition):
            group_of = {self._ids[n]: gi for gi, g in enumerate(f.groups) for n in g}
            self._partitions.append((f, group_of))
        elif isinstance(f, LinkFault):
            self._link.append((f, _Scope(f, self._ids)))

    def add(self, f: Fault) -> None:
        """Add a fault while the run goes on (the simulator times node faults itself)."""
        self.schedule.add(f)
        self._register(f)

    def note_fired(self, kind: str, n: int = 1) -> None:
        self.fired[kind] = self.fired.get(kind, 0) + n

    # --- per tick ---------------------------------------------------------------------------

    def begin_tick(self, t: float) -> None:
        """Select the faults active at ``t`` (windows are half-open: ``[start, end)``)."""
        # Fixed order whatever the schedule's order: a copy that is dropped is never counted as
        # corrupted, duplicated or delayed.
        active = [(f, s) for f, s in self._link if f.active(t)]
        self._active = sorted(active, key=lambda fs: _ORDER[fs[0].kind])
        self._active_partitions = [(p, g) for p, g in self._partitions if p.active(t)]

    def blocked(self, src: int, dst: int) -> bool:
        for p, group_of in self._active_partitions:
            if p.separates(group_of.get(src), group_of.get(dst)):
                return True
        return False

    @property
    def idle(self) -> bool:
        return not self._active and not self._active_partitions

    # --- the radio's LinkFilter -------------------------------------------------------------

    def filter(self, t: float, src: int, dst: int, data: bytes,
               rng: np.random.Generator) -> tuple[list[tuple[float, bytes]], str | None]:
        if self.blocked(src, dst):
            self.fired["partition"] += 1
            return [], "partition"
        if not self._active:
            return [(0.0, data)], None
        extra = 0.0
        n_copies = 1
        for f, scope in self._active:
            if not scope.covers(src, dst):
                continue
            if type(f) is Drop:
                if rng.random() < f.rate:
                    self.fired["drop"] += 1
                    return [], "drop"
            elif type(f) is Burst:
                key = (id(f), src, dst)
                bad = self._burst_bad.get(key, False)
                bad = (rng.random() >= f.p_exit_bad) if bad else (rng.random() < f.p_enter_bad)
                self._burst_bad[key] = bad
                if rng.random() < (f.loss_bad if bad else f.loss_good):
                    self.fired["burst"] += 1
                    return [], "burst"
            elif type(f) is Corrupt:
                if rng.random() < f.rate and data:
                    buf = bytearray(data)
                    pos = rng.choice(len(buf), size=min(f.bytes, len(buf)), replace=False)
                    flips = rng.integers(1, 256, size=len(pos))  # never 0: each byte really changes
                    for p, x in zip(pos.tolist(), flips.tolist()):
                        buf[p] ^= x
                    data = bytes(buf)
                    self.fired["corrupt"] += 1
            elif type(f) is Duplicate:
                if rng.random() < f.rate:
                    n_copies += 1
                    self.fired["duplicate"] += 1
            elif type(f) is Delay:
                extra += f.extra_s + (f.jitter_s * rng.random() if f.jitter_s > 0 else 0.0)
                self.fired["delay"] += 1
        return [(extra, data)] * n_copies, None
