"""The event log: every notable thing a run does, as msgpack, hashed as it is written.

An event is a flat array ``[kind, t, field, ...]`` (kinds and fields are listed in the README).
Events of one tick are packed together at the end of the tick into one growing byte buffer and
fed to SHA-256, so the hash is of exactly the bytes written to ``events.msgpack``. Nothing in
an event comes from the wall clock or from Python's ``hash``: the same scenario and seed give
the same bytes in any process.

Subscribers (the embedding API) get each event live as ``callback(event_tuple)``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterable, Iterator

import msgpack

Event = tuple


def _array_header_size(n: int) -> int:
    """Bytes of the msgpack header of an array of ``n`` items (fixarray, array 16, array 32)."""
    return 1 if n < 16 else 3 if n < 0x10000 else 5


class EventLog:
    def __init__(self) -> None:
        self._pending: list[Event] = []
        self._buf = bytearray()
        self._sha = hashlib.sha256()
        self._packer = msgpack.Packer(use_bin_type=True)
        self._subs: list[tuple[Callable[[Event], None], frozenset[str] | None]] = []
        self.count = 0

    def emit(self, *event) -> None:
        self._pending.append(event)
        if self._subs:
            self._notify(event)

    def extend(self, events: list[Event]) -> None:
        """``emit(*e)`` for each event tuple of ``events``, in order (one call for many)."""
        if not self._subs:
            self._pending.extend(events)
            return
        append = self._pending.append
        for event in events:  # each subscriber call sees the log as emit() would leave it
            append(event)
            self._notify(event)

    def extend_packed(self, data: bytes, count: int, events: Callable[[], list[Event]]) -> None:
        """``extend(events())`` for events given already packed: ``data`` is the bytes of packing
        each of the ``count`` events of ``events()`` in order (issue 25: a tick's 10^5 ``target``
        events are packed from arrays at once, not made into tuples and packed one by one). The
        tuples are made only for subscribers; the log's bytes are the same either way."""
        if self._subs:
            self.extend(events())
            return
        self.flush()  # (what was emitted before them comes first)
        self.count += count
        self._buf += data
        self._sha.update(data)

    def _notify(self, event: Event) -> None:
        kind = event[0]
        for cb, kinds in self._subs:
            if kinds is None or kind in kinds:
                cb(event)

    @property
    def total(self) -> int:
        """Events emitted so far, packed or not."""
        return self.count + len(self._pending)

    def flush(self) -> None:
        """Pack pending events (called once per tick and at the end)."""
        pending = self._pending
        if not pending:
            return
        n = len(pending)
        # One pack() call for the whole tick: a msgpack array of the events is its header
        # followed by each event packed on its own, so dropping the header leaves exactly the
        # bytes of packing them one by one (tests/test_recorder.py checks this).
        chunk = memoryview(self._packer.pack(pending))[_array_header_size(n):]
        self.count += n
        pending.clear()
        self._buf += chunk
        self._sha.update(chunk)

    def subscribe(self, callback: Callable[[Event], None], kinds: Iterable[str] | None = None) -> Callable[[], None]:
        entry = (callback, frozenset(kinds) if kinds is not None else None)
        self._subs.append(entry)

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


# Where events hold UAV ids (positions in the event array, kind first): read_events(names=True)
# turns them into names with the start header's id -> name table. A violation's second party
# is a UAV only for separation (for threat it is the threat's id).
UAV_FIELDS: dict[str, tuple[int, ...]] = {
    "pose": (2,), "mode": (2,), "found": (3,), "release": (3,), "handover": (3, 4), "rx": (2, 3),
    "lost": (2, 3), "join": (2,), "crash": (2,),
}


def uav_names(header: dict) -> dict[int, str]:
    """The id -> name table of a run's ``start`` event (``header = events[0][2]``)."""
    return {int(uid): str(name) for uid, name, *_type in header.get("uavs", [])}


def read_events(data: bytes, *, names: bool = False) -> Iterator[list]:
    """Iterate the events of an ``events.msgpack`` file's bytes (or ``RunResult.events``).

    ``names=True``: UAV ids are replaced by UAV names (see :data:`UAV_FIELDS`), using the
    ``start`` header and the ``join`` events of UAVs added while the run went on."""
    unpacker = msgpack.Unpacker(raw=False, strict_map_key=False)
    unpacker.feed(data)
    if not names:
        yield from unpacker
        return
    table: dict[int, str] = {}
    for event in unpacker:
        kind = event[0]
        if kind == "start":
            table.update(uav_names(event[2]))
        elif kind == "join":
            table[event[2]] = event[3]
        for i in UAV_FIELDS.get(kind, ()):
            event[i] = table.get(event[i], event[i])
        if kind == "violation" and event[2] == "separation":
            event[3], event[4] = table.get(event[3], event[3]), table.get(event[4], event[4])
        yield event
