"""The event log's schema: every event kind once, as a typed record, with its fields in log order.

On disk (``events.msgpack``, :mod:`swarm.kernel.recorder`) an event is a flat msgpack array
``[kind, t, field, ...]``. This module is the one place that knows which field sits where:
each kind is a record class below whose fields are, in order, the array's items after the
kind (``t`` first), then the fields derived when reading:

* a UAV id field gets the UAV's name beside it, at the end (``uav`` -> ``uav_name``, ``src`` ->
  ``src_name``, ...), from the ``start`` header and the ``join`` and ``restart`` events; the
  ids stay (``None`` for a name nobody gave: a spoofer's ``src`` -1);
* a mode is written as a code (``comms.messages.MODE_NAMES``) and read as its name
  (``"search"``, ``"surveil"``).

Units are in the annotations (:class:`Meta`: ``Seconds`` is simulated seconds since the run
began, ``Metres`` are from the area's south-west corner, ``Radians`` a heading from east,
counter-clockwise). ``KINDS`` is the schema as data: the recorder checks written events
against it (:attr:`swarm.kernel.recorder.EventLog.check_schema`), the readers decode through it
(:func:`read_events`, :func:`read_columns`, :class:`Decoder`) and the Parquet export builds its
columns from it (:mod:`swarm.export`). docs/outputs.md's table of kinds is
:func:`markdown_table`; the order of a tick's events is documented there too ("Order within a
tick").

Records are slots dataclasses, not tuples: a reader names the field it wants (``e.x``), and
indexing a record by position fails loudly instead of reading the wrong field. They are not
frozen: a frozen dataclass costs four times as much to build (1.2 against 0.3 microseconds for
a pose), and live subscribers and full-log readers build one per event. Treat them as read-only.

The simulation writes an event as the log's array, a tuple (three times cheaper than a record,
and the bytes are the same; nothing is converted unless someone subscribes), made by this
module's writer of its kind: one function per kind, named after it (:func:`pose`,
:func:`found`, ...), whose arguments are keywords, so that a write site names every field and
never knows their order (a :data:`Wire`, the one type the recorder takes). A tick's many
``target`` events are packed from arrays by :func:`pack_target_events`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import typing
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from operator import itemgetter
from typing import Annotated, Any, ClassVar, NewType

import msgpack
import numpy as np

from comms.messages import MODE_NAMES
from swarm.errors import SwarmError, UsageError

__all__ = [
    "KINDS",
    "MODE_CODES",
    "NAMING_KINDS",
    "Crash",
    "EnergyOut",
    "Landed",
    "Launched",
    "Relief",
    "ReturnToBase",
    "Wind",
    "Decoder",
    "Event",
    "EventLogError",
    "EventRecords",
    "FaultOff",
    "FaultOn",
    "FieldSpec",
    "Found",
    "Handover",
    "Host",
    "Join",
    "KindSpec",
    "Lost",
    "Meta",
    "Mode",
    "Pause",
    "Pose",
    "Radio",
    "Release",
    "Restart",
    "Resume",
    "Rx",
    "Start",
    "Target",
    "Violation",
    "PROVENANCE_KEY",
    "Wire",
    "crash",
    "energy_out",
    "fault_off",
    "fault_on",
    "found",
    "handover",
    "host",
    "join",
    "landed",
    "launched",
    "lost",
    "mode",
    "pack_target_events",
    "pause",
    "pose",
    "radio",
    "release",
    "relief",
    "restart",
    "resume",
    "rtb",
    "rx",
    "start",
    "target",
    "violation",
    "wind",
    "check_kinds",
    "check_log",
    "check_wire",
    "first_difference_s",
    "log_sha256",
    "markdown_table",
    "read_columns",
    "read_events",
    "records",
    "split_provenance",
    "to_wire",
    "uav_names",
    "wire_kind",
    "with_provenance",
]


class EventLogError(SwarmError, ValueError):
    """Bytes or an array that are not an event log this version can read (an unknown kind, an
    event with the wrong number of fields, a field of the wrong type)."""


# --- field annotations ----------------------------------------------------------------------------

VALUE, UAV, MODE, NAME = "value", "uav", "mode", "name"


@dataclass(frozen=True, slots=True)
class Meta:
    """What an annotation says about a field besides its Python type.

    ``unit``: the SI symbol of a quantity (``None`` for ids, names and labels). ``role``:
    ``"uav"`` a UAV id (it gets a name field); ``"mode"`` a mode, a code in the log and a name
    in a record; ``"name"`` a name derived when reading, of the id field ``of`` (only when the
    field ``when[0]`` equals ``when[1]``: a violation's second party is a UAV only for
    separation). ``label``: what a value without a unit is, for the docs."""

    unit: str | None = None
    role: str = VALUE
    of: str | None = None
    when: tuple[str, str] | None = None
    label: str = ""  # what the value is, for the docs when it has no unit


Seconds = Annotated[float, Meta("s")]  # simulated seconds since the run began
Metres = Annotated[float, Meta("m")]  # from the area's south-west corner (x east, y north)
MetresPerSecond = Annotated[float, Meta("m/s")]
Radians = Annotated[float, Meta("rad")]  # a heading: from east, counter-clockwise
ByteCount = Annotated[int, Meta("B")]  # bytes of frames on the air (MACs included)
FrameCount = Annotated[int, Meta("frames")]
UavId = Annotated[int, Meta(role=UAV)]  # a UAV's id: its index in the start header (-1: a spoofer)
TargetId = Annotated[int, Meta(label="target id")]  # a target's id (its index)
PlanTarget = Annotated[int, Meta(label="target id, -1: none")]  # the target a plan watches
ModeName = Annotated[str, Meta(role=MODE)]  # "search" or "surveil"
UavName = Annotated[str, Meta(label="UAV name")]  # written in the event itself


def _name_of(field: str, when: tuple[str, str] | None = None) -> Meta:
    return Meta(role=NAME, of=field, when=when)


# --- the records ------------------------------------------------------------------------------------


@dataclass(slots=True)
class Event:
    """Every record: its ``kind`` (a class constant, the array's first item) and time ``t``."""

    kind: ClassVar[str] = ""
    t: Seconds


@dataclass(slots=True)
class Start(Event):
    """The run's header, first in every log (scenario, seed, planner, UAVs, fault schedule)."""

    kind: ClassVar[str] = "start"
    # scenario, seed, planner, dt (s), uavs [[id, name, type], ...], targets and threats
    # (counts), faults (the schedule, as fault tables), and "recording" when not "frames".
    header: Annotated[dict[str, Any], Meta(label="table")]

    @property
    def uavs(self) -> dict[int, str]:
        """UAV id -> name of the UAVs the run began with."""
        return uav_names(self.header)


@dataclass(slots=True)
class Pose(Event):
    """A flying UAV's state at a tick, once per tick per flying UAV."""

    kind: ClassVar[str] = "pose"
    uav: UavId
    x: Metres
    y: Metres
    v: MetresPerSecond  # airspeed
    theta: Radians  # heading
    mode: ModeName  # its plan's mode
    target: PlanTarget
    uav_name: Annotated[str | None, _name_of("uav")]


@dataclass(slots=True)
class Target(Event):
    """A target's true position, every target every tick."""

    kind: ClassVar[str] = "target"
    target: TargetId
    x: Metres
    y: Metres


@dataclass(slots=True)
class Mode(Event):
    """A UAV's plan changed mode or target (logged before its pose of that tick)."""

    kind: ClassVar[str] = "mode"
    uav: UavId
    mode: ModeName
    target: PlanTarget
    uav_name: Annotated[str | None, _name_of("uav")]


@dataclass(slots=True)
class Found(Event):
    """A target first reported by a UAV's sensor (once per target)."""

    kind: ClassVar[str] = "found"
    target: TargetId
    uav: UavId
    uav_name: Annotated[str | None, _name_of("uav")]


@dataclass(slots=True)
class Release(Event):
    """The UAV that held a target stopped watching it and nobody holds it now."""

    kind: ClassVar[str] = "release"
    target: TargetId
    uav: UavId  # the owner that let go
    uav_name: Annotated[str | None, _name_of("uav")]


@dataclass(slots=True)
class Handover(Event):
    """A target passed from one watching UAV to another (docs/modelling.md)."""

    kind: ClassVar[str] = "handover"
    target: TargetId
    from_uav: UavId
    to_uav: UavId
    from_name: Annotated[str | None, _name_of("from_uav")]
    to_name: Annotated[str | None, _name_of("to_uav")]


@dataclass(slots=True)
class Rx(Event):
    """A frame copy a UAV read from its mailbox (recording level "frames")."""

    kind: ClassVar[str] = "rx"
    src: UavId  # the sender (-1: a spoofer)
    dst: UavId  # the reader
    bytes: ByteCount
    accepted: Annotated[bool, Meta(label="false: rejected")]  # malformed or failing its MAC
    src_name: Annotated[str | None, _name_of("src")]
    dst_name: Annotated[str | None, _name_of("dst")]


@dataclass(slots=True)
class Lost(Event):
    """A frame copy lost, with its cause (recording level "frames")."""

    kind: ClassVar[str] = "lost"
    src: UavId  # the sender (-1: a spoofer)
    dst: UavId  # the UAV it was for
    bytes: ByteCount
    # loss, bandwidth, receiver_down, mailbox_full, or the fault that took it: partition,
    # bridge, swizzle, jammer, drop, burst
    cause: Annotated[str, Meta(label="why, below")]
    src_name: Annotated[str | None, _name_of("src")]
    dst_name: Annotated[str | None, _name_of("dst")]


@dataclass(slots=True)
class Radio(Event):
    """A tick's radio totals since the previous one (recording level "summary" only)."""

    kind: ClassVar[str] = "radio"
    read: FrameCount  # frame copies read
    rejected: FrameCount  # of those, malformed or failing their MAC
    bytes_read: ByteCount
    lost: Annotated[dict[str, list[int]], Meta(label="cause: [copies, bytes]")]  # causes sorted


@dataclass(slots=True)
class Join(Event):
    """A UAV began to fly (at the start, or later: a join fault or add_uav)."""

    kind: ClassVar[str] = "join"
    uav: UavId
    uav_name: UavName
    x: Metres
    y: Metres


@dataclass(slots=True)
class Crash(Event):
    """A UAV went down (a crash, or the first half of a restart)."""

    kind: ClassVar[str] = "crash"
    uav: UavId
    uav_name: UavName


@dataclass(slots=True)
class Violation(Event):
    """A safety rule broken at a tick: two UAVs too close, or a UAV inside a threat."""

    kind: ClassVar[str] = "violation"
    invariant: Annotated[str, Meta(label="separation or threat")]
    uav: UavId
    other: Annotated[int, Meta(label="UAV id or threat index")]  # separation: the other UAV; threat: the threat
    uav_name: Annotated[str | None, _name_of("uav")]
    other_name: Annotated[str | None, _name_of("other", ("invariant", "separation"))]  # None for a threat


@dataclass(slots=True)
class Pause(Event):
    """A pause fault stopped a UAV's process (its airframe flies its last command)."""

    kind: ClassVar[str] = "pause"
    uav: UavId
    uav_name: Annotated[str | None, _name_of("uav")]


@dataclass(slots=True)
class Resume(Event):
    """A paused UAV's process runs again."""

    kind: ClassVar[str] = "resume"
    uav: UavId
    uav_name: Annotated[str | None, _name_of("uav")]


@dataclass(slots=True)
class Restart(Event):
    """A restarted UAV flies again with a fresh process, where it went down."""

    kind: ClassVar[str] = "restart"
    uav: UavId
    uav_name: UavName
    x: Metres
    y: Metres


@dataclass(slots=True)
class FaultOn(Event):
    """A node or sensing fault began to act on a UAV (clock_skew, nav_error, sensor, liar)."""

    kind: ClassVar[str] = "fault_on"
    fault: Annotated[str, Meta(label="fault kind")]
    uav: UavId
    uav_name: Annotated[str | None, _name_of("uav")]


@dataclass(slots=True)
class FaultOff(Event):
    """A node or sensing fault's window closed for a UAV it acted on."""

    kind: ClassVar[str] = "fault_off"
    fault: Annotated[str, Meta(label="fault kind")]
    uav: UavId
    uav_name: Annotated[str | None, _name_of("uav")]


# --- real-world missions (issue 26, swarm.kernel.mission): only runs with [wind] or [endurance] log these ---
@dataclass(slots=True)
class Wind(Event):
    """The wind every UAV drifts with from this tick to the next (mean plus gust), once per tick."""

    kind: ClassVar[str] = "wind"
    wx: MetresPerSecond  # towards east
    wy: MetresPerSecond  # towards north


@dataclass(slots=True)
class Relief(Event):
    """A watcher that must go home asked for relief on station (``asked``; ``by`` the time its
    energy says go), or went home with nobody to take its target over (``unrelieved``): rule 6
    of docs/modelling.md's assignment rules."""

    kind: ClassVar[str] = "relief"
    uav: UavId
    target: TargetId
    by: Seconds  # when it must go (asked); when it went (unrelieved)
    status: Annotated[str, Meta(label="asked or unrelieved")]
    uav_name: Annotated[str | None, _name_of("uav")]


@dataclass(slots=True)
class ReturnToBase(Event):
    """A UAV turned home: its energy left is what its way home takes against the wind plus the
    reserve, or it had asked for relief and its target is taken over."""

    kind: ClassVar[str] = "rtb"
    uav: UavId
    energy_wh: Annotated[float, Meta("Wh")]  # left
    needed_wh: Annotated[float, Meta("Wh")]  # to fly home, plus the reserve
    target: PlanTarget  # the target it watched when the energy said so (handed over first), -1: none
    uav_name: Annotated[str | None, _name_of("uav")]


@dataclass(slots=True)
class Landed(Event):
    """A returning UAV landed at its base (it no longer flies, senses or sends until it launches)."""

    kind: ClassVar[str] = "landed"
    uav: UavId
    energy_wh: Annotated[float, Meta("Wh")]  # left on landing
    uav_name: Annotated[str | None, _name_of("uav")]


@dataclass(slots=True)
class Launched(Event):
    """A UAV took off again from its base, turned around (a full battery), keeping its memory."""

    kind: ClassVar[str] = "launched"
    uav: UavId
    x: Metres
    y: Metres
    uav_name: Annotated[str | None, _name_of("uav")]


@dataclass(slots=True)
class EnergyOut(Event):
    """A UAV's energy ran out in flight: it is lost (a crash event follows)."""

    kind: ClassVar[str] = "energy_out"
    uav: UavId
    uav_name: Annotated[str | None, _name_of("uav")]


# --- embedding (issue 34, swarm.kernel.host): only runs a host changed log these ---
@dataclass(slots=True)
class Host(Event):
    """A host program changed the run (embedding API), at this tick boundary, before the tick.

    ``change`` is the call (``add_target``, ``add_uav``, ``add_fault``, ``take_control``,
    ``release_control``, ``set_state``, ``set_waypoint``), ``args`` its arguments as applied;
    what :func:`swarm.kernel.hostlog.schedule_recorded_host_changes` replays."""

    kind: ClassVar[str] = "host"
    change: Annotated[str, Meta(label="change")]  # the call's name
    args: Annotated[dict[str, Any], Meta(label="table")]  # its arguments as applied (UAVs by name)


# The kinds in the order docs/outputs.md lists them.
_RECORDS: tuple[type[Event], ...] = (
    Start, Pose, Target, Mode, Found, Release, Handover, Rx, Lost, Radio, Join, Crash, Violation,
    Pause, Resume, Restart, FaultOn, FaultOff, Wind, Relief, ReturnToBase, Landed, Launched, EnergyOut, Host,
)


# --- writing: one call per kind -------------------------------------------------------------------
# What the simulation writes: the log's array of an event, as a tuple, from the writer of its
# kind below. The arguments are keywords (a write site names each field; the order is known
# here only). tests/test_events.py checks each writer against its record: the written fields,
# in order, of the same types.

# An event as the log holds it: (kind, t, field, ...). For the type checker a type of its own,
# which only the writers make and the recorder takes (a plain tuple is refused); at run time
# the tuple itself (``Wire(x)`` returns ``x``: a NewType's call would cost a Python call an event).
if typing.TYPE_CHECKING:
    Wire = NewType("Wire", tuple[Any, ...])
else:
    Wire = tuple


def start(*, t: float, header: dict[str, Any]) -> Wire:
    return Wire(("start", t, header))


def pose(*, t: float, uav: int, x: float, y: float, v: float, theta: float, mode: int, target: int) -> Wire:
    return Wire(("pose", t, uav, x, y, v, theta, mode, target))


def target(*, t: float, target: int, x: float, y: float) -> Wire:
    return Wire(("target", t, target, x, y))


def mode(*, t: float, uav: int, mode: int, target: int) -> Wire:
    return Wire(("mode", t, uav, mode, target))


def found(*, t: float, target: int, uav: int) -> Wire:
    return Wire(("found", t, target, uav))


def release(*, t: float, target: int, uav: int) -> Wire:
    return Wire(("release", t, target, uav))


def handover(*, t: float, target: int, from_uav: int, to_uav: int) -> Wire:
    return Wire(("handover", t, target, from_uav, to_uav))


def rx(*, t: float, src: int, dst: int, bytes: int, accepted: bool) -> Wire:
    return Wire(("rx", t, src, dst, bytes, accepted))


def rx_many(*, t: float, dst: int, received: Iterable[tuple[int, int, bool]]) -> list[Wire]:
    """``[rx(t=t, src=src, dst=dst, bytes=n, accepted=ok) for src, n, ok in received]``, in one
    call: the frames a UAV read in a tick (the observer's per-frame hot path at recording level
    "frames")."""
    return [Wire(("rx", t, src, dst, n, ok)) for src, n, ok in received]


def lost(*, t: float, src: int, dst: int, bytes: int, cause: str) -> Wire:
    return Wire(("lost", t, src, dst, bytes, cause))


def radio(*, t: float, read: int, rejected: int, bytes_read: int, lost: dict[str, list[int]]) -> Wire:
    return Wire(("radio", t, read, rejected, bytes_read, lost))


def join(*, t: float, uav: int, uav_name: str, x: float, y: float) -> Wire:
    return Wire(("join", t, uav, uav_name, x, y))


def crash(*, t: float, uav: int, uav_name: str) -> Wire:
    return Wire(("crash", t, uav, uav_name))


def violation(*, t: float, invariant: str, uav: int, other: int) -> Wire:
    return Wire(("violation", t, invariant, uav, other))


def pause(*, t: float, uav: int) -> Wire:
    return Wire(("pause", t, uav))


def resume(*, t: float, uav: int) -> Wire:
    return Wire(("resume", t, uav))


def restart(*, t: float, uav: int, uav_name: str, x: float, y: float) -> Wire:
    return Wire(("restart", t, uav, uav_name, x, y))


def fault_on(*, t: float, fault: str, uav: int) -> Wire:
    return Wire(("fault_on", t, fault, uav))


def fault_off(*, t: float, fault: str, uav: int) -> Wire:
    return Wire(("fault_off", t, fault, uav))


def wind(*, t: float, wx: float, wy: float) -> Wire:
    return Wire(("wind", t, wx, wy))


def relief(*, t: float, uav: int, target: int, by: float, status: str) -> Wire:
    return Wire(("relief", t, uav, target, by, status))


def rtb(*, t: float, uav: int, energy_wh: float, needed_wh: float, target: int) -> Wire:
    return Wire(("rtb", t, uav, energy_wh, needed_wh, target))


def landed(*, t: float, uav: int, energy_wh: float) -> Wire:
    return Wire(("landed", t, uav, energy_wh))


def launched(*, t: float, uav: int, x: float, y: float) -> Wire:
    return Wire(("launched", t, uav, x, y))


def energy_out(*, t: float, uav: int) -> Wire:
    return Wire(("energy_out", t, uav))


def host(*, t: float, change: str, args: dict[str, Any]) -> Wire:
    return Wire(("host", t, change, args))


def _target_event_dtype(id_tag: bytes, id_type: str) -> np.dtype:
    """The msgpack bytes of one :func:`target` event, as a packed record: a fixarray of 5, the
    fixstr "target", float 64 t, the id (as msgpack writes that many bits of it) and float 64 x
    and y, big-endian."""
    fields: list[tuple[str, str]] = [("head", "S8"), ("tt", "u1"), ("t", ">f8")]
    if id_tag:
        fields.append(("it", "u1"))
    fields += [("i", id_type), ("xt", "u1"), ("x", ">f8"), ("yt", "u1"), ("y", ">f8")]
    return np.dtype(fields)


# (first id, last id + 1, id tag, id type): msgpack's positive fixint, uint 8, 16 and 32.
_ID_FORMS = ((0, 0x80, b"", "u1"), (0x80, 0x100, b"\xcc", "u1"), (0x100, 0x10000, b"\xcd", ">u2"),
             (0x10000, 0x100000000, b"\xce", ">u4"))


def pack_target_events(t: float, xy: np.ndarray) -> bytes:
    """``b"".join(msgpack.packb(target(t=t, target=i, x=x, y=y)) for i, (x, y) in enumerate(xy))``,
    from the arrays (``t`` a float, ``xy`` float64 (n, 2), n < 2**32): what the observer logs of
    every target each tick when there are many (tests/test_many_targets.py checks the bytes)."""
    n = len(xy)
    parts = []
    for lo, hi, tag, id_type in _ID_FORMS:
        if n <= lo:
            break
        k = min(n, hi) - lo
        rec = np.empty(k, _target_event_dtype(tag, id_type))
        rec["head"] = b"\x95\xa6target"
        rec["tt"] = rec["xt"] = rec["yt"] = 0xCB
        rec["t"] = t
        if tag:
            rec["it"] = tag[0]
        rec["i"] = np.arange(lo, lo + k)
        rec["x"] = xy[lo:lo + k, 0]
        rec["y"] = xy[lo:lo + k, 1]
        parts.append(rec.tobytes())
    return b"".join(parts)


# --- the schema as data -----------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class FieldSpec:
    """One field of a record: its name, Python type (``float``, ``int``, ``str``, ``bool`` or
    ``dict``), whether it may be ``None``, its :class:`Meta`, and the full annotation without
    them (``dict[str, list[int]]``: what a table's column type is made from)."""

    name: str
    py_type: type
    nullable: bool
    meta: Meta
    annotation: Any

    @property
    def unit(self) -> str | None:
        return self.meta.unit

    @property
    def role(self) -> str:
        return self.meta.role

    @property
    def written(self) -> bool:
        """In the log's array (else derived when reading: a name)."""
        return self.meta.role != NAME

    @property
    def wire_type(self) -> type:
        """The type of its value in the log (a mode is written as its int code)."""
        return int if self.meta.role == MODE else self.py_type


@dataclass(frozen=True, slots=True)
class KindSpec:
    """One event kind: its record class and fields (``fields``: all, in record order; ``wire``:
    those written, in array order after the kind; ``derived``: the names added when reading)."""

    kind: str
    cls: type[Event]
    fields: tuple[FieldSpec, ...]
    wire: tuple[FieldSpec, ...]
    derived: tuple[FieldSpec, ...]
    # Decoding plan (array indices, kind at 0): mode codes to names; per derived name, the id's
    # index and the condition (index, value) under which it names a UAV.
    mode_at: tuple[int, ...]
    name_at: tuple[tuple[int, int | None, str | None], ...]
    tables_at: tuple[int, ...]  # dict fields (a live decoder copies them)

    @property
    def arity(self) -> int:
        """Items of its array in the log, the kind included."""
        return 1 + len(self.wire)

    @property
    def doc(self) -> str:
        return (self.cls.__doc__ or "").strip().splitlines()[0]


def _field_spec(name: str, hint: Any) -> FieldSpec:
    meta = Meta()
    if typing.get_origin(hint) is Annotated:
        meta = next((m for m in hint.__metadata__ if isinstance(m, Meta)), meta)
        hint = hint.__origin__
    nullable = False
    args = typing.get_args(hint)
    if type(None) in args:
        nullable = True
        (hint,) = [a for a in args if a is not type(None)]
    base = typing.get_origin(hint) or hint  # dict[str, Any] -> dict
    return FieldSpec(name, base, nullable, meta, hint)


def _kind_spec(cls: type[Event]) -> KindSpec:
    hints = typing.get_type_hints(cls, include_extras=True)
    fields = tuple(_field_spec(f.name, hints[f.name]) for f in dataclasses.fields(cls))
    wire = tuple(f for f in fields if f.written)
    derived = tuple(f for f in fields if not f.written)
    # Written fields first, names after: a record's leading fields are the array's items.
    assert fields == wire + derived, f"{cls.__name__}: derived fields must come after the written ones"
    index = {f.name: 1 + i for i, f in enumerate(wire)}
    name_at = []
    for f in derived:
        when = f.meta.when
        # (a field that holds a UAV id only sometimes says when)
        assert f.meta.of in index and (when or fields[index[f.meta.of] - 1].role == UAV), f"{cls.__name__}.{f.name}"
        name_at.append((index[f.meta.of], index[when[0]] if when else None, when[1] if when else None))
    return KindSpec(cls.kind, cls, fields, wire, derived, tuple(index[f.name] for f in wire if f.role == MODE),
                    tuple(name_at), tuple(index[f.name] for f in wire if f.py_type is dict))


#: kind -> its schema, in the order docs/outputs.md lists them.
KINDS: dict[str, KindSpec] = {cls.kind: _kind_spec(cls) for cls in _RECORDS}

# Kinds that teach a reader UAV names (the start header; join and restart carry the name).
NAMING_KINDS = frozenset({"start", "join", "restart"})

#: Mode name -> the code the log writes (for readers that keep modes in numeric arrays).
MODE_CODES: dict[str, int] = {name: code for code, name in MODE_NAMES.items()}

#: The kind of an event array as the simulation emits it (``wire_kind(("pose", 1.0, ...))``).
wire_kind: typing.Callable[[Sequence[Any]], str] = itemgetter(0)


def uav_names(header: Mapping[str, Any]) -> dict[int, str]:
    """The id -> name table of a run's ``start`` header."""
    return {int(uid): str(name) for uid, name, *_type in header.get("uavs", [])}


def check_kinds(kinds: Iterable[str] | None) -> frozenset[str] | None:
    """``kinds`` as a set, refusing a name that is not an event kind (``None``: every kind)."""
    if kinds is None:
        return None
    wanted = frozenset([kinds] if isinstance(kinds, str) else kinds)
    unknown = sorted(wanted - KINDS.keys())
    if unknown:
        raise UsageError(f"unknown event kind(s) {', '.join(map(repr, unknown))}; the kinds are {', '.join(KINDS)}")
    return wanted


# --- decoding -------------------------------------------------------------------------------------


def _spec_of(wire: Sequence[Any]) -> KindSpec:
    try:
        spec = KINDS[wire[0]]
    except (KeyError, IndexError, TypeError):
        head = wire[0] if isinstance(wire, (list, tuple)) and wire else wire
        raise EventLogError(f"not an event: {head!r} is not an event kind (the kinds are {', '.join(KINDS)})") from None
    if len(wire) != spec.arity:
        raise EventLogError(f"a {spec.kind!r} event has {spec.arity} items ([kind, {', '.join(f.name for f in spec.wire)}]), "
                            f"this one {len(wire)}: {list(wire)!r:.200}")
    return spec


class Decoder:
    """Turns event arrays into records, in log order, learning UAV names as it goes (from the
    ``start`` header and ``join`` / ``restart`` events). ``names=False``: name fields stay
    ``None`` (ids only). ``live=True`` (the recorder's, for subscribers): a record's tables (the
    start header, a radio event's losses) are copies as the log will hold them (lists for
    tuples), so a subscriber sees what a reader of the file sees and cannot change what is
    written."""

    def __init__(self, *, names: bool = True, live: bool = False) -> None:
        self.names: dict[int, str] = {}
        self._with_names = names
        self._live = live

    def __call__(self, wire: Sequence[Any]) -> Event:
        spec = _spec_of(wire)
        if self._live and spec.tables_at:
            wire = list(wire)
            for i in spec.tables_at:
                wire[i] = msgpack.unpackb(msgpack.packb(wire[i], use_bin_type=True), raw=False, strict_map_key=False)
        if spec.mode_at or spec.name_at:
            args = list(wire)
            for i in spec.mode_at:
                code = args[i]
                try:
                    args[i] = MODE_NAMES[code]
                except (KeyError, TypeError):
                    raise EventLogError(f"a {spec.kind!r} event has mode {code!r}, not one of {MODE_NAMES}") from None
            table = self.names if self._with_names else {}
            for id_at, cond_at, cond in spec.name_at:
                args.append(table.get(args[id_at]) if cond_at is None or args[cond_at] == cond else None)
            record = spec.cls(*args[1:])
        else:
            record = spec.cls(*wire[1:])
        if spec.kind in NAMING_KINDS:
            self.learn(record)
        return record

    def learn(self, record: Event) -> None:
        if isinstance(record, Start):
            self.names.update(record.uavs)
        elif isinstance(record, (Join, Restart)):
            self.names[record.uav] = record.uav_name


def to_wire(record: Event) -> tuple[Any, ...]:
    """The array a record is written as: ``(kind, t, ...)`` (mode names back to codes; the
    derived names dropped)."""
    spec = KINDS[record.kind]
    values = [getattr(record, f.name) for f in spec.wire]
    for i in spec.mode_at:
        values[i - 1] = MODE_CODES[values[i - 1]]
    return (spec.kind, *values)


def check_wire(wire: Sequence[Any]) -> None:
    """Raise :class:`EventLogError` unless ``wire`` is an event array as the schema defines it:
    a known kind, its number of items, and each field of its type (``float`` fields: a float)."""
    spec = _spec_of(wire)
    for f, value in zip(spec.wire, wire[1:]):
        want = f.wire_type
        ok = (isinstance(value, want) and not (want is int and isinstance(value, bool))) or (value is None and f.nullable)
        if not ok:
            raise EventLogError(f"a {spec.kind!r} event's {f.name} should be {want.__name__}, "
                                f"found {type(value).__name__} {value!r:.80}: {list(wire)!r:.200}")


# --- the file's provenance record ------------------------------------------------------------------
# A written ``events.msgpack`` may begin with one msgpack *map* ``{"provenance": {...}}`` (the
# versions that produced it: swarm.provenance) before the events, which are arrays. It is not an
# event and not hashed: the event-log hash (metrics.json's event_log_sha256) is of the events
# alone, so it does not change with the machine or a release that changes nothing the run does.
PROVENANCE_KEY = "provenance"


def with_provenance(events: bytes, provenance: Mapping[str, Any]) -> bytes:
    """The bytes of an ``events.msgpack`` file: the provenance record, then the events."""
    header: bytes = msgpack.packb({PROVENANCE_KEY: dict(provenance)}, use_bin_type=True)
    return header + events


def split_provenance(data: bytes) -> tuple[dict[str, Any] | None, bytes]:
    """``(provenance, events)`` of an event log file's bytes (``None`` when it has no record)."""
    if not data or not (0x80 <= data[0] <= 0x8F or data[0] in (0xDE, 0xDF)):  # not a msgpack map
        return None, data
    unpacker = msgpack.Unpacker(raw=False, strict_map_key=False)
    unpacker.feed(data)
    try:
        head = unpacker.unpack()
    except (msgpack.OutOfData, ValueError) as exc:
        raise EventLogError(f"the event log's provenance record cannot be read ({exc})") from None
    if not isinstance(head, dict) or not isinstance(head.get(PROVENANCE_KEY), dict):
        raise EventLogError(f"the event log begins with {head!r:.80}, neither an event nor its provenance record")
    return head[PROVENANCE_KEY], data[unpacker.tell():]


def log_sha256(data: bytes) -> str:
    """The event-log hash of a log's bytes, as ``metrics.json`` records it: the SHA-256 of its
    events (the provenance record left out)."""
    return hashlib.sha256(split_provenance(bytes(data))[1]).hexdigest()


def _unpacker(data: bytes) -> msgpack.Unpacker:
    unpacker = msgpack.Unpacker(raw=False, strict_map_key=False)
    unpacker.feed(split_provenance(data)[1])
    return unpacker


def check_log(data: bytes) -> int:
    """The number of events of a log's bytes, each checked against the schema; raises
    :class:`EventLogError` for a log that is damaged, empty or cut short (a log cut inside an
    event would otherwise read as a shorter one: the unpacker stops at the last whole event)."""
    events = split_provenance(bytes(data))[1]
    unpacker = msgpack.Unpacker(raw=False, strict_map_key=False)
    unpacker.feed(events)
    count = 0
    try:
        for wire in unpacker:
            check_wire(wire)
            count += 1
    except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError) as exc:
        raise EventLogError(f"the event log is damaged after {count} events ({exc})") from None
    if unpacker.tell() != len(events):
        raise EventLogError(f"the event log is cut short: {len(events) - unpacker.tell()} bytes after the last whole event "
                            f"(the run that wrote it did not finish writing)")
    if count == 0:
        raise EventLogError("the event log holds no events")
    return count


def first_difference_s(a: bytes, b: bytes) -> float | None:
    """The time of the first event at which two logs differ (the first tick whose events
    differ), ``None`` when their events are the same; provenance records are not compared."""
    left, right = iter(_unpacker(a)), iter(_unpacker(b))
    while True:
        x, y = next(left, None), next(right, None)
        if x == y:
            if x is None:
                return None
            continue
        times = [float(e[1]) for e in (x, y) if e is not None]  # (index 1 of every event array is its t)
        return min(times)


class EventRecords:
    """The records of an event log's bytes (:func:`read_events`). Iterating decodes the bytes
    afresh each time, so it can be read twice (or ``list()``-ed once, to keep the records)."""

    def __init__(self, data: bytes, kinds: Iterable[str] | None = None, *, names: bool = True) -> None:
        self._data = bytes(data)
        self._kinds = check_kinds(kinds)
        self._names = names

    def __iter__(self) -> Iterator[Event]:
        decode = Decoder(names=self._names)
        wanted = self._kinds
        for wire in _unpacker(self._data):
            if wanted is None:
                yield decode(wire)
            elif wire_kind(wire) in wanted:
                yield decode(wire)
            elif wire_kind(wire) in NAMING_KINDS:
                decode(wire)  # (names for the kinds asked for)

    def __repr__(self) -> str:
        kinds = "every kind" if self._kinds is None else ", ".join(sorted(self._kinds))
        return f"<EventRecords of {len(self._data)} bytes: {kinds}>"


def read_events(data: bytes, kinds: Iterable[str] | None = None, *, names: bool = True) -> EventRecords:
    """The events of an ``events.msgpack`` file's bytes (or ``RunResult.events``) as records
    (:class:`Pose`, :class:`Found`, ...), in log order; only ``kinds`` if given. Re-iterable:
    each ``for`` decodes the bytes again. UAV names come from the ``start`` header and the
    ``join`` / ``restart`` events (``names=False``: ids only, the name fields ``None``)."""
    return EventRecords(data, kinds, names=names)


def read_columns(data: bytes, kinds: Iterable[str] | None = None, *, positions: bool = False
                 ) -> dict[str, dict[str, list[Any]]]:
    """The event log by kind, as columns: ``{kind: {field: values}}`` with the fields of the
    kind's record (derived names and mode names included), every kind asked for present (with
    empty columns when the log has none). Cheaper than records for bulk reading (replays,
    exports): no object per event. Names come from the whole log (a UAV's id never changes
    name). ``positions``: also ``"seq"`` first, each event's index in the log (0: ``start``),
    which orders events across kinds."""
    wanted = check_kinds(kinds)
    chosen = [k for k in KINDS if wanted is None or k in wanted]
    rows: dict[str, list[Sequence[Any]]] = {k: [] for k in chosen}
    seq: dict[str, list[int]] = {k: [] for k in chosen}
    learn = Decoder()
    for i, wire in enumerate(_unpacker(data)):
        spec = _spec_of(wire)
        if spec.kind in NAMING_KINDS:
            learn(wire)
        bucket = rows.get(spec.kind)
        if bucket is not None:
            bucket.append(wire)
            seq[spec.kind].append(i)
    table = learn.names
    out: dict[str, dict[str, list[Any]]] = {}
    for kind in chosen:
        spec = KINDS[kind]
        got = rows[kind]
        items = list(zip(*got)) if got else [() for _ in range(spec.arity)]
        columns: dict[str, list[Any]] = {"seq": seq[kind]} if positions else {}
        columns.update({f.name: list(items[i]) for i, f in enumerate(spec.wire, start=1)})
        for i in spec.mode_at:
            name = spec.wire[i - 1].name
            try:
                columns[name] = [MODE_NAMES[c] for c in columns[name]]
            except KeyError as exc:
                raise EventLogError(f"a {kind!r} event has mode {exc.args[0]!r}, not one of {MODE_NAMES}") from None
        for f, (id_at, cond_at, cond) in zip(spec.derived, spec.name_at):
            ids = items[id_at]
            if cond_at is None:
                columns[f.name] = [table.get(u) for u in ids]
            else:
                columns[f.name] = [table.get(u) if c == cond else None for u, c in zip(ids, items[cond_at])]
        out[kind] = columns
    return out


def records(kind: str, columns: Mapping[str, Sequence[Any]]) -> list[Event]:
    """The records of one kind from its columns (as :func:`read_columns` gives them)."""
    spec = KINDS[kind]
    return [spec.cls(*row) for row in zip(*(columns[f.name] for f in spec.fields))]


# --- documentation ----------------------------------------------------------------------------------


def _describe(f: FieldSpec) -> str:
    if f.role == UAV:
        note = "UAV id"
    elif f.role == MODE:
        note = "search or surveil"
    else:
        note = f.unit or f.meta.label
    return f"`{f.name}`" + (f" ({note})" if note else "")


def markdown_table() -> str:
    """The kinds and their fields as the Markdown table docs/outputs.md shows (a test keeps the
    two the same)."""
    lines = ["| kind | when | fields in log order (unit) | added when read |", "|---|---|---|---|"]
    for spec in KINDS.values():
        written = ", ".join(_describe(f) for f in spec.wire)
        derived = ", ".join(f"`{f.name}`" for f in spec.derived) or "-"
        lines.append(f"| `{spec.kind}` | {spec.doc} | {written} | {derived} |")
    return "\n".join(lines) + "\n"
