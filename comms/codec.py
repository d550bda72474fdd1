"""msgpack frames: encode on send, decode and schema-check on receipt.

Wire format: one msgpack array followed by a 4-byte little-endian CRC-32 of it (the link
layer's frame check sequence: without it a flipped byte inside a float decodes as a valid but
wrong number, e.g. a scan time of 1e300 that would poison a map forever)::

    [MAGIC, VERSION, sender, seq, t, [[kind, field, ...], ...]] + crc32

With a swarm key (``[radio] auth = true``) the msgpack array is followed by its MAC, the first
:data:`MAC_BYTES` (16) bytes of HMAC-SHA256 under the key (a truncation RFC 2104 and NIST
SP 800-107 allow: 128 bits), and the CRC covers both::

    [MAGIC, VERSION, ...] + mac16 + crc32

The CRC is the link layer's and is checked first (a frame damaged in flight fails it); the MAC
then says whether a member of the swarm wrote the frame: one without the key (a spoofer, or a
sender without auth) cannot make it, and :func:`decode` raises :class:`AuthError` (a
:class:`FrameError`). The MAC proves origin, not freshness: a captured frame replayed verbatim
passes. Without a key nothing of this runs (no MAC written, none checked).

Decoding never trusts the bytes: size cap first, then the CRC, the MAC (with a key), msgpack
with container limits, then a strict shape and type check of every field. Anything wrong raises
:class:`FrameError`, which the receiver counts as a rejected frame and carries on. Decoding
is two steps: :func:`read` (the wire: size, CRC, MAC, msgpack, magic and version) gives a
:class:`FrameRecord`, whose header and messages the readers check (:func:`message_kind`,
:func:`read_hello`, ...); :func:`decode` builds a :class:`Frame` of them, a receiver on the tick
plane reads a record straight into what it keeps (:func:`agents.inbox.check_frame`).
"""

from __future__ import annotations

import hmac
import math
import zlib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol, cast

import msgpack

from comms.errors import SwarmError
from comms.messages import (
    Hello,
    Intent,
    Message,
    ScanDigest,
    ScanRecords,
    ThreatItem,
    Threats,
    TrackDigest,
    TrackItem,
    Tracks,
)

MAGIC = 0x5357  # "SW"
VERSION = 1
DEFAULT_MAX_BYTES = 65536
MAC_BYTES = 16  # HMAC-SHA256 truncated to 128 bits
# What a sender budgets in a frame: the bytes of one scan in a ScanRecords message (four msgpack
# floats) and the room it keeps for the frame's own header (and MAC and CRC).
SCAN_BYTES = 36
FRAME_SLACK = 256

K_HELLO, K_INTENT, K_SCAN, K_TRACKS, K_THREATS, K_DIGEST = 1, 2, 3, 4, 5, 6
K_TRACK_DIGEST = 7  # (issue 36, M1: tracks on change)


class FrameError(SwarmError, ValueError):
    """A received frame is malformed, truncated, oversized or fails the schema."""


class AuthError(FrameError):
    """A received frame fails its MAC (:func:`decode` with a key): written without the swarm key."""


def mac(key: bytes, payload: bytes) -> bytes:
    """The MAC of ``payload`` under ``key``: HMAC-SHA256, its first :data:`MAC_BYTES` bytes."""
    return hmac.digest(key, payload, "sha256")[:MAC_BYTES]


@dataclass(frozen=True, slots=True)
class Frame:
    sender: int
    seq: int
    t: float
    messages: tuple[Message, ...]


# The packed form of each message kind (what encode() writes for it). A sender may hand
# encode() these lists instead of Message objects: the same bytes, without building an object
# only to unpack it again (every UAV sends a beacon every tick).
Packed = list[object]


class TrackLike(Protocol):
    """What :func:`pack_tracks` reads of an item: :class:`~comms.messages.TrackItem`'s fields."""

    @property
    def target(self) -> int: ...
    @property
    def x(self) -> float: ...
    @property
    def y(self) -> float: ...
    @property
    def vx(self) -> float: ...
    @property
    def vy(self) -> float: ...
    @property
    def t(self) -> float: ...
    @property
    def value(self) -> float: ...


class ThreatLike(Protocol):
    """What :func:`pack_threats` reads of an item: :class:`~comms.messages.ThreatItem`'s fields."""

    @property
    def threat(self) -> int: ...
    @property
    def x(self) -> float: ...
    @property
    def y(self) -> float: ...
    @property
    def radius(self) -> float: ...
    @property
    def d_max(self) -> float: ...


def pack_hello(uav: int, type: str, x: float, y: float, v: float, theta: float) -> Packed:
    """= ``Hello(uav, type, x, y, v, theta)``, packed."""
    return [K_HELLO, uav, type, x, y, v, theta]


def pack_intent(uav: int, wx: float, wy: float, mode: int, target: int) -> Packed:
    """= ``Intent(uav, wx, wy, mode, target)``, packed."""
    return [K_INTENT, uav, wx, wy, mode, target]


def pack_scans(uav: int, records: Sequence[float]) -> Packed:
    """= ``ScanRecords(uav, tuple(records))``, packed (a tuple or a list of the flat records)."""
    return [K_SCAN, uav, records]  # (msgpack writes a tuple as the array of its items)


def pack_tracks(items: Iterable[TrackLike]) -> Packed:
    """= ``Tracks(tuple(items))``, packed. ``items``: any objects with
    :class:`~comms.messages.TrackItem`'s fields give the same bytes, e.g. a UAV's own
    :class:`~agents.knowledge.Track` records (no TrackItem copy of each to send them)."""
    return [K_TRACKS, [[i.target, i.x, i.y, i.vx, i.vy, i.t, i.value] for i in items]]


def pack_threats(items: Iterable[ThreatLike]) -> Packed:
    """= ``Threats(tuple(items))``, packed. ``items``: any objects with
    :class:`~comms.messages.ThreatItem`'s fields give the same bytes (a UAV's own
    :class:`~agents.knowledge.KnownThreat` records)."""
    return [K_THREATS, [[i.threat, i.x, i.y, i.radius, i.d_max] for i in items]]


def pack_track_digest(uav: int, t: float, targets: Sequence[int], times: Sequence[float],
                      threats: Sequence[int]) -> Packed:
    """= ``TrackDigest(uav, t, tuple(targets), tuple(times), tuple(threats))``, packed (lists:
    what msgpack reads back)."""
    return [K_TRACK_DIGEST, uav, t, list(targets), list(times), list(threats)]


def _pack_message(m: Message | Packed) -> Packed:
    if type(m) is list:  # packed already (pack_hello, ...): what the actors' outboxes send
        return m
    if type(m) is Hello:
        return pack_hello(m.uav, m.type, m.x, m.y, m.v, m.theta)
    if type(m) is Intent:
        return pack_intent(m.uav, m.wx, m.wy, m.mode, m.target)
    if type(m) is ScanRecords:
        return pack_scans(m.uav, m.records)
    if type(m) is Tracks:
        return pack_tracks(m.items)
    if type(m) is Threats:
        return pack_threats(m.items)
    if type(m) is ScanDigest:
        return [K_DIGEST, m.uav, m.t_cut, m.tick0, m.lo, m.hi, [[origin, bits] for origin, bits in m.bitmaps]]
    if type(m) is TrackDigest:
        return pack_track_digest(m.uav, m.t, m.targets, m.times, m.threats)
    raise TypeError(f"not a message: {m!r}")


# One packer for every frame (msgpack.packb builds a new one, with its buffer, per call). Safe to
# share: pack() runs in C from start to finish, holding the GIL, and returns a new bytes object.
_packer = msgpack.Packer(use_bin_type=True)


def encode(sender: int, seq: int, t: float, messages: Sequence[Message | Packed], key: bytes | None = None) -> bytes:
    """The frame of ``messages``: :class:`~comms.messages.Message` objects, or their packed forms
    (:func:`pack_hello`, ...). ``key``: the swarm key; the frame then carries its MAC."""
    return _wire(sender, seq, float(t), [_pack_message(m) for m in messages], key)


def _wire(sender: int, seq: int, t: float, packed: list[Packed], key: bytes | None) -> bytes:
    payload: bytes = _packer.pack([MAGIC, VERSION, sender, seq, t, packed])
    if key is not None:
        payload += mac(key, payload)
    return payload + zlib.crc32(payload).to_bytes(4, "little")


def encode_decoded(sender: int, seq: int, t: float, messages: Sequence[Message | Packed], key: bytes | None = None,
                   max_bytes: int = DEFAULT_MAX_BYTES) -> tuple[bytes, Frame | None]:
    """``encode(sender, seq, t, messages, key)`` and the :class:`Frame` that ``decode(data,
    max_bytes, key)`` gives for those bytes, built from the packed messages without the wire,
    or None where that is not certain (decoding then decides): the sender's side of
    :class:`comms.framecache.DecodeCache`.

    The frame is what decoding builds, by the same checks (:func:`_message`), applied to what
    msgpack would give back. That is the packed messages themselves: every check admits exact
    builtin types only (int, float, str, bytes, list), which msgpack reads back as they were
    written; the one tuple _pack_message may leave (a ScanRecords' records) is read back as a
    list, and is passed as one. A value that fails a check (a numpy float, a NaN, a bool)
    gives None, not an error: decoding may accept it (a float subclass is written as a float)
    or reject it, as it will."""
    t = float(t)
    packed = [_pack_message(m) for m in messages]
    data = _wire(sender, seq, t, packed, key)
    if len(data) > max_bytes:
        return data, None
    try:
        frame = _frame(sender, seq, t, [_as_read_back(m) for m in packed])
    except (FrameError, TypeError, ValueError, IndexError):
        return data, None
    return data, frame


class FrameRecord(NamedTuple):
    """A frame's header values and messages, unchecked: what msgpack gives back for its bytes
    (:func:`read`), or what its sender packed into them (:func:`encode_record`). The tick
    plane's memo of a sent frame (:class:`comms.framecache.DecodeCache` with ``records``): no
    message object is built at send time, and a receiver checks the record as decoding checks
    what msgpack gives, reading it straight into what it keeps (:func:`message_kind` and the
    readers; :func:`agents.inbox.check_frame`)."""

    sender: Any
    seq: Any
    t: Any
    messages: list[Any]
    # True: the sender's packed values, which are what msgpack reads back wherever a check
    # admits them (exact int, float, str, bytes, list, as for encode_decoded); a value a
    # check rejects (a numpy float, a tuple, a bool) may be read back as another that passes
    # or fails, so the bytes decide (read). False: read from the bytes (read), final.
    sent: bool


def encode_record(sender: int, seq: int, t: float, messages: Sequence[Message | Packed], key: bytes | None = None,
                  max_bytes: int = DEFAULT_MAX_BYTES) -> tuple[bytes, FrameRecord | None]:
    """``encode(sender, seq, t, messages, key)`` and its :class:`FrameRecord` (``sent``), or
    None when the bytes exceed ``max_bytes`` (decoding rejects them). Nothing is checked: the
    record's messages are the packed ones, as msgpack reads them back where that differs
    only by a ScanRecords' records tuple (:func:`_as_read_back`). The messages must not change
    after (the record holds them, not a copy; every sender builds them afresh per frame)."""
    t = float(t)
    packed = [_pack_message(m) for m in messages]
    data = _wire(sender, seq, t, packed, key)
    if len(data) > max_bytes:
        return data, None
    return data, FrameRecord(sender, seq, t, [_as_read_back(m) for m in packed], True)


def _as_read_back(m: Packed) -> Packed:
    """A packed message as msgpack reads it back: itself, but for a ScanRecords' records
    tuple, which comes back as a list."""
    if len(m) == 3 and m[0] == K_SCAN and type(m[2]) is tuple:
        return [m[0], m[1], list(m[2])]
    return m


# --- decoding -----------------------------------------------------------------------------
# What msgpack gives is untyped: each check below narrows an ``object`` to the type it admits
# (an array's items stay ``Any`` until checked).


def _int(v: object) -> int:
    if type(v) is not int:
        raise FrameError(f"expected an integer, got {type(v).__name__}")
    return v


def _num(v: object) -> float:
    # msgpack gives int or float; bool is an int subclass and must not pass.
    if type(v) is float:
        if not math.isfinite(v):
            raise FrameError("non-finite number")
        return v
    if type(v) is int:
        return float(v)
    raise FrameError(f"expected a number, got {type(v).__name__}")


_FLOAT = {float}


def _nums(values: list[Any]) -> tuple[float, ...]:
    """``_num`` of each value, as a tuple. A list of finite floats (what :func:`encode` writes)
    passes both checks in C, with no Python call per value (scan records can be thousands)."""
    if set(map(type, values)) <= _FLOAT and all(map(math.isfinite, values)):
        return tuple(values)
    return tuple([_num(v) for v in values])


def _list(v: object, n: int | None = None) -> list[Any]:
    if type(v) is not list:
        raise FrameError(f"expected an array, got {type(v).__name__}")
    if n is not None and len(v) != n:
        raise FrameError(f"expected {n} fields, got {len(v)}")
    return v


def message_kind(raw: object) -> int:
    """The kind of a message as msgpack gives it (an array, its first item a known kind), or
    :class:`FrameError`. Its fields are checked by the kind's reader: :func:`read_hello`,
    :func:`read_intent`, :func:`read_scans`, :func:`read_track_items`, :func:`read_threat_items`,
    :func:`read_digest`, :func:`read_track_digest` (decoding builds the messages with them, :func:`_message`; a receiver
    may read a frame's messages with them straight into what it keeps, without the message
    objects: :func:`agents.inbox.check_frame` of a :class:`FrameRecord`)."""
    if type(raw) is not list:
        raise FrameError(f"expected an array, got {type(raw).__name__}")
    if not raw:
        raise FrameError("empty message")
    kind = raw[0]
    if type(kind) is not int:
        raise FrameError(f"expected an integer, got {type(kind).__name__}")
    if not K_HELLO <= kind <= K_TRACK_DIGEST:
        raise FrameError(f"unknown message kind {kind}")
    return kind


_INF = math.inf
_tuple_new = tuple.__new__


def read_hello(raw: list[Any]) -> Hello:
    """The :class:`Hello` of a message of kind ``K_HELLO`` (:func:`message_kind`), or :class:`FrameError`."""
    n = len(raw)
    if n != 7:
        raise FrameError(f"expected 7 fields, got {n}")
    _, uav, name, x, y, v, theta = raw
    if type(name) is not str or len(name) > 64:
        raise FrameError("hello: bad type name")
    # (What encode writes, checked without a call per field: exact floats whose sum is finite
    # are all finite. Anything else, an int among them say, takes the checks one by one.)
    if (type(uav) is int and type(x) is float and type(y) is float and type(v) is float and type(theta) is float
            and -_INF < x + y + v + theta < _INF):
        return Hello(uav, name, x, y, v, theta)
    return Hello(_int(uav), name, _num(x), _num(y), _num(v), _num(theta))


def read_intent(raw: list[Any]) -> Intent:
    """The :class:`Intent` of a message of kind ``K_INTENT``, or :class:`FrameError`."""
    n = len(raw)
    if n != 6:
        raise FrameError(f"expected 6 fields, got {n}")
    mode = _int(raw[4])
    if mode not in (0, 1):
        raise FrameError("intent: bad mode")
    _, uav, wx, wy, _mode, target = raw
    if type(uav) is int and type(wx) is float and type(wy) is float and type(target) is int and -_INF < wx + wy < _INF:
        return Intent(uav, wx, wy, mode, target)
    return Intent(_int(uav), _num(wx), _num(wy), mode, _int(target))


def read_scans(raw: list[Any]) -> tuple[int, tuple[float, ...]]:
    """``(origin, records)`` of a message of kind ``K_SCAN`` (a :class:`ScanRecords`' fields),
    or :class:`FrameError`."""
    n = len(raw)
    if n != 3:
        raise FrameError(f"expected 3 fields, got {n}")
    recs = _list(raw[2])
    if len(recs) % 4:
        raise FrameError("scan: record list not a multiple of 4")
    return _int(raw[1]), _nums(recs)


def read_track_item(it: object) -> TrackItem:
    """One item of a ``K_TRACKS`` message's item list (:func:`read_track_items`), or :class:`FrameError`."""
    if type(it) is list and len(it) == 7:
        target, x, y, vx, vy, t, value = it
        if (type(target) is int and type(x) is float and type(y) is float and type(vx) is float
                and type(vy) is float and type(t) is float and type(value) is float
                and -_INF < x + y + vx + vy + t + value < _INF):
            return _tuple_new(TrackItem, it)  # (= TrackItem(*it): a named tuple)
    it = _list(it, 7)
    return TrackItem(_int(it[0]), *_nums(it[1:]))


def read_track_items(raw: list[Any]) -> list[TrackItem]:
    """The items of a message of kind ``K_TRACKS`` (a :class:`Tracks`' items), or :class:`FrameError`."""
    _list(raw, 2)
    return [read_track_item(it) for it in _list(raw[1])]


def read_threat_items(raw: list[Any]) -> list[ThreatItem]:
    """The items of a message of kind ``K_THREATS`` (a :class:`Threats`' items), or :class:`FrameError`."""
    _list(raw, 2)
    threats: list[ThreatItem] = []
    for it in _list(raw[1]):
        it = _list(it, 5)
        item = ThreatItem(_int(it[0]), *_nums(it[1:]))
        if item.radius <= 0 or item.d_max < item.radius:
            raise FrameError("threat: bad radius")
        threats.append(item)
    return threats


def read_digest(raw: list[Any]) -> ScanDigest:
    """The :class:`ScanDigest` of a message of kind ``K_DIGEST``, or :class:`FrameError`."""
    _list(raw, 7)
    bitmaps: list[tuple[int, bytes]] = []
    append = bitmaps.append
    for it in _list(raw[6]):
        if type(it) is list and len(it) == 2:
            origin, bits = it
            if type(origin) is int and type(bits) is bytes:
                append((origin, bits))
                continue
        it = _list(it, 2)
        if type(it[1]) is not bytes:
            raise FrameError("digest: bitmap is not bytes")
        append((_int(it[0]), it[1]))
    return ScanDigest(_int(raw[1]), _num(raw[2]), _int(raw[3]), _int(raw[4]), _int(raw[5]), tuple(bitmaps))


def _ints(values: list[Any]) -> tuple[int, ...]:
    """``_int`` of each value, as a tuple (a list of exact ints passes in C)."""
    if set(map(type, values)) <= _INT:
        return tuple(values)
    return tuple([_int(v) for v in values])


_INT = {int}


def read_track_digest(raw: list[Any]) -> TrackDigest:
    """The :class:`TrackDigest` of a message of kind ``K_TRACK_DIGEST``, or :class:`FrameError`
    (its targets and times must pair up)."""
    _list(raw, 6)
    targets = _ints(_list(raw[3]))
    times = _nums(_list(raw[4]))
    if len(targets) != len(times):
        raise FrameError(f"track digest: {len(targets)} targets, {len(times)} times")
    return TrackDigest(_int(raw[1]), _num(raw[2]), targets, times, _ints(_list(raw[5])))


def _message(raw: object) -> Message:
    kind = message_kind(raw)
    raw = cast("list[Any]", raw)
    if kind == K_HELLO:
        return read_hello(raw)
    if kind == K_INTENT:
        return read_intent(raw)
    if kind == K_SCAN:
        return ScanRecords(*read_scans(raw))
    if kind == K_TRACKS:
        return Tracks(tuple(read_track_items(raw)))
    if kind == K_THREATS:
        return Threats(tuple(read_threat_items(raw)))
    if kind == K_TRACK_DIGEST:
        return read_track_digest(raw)
    return read_digest(raw)


def read_header(rec: FrameRecord) -> tuple[int, int, float]:
    """A frame record's ``(sender, seq, t)``, checked as decoding checks them (before its
    messages), or :class:`FrameError`."""
    return _int(rec.sender), _int(rec.seq), _num(rec.t)


def _frame(sender: object, seq: object, t: object, messages: list[Any]) -> Frame:
    """The checked :class:`Frame` of a frame's header values and messages as msgpack gives them."""
    return Frame(_int(sender), _int(seq), _num(t), tuple([_message(m) for m in messages]))


def read(data: bytes, max_bytes: int = DEFAULT_MAX_BYTES, key: bytes | None = None) -> FrameRecord:
    """Bytes -> their :class:`FrameRecord` (not ``sent``): the checks of :func:`decode` up to
    the frame's header fields and messages, which are left to check (:func:`_frame`,
    :func:`message_kind` and the readers), or :class:`FrameError` (:class:`AuthError`)."""
    if not isinstance(data, (bytes, bytearray)):
        raise FrameError("frame is not bytes")
    if len(data) > max_bytes:
        raise FrameError(f"oversized frame: {len(data)} > {max_bytes} bytes")
    if len(data) < 5:
        raise FrameError(f"truncated frame: {len(data)} bytes")
    payload = bytes(data[:-4])
    if zlib.crc32(payload).to_bytes(4, "little") != bytes(data[-4:]):
        raise FrameError("checksum mismatch (corrupted or truncated frame)")
    if key is not None:
        if len(payload) <= MAC_BYTES:
            raise AuthError("no MAC")
        tag = payload[-MAC_BYTES:]
        payload = payload[:-MAC_BYTES]
        if not hmac.compare_digest(mac(key, payload), tag):
            raise AuthError("MAC mismatch (not written with the swarm key)")
    try:
        raw = msgpack.unpackb(
            payload,
            raw=False,
            strict_map_key=True,
            max_str_len=max_bytes,
            max_bin_len=max_bytes,
            max_array_len=max_bytes,
            max_map_len=max_bytes,
            max_ext_len=max_bytes,
        )
    except Exception as exc:  # msgpack raises several unrelated types for bad input
        raise FrameError(f"undecodable frame: {type(exc).__name__}") from None
    try:
        raw = _list(raw, 6)
        if raw[0] != MAGIC or type(raw[0]) is not int:
            raise FrameError("bad magic")
        if raw[1] != VERSION or type(raw[1]) is not int:
            raise FrameError(f"unsupported version {raw[1]!r}")
        return FrameRecord(raw[2], raw[3], raw[4], _list(raw[5]), False)
    except FrameError:
        raise
    except UNFORESEEN as exc:
        raise malformed(exc) from None


# What checking msgpack's output may raise besides FrameError (an unforeseen shape): raised as
# a FrameError, "malformed frame" (malformed).
UNFORESEEN = (TypeError, ValueError, IndexError, RecursionError)


def malformed(exc: Exception) -> FrameError:
    """The :class:`FrameError` for an error of :data:`UNFORESEEN` met checking a frame."""
    return FrameError(f"malformed frame: {exc}")


def decode(data: bytes, max_bytes: int = DEFAULT_MAX_BYTES, key: bytes | None = None) -> Frame:
    """Bytes -> :class:`Frame`, or :class:`FrameError`; never any other exception. ``key``: the
    swarm key; a frame whose MAC is not right under it (or that has none) raises
    :class:`AuthError`."""
    return frame_of(read(data, max_bytes, key))


def frame_of(rec: FrameRecord) -> Frame:
    """The checked :class:`Frame` of a frame record (what :func:`decode` gives for its bytes),
    or :class:`FrameError`."""
    try:
        return _frame(rec.sender, rec.seq, rec.t, rec.messages)
    except FrameError:
        raise
    except UNFORESEEN as exc:
        raise malformed(exc) from None
