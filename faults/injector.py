"""Applies a fault schedule on the simulation clock and counts what actually fired.

Link faults plug into the radio as its :class:`comms.radio.LinkFilter`: each frame copy on a
directed link passes through the active faults in a fixed order (the cuts: partition, bridge,
swizzle; then jammer, drop, burst, corrupt, duplicate, delay), drawing only from that link's
random stream. Node faults (crash, join) are handed to the simulator as timed events; it
reports back when one took effect. A spoofer is not a link fault: the simulator makes its
frames (:meth:`FaultInjector.spoofer_due` says how many, from the fault's own stream).

``fired`` counts, per kind, the times a fault changed something (a copy blocked, dropped,
corrupted, duplicated or delayed; a UAV crashed or joined; a spoofed frame sent), so an inert
fault shows as 0.

Draws a fault makes for itself (the swizzle's subset and order, a spoofer's frames) come from
its own stream, ``fault_rng(kind, k)`` (the simulator's ``rng.generator("fault", kind, k)``,
``k`` the fault's index among the faults of its kind): no other stream shifts because of them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from faults.schedule import (
    Bridge,
    Burst,
    Corrupt,
    Delay,
    Drop,
    Duplicate,
    Fault,
    FaultSchedule,
    Jammer,
    LinkFault,
    Partition,
    Spoofer,
    Swizzle,
)

FaultRng = Callable[[str, int], np.random.Generator]

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


class _SwizzleState:
    """A swizzle's plan (drawn at its ``start_s``) and the UAVs clogged at the current tick."""

    __slots__ = ("fault", "index", "plan", "clogged")

    def __init__(self, fault: Swizzle, index: int):
        self.fault = fault
        self.index = index
        self.plan: dict[int, tuple[float, float]] | None = None
        self.clogged: frozenset[int] = frozenset()


class _SpooferState:
    """A spoofer's own stream, its fractional frame credit and its frame counter."""

    __slots__ = ("fault", "rng", "credit", "seq")

    def __init__(self, fault: Spoofer, rng: np.random.Generator):
        self.fault = fault
        self.rng = rng
        self.credit = 0.0
        self.seq = 0


def _default_fault_rng(kind: str, k: int) -> np.random.Generator:
    raise ValueError(f"a {kind} fault draws from its own stream: give FaultInjector a fault_rng")


class FaultInjector:
    def __init__(self, schedule: FaultSchedule, ids: Mapping[str, int], fault_rng: FaultRng | None = None):
        self.schedule = schedule
        self._ids = ids
        self._fault_rng = fault_rng or _default_fault_rng
        self.fired: dict[str, int] = {k: 0 for k in schedule.kinds()}
        self._link: list[tuple[LinkFault, _Scope]] = []
        # Partitions and bridges (as the partition they are), each with its group of every UAV.
        self._partitions: list[tuple[Partition, dict[int, int], str]] = []
        self._jammers: list[Jammer] = []
        self._swizzles: list[_SwizzleState] = []
        self._spoofers: list[_SpooferState] = []
        self._burst_bad: dict[tuple[int, int, int], bool] = {}
        self._active: list[tuple[LinkFault, _Scope]] = []
        self._active_partitions: list[tuple[Partition, dict[int, int], str]] = []
        self._active_jammers: list[Jammer] = []
        self._jammed: list[tuple[Jammer, frozenset[int]]] = []  # active jammers, UAVs inside
        self._clogged: frozenset[int] = frozenset()  # by any swizzle, this tick
        self._t = -math.inf
        for f in schedule.faults:
            self._register(f)

    def _register(self, f: Fault) -> None:
        self.fired.setdefault(f.kind, 0)
        if isinstance(f, (Partition, Bridge)):
            p = f.partition() if isinstance(f, Bridge) else f
            group_of = {self._ids[n]: gi for gi, g in enumerate(p.groups) for n in g}
            self._partitions.append((p, group_of, f.kind))
        elif isinstance(f, LinkFault):
            self._link.append((f, _Scope(f, self._ids)))
        elif isinstance(f, Jammer):
            self._jammers.append(f)
        elif isinstance(f, Swizzle):
            self._swizzles.append(_SwizzleState(f, len(self._swizzles)))
        elif isinstance(f, Spoofer):
            self._spoofers.append(_SpooferState(f, self._fault_rng("spoofer", len(self._spoofers))))
    def add(self, f: Fault) -> None:
        """Add a fault while the run goes on (the simulator times node faults itself)."""
        self.schedule.add(f)
        self._register(f)

    def note_fired(self, kind: str, n: int = 1) -> None:
        self.fired[kind] = self.fired.get(kind, 0) + n

    # --- per tick ---------------------------------------------------------------------------

    def begin_tick(self, t: float) -> None:
        """Select the faults active at ``t`` (windows are half-open: ``[start, end)``)."""
        self._t = t
        # Fixed order whatever the schedule's order: a copy that is dropped is never counted as
        # corrupted, duplicated or delayed.
        active = [(f, s) for f, s in self._link if f.active(t)]
        self._active = sorted(active, key=lambda fs: _ORDER[fs[0].kind])
        self._active_partitions = [pg for pg in self._partitions if pg[0].active(t)]
        self._active_jammers = [j for j in self._jammers if j.active(t)]
        self._jammed = []  # until set_positions: nobody is inside
        clogged: set[int] = set()
        for sw in self._swizzles:
            f = sw.fault
            if sw.plan is None and t >= f.start_s:
                # Drawn once, when the window opens (or at the first tick after a late add_fault).
                pool = sorted({self._ids[n] for n in f.uavs} if f.uavs else set(self._ids.values()))
                sw.plan = f.plan(pool, self._fault_rng("swizzle", sw.index))
            if sw.plan:
                sw.clogged = frozenset(u for u, (cut, restore) in sw.plan.items() if cut <= t < restore)
                clogged |= sw.clogged
        self._clogged = frozenset(clogged)

    def set_positions(self, ids: Sequence[int], xy: np.ndarray) -> None:
        """The live UAVs' positions of this tick (``xy`` shape (n, 2), rows in ``ids`` order):
        who is inside each active jammer's circle. Call after :meth:`begin_tick`, before the
        tick's frames are filtered."""
        if not self._active_jammers:
            return
        pts = np.asarray(xy, dtype=float).reshape(-1, 2)
        jammed = []
        for j in self._active_jammers:
            inside = np.hypot(pts[:, 0] - j.x_m, pts[:, 1] - j.y_m) <= j.radius_m
            jammed.append((j, frozenset(u for u, k in zip(ids, inside.tolist()) if k)))
        self._jammed = jammed

    def jammed(self) -> list[tuple[Jammer, frozenset[int]]]:
        """The active jammers of this tick, each with the UAVs inside its circle."""
        return list(self._jammed)

    def clogged(self) -> frozenset[int]:
        """The UAVs a swizzle has clogged at this tick."""
        return self._clogged

    def swizzle_plan(self, f: Swizzle) -> dict[int, tuple[float, float]] | None:
        """A swizzle's plan ``{uav id: (cut_s, restore_s)}`` once drawn (None before its start)."""
        for sw in self._swizzles:
            if sw.fault is f:
                return sw.plan
        raise KeyError(f"not a fault of this injector: {f!r}")

    def _cut(self, src: int, dst: int) -> str | None:
        """Why no copy passes from ``src`` to ``dst`` this tick (a cause), or None."""
        for p, group_of, kind in self._active_partitions:
            if p.separates(group_of.get(src), group_of.get(dst)):
                return kind
        if self._clogged and (src in self._clogged or dst in self._clogged):
            return "swizzle"
        return None

    def blocked(self, src: int, dst: int) -> bool:
        """Whether a partition, bridge or swizzle cuts ``src -> dst`` this tick."""
        return self._cut(src, dst) is not None

    @property
    def idle(self) -> bool:
        return not (self._active or self._active_partitions or self._active_jammers or self._clogged)

    # --- spoofers ---------------------------------------------------------------------------

    def spoofer_due(self, t: float, dt: float) -> list[tuple[Spoofer, int, np.random.Generator, int]]:
        """The active spoofers at ``t`` with the frames each sends this tick: ``(fault, n, its
        own stream, the number of its first frame)``. ``rate_per_s * dt`` frames a tick, the
        fractions carried over (no draw: 0.3 frames a tick sends one every third or fourth
        tick). Counts them as fired (frames transmitted, whoever is in range)."""
        due = []
        for sp in self._spoofers:
            f = sp.fault
            if not f.active(t):
                continue
            sp.credit += f.rate_per_s * dt
            n = int(sp.credit + 1e-9)  # (1e-9: 0.1 * 10 ticks makes one frame, not 0.999...)
            sp.credit -= n
            if n:
                due.append((f, n, sp.rng, sp.seq))
                sp.seq += n
                self.fired["spoofer"] += n
        return due

    # --- the radio's LinkFilter -------------------------------------------------------------

    def filter(self, t: float, src: int, dst: int, data: bytes,
               rng: np.random.Generator) -> tuple[list[tuple[float, bytes]], str | None]:
        if self.blocked(src, dst):  # (then _cut names the cause; blocked is what a test may replace)
            cut = self._cut(src, dst) or "partition"
            self.fired[cut] += 1
            return [], cut
        for j, inside in self._jammed:
            if (src in inside or dst in inside) and rng.random() < j.rate:
                self.fired["jammer"] += 1
                return [], "jammer"
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
