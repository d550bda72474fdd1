"""The event log: every notable thing a run does, as msgpack, hashed as it is written.

An event is a flat array ``[kind, t, field, ...]``; :mod:`swarm.events` defines every kind and
its fields once (and reads logs back: :func:`swarm.events.read_events`). Events of one tick are
packed together at the end of the tick into one growing byte buffer and fed to SHA-256, so the
hash is of exactly the bytes written to ``events.msgpack``. Nothing in an event comes from the
wall clock or from Python's ``hash``: the same scenario and seed give the same bytes in any
process.

The simulation emits plain tuples (cheapest to build and pack). Subscribers (the embedding
API) get each event live as a record of :mod:`swarm.events`, with UAV and mode names; the
conversion happens only when someone subscribes, once per event whatever the number of
subscribers.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterable
from typing import Any, ClassVar

import msgpack

from swarm.events import NAMING_KINDS, Decoder, Event, check_kinds, check_wire, read_events, wire_kind

__all__ = ["EventLog", "read_events"]  # read_events lives in swarm.events (kept here for older code)

Callback = Callable[[Event], None]


def _array_header_size(n: int) -> int:
    """Bytes of the msgpack header of an array of ``n`` items (fixarray, array 16, array 32)."""
    return 1 if n < 16 else 3 if n < 0x10000 else 5


class EventLog:
    # Tests turn this on to check every event written against the schema (swarm.events).
    check_schema: ClassVar[bool] = False

    def __init__(self) -> None:
        self._pending: list[tuple[Any, ...]] = []
        self._buf = bytearray()
        self._sha = hashlib.sha256()
        self._packer = msgpack.Packer(use_bin_type=True)
        self._subs: list[tuple[Callback, frozenset[str] | None]] = []
        # Turns tuples into records for subscribers; made by the first subscribe() (so a log
        # nobody subscribes to converts nothing), knowing the UAV names logged before it.
        self._decoder: Decoder | None = None
        self.count = 0

    def emit(self, *event: Any) -> None:
        self._pending.append(event)
        if self._subs:
            self._notify(event)

    def extend(self, events: list[tuple[Any, ...]]) -> None:
        """``emit(*e)`` for each event tuple of ``events``, in order (one call for many)."""
        if not self._subs:
            self._pending.extend(events)
            return
        append = self._pending.append
        for event in events:  # each subscriber call sees the log as emit() would leave it
            append(event)
            self._notify(event)

    def extend_packed(self, data: bytes, count: int, events: Callable[[], list[tuple[Any, ...]]]) -> None:
        """``extend(events())`` for events given already packed: ``data`` is the bytes of packing
        each of the ``count`` events of ``events()`` in order (issue 25: a tick's 10^5 ``target``
        events are packed from arrays at once, not made into tuples and packed one by one). The
        tuples are made only for subscribers (and the schema check); the log's bytes are the
        same either way."""
        if self._subs:
            self.extend(events())
            return
        if self.check_schema:
            for event in events():
                check_wire(event)
        self.flush()  # (what was emitted before them comes first)
        self.count += count
        self._buf += data
        self._sha.update(data)

    def _notify(self, event: tuple[Any, ...]) -> None:
        decode = self._decoder
        assert decode is not None  # (made by subscribe)
        kind = wire_kind(event)
        # One record per event, shared by the subscribers that want it; the events that name
        # UAVs are decoded even if nobody wants them, to keep the decoder's names current.
        record = decode(event) if kind in NAMING_KINDS else None
        for cb, kinds in self._subs:
            if kinds is None or kind in kinds:
                if record is None:
                    record = decode(event)
                cb(record)

    @property
    def total(self) -> int:
        """Events emitted so far, packed or not."""
        return self.count + len(self._pending)

    def flush(self) -> None:
        """Pack pending events (called once per tick and at the end)."""
        pending = self._pending
        if not pending:
            return
        if self.check_schema:
            for event in pending:
                check_wire(event)
        n = len(pending)
        # One pack() call for the whole tick: a msgpack array of the events is its header
        # followed by each event packed on its own, so dropping the header leaves exactly the
        # bytes of packing them one by one (tests/test_recorder.py checks this).
        chunk = memoryview(self._packer.pack(pending))[_array_header_size(n):]
        self.count += n
        pending.clear()
        self._buf += chunk
        self._sha.update(chunk)

    def subscribe(self, callback: Callback, kinds: Iterable[str] | None = None) -> Callable[[], None]:
        """Call ``callback(record)`` for each event logged from now on (only ``kinds``, if given:
        names of :data:`swarm.events.KINDS`); returns an unsubscribe function. A subscriber
        added before the first flush (the end of the first tick) first gets the events logged
        so far: the ``start`` header, which the simulation logs when it is built."""
        wanted = check_kinds(kinds)
        decode = self._decoder
        if decode is None or not self._subs:
            # The UAV names logged while nobody listened: from the bytes and the pending events.
            decode = self._decoder = Decoder(live=True)
            for record in read_events(bytes(self._buf), NAMING_KINDS):
                decode.learn(record)
            for event in self._pending:
                if wire_kind(event) in NAMING_KINDS:
                    decode(event)
        catch_up = [decode(e) for e in self._pending] if self.count == 0 else []
        entry = (callback, wanted)
        self._subs.append(entry)
        for record in catch_up:
            if wanted is None or record.kind in wanted:
                callback(record)

        def unsubscribe() -> None:
            if entry in self._subs:
                self._subs.remove(entry)

        return unsubscribe

    def to_bytes(self) -> bytes:
        self.flush()
        return bytes(self._buf)

    def sha256(self) -> str:
        self.flush()
        return self._sha.hexdigest()
