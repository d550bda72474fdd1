"""Faults as data: timed, typed events that a run applies and records (the public names).

UAVs are named by their scenario names (``"B1"``); the injector resolves names to ids. Link
faults act on frame copies while ``start_s <= t < end_s`` and can be restricted to frames from
or to some UAVs (``uavs``) or to directed links (``links``). Node events (crash, join,
restart) happen once at ``at_s``; the other node and sensing faults (pause, clock_skew,
nav_error, sensor, liar) act on their UAVs' ticks in their window (:mod:`faults.tick`).

Each kind is defined once, with its behaviour and its excuses, in the module of its family
(:mod:`faults.link`, :mod:`faults.cuts`, :mod:`faults.node`, :mod:`faults.sensing`,
:mod:`faults.adversary`) and listed once, by registering (:data:`FAULT_KINDS`). This module
gathers their names for ``from faults.schedule import ...``.
"""

from __future__ import annotations

from faults.adversary import Liar, Spoofer
from faults.base import PHANTOM_TARGET_ID, FaultKind, Windowed
from faults.cuts import Bridge, Jammer, Partition, Swizzle
from faults.energy import Battery
from faults.link import Burst, Corrupt, Delay, Drop, Duplicate, LinkFault
from faults.node import Crash, Join, Pause, Restart
from faults.registry import FAULT_KINDS, FaultSchedule, fault_from_dict, fault_to_dict, register, uav_names
from faults.sensing import ClockSkew, NavError, Sensor
from faults.tick import TickFault

# Any fault: an instance of a registered kind.
Fault = FaultKind

__all__ = [
    "FAULT_KINDS", "PHANTOM_TARGET_ID", "Battery", "Bridge", "Burst", "ClockSkew", "Corrupt", "Crash", "Delay", "Drop",
    "Duplicate", "Fault", "FaultKind", "FaultSchedule", "Jammer", "Join", "Liar", "LinkFault", "NavError",
    "Partition", "Pause", "Restart", "Sensor", "Spoofer", "Swizzle", "TickFault", "Windowed",
    "fault_from_dict", "fault_to_dict", "register", "uav_names",
]
