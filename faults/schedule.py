"""Faults as data: timed, typed events that a run applies and records.

UAVs are named by their scenario names (``"B1"``); the injector resolves names to ids. Link
faults act on frame copies while ``start_s <= t < end_s`` and can be restricted to frames from
or to some UAVs (``uavs``) or to directed links (``links``). Node faults (crash, join) happen
once at ``at_s``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any, ClassVar, Literal

# This module is the one definition of the fault kinds: their fields, defaults (a field without
# one is required, here and in a scenario's [[faults]] table) and the bounds a value must keep.
# Field metadata carries the bounds (``ge``, ``gt``, ``le``, ``lt``), a ``note`` on the unit or
# meaning, and for a field that is not a number the ``expected`` words of an error message.
# swarm.scenario.model builds its [[faults]] tables from these classes, so the bounds are checked
# when a scenario loads; faults made in Python are taken as given (a test may want an extreme).
_START = {"ge": 0}
_END = {"gt": 0, "note": "> start_s; absent = until the end"}  # math.inf: absent from a scenario


@dataclass(frozen=True, kw_only=True)
class LinkFault:
    """A fault on frame copies while ``start_s <= t < end_s``, on every link or on those from or
    to ``uavs`` (empty: all) and on the directed ``links`` (empty: all)."""

    start_s: float = field(default=0.0, metadata=_START)
    end_s: float = field(default=math.inf, metadata=_END)
    uavs: tuple[str, ...] = field(default=(), metadata={"expected": "an array of UAV names (empty = all)"})
    links: tuple[tuple[str, str], ...] = field(
        default=(), metadata={"expected": "an array of [sender, receiver] UAV name pairs (empty = all)"}
    )
    # Each kind's tag: a class variable, not a field (the subclasses give the value).
    kind: ClassVar[str]

    def active(self, t: float) -> bool:
        return self.start_s <= t < self.end_s


_PROBABILITY = {"ge": 0, "le": 1}


@dataclass(frozen=True, kw_only=True)
class Drop(LinkFault):
    """i.i.d. loss of each frame copy with probability ``rate``."""

    rate: float = field(metadata=_PROBABILITY)
    kind: ClassVar[Literal["drop"]] = "drop"


@dataclass(frozen=True, kw_only=True)
class Burst(LinkFault):
    """Gilbert-Elliott burst loss: a two-state chain per directed link, stepped per copy."""

    p_enter_bad: float = field(metadata=_PROBABILITY)
    p_exit_bad: float = field(metadata={"gt": 0, "le": 1})
    loss_good: float = field(default=0.0, metadata=_PROBABILITY)
    loss_bad: float = field(default=1.0, metadata=_PROBABILITY)
    kind: ClassVar[Literal["burst"]] = "burst"


@dataclass(frozen=True, kw_only=True)
class Delay(LinkFault):
    """Extra latency plus uniform jitter in ``[0, jitter_s)``."""

    extra_s: float = field(metadata={"ge": 0})
    jitter_s: float = field(default=0.0, metadata={"ge": 0})
    kind: ClassVar[Literal["delay"]] = "delay"


@dataclass(frozen=True, kw_only=True)
class Duplicate(LinkFault):
    """One more copy of a frame with probability ``rate``."""

    rate: float = field(metadata=_PROBABILITY)
    kind: ClassVar[Literal["duplicate"]] = "duplicate"


@dataclass(frozen=True, kw_only=True)
class Corrupt(LinkFault):
    """Flip ``bytes`` random bytes of a copy with probability ``rate``."""

    rate: float = field(metadata=_PROBABILITY)
    bytes: int = field(default=1, metadata={"ge": 1, "note": "bytes flipped per corrupted frame"})
    kind: ClassVar[Literal["corrupt"]] = "corrupt"


@dataclass(frozen=True, kw_only=True)
class Partition:
    """Cut the links between groups from ``start_s`` until ``end_s`` (the heal time).

    ``one_way``: only frames from an earlier-listed group to a later-listed one are blocked.
    UAVs in no group are unaffected.
    """

    groups: tuple[tuple[str, ...], ...] = field(
        metadata={"expected": "an array of at least 2 non-empty arrays of UAV names"}
    )
    start_s: float = field(default=0.0, metadata=_START)
    end_s: float = field(default=math.inf, metadata=_END)
    one_way: bool = False
    kind: ClassVar[Literal["partition"]] = "partition"

    def active(self, t: float) -> bool:
        return self.start_s <= t < self.end_s

    def separates(self, group_of_src: int | None, group_of_dst: int | None) -> bool:
        """Whether this partition, while active, blocks a frame from a UAV of group
        ``group_of_src`` to one of group ``group_of_dst`` (indices into ``groups``; None: the
        UAV is in no group)."""
        if group_of_src is None or group_of_dst is None or group_of_src == group_of_dst:
            return False
        return not self.one_way or group_of_src < group_of_dst


_UAV = {"expected": "a UAV name defined in [[uavs]]"}


@dataclass(frozen=True, kw_only=True)
class Crash:
    """Fail-stop: the UAV stops sensing, sending, receiving and moving at ``at_s``."""

    uav: str = field(metadata=_UAV)
    at_s: float = field(metadata={"ge": 0})
    kind: ClassVar[Literal["crash"]] = "crash"


@dataclass(frozen=True, kw_only=True)
class Join:
    """The UAV enters the world at ``at_s`` (a late joiner)."""

    uav: str = field(metadata=_UAV)
    at_s: float = field(metadata={"ge": 0})
    kind: ClassVar[Literal["join"]] = "join"


Fault = Drop | Burst | Delay | Duplicate | Corrupt | Partition | Crash | Join
# In the order error messages list them ("kind = one of: drop, burst, partition, ...").
FAULT_KINDS: dict[str, type[Fault]] = {
    cls.kind: cls for cls in (Drop, Burst, Partition, Delay, Duplicate, Corrupt, Crash, Join)
}


def fault_to_dict(f: Fault) -> dict[str, Any]:
    d = asdict(f)
    for k, v in list(d.items()):
        if isinstance(v, float) and math.isinf(v):
            d[k] = None
    return {"kind": f.kind, **d}


def fault_from_dict(d: Mapping[str, Any]) -> Fault:
    """Inverse of :func:`fault_to_dict` (validated input, e.g. a scenario's ``[[faults]]``)."""
    d = dict(d)
    cls = FAULT_KINDS[d.pop("kind")]
    if d.get("end_s", 0.0) is None:
        d["end_s"] = math.inf
    for key in ("uavs",):
        if key in d:
            d[key] = tuple(d[key])
    if "links" in d:
        d["links"] = tuple(tuple(p) for p in d["links"])
    if "groups" in d:
        d["groups"] = tuple(tuple(g) for g in d["groups"])
    return cls(**{k: v for k, v in d.items() if v is not None or k == "end_s"})


@dataclass
class FaultSchedule:
    """An ordered list of faults; what a run applied is recorded with it."""

    faults: list[Fault] = field(default_factory=list)

    def add(self, fault: Fault) -> None:
        self.faults.append(fault)

    def __iter__(self) -> Iterator[Fault]:
        return iter(self.faults)

    def __len__(self) -> int:
        return len(self.faults)

    def kinds(self) -> list[str]:
        return sorted({f.kind for f in self.faults})

    def to_list(self) -> list[dict[str, Any]]:
        return [fault_to_dict(f) for f in self.faults]
