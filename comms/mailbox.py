"""A UAV's bounded inbox of raw frames, with statistics (cf. Trio's memory channels)."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass


@dataclass(slots=True)
class MailboxStats:
    accepted: int = 0
    dropped_full: int = 0
    max_depth: int = 0


class Mailbox:
    """FIFO of ``(arrival_t, sender, frame_bytes)``; when full, new frames are dropped and counted."""

    __slots__ = ("capacity", "_items", "stats")

    def __init__(self, capacity: int):
        if capacity < 1:
            raise ValueError(f"mailbox capacity must be >= 1, got {capacity}")
        self.capacity = capacity
        self._items: deque[tuple[float, int, bytes]] = deque()
        self.stats = MailboxStats()

    def put(self, t: float, sender: int, data: bytes) -> bool:
        items = self._items
        stats = self.stats
        n = len(items)
        if n >= self.capacity:
            stats.dropped_full += 1
            return False
        items.append((t, sender, data))
        stats.accepted += 1
        if n >= stats.max_depth:
            stats.max_depth = n + 1
        return True

    def put_many(self, items: list[tuple[float, int, bytes]]) -> int:
        """:meth:`put` of each ``(t, sender, frame_bytes)`` of ``items`` in turn, at once; returns
        how many were accepted (the first ones: the rest found the mailbox full, and are counted)."""
        mine = self._items
        stats = self.stats
        n, k = len(mine), len(items)
        take = k if n + k <= self.capacity else max(self.capacity - n, 0)
        if take < k:
            stats.dropped_full += k - take
            items = items[:take]
        if take:
            mine.extend(items)
            stats.accepted += take
            if n + take > stats.max_depth:
                stats.max_depth = n + take
        return take

    def drain(self) -> list[tuple[float, int, bytes]]:
        items = list(self._items)
        self._items.clear()
        return items

    def __len__(self) -> int:
        return len(self._items)
