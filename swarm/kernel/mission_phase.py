"""The mission phase's interface (issue 33): what the simulation calls each tick, and the phase
of a run without ``[wind]`` or ``[endurance]``, which does nothing (:mod:`swarm.kernel.mission` is the
real one; importing it, and shapely with it, is left to runs that have those tables)."""

from __future__ import annotations

from typing import Protocol

from agents.actor import SensorReading

__all__ = ["NO_MISSION", "MissionPhase"]


class MissionPhase(Protocol):
    def begin_tick(self, t: float) -> None:
        """At the start of the tick at ``t``, after the faults' start."""

    def sense(self, t: float, alive: list[int], readings: dict[int, SensorReading]) -> None:
        """After the tick faults acted on the readings."""


class _NoMission:
    def begin_tick(self, t: float) -> None:
        pass

    def sense(self, t: float, alive: list[int], readings: dict[int, SensorReading]) -> None:
        pass


NO_MISSION: MissionPhase = _NoMission()
