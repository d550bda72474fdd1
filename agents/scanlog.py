"""Every scan a UAV knows of, by origin and tick: what anti-entropy compares and resends.

A UAV's map is the union (per-cell max of last-seen times) of scan disks: its own, one per tick,
and those it heard in other UAVs' :class:`~comms.messages.ScanRecords`. A lost frame loses the
disks in it; a partition or a late join means whole stretches of others' scans were never
heard. Comparing maps cell by cell would cost a pass over the grid per peer; comparing *which
scans* each side knows is exact and cheap, because a UAV makes at most one scan per tick:

* the log keeps, per origin UAV, a bitmap of the ticks whose scan it knows, and the scans
  themselves ``(t, x, y, r)``;
* a *digest* is those bitmaps (up to a cut-off time); a peer ANDs its own bitmaps with the
  complement of the digest's and resends exactly the scans the sender lacks, including scans
  of third UAVs it relayed: so knowledge also crosses several radio hops.

Applying a scan twice changes nothing (the map is a max-CRDT), so the log also lets a receiver
skip scans it already applied.
"""

from __future__ import annotations

from collections.abc import Iterator

ORIGIN_MAX = 2**31 - 1  # "every origin from lo on" in a digest's range


class ScanLog:
    __slots__ = ("dt", "_bits", "_scans", "count", "_version", "_cut_cache")

    def __init__(self, dt: float):
        self.dt = dt
        self._bits: dict[int, bytearray] = {}  # origin -> bit k set: the scan of tick k is known
        self._scans: dict[int, dict[int, tuple[float, float, float, float]]] = {}
        self.count = 0
        self._version = 0  # bumped by every add: invalidates _cut_cache
        self._cut_cache: tuple[int, int, dict[int, bytes]] | None = None

    def tick_of(self, t: float) -> int:
        return round(t / self.dt)

    def add(self, origin: int, t: float, x: float, y: float, r: float) -> bool:
        """Record a scan; False if this origin's scan of that tick was known already (or ``t < 0``)."""
        k = round(t / self.dt)
        if k < 0:
            return False
        bits = self._bits.get(origin)
        if bits is None:
            bits = self._bits[origin] = bytearray()
            self._scans[origin] = {}
        i = k >> 3
        bit = 1 << (k & 7)
        if i < len(bits):
            old = bits[i]
            if old & bit:
                return False
            bits[i] = old | bit
        else:
            bits.extend(bytes(i - len(bits)))
            bits.append(bit)
        self._scans[origin][k] = (t, x, y, r)
        self.count += 1
        self._version += 1
        return True

    def _cut(self, k_cut: int) -> dict[int, bytes]:
        """Per origin, the bitmap bytes of ticks ``<= k_cut`` (trailing zero bytes dropped):
        exactly what a digest with that cut carries. Memoised until the next :meth:`add`, so the
        digests heard in one tick (same cut) are compared against one computation."""
        c = self._cut_cache
        if c is not None and c[0] == k_cut and c[1] == self._version:
            return c[2]
        n = (k_cut >> 3) + 1
        keep = (1 << ((k_cut & 7) + 1)) - 1  # bits 0..k_cut%8 of the last byte
        out = {}
        for origin in sorted(self._bits):
            b = self._bits[origin][:n]
            if len(b) == n:
                b[-1] &= keep
            out[origin] = bytes(b.rstrip(b"\0"))
        self._cut_cache = (k_cut, self._version, out)
        return out

    def digest(self, t_cut: float, start: int = 0, max_bytes: int | None = None
               ) -> tuple[int, int, tuple[tuple[int, bytes], ...], int]:
        """``(lo, hi, bitmaps, next_start)``: per origin (ascending) in ``[lo, hi]``, the bitmap of
        known scans at ticks ``<= t_cut`` (little-endian: bit ``k % 8`` of byte ``k // 8``).

        All origins if they fit in ``max_bytes`` of bitmaps; otherwise those from the
        ``start``-th known origin on that fit, and ``next_start`` says where the next digest
        should begin, so successive digests cover everything. An origin in ``[lo, hi]`` that is
        not listed is one this log knows nothing of.
        """
        k_cut = int(t_cut // self.dt)
        if k_cut < 0 or not self._bits:
            return 0, ORIGIN_MAX, (), 0
        cut = self._cut(k_cut)
        origins = list(cut)
        start = start if 0 <= start < len(origins) else 0
        out = []
        used = 0
        i = start
        while i < len(origins):
            b = cut[origins[i]]
            if max_bytes is not None and out and used + len(b) + 8 > max_bytes:
                break
            out.append((origins[i], b))
            used += len(b) + 8
            i += 1
        lo = 0 if start == 0 else origins[start]
        hi = ORIGIN_MAX if i == len(origins) else origins[i] - 1
        return lo, hi, tuple(out), (i if i < len(origins) else 0)

    def missing(self, lo: int, hi: int, bitmaps, t_cut: float, limit: int) -> Iterator[tuple[int, list[float]]]:
        """The scans this log knows at ticks ``<= t_cut`` of origins in ``[lo, hi]`` that the
        digest ``bitmaps`` lacks, as ``(origin, [t, x, y, r, ...])`` per origin (ascending), at
        most ``limit`` scans in all, oldest first within an origin."""
        k_cut = int(t_cut // self.dt)
        if k_cut < 0 or limit <= 0 or not self._bits:
            return
        theirs = dict(bitmaps)
        left = limit
        for origin, mine in self._cut(k_cut).items():
            if not lo <= origin <= hi or not mine:
                continue
            other = theirs.get(origin, b"")
            if other == mine:  # the usual case on a good radio: nothing to send
                continue
            lack = int.from_bytes(mine, "little") & ~int.from_bytes(other, "little")
            if not lack:
                continue
            scans = self._scans[origin]
            flat: list[float] = []
            while lack and left:
                low = lack & -lack
                flat.extend(scans[low.bit_length() - 1])
                lack ^= low
                left -= 1
            yield origin, flat
            if not left:
                return


__all__ = ["ORIGIN_MAX", "ScanLog"]
