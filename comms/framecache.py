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

Beside each frame the cache keeps one value derived from it by its receivers
(:meth:`DecodeCache.keep`, :attr:`DecodeCache.derived`; the actors keep what they accept of the
frame at the tick's time, :func:`agents.inbox.check_frame`): also a pure memo, dropped with its
frame.

The receivers' fast paths are plain dict lookups, bound once: :attr:`DecodeCache.lookup` (the
frame of some bytes) and :attr:`DecodeCache.derived` (the value kept for them).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from itertools import islice

from comms.codec import DEFAULT_MAX_BYTES, Frame, Packed, decode, encode_decoded
from comms.messages import Message

DECODE_CACHE_SIZE = 8192


class DecodeCache:
    __slots__ = ("max_bytes", "key", "size", "_frames", "_derived", "decoded", "lookup", "derived")

    lookup: Callable[[bytes], Frame | None]
    derived: Callable[[bytes], object | None]

    def __init__(self, max_bytes: int = DEFAULT_MAX_BYTES, size: int = DECODE_CACHE_SIZE, key: bytes | None = None):
        self.max_bytes = max_bytes
        self.key = key
        self.size = max(1, size)
        self._frames: dict[bytes, Frame] = {}
        self._derived: dict[bytes, object] = {}  # bytes -> a value derived from the frame: see keep()
        self.decoded = 0  # frames actually run through the codec
        # lookup(data) -> the cached Frame or None, without decoding (``data`` must be bytes);
        # derived(data) -> the value kept for the frame of ``data`` (keep()), or None. The
        # receivers' fast paths: plain dict lookups.
        self.lookup = self._frames.get
        self.derived = self._derived.get

    def decode(self, data: bytes) -> Frame:
        """:func:`comms.codec.decode` ``(data, max_bytes, key)``, memoised for ``bytes`` that decode."""
        frames = self._frames
        if type(data) is bytes:
            frame = frames.get(data)
            if frame is not None:
                return frame
        self.decoded += 1
        frame = decode(data, self.max_bytes, self.key)  # raises FrameError: not cached
        if type(data) is bytes:
            self._remember(data, frame)
        return frame

    def encode(self, sender: int, seq: int, t: float, messages: Sequence[Message | Packed]) -> bytes:
        """:func:`comms.codec.encode` ``(sender, seq, t, messages, key)``, remembering the frame
        its bytes decode to as if it had decoded them (:func:`comms.codec.encode_decoded`): the
        sender has the messages its receivers would decode, and they find the frame here."""
        data, frame = encode_decoded(sender, seq, t, messages, self.key, self.max_bytes)
        if frame is not None and data not in self._frames:
            self._remember(data, frame)
        return data

    def _remember(self, data: bytes, frame: Frame) -> None:
        frames = self._frames
        if len(frames) >= self.size:
            derived = self._derived
            for k in list(islice(frames, max(1, self.size // 4))):  # oldest first
                del frames[k]
                derived.pop(k, None)
        frames[data] = frame

    def keep(self, data: bytes, value: object) -> None:
        """Keep ``value``, derived from the frame of ``data`` (a cached frame), in place of any
        value kept for it before. The value must say what it was derived for (the receivers'
        clock, say) and be a pure function of the frame and that, so that using it where that
        matches is the same as deriving it again."""
        if data in self._frames:
            self._derived[data] = value

    def __len__(self) -> int:
        return len(self._frames)
