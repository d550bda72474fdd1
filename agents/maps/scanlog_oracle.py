"""The scan log kept per origin in Python containers: the oracle of :mod:`agents.maps.scanlog`.

Before issue 36 this was :class:`~agents.maps.scanlog.ScanLog` itself. It stays, unchanged in what
it does, as the specification the array log is tested against (``tests/test_scanlog.py``'s state
machine compares every result of the two) and is what ``Simulation(tick_plane=False)`` builds.
Per origin: a bitmap of the ticks whose scan it knows (a ``bytearray`` from a base tick on, which
grows downwards when an older scan arrives), the scans by tick, and their centres in an
``array('d')`` for :meth:`OracleScanLog.missing`'s horizon test.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Iterator
from itertools import groupby
from operator import itemgetter
from typing import Any, cast

import numpy as np

from agents.maps.scanlog import FORGET_SLACK_TICKS, ORIGIN_MAX, Bitmaps, Near, ScanLog, Share, kept

# Per origin: [bitmap, its base tick, tick -> scan, centres] (see OracleScanLog.__init__).
_Origin = list[Any]  # (a list, mutated in place: cheaper than an object on add_tick's path)


class OracleScanLog(ScanLog):
    """:class:`ScanLog` kept per origin in Python containers (a subclass so that it goes wherever
    a ScanLog does; it uses none of the arrays). ``add``, ``merge``, ``window`` and ``digest``
    are ScanLog's own, over this class's ``_cut``."""

    __slots__ = ("_org", "_scans")

    def __init__(self, dt: float, horizon_s: float = math.inf):  # (not ScanLog's: no arrays)
        self.dt = dt
        self.horizon_ticks = math.inf if math.isinf(horizon_s) else max(1, math.ceil(horizon_s / dt))
        # origin -> [bits, base, scans, centres], one record per origin (add_tick, the receivers'
        # hot path, looks up one dict instead of several):
        # bits: bitmap of ticks >= base (bit k - base set: the scan of tick k is known), base a
        #   multiple of 8 (bitmaps start on a byte);
        # scans: tick -> (t, x, y, r);
        # centres: x and y of the scan of tick k at 2 (k - base) and 2 (k - base) + 1, two
        #   doubles per bit of `bits` (0.0 where no scan is known: the bits say which are): what
        #   missing() tests a digest's lacking scans against the sender's horizon with, all at
        #   once as one numpy array (a digest lacks hundreds of scans outside that horizon, and
        #   lacks them again at every digest).
        self._org: dict[int, _Origin] = {}
        self._floor = 0  # ticks before this are forgotten (forget_before)
        self._scans: dict[int, dict[int, tuple[float, float, float, float]]] = {}  # origin -> its scans (as in _org)
        self.count = 0  # scans held
        self._version = 0  # bumped by every change: invalidates _cut_cache
        self._cut_cache: tuple[int, int, int, dict[int, bytes], Bitmaps] | None = None

    def add_tick(self, origin: int, tick: int, scan: tuple[float, float, float, float]) -> bool:
        """:meth:`add` of ``scan = (t, x, y, r)`` whose tick ``round(t / dt) >= 0`` the caller
        knows already (a heard frame's scans are checked once for all receivers:
        :func:`agents.inbox.check_frame`); the tuple is stored as it is (shared, immutable)."""
        if tick < self._floor:
            return True
        entry = self._org.get(origin)
        if entry is None:
            entry = self._org[origin] = [bytearray(), tick & ~7, {}, array("d")]
            self._scans[origin] = entry[2]
        bits: bytearray = entry[0]
        base: int = entry[1]
        centres: array[float] = entry[3]
        if tick < base:  # an older scan (resent, or delayed): the bitmap grows downwards
            grow = (base - (tick & ~7)) >> 3
            bits[:0] = bytes(grow)
            centres[:0] = array("d", bytes(128 * grow))  # (16 doubles a byte of bits)
            base = entry[1] = base - 8 * grow
        k = tick - base
        i = k >> 3
        bit = 1 << (k & 7)
        if i < len(bits):
            old = bits[i]
            if old & bit:
                return False
            bits[i] = old | bit
        else:
            centres.frombytes(bytes(128 * (i + 1 - len(bits))))
            bits.extend(bytes(i - len(bits)))
            bits.append(bit)
        entry[2][tick] = scan
        centres[2 * k] = scan[1]
        centres[2 * k + 1] = scan[2]
        self.count += 1
        self._version += 1
        return True

    def scans(self) -> Iterator[tuple[int, tuple[float, float, float, float]]]:
        """Every scan held, as ``(origin, (t, x, y, r))``, by origin then tick."""
        for origin in sorted(self._scans):
            byt = self._scans[origin]
            for k in sorted(byt):
                yield origin, byt[k]

    def forget_before(self, t: float) -> None:
        """Drop scans (and their bits) of ticks well before ``t - horizon_s``: a slack of
        :data:`FORGET_SLACK_TICKS` keeps every tick of the log's own digest windows (cut a few
        seconds back), or it would claim to lack scans it dropped and be sent them every time."""
        if math.isinf(self.horizon_ticks):
            return
        k_min = (round(t / self.dt) - cast(int, self.horizon_ticks) - FORGET_SLACK_TICKS) & ~7  # (finite: an int)
        if k_min <= self._floor:
            return
        self._floor = k_min
        for entry in self._org.values():
            base = entry[1]
            if base >= k_min:
                continue
            drop = (k_min - base) >> 3
            del entry[0][:drop]
            del entry[3][:16 * drop]
            entry[1] = base + 8 * drop
            scans = entry[2]
            for k in range(base, k_min):  # a few ticks per call: the log is trimmed as it goes
                if scans.pop(k, None) is not None:
                    self.count -= 1
            self._version += 1

    def _cut(self, tick0: int, k_cut: int) -> tuple[dict[int, bytes], Bitmaps]:
        """Per origin, the bitmap bytes of ticks ``tick0..k_cut`` (bit ``k - tick0``; trailing
        zero bytes dropped, origins with none left out): what a digest with that window
        carries, as a dict and as the digest's tuple. Memoised until the log changes, so the
        digests heard in one tick (same window) are compared against one computation."""
        c = self._cut_cache
        if c is not None and c[0] == tick0 and c[1] == k_cut and c[2] == self._version:
            return c[3], c[4]
        out: dict[int, bytes] = {}
        org = self._org
        n = ((k_cut - tick0) >> 3) + 1
        last = (1 << (((k_cut - tick0) & 7) + 1)) - 1  # the last byte's ticks up to k_cut
        for origin in sorted(org):
            bits, base = org[origin][0], org[origin][1]
            if base > k_cut:
                continue
            i = (tick0 - base) >> 3  # the window's first byte in bits (tick0, base: multiples of 8)
            b: bytearray = bits[i:i + n] if i >= 0 else bytearray(-i) + bits[:n + i]  # (< 0: pad)
            if len(b) == n:
                b[-1] &= last
            packed = bytes(b.rstrip(b"\0"))
            if packed:
                out[origin] = packed
        items = tuple(out.items())
        self._cut_cache = (tick0, k_cut, self._version, out, items)
        return out, items

    def missing(self, tick0: int, lo: int, hi: int, bitmaps: Bitmaps, t_cut: float, limit: int,
                near: Near | None = None, *, newest: int = 0, share: Share | None = None
                ) -> Iterator[tuple[int, list[float]]]:
        """The scans this log holds at ticks ``tick0..t_cut`` of origins in ``[lo, hi]`` that
        the digest ``bitmaps`` (relative to ``tick0``) lacks, as ``(origin, [t, x, y, r, ...])``
        per origin (ascending), at most ``limit`` scans in all, oldest first within an origin.
        ``near``: only scans centred inside that horizon (the digest sender's: it would not
        keep the others, and would be sent them again at every digest). ``newest``, ``share``:
        flow control, as :meth:`ScanLog.missing` (:func:`~agents.maps.scanlog.kept`)."""
        k_cut = math.floor(t_cut / self.dt)
        if k_cut < 0 or limit <= 0 or not self._org or tick0 < 0 or tick0 & 7 or tick0 > k_cut:
            return
        mine, items = self._cut(tick0, k_cut)
        if lo == 0 and hi == ORIGIN_MAX and bitmaps == items:
            return  # the usual case on a good radio: the same knowledge, nothing to send
        theirs = dict(bitmaps)
        differ = [(origin, b, other) for origin, b in mine.items()
                  if lo <= origin <= hi and (other := theirs.get(origin, b"")) != b]
        if not differ:
            return
        # All at once, a row of w ticks (tick0 on) per origin that differs: bit r * w + j set
        # where this log knows the scan of tick tick0 + j of the r-th and the digest does not.
        n = ((k_cut - tick0) >> 3) + 1
        w = 8 * n
        have = np.frombuffer(b"".join([b.ljust(n, b"\0") for _, b, _ in differ]), np.uint8)
        known = np.frombuffer(b"".join([other[:n].ljust(n, b"\0") for _, _, other in differ]), np.uint8)
        lacks = np.flatnonzero(np.unpackbits(have & ~known, bitorder="little").view(bool))
        if near is not None and lacks.size:
            lacks = lacks[_inside(lacks, w, tick0, [self._org[origin] for origin, _, _ in differ], near)]
        if (newest > 0 or share is not None) and lacks.size:
            r, j = np.divmod(lacks, w)
            keep = kept(np.array([origin for origin, _, _ in differ], np.int64).take(r), j + tick0, newest, share)
            if keep is not None:
                lacks = lacks[keep]
        # The first `limit`, by origin then tick (the rows' order, then the bits').
        row, j = np.divmod(lacks[:limit], w)
        for r, ticks in groupby(zip(row.tolist(), (j + tick0).tolist()), itemgetter(0)):
            origin = differ[r][0]
            scans = self._org[origin][2]
            yield origin, [v for _, k in ticks for v in scans[k]]


def _inside(lacks: np.ndarray, w: int, tick0: int, entries: list[_Origin], near: Near) -> np.ndarray:
    """Which of the bits ``lacks`` (bit ``r * w + j``: the scan of tick ``tick0 + j`` of
    ``entries[r]``) are scans centred within the horizon ``near``: :func:`within` of each,
    as one array (the same operations on the same doubles, so the same results)."""
    row = lacks // w
    # Every entry's centres one after the other, each pair as one complex x + iy (one gather
    # for both): bit r * w + j's scan is at index r * w + j + shift[r].
    shift, start = [], 0
    for r, entry in enumerate(entries):
        shift.append(start + tick0 - entry[1] - r * w)
        start += len(entry[3]) >> 1
    z = np.frombuffer(b"".join([entry[3] for entry in entries]), np.complex128).take(lacks + np.array(shift).take(row))
    z -= complex(near[0], near[1])  # (x - near[0]) + i (y - near[1])
    dx, dy = z.real, z.imag
    inside: np.ndarray = dx * dx + dy * dy <= near[2] * near[2]
    return inside


__all__ = ["OracleScanLog"]
