"""Faults on a UAV's process: crash, join, restart (once, at ``at_s``) and pause (a window)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar, Literal

from faults.base import START, UAV, Draws, FaultEvents, FaultHost, FaultKind
from faults.registry import register
from faults.tick import TickFault, TickFaults


@register
@dataclass(frozen=True, kw_only=True)
class Crash(FaultKind):
    """Fail-stop: the UAV stops sensing, sending, receiving and moving at ``at_s`` (one not yet
    joined never flies)."""

    uav: str = field(metadata=UAV)
    at_s: float = field(metadata={"ge": 0})
    kind: ClassVar[Literal["crash"]] = "crash"
    shrink_rank: ClassVar[int] = 100
    min_uavs: ClassVar[int] = 1

    @classmethod
    def generate(cls, d: Draws) -> Crash:
        return cls(uav=d.draw(d.names()), at_s=d.draw(d.times()))

    def install(self, host: FaultHost, index: int) -> None:
        uid = host.uid(self.uav)

        def crash() -> None:
            if host.state(uid) != "crashed":
                host.fired(self.kind)
                host.fail_stop(uid)

        host.at(max(self.at_s, host.now), crash)

    def absence(self) -> tuple[float, float]:
        return (self.at_s, math.inf)


@register
@dataclass(frozen=True, kw_only=True)
class Join(FaultKind):
    """The UAV enters the world at ``at_s`` (a late joiner)."""

    uav: str = field(metadata=UAV)
    at_s: float = field(metadata={"ge": 0})
    kind: ClassVar[Literal["join"]] = "join"
    applied_by_loader: ClassVar[bool] = True  # (the UAV's join_s)
    shrink_rank: ClassVar[int] = 110
    min_uavs: ClassVar[int] = 1
    min_ticks: ClassVar[int] = 2
    joins_late: ClassVar[bool] = True

    @classmethod
    def generate(cls, d: Draws) -> Join:
        """At one tick or later (a join at 0 is no fault)."""
        return cls(uav=d.draw(d.names()), at_s=d.draw(d.times(min_s=d.step_s)))

    def install(self, host: FaultHost, index: int) -> None:
        host.set_join(host.uid(self.uav), self.at_s)


@register
@dataclass(frozen=True, kw_only=True)
class Restart(FaultKind):
    """Crash at ``at_s``, then rejoin ``downtime_s`` later where it went down (same speed and
    heading), with an empty memory (map, tracks, peers, scan log, planner, a new random
    stream): a reboot that loses everything not flown. Its mailbox and counters carry over. A
    UAV not flying at ``at_s`` is not restarted."""

    uav: str = field(metadata=UAV)
    at_s: float = field(metadata={"ge": 0})
    downtime_s: float = field(metadata={"gt": 0, "note": "s between the crash and the rejoin"})
    kind: ClassVar[Literal["restart"]] = "restart"
    shrink_rank: ClassVar[int] = 130
    min_uavs: ClassVar[int] = 1
    min_ticks: ClassVar[int] = 3

    @classmethod
    def generate(cls, d: Draws) -> Restart:
        """Back at least one tick later and before the end: ``at_s + downtime_s < duration_s``."""
        at = d.draw(d.st.integers(0, d.steps - 3))
        down = d.draw(d.st.integers(1, d.steps - 2 - at))
        return cls(uav=d.draw(d.names()), at_s=at * d.step_s, downtime_s=down * d.step_s)

    def span(self) -> tuple[float, float]:
        return (self.at_s, self.at_s + self.downtime_s)

    def absence(self) -> tuple[float, float]:
        return self.span()

    def install(self, host: FaultHost, index: int) -> None:
        uid = host.uid(self.uav)
        at = max(self.at_s, host.now)
        took_down = [False]  # only the restart that took the UAV down brings it back

        def down() -> None:
            if host.state(uid) == "alive":
                host.fail_stop(uid, back_at=at + self.downtime_s)
                took_down[0] = True

        def up() -> None:
            if took_down[0]:
                took_down[0] = False
                host.fired(self.kind)
                host.revive(uid, ("restart", index))

        host.at(at, down)
        host.at(at + self.downtime_s, up)


@register
@dataclass(frozen=True, kw_only=True)
class Pause(TickFault):
    """The UAV's actor stops: no inbox, no planning, no sending, from ``start_s`` until ``end_s``.

    Its airframe keeps flying its last command, and its mailbox fills and overflows (frames
    lost as ``mailbox_full``) as a bounded mailbox does. Then it goes on where it stopped, with
    what it knew (a process pause, Jepsen's SIGSTOP / SIGCONT). While paused it reads no
    sensor (its scans count nowhere). A UAV on its first tick (just joined or restarted) has no
    last command and is paused from its second."""

    uav: str = field(metadata=UAV)
    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(metadata={"gt": 0, "note": "> start_s: when the actor resumes"})
    kind: ClassVar[Literal["pause"]] = "pause"
    impairs_control: ClassVar[bool] = True
    ends_with_process: ClassVar[bool] = True
    tick_order: ClassVar[int] = 3
    shrink_rank: ClassVar[int] = 120
    min_uavs: ClassVar[int] = 1

    @classmethod
    def generate(cls, d: Draws) -> Pause:
        """For a finite window (at least one tick) inside the run."""
        start, end = d.draw(d.windows(open_ended=False))
        return cls(uav=d.draw(d.names()), start_s=start, end_s=end)

    def disturbs_maps(self, t: float) -> bool:
        return self.active(t)  # a paused UAV merges nothing

    def absence(self) -> tuple[float, float]:
        return (self.start_s, self.end_s)

    def on_tick(self, faults: TickFaults, index: int, uid: int) -> None:
        if not faults.pausable(uid):
            return  # never woken yet (just joined or restarted): no last command to fly
        faults.paused.add(uid)
        if faults.first(index, uid):
            faults.events.pause(t=faults.t, uav=uid)
            faults.fired(self.kind, 1)

    def ended(self, events: FaultEvents, t: float, uid: int) -> None:
        events.resume(t=t, uav=uid)

