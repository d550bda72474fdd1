"""Decode each broadcast frame once, however many UAVs receive it.

A broadcast reaches every neighbour as the *same* ``bytes`` object (unless a fault corrupted
that copy, which makes it a different byte string). Decoding is a pure function of the bytes
and the size cap, and a decoded :class:`~comms.codec.Frame` is immutable (frozen dataclasses
and tuples all the way down), so receivers can share one decoded frame: :class:`DecodeCache`
keeps the frames it decoded, keyed by their bytes, for a while.

A cache decodes with one swarm key (``key``: :func:`comms.codec.decode`'s), that of every
receiver sharing it; a frame it holds passed the MAC.

Failures are not remembered: a frame that does not decode is rejected by each receiver that
gets it, each time (a corrupted copy is almost always unique to one link anyway). The cache
only changes how often the codec runs, never what a receiver gets: a hit returns the frame
decoding those bytes would give, a miss decodes them.

Beside each frame the cache keeps one value derived from it by its receivers, with what it
was derived for (:meth:`DecodeCache.derive`: the actors keep what they accept of the frame at
the tick's time, :func:`agents.inbox.check_frame`): also a pure memo, dropped with its frame.
A receiver makes one call per heard frame: the value kept, or (decoding the bytes if the frame
is not held) the value derived now and kept.

With ``records`` (the tick plane's frame records, issue 36 T1; ``Simulation(tick_plane=True)``)
the cache holds, for each frame, its :class:`~comms.codec.FrameRecord` instead of a decoded
:class:`~comms.codec.Frame`: a sender leaves the messages it packed, keyed by the bytes, with
nothing checked or built at send time (:func:`comms.codec.encode_record`), and a receiver's
derive reads the record straight into what it keeps, running decoding's checks as it goes
(:func:`agents.inbox.check_frame`). Bytes not held (a corrupted copy, a spoofer's frame, a
copy delayed past eviction) are read from the wire (:func:`comms.codec.read`: size, CRC, MAC,
msgpack) and checked the same way. A sender's record that fails a check is not final (a numpy
float in it is a float once read back): the bytes decide. Without ``records`` (the per-actor
path, the oracle), frames as described above.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence
from itertools import islice
from typing import Any, TypeVar, cast

from comms.codec import (
    DEFAULT_MAX_BYTES,
    UNFORESEEN,
    Frame,
    FrameError,
    FrameRecord,
    Packed,
    decode,
    encode_decoded,
    encode_record,
    frame_of,
    malformed,
    read,
)
from comms.messages import Message

DECODE_CACHE_SIZE = 8192

V = TypeVar("V")


class DecodeCache:
    __slots__ = ("max_bytes", "key", "size", "records", "_frames", "_derived", "decoded", "lookup")

    lookup: Callable[[bytes], Frame | FrameRecord | None]

    def __init__(self, max_bytes: int = DEFAULT_MAX_BYTES, size: int = DECODE_CACHE_SIZE, key: bytes | None = None,
                 records: bool = False):
        """``records``: hold frame records (the tick plane's; module docstring), not frames."""
        self.max_bytes = max_bytes
        self.key = key
        self.size = max(1, size)
        self.records = records
        # bytes -> their Frame; with ``records``, their FrameRecord
        self._frames: dict[bytes, Frame | FrameRecord] = {}
        # bytes -> (what a value was derived for, the value derived from their frame): derive()
        self._derived: dict[bytes, tuple[Hashable, Any]] = {}
        self.decoded = 0  # frames actually run through the codec
        # lookup(data) -> what is held for ``data`` (a Frame; with ``records`` a FrameRecord) or
        # None, without decoding (``data`` must be bytes): a plain dict lookup.
        self.lookup = self._frames.get

    def decode(self, data: bytes) -> Frame:
        """:func:`comms.codec.decode` ``(data, max_bytes, key)``, memoised for ``bytes`` that
        decode (with ``records``: their record, from which the frame is built again)."""
        if self.records:
            return self._decode_record(data)
        frames = self._frames
        if type(data) is bytes:
            frame = frames.get(data)
            if frame is not None:
                return cast(Frame, frame)  # (not ``records``: frames held)
        self.decoded += 1
        frame = decode(data, self.max_bytes, self.key)  # raises FrameError: not cached
        if type(data) is bytes:
            self._remember(data, frame)
        return frame

    def encode(self, sender: int, seq: int, t: float, messages: Sequence[Message | Packed]) -> bytes:
        """:func:`comms.codec.encode` ``(sender, seq, t, messages, key)``, remembering the frame
        its bytes decode to as if it had decoded them (:func:`comms.codec.encode_decoded`): the
        sender has the messages its receivers would decode, and they find the frame here. With
        ``records``, the frame's record (:func:`comms.codec.encode_record`): nothing checked
        or built, the receivers check it."""
        held: Frame | FrameRecord | None
        if self.records:
            data, held = encode_record(sender, seq, t, messages, self.key, self.max_bytes)
        else:
            data, held = encode_decoded(sender, seq, t, messages, self.key, self.max_bytes)
        if held is not None and data not in self._frames:
            self._remember(data, held)
        return data

    def _remember(self, data: bytes, held: Frame | FrameRecord) -> None:
        frames = self._frames
        if len(frames) >= self.size:
            derived = self._derived
            for k in list(islice(frames, max(1, self.size // 4))):  # oldest first
                del frames[k]
                derived.pop(k, None)
        frames[data] = held

    def derive(self, data: bytes, key: Hashable, derive: Callable[[Frame | FrameRecord], V]) -> V:
        """``derive(frame)`` of the frame ``data`` decodes to, kept beside the frame for ``key``.

        ``key`` says what the value is derived for (the receivers' clock and bounds, say):
        ``derive`` must be a pure function of the frame and ``key``, so that the value kept for
        an equal key is the value deriving it again would give. If a value is kept for ``data``
        with an equal key, that value; else the frame (the cached one, or ``data`` decoded now,
        which raises :class:`~comms.codec.FrameError` and keeps nothing) is derived, and the
        value kept for ``key`` in place of any kept before. One call per heard frame, one dict
        lookup when the value is kept. ``data`` that is not ``bytes`` is decoded and derived,
        nothing kept.

        With ``records``, ``derive`` is given the frame's :class:`~comms.codec.FrameRecord`
        and checks it as decoding would (raising :class:`~comms.codec.FrameError` where
        decoding does; :func:`agents.inbox.check_frame`): the sender's record held, or ``data``
        read now (:func:`comms.codec.read`, its record held once derived). A sender's record
        that fails a check is not final (a numpy float in it is read back as a float): ``data``
        is read, and its record derived and held in its place."""
        if self.records:
            return self._derive_record(data, key, derive)
        if type(data) is not bytes:
            return derive(self.decode(data))
        kept = self._derived.get(data)
        if kept is not None and kept[0] == key:
            value: V = kept[1]
            return value
        value = derive(self.decode(data))  # (the frame held, or decoded: a FrameError keeps nothing)
        self._derived[data] = (key, value)
        return value

    # --- records (the tick plane) ----------------------------------------------------------

    def _held(self, data: bytes) -> FrameRecord | None:
        rec = self._frames.get(data) if type(data) is bytes else None
        assert rec is None or type(rec) is FrameRecord
        return rec

    def _hold(self, data: bytes, rec: FrameRecord) -> None:
        """Hold ``rec``, read from ``data``: in place of a sender's record, or as a new one."""
        if type(data) is bytes:
            if data in self._frames:
                self._frames[data] = rec
            else:
                self._remember(data, rec)

    def _derive_record(self, data: bytes, key: Hashable, derive: Callable[[Frame | FrameRecord], V]) -> V:
        kept = self._derived.get(data) if type(data) is bytes else None
        if kept is not None and kept[0] == key:
            value: V = kept[1]
            return value
        rec = self._held(data)
        fresh = rec is None
        if rec is not None and rec.sent:
            try:
                value = derive(rec)
            except (FrameError, *UNFORESEEN):
                rec, fresh = None, True  # (not final: the bytes decide)
            else:
                self._derived[data] = (key, value)
                return value
        if rec is None:
            self.decoded += 1
            rec = read(data, self.max_bytes, self.key)  # (FrameError: nothing held)
        try:
            value = derive(rec)
        except FrameError:
            raise
        except UNFORESEEN as exc:
            raise malformed(exc) from None
        if type(data) is bytes:
            if fresh:
                self._hold(data, rec)
            self._derived[data] = (key, value)
        return value

    def _decode_record(self, data: bytes) -> Frame:
        rec = self._held(data)
        fresh = rec is None
        if rec is not None and rec.sent:
            try:
                return frame_of(rec)
            except FrameError:
                rec, fresh = None, True  # (not final: the bytes decide)
        if rec is None:
            self.decoded += 1
            rec = read(data, self.max_bytes, self.key)  # (FrameError: nothing held)
        frame = frame_of(rec)
        if fresh:
            self._hold(data, rec)
        return frame

    def __len__(self) -> int:
        return len(self._frames)
