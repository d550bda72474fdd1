"""Faults as data: timed, typed events that a run applies and records.

UAVs are named by their scenario names (``"B1"``); the injector resolves names to ids. Link
faults act on frame copies while ``start_s <= t < end_s`` and can be restricted to frames from
or to some UAVs (``uavs``) or to directed links (``links``). Node faults (crash, join) happen
once at ``at_s``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field


@dataclass(frozen=True)
class LinkFault:
    start_s: float = 0.0
    end_s: float = math.inf
    uavs: tuple[str, ...] = ()
    links: tuple[tuple[str, str], ...] = ()

    def active(self, t: float) -> bool:
        return self.start_s <= t < self.end_s


@dataclass(frozen=True)
class Drop(LinkFault):
    """i.i.d. loss of each frame copy with probability ``rate``."""

    rate: float = 1.0
    kind = "drop"


@dataclass(frozen=True)
class Burst(LinkFault):
    """Gilbert-Elliott burst loss: a two-state chain per directed link, stepped per copy."""

    p_enter_bad: float = 0.1
    p_exit_bad: float = 0.3
    loss_good: float = 0.0
    loss_bad: float = 1.0
    kind = "burst"


@dataclass(frozen=True)
class Delay(LinkFault):
    """Extra latency plus uniform jitter in ``[0, jitter_s)``."""

    extra_s: float = 1.0
    jitter_s: float = 0.0
    kind = "delay"


@dataclass(frozen=True)
class Duplicate(LinkFault):
    rate: float = 0.5
    kind = "duplicate"


@dataclass(frozen=True)
class Corrupt(LinkFault):
    """Flip ``bytes`` random bytes of a copy with probability ``rate``."""

    rate: float = 0.5
    bytes: int = 1
    kind = "corrupt"


@dataclass(frozen=True)
class Partition:
    """Cut the links between groups from ``start_s`` until ``end_s`` (the heal time).

    ``one_way``: only frames from an earlier-listed group to a later-listed one are blocked.
    UAVs in no group are unaffected.
    """

    groups: tuple[tuple[str, ...], ...] = ()
    start_s: float = 0.0
    end_s: float = math.inf
    one_way: bool = False
    kind = "partition"

    def active(self, t: float) -> bool:
        return self.start_s <= t < self.end_s


@dataclass(frozen=True)
class Crash:
    """Fail-stop: the UAV stops sensing, sending, receiving and moving at ``at_s``."""

    uav: str = ""
    at_s: float = 0.0
    kind = "crash"


@dataclass(frozen=True)
class Join:
    """The UAV enters the world at ``at_s`` (a late joiner)."""

    uav: str = ""
    at_s: float = 0.0
    kind = "join"


Fault = Drop | Burst | Delay | Duplicate | Corrupt | Partition | Crash | Join
FAULT_KINDS: dict[str, type] = {
    cls.kind: cls for cls in (Drop, Burst, Delay, Duplicate, Corrupt, Partition, Crash, Join)
}


def fault_to_dict(f: Fault) -> dict:
    d = asdict(f)
    for k, v in list(d.items()):
        if isinstance(v, float) and math.isinf(v):
            d[k] = None
    return {"kind": f.kind, **d}


def fault_from_dict(d: dict) -> Fault:
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

    def kinds(self) -> list[str]:
        return sorted({f.kind for f in self.faults})

    def to_list(self) -> list[dict]:
        return [fault_to_dict(f) for f in self.faults]
