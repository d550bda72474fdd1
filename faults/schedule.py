"""Faults as data: timed, typed events that a run applies and records.

UAVs are named by their scenario names (``"B1"``); the injector resolves names to ids. Link
faults act on frame copies while ``start_s <= t < end_s`` and can be restricted to frames from
or to some UAVs (``uavs``) or to directed links (``links``). Node events (crash, join,
restart) happen once at ``at_s``; the other node and sensing faults (pause, clock_skew,
nav_error, sensor, liar) act on their UAVs' ticks in their window (swarm.node_faults).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np

# This module is the one definition of the fault kinds: their fields, defaults (a field without
# one is required, here and in a scenario's [[faults]] table) and the bounds a value must keep.
# Field metadata carries the bounds (``ge``, ``gt``, ``le``, ``lt``), a ``note`` on the unit or
# meaning, and for a field that is not a number the ``expected`` words of an error message.
# swarm.scenario.generated builds its [[faults]] tables from these classes, so the bounds are checked
# when a scenario loads; faults made in Python are taken as given (a test may want an extreme).
_START = {"ge": 0}
_END = {"gt": 0, "note": "> start_s; absent = until the end"}  # math.inf: absent from a scenario


class Windowed:
    """A fault that lasts over the half-open window ``[start_s, end_s)`` (the subclasses'
    fields: each declares its own defaults and bounds)."""

    start_s: float
    end_s: float

    def active(self, t: float) -> bool:
        return self.start_s <= t < self.end_s


@dataclass(frozen=True, kw_only=True)
class LinkFault(Windowed):
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
class Partition(Windowed):
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


@dataclass(frozen=True, kw_only=True)
class Pause(Windowed):
    """The UAV's actor stops: no inbox, no planning, no sending, from ``start_s`` until ``end_s``.

    Its airframe keeps flying its last command, and its mailbox fills and overflows (frames
    lost as ``mailbox_full``) as a bounded mailbox does. Then it goes on where it stopped, with
    what it knew (a process pause, Jepsen's SIGSTOP / SIGCONT). While paused it reads no
    sensor (its scans count nowhere). A UAV on its first tick (just joined or restarted) has no
    last command and is paused from its second."""

    uav: str = field(metadata=_UAV)
    start_s: float = field(default=0.0, metadata=_START)
    end_s: float = field(metadata={"gt": 0, "note": "> start_s: when the actor resumes"})
    kind: ClassVar[Literal["pause"]] = "pause"


@dataclass(frozen=True, kw_only=True)
class Restart:
    """Crash at ``at_s``, then rejoin ``downtime_s`` later where it went down (same speed and
    heading), with an empty memory (map, tracks, peers, scan log, planner, a new random
    stream): a reboot that loses everything not flown. Its mailbox and counters carry over. A
    UAV not flying at ``at_s`` is not restarted."""

    uav: str = field(metadata=_UAV)
    at_s: float = field(metadata={"ge": 0})
    downtime_s: float = field(metadata={"gt": 0, "note": "s between the crash and the rejoin"})
    kind: ClassVar[Literal["restart"]] = "restart"


@dataclass(frozen=True, kw_only=True)
class ClockSkew(Windowed):
    """While active the UAV's clock reads ``t + offset_s + drift * (t - start_s)``: every time
    it stamps (its scans, its frames, the tracks it sees) is skewed. Receivers ignore what is
    stamped later than their own clock (a max-CRDT would keep such cells fresh forever)."""

    uav: str = field(metadata=_UAV)
    start_s: float = field(default=0.0, metadata=_START)
    end_s: float = field(default=math.inf, metadata=_END)
    offset_s: float = field(default=0.0, metadata={"ge": -1.0e6, "le": 1.0e6, "note": "s"})
    drift: float = field(default=0.0, metadata={"ge": -0.5, "le": 0.5, "note": "s of error per s"})
    kind: ClassVar[Literal["clock_skew"]] = "clock_skew"

    def error(self, t: float) -> float:
        """The clock's error at true time ``t`` (while active)."""
        return self.offset_s + self.drift * (t - self.start_s)


@dataclass(frozen=True, kw_only=True)
class NavError(Windowed):
    """The UAV believes it is at its true position plus ``(bias_x_m, bias_y_m)`` plus Gaussian
    noise of ``noise_m`` per axis (drawn each tick): it plans, flies and stamps its scans there,
    while the ground truth senses where it really is."""

    uav: str = field(metadata=_UAV)
    start_s: float = field(default=0.0, metadata=_START)
    end_s: float = field(default=math.inf, metadata=_END)
    bias_x_m: float = field(default=0.0, metadata={"ge": -1.0e6, "le": 1.0e6, "note": "m"})
    bias_y_m: float = field(default=0.0, metadata={"ge": -1.0e6, "le": 1.0e6, "note": "m"})
    noise_m: float = field(default=0.0, metadata={"ge": 0, "le": 1.0e6, "note": "m, standard deviation per axis"})
    kind: ClassVar[Literal["nav_error"]] = "nav_error"


# Ids of phantom targets (false alarms, liars' tracks): far above any real target's.
PHANTOM_TARGET_ID = 1_000_000_000


@dataclass(frozen=True, kw_only=True)
class Sensor(Windowed):
    """Detection faults of ``uavs`` (empty: all): each target inside the detection radius is
    seen with probability ``p_detect`` per tick, and phantom targets (false alarms) appear in
    the detection disk at ``false_alarm_rate`` per UAV-second."""

    uavs: tuple[str, ...] = field(default=(), metadata={"expected": "an array of UAV names (empty = all)"})
    start_s: float = field(default=0.0, metadata=_START)
    end_s: float = field(default=math.inf, metadata=_END)
    p_detect: float = field(default=1.0, metadata=_PROBABILITY)
    false_alarm_rate: float = field(default=0.0, metadata={"ge": 0, "le": 100, "note": "phantoms per UAV-second"})
    kind: ClassVar[Literal["sensor"]] = "sensor"


@dataclass(frozen=True, kw_only=True)
class Jammer(Windowed):
    """A circle in which every frame copy to or from a UAV inside is lost with probability
    ``rate``."""

    x_m: float = field(metadata={"note": "m, the centre"})
    y_m: float = field(metadata={"note": "m, the centre"})
    radius_m: float = field(metadata={"gt": 0, "note": "m"})
    rate: float = field(default=1.0, metadata=_PROBABILITY)
    start_s: float = field(default=0.0, metadata=_START)
    end_s: float = field(default=math.inf, metadata=_END)
    kind: ClassVar[Literal["jammer"]] = "jammer"


@dataclass(frozen=True, kw_only=True)
class Bridge(Windowed):
    """A partition between ``groups`` in which the ``bridge`` UAV (taken out of any group that
    lists it) still talks to every side (Jepsen's bridge)."""

    groups: tuple[tuple[str, ...], ...] = field(
        metadata={"expected": "an array of at least 2 non-empty arrays of UAV names"}
    )
    bridge: str = field(metadata=_UAV)
    start_s: float = field(default=0.0, metadata=_START)
    end_s: float = field(default=math.inf, metadata=_END)
    kind: ClassVar[Literal["bridge"]] = "bridge"

    def partition(self) -> Partition:
        """The partition this bridge is: its groups without the bridge UAV (which is then in no
        group, so :meth:`Partition.separates` never blocks it), same window. The one definition
        of who a bridge separates, for the injector and the invariant checkers alike."""
        groups = tuple(tuple(n for n in g if n != self.bridge) for g in self.groups)
        return Partition(groups=groups, start_s=self.start_s, end_s=self.end_s)


@dataclass(frozen=True, kw_only=True)
class Swizzle(Windowed):
    """FoundationDB's swizzle-clog: at ``start_s`` a random ``count`` UAVs of ``uavs`` (empty:
    all) are drawn; their links are cut one UAV at a time over the first half of the window,
    then restored one at a time, in a random order, over the second half."""

    uavs: tuple[str, ...] = field(default=(), metadata={"expected": "an array of UAV names (empty = all)"})
    count: int = field(metadata={"ge": 1, "note": "UAVs clogged"})
    start_s: float = field(default=0.0, metadata=_START)
    end_s: float = field(metadata={"gt": 0, "note": "> start_s: when the last link is restored"})
    kind: ClassVar[Literal["swizzle"]] = "swizzle"

    def plan(self, pool: Sequence[int], rng: np.random.Generator) -> dict[int, tuple[float, float]]:
        """Who is clogged when: ``{uav: (cut_s, restore_s)}``, the UAV clogged while
        ``cut_s <= t < restore_s``. ``pool``: the candidate UAV ids (``uavs`` resolved, or every
        UAV), in id order; ``rng``: the fault's own stream. ``min(count, len(pool))`` of them are
        drawn, in the order they are cut; the k-th is cut at ``start_s + k * step`` (``step`` =
        half the window / the number drawn), and they are restored in a second random order,
        the k-th at ``start_s + half + (k + 1) * step``: the last one at ``end_s``. The one
        definition, for the injector and the invariant checkers."""
        n = min(self.count, len(pool))
        if n == 0:
            return {}
        chosen = [int(u) for u in rng.choice(np.asarray(pool, dtype=np.int64), size=n, replace=False)]
        restore_order = [chosen[int(i)] for i in rng.permutation(n)]
        half = 0.5 * (self.end_s - self.start_s)
        step = half / n
        cut = {u: self.start_s + k * step for k, u in enumerate(chosen)}
        return {u: (cut[u], self.start_s + half + (k + 1) * step) for k, u in enumerate(restore_order)}


@dataclass(frozen=True, kw_only=True)
class Liar(Windowed):
    """A Byzantine member (it holds the swarm key): it broadcasts scan records it never made
    (``scans_per_s``, uniform over the area, stamped now, under made-up origin ids since a
    receiver keeps one scan per origin and tick) and false target tracks (``tracks_per_s``,
    phantom targets at uniform positions), with its beacons."""

    uav: str = field(metadata=_UAV)
    start_s: float = field(default=0.0, metadata=_START)
    end_s: float = field(default=math.inf, metadata=_END)
    scans_per_s: float = field(default=1.0, metadata={"ge": 0, "le": 1000, "note": "fake scan records per s"})
    tracks_per_s: float = field(default=0.0, metadata={"ge": 0, "le": 1000, "note": "fake tracks per s"})
    kind: ClassVar[Literal["liar"]] = "liar"


@dataclass(frozen=True, kw_only=True)
class Spoofer(Windowed):
    """A transmitter that is not a swarm member: from ``(x_m, y_m)`` it sends ``rate_per_s``
    well-formed frames a second, with a forged sender (``as_uav``; empty: a random member per
    frame) and without the swarm key, to every live UAV within ``range_m``."""

    x_m: float = field(metadata={"note": "m"})
    y_m: float = field(metadata={"note": "m"})
    range_m: float = field(metadata={"gt": 0, "note": "m"})
    start_s: float = field(default=0.0, metadata=_START)
    end_s: float = field(default=math.inf, metadata=_END)
    rate_per_s: float = field(default=1.0, metadata={"gt": 0, "le": 1000, "note": "frames per s"})
    as_uav: str = field(default="", metadata={"expected": "a UAV name defined in [[uavs]], or \"\" (a random member per frame)"})
    kind: ClassVar[Literal["spoofer"]] = "spoofer"


Fault = (Drop | Burst | Delay | Duplicate | Corrupt | Partition | Crash | Join | Pause | Restart | ClockSkew
         | NavError | Sensor | Jammer | Bridge | Swizzle | Liar | Spoofer)
# In the order error messages list them ("kind = one of: drop, burst, partition, ...").
FAULT_KINDS: dict[str, type[Fault]] = {
    cls.kind: cls for cls in (Drop, Burst, Partition, Delay, Duplicate, Corrupt, Crash, Join, Pause, Restart,
                              ClockSkew, NavError, Sensor, Jammer, Bridge, Swizzle, Liar, Spoofer)
}
# Kinds that happen once, at ``at_s`` (the others have a window).
NODE_EVENT_KINDS = ("crash", "join", "restart")


def uav_names(f: Fault) -> list[tuple[tuple[str | int, ...], str]]:
    """Every UAV name a fault refers to, with its path inside the fault (``("groups", 0, 1)``):
    what a scenario's validation and ``Simulation.add_fault`` check against the UAVs."""
    names: list[tuple[tuple[str | int, ...], str]] = []
    for key in ("uav", "bridge"):
        if hasattr(f, key):
            names.append(((key,), getattr(f, key)))
    # (by name, not by type: a scenario's [[faults]] table is not an instance of the dataclass)
    as_uav = getattr(f, "as_uav", "")  # "" = a random member per frame
    if as_uav:
        names.append((("as_uav",), as_uav))
    for k, name in enumerate(getattr(f, "uavs", ())):
        names.append((("uavs", k), name))
    for k, pair in enumerate(getattr(f, "links", ())):
        for end, name in enumerate(pair):
            names.append((("links", k, end), name))
    for g, group in enumerate(getattr(f, "groups", ())):
        for k, name in enumerate(group):
            names.append((("groups", g, k), name))
    return names


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
