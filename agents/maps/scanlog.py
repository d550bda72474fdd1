"""Every recent scan a UAV knows of, by origin and tick: what anti-entropy compares and resends.

A UAV's map is the union (per-cell max of last-seen times) of scan disks: its own, one per tick,
and those it heard in other UAVs' :class:`~comms.messages.ScanRecords`. A lost frame loses the
disks in it; a partition or a late join means whole stretches of others' scans were never
heard. Comparing maps cell by cell would cost a pass over the grid per peer; comparing *which
scans* each side knows is exact and cheap, because a UAV makes at most one scan per tick:

* the log keeps, per origin UAV, a bitmap of the ticks whose scan it knows, and the scans
  themselves ``(t, x, y, r)``;
* a *digest* is those bitmaps over a window of ticks; a peer ANDs its own bitmaps with the
  complement of the digest's and resends exactly the scans the sender lacks, including scans
  of third UAVs it relayed: so knowledge also crosses several radio hops.

Only the last ``horizon_s`` seconds are kept and compared: a scan that old carries little
information (``q`` is back near 1 after a few ``1/tau``) and memory stays bounded by
``origins x horizon_s / dt`` scans per UAV however long the run. Applying a scan twice changes
nothing (the map is a max-CRDT), so the log also lets a receiver skip scans it already applied.

Knowledge horizon (``[radio] sync_horizon_m``, default ``inf`` = none). Without one, a UAV's
log and map converge to every scan of its whole connected swarm: memory and digest size grow
with the swarm. With a horizon ``H`` a UAV applies to its map, logs (so relays and lists in its
digests) only the heard scans whose centre lies within ``H`` of where it is when it hears them
(its own scans always), and answers a digest only with scans within ``H`` of the digest's
sender (:meth:`ScanLog.missing`'s ``near``). Its log then holds the scans of the UAVs that flew
within ``H`` of its path over the last ``horizon_s``: it grows with local density, not with the
swarm. Both are still max-CRDTs: the log's state is a set of scans and its join the union
(:meth:`ScanLog.merge`), the map's the per-cell max of the applied disks; a filter with a fixed
centre commutes with both (``keep(A | B) = keep(A) | keep(B)``), so order, loss and duplicates
still cannot change the result. What "maps agree" then means is stated in
:class:`swarm.testing.invariants.MapAgreementChecker`.

Storage (issue 36, T5 and T6): one bit matrix per log, a row per origin and a column per tick in
a ring of ``cap`` ticks (tick ``k`` in column ``k % cap``), with the scans' centres in a matrix of
the same shape: adding a scan sets one bit and two doubles, forgetting clears whole columns, and
a digest or an answer is a few array operations over all origins at once (the window's bytes of
every row; their AND-NOT with a digest's rows; the horizon test on the centres of the lacking
scans; the limit by position). :class:`agents.maps.scanlog_oracle.OracleScanLog` is the same log
kept per origin in Python containers, the code this replaces: the specification the arrays are
tested against (``Simulation(tick_plane=False)`` runs it).
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from collections.abc import Iterable, Iterator
from itertools import groupby
from operator import itemgetter
from typing import cast

import numpy as np

ORIGIN_MAX = 2**31 - 1  # "every origin from lo on" in a digest's range
FORGET_SLACK_TICKS = 64

Scan = tuple[float, float, float, float]  # (t, x, y, r)
Bitmaps = tuple[tuple[int, bytes], ...]  # a digest's (origin, bits) pairs (ScanDigest.bitmaps)
Near = tuple[float, float, float]  # (x, y, H): only scans centred within H of (x, y)


def within(x: float, y: float, near: Near | None) -> bool:
    """Whether a scan centred at ``(x, y)`` lies inside the horizon ``near`` (None: no horizon)."""
    if near is None:
        return True
    dx, dy = x - near[0], y - near[1]
    return dx * dx + dy * dy <= near[2] * near[2]


_M64 = 0xFFFFFFFFFFFFFFFF
_U = np.uint64


def share_hash(origin: int, tick: int, key: int) -> int:
    """A well-mixed non-negative integer of a scan (its origin and tick) and an answer's round
    ``key``: which of the answerers of a digest sends that scan (``[radio] sync_split``)."""
    h = (origin * 0x9E3779B97F4A7C15 + tick * 0xC2B2AE3D27D4EB4F + (key & _M64) * 0x165667B19E3779F9) & _M64
    h ^= h >> 31
    h = (h * 0xBF58476D1CE4E5B9) & _M64
    return h ^ (h >> 29)


def share_hashes(origins: np.ndarray, ticks: np.ndarray, key: int) -> np.ndarray:
    """:func:`share_hash` of every ``(origins[i], ticks[i])`` (non-negative ints) at once (uint64:
    the same integers; numpy's unsigned arithmetic wraps modulo 2**64 as the masks do)."""
    with np.errstate(over="ignore"):
        h = (origins.astype(_U) * _U(0x9E3779B97F4A7C15) + ticks.astype(_U) * _U(0xC2B2AE3D27D4EB4F)
             + _U(((key & _M64) * 0x165667B19E3779F9) & _M64))
        h ^= h >> _U(31)
        h *= _U(0xBF58476D1CE4E5B9)
        h ^= h >> _U(29)
    return h


Share = tuple[int, int, int]  # (slot, of, key): only the scans whose share_hash(origin, tick, key) % of == slot


def kept(origins: np.ndarray, ticks: np.ndarray, newest: int, share: Share | None) -> np.ndarray | None:
    """Which of the lacking scans ``(origins[i], ticks[i])`` (in answer order) an answer sends
    under flow control (``[radio] sync_split`` and ``sync_resend_cap``): with ``share``, those of
    this answerer's slot; of those, with ``newest > 0``, the ``newest`` of the latest ticks
    (ties: lower origin first). A boolean mask, or None: all of them. :meth:`ScanLog.missing`
    and its oracle both take their scans through this one rule."""
    keep: np.ndarray | None = None
    if share is not None:
        slot, of, key = share
        keep = share_hashes(origins, ticks, key) % _U(of) == _U(slot)
    if 0 < newest < (len(ticks) if keep is None else int(np.count_nonzero(keep))):
        idx = np.flatnonzero(keep) if keep is not None else np.arange(len(ticks))
        order = np.lexsort((origins.take(idx), -ticks.take(idx).astype(np.int64)))  # latest tick, then origin
        keep = np.zeros(len(ticks), bool)
        keep[idx.take(order[:newest])] = True
    return keep


def _round_cap(ticks: int) -> int:
    """A ring size of at least ``ticks``: a multiple of 64 ticks (8 bytes of a row)."""
    return -(-max(ticks, 64) // 64) * 64


class ScanLog:
    __slots__ = ("dt", "horizon_ticks", "_floor", "count", "_version", "_cut_cache",
                 "_row", "_origins", "_sorted", "_rows", "_recs", "_bits", "_cen", "_bv", "_cv",
                 "_cap", "_cap8", "_lo", "_hi")

    def __init__(self, dt: float, horizon_s: float = math.inf):
        self.dt = dt
        self.horizon_ticks = math.inf if math.isinf(horizon_s) else max(1, math.ceil(horizon_s / dt))
        self._floor = 0  # ticks before this are forgotten (forget_before)
        self.count = 0  # scans held
        self._version = 0  # bumped by every change: invalidates _cut_cache
        self._cut_cache: tuple[int, int, int, dict[int, bytes], Bitmaps] | None = None
        # Rows: origin -> row (in the order origins were first heard; with its scans), row -> origin, and the
        # origins ascending with their rows (built again when a row is added: None until then).
        self._row: dict[int, tuple[int, dict[int, Scan]]] = {}  # (its row, _recs[row])
        self._origins: list[int] = []
        self._sorted: list[int] | None = []
        self._rows = np.zeros(0, np.intp)
        self._recs: list[dict[int, Scan]] = []  # row -> tick -> the scan as it was added (shared tuple)
        # The ring: tick k of row r is bit k % 8 of _bits[r, (k % cap) // 8] (set: the scan is
        # known), its centre _cen[r, 2 (k % cap)] and the next double (x, y; stale where the bit
        # is clear). Every tick held lies in [_lo, _hi) (multiples of 8, _hi - _lo <= cap; empty
        # when _lo >= _hi), so no two share a column; the ring grows when that would not hold.
        # _bv and _cv: the same memory as flat memoryviews (add_tick's single bits and doubles).
        # The ring starts small and grows by half as the ticks held spread (to about
        # horizon_ticks + FORGET_SLACK_TICKS + a digest period, once forgetting keeps pace).
        cap = _round_cap(0)
        self._cap, self._cap8 = cap, cap // 8
        self._set_ring(np.zeros((4, cap // 8), np.uint8), np.zeros((4, 2 * cap), np.float64))
        self._lo = self._hi = 0

    def add(self, origin: int, t: float, x: float, y: float, r: float) -> bool:
        """Record a scan. False if this origin's scan of that tick was known already (or
        ``t < 0``): the caller need not apply it again. A scan older than what the log keeps
        (see :meth:`forget_before`) is reported new (applying it twice is harmless), not stored."""
        tick = round(t / self.dt)
        if tick < 0:
            return False
        return self.add_tick(origin, tick, (t, x, y, r))

    def add_tick(self, origin: int, tick: int, scan: Scan) -> bool:
        """:meth:`add` of ``scan = (t, x, y, r)`` whose tick ``round(t / dt) >= 0`` the caller
        knows already (a heard frame's scans are checked once for all receivers:
        :func:`agents.inbox.check_frame`); the tuple is stored as it is (shared, immutable)."""
        if tick < self._floor:
            return True
        held = self._row.get(origin)
        if held is None:
            held = self._new_row(origin)
        row, recs = held
        if tick in recs:  # (= its bit set)
            return False
        recs[tick] = scan
        if not self._lo <= tick < self._hi:
            self._extend(tick)
        cap = self._cap
        c = tick % cap
        self._bv[row * self._cap8 + (c >> 3)] |= 1 << (tick & 7)
        j = 2 * (row * cap + c)
        cv = self._cv
        cv[j] = scan[1]
        cv[j + 1] = scan[2]
        self.count += 1
        self._version += 1
        return True

    def add_ticks(self, heard: Iterable[tuple[int, int, Scan, object]]) -> list[bool]:
        """:meth:`add_tick` of each ``(origin, tick, scan, ...)`` of ``heard`` in order (a
        receiver's heard scans of a tick, :data:`agents.inbox.HeardScan`: anything after the
        scan is ignored), in one call: whether each was new (of two equal ones in ``heard``
        the first). The same log as the calls one by one (``tests/test_scanlog.py``)."""
        out: list[bool] = []
        append = out.append
        floor = self._floor
        rows = self._row
        lo, hi, cap, cap8, bv, cv = self._lo, self._hi, self._cap, self._cap8, self._bv, self._cv
        added = 0
        for origin, tick, scan, _ in heard:
            if tick < floor:
                append(True)
                continue
            held = rows.get(origin)
            if held is None:
                held = self._new_row(origin)  # (may make the ring matrices anew)
                bv, cv = self._bv, self._cv
            row, recs = held
            if tick in recs:
                append(False)
                continue
            recs[tick] = scan
            if not lo <= tick < hi:
                self._extend(tick)  # (may make the ring anew, larger)
                lo, hi, cap, cap8, bv, cv = self._lo, self._hi, self._cap, self._cap8, self._bv, self._cv
            c = tick % cap
            bv[row * cap8 + (c >> 3)] |= 1 << (tick & 7)
            j = 2 * (row * cap + c)
            cv[j] = scan[1]
            cv[j + 1] = scan[2]
            added += 1
            append(True)
        if added:
            self.count += added
            self._version += added
        return out

    def _new_row(self, origin: int) -> tuple[int, dict[int, Scan]]:
        """The row of an origin heard for the first time, and its scans by tick (the matrices
        grow by half as many rows)."""
        row = len(self._origins)
        if row == len(self._bits):
            n = row + max(4, row // 2)
            bits = np.zeros((n, self._cap8), np.uint8)
            bits[:row] = self._bits
            cen = np.zeros((n, 2 * self._cap), np.float64)
            if self._lo < self._hi:  # (only the centres of the ticks held: the rest of a row stays untouched memory)
                cols = np.arange(self._lo, self._hi) % self._cap
                cen.view(np.complex128)[:row, cols] = self._cen.view(np.complex128)[:row, cols]
            self._set_ring(bits, cen)
        recs: dict[int, Scan] = {}
        self._row[origin] = (row, recs)
        self._origins.append(origin)
        self._recs.append(recs)
        self._sorted = None
        return row, recs

    def _set_ring(self, bits: np.ndarray, cen: np.ndarray) -> None:
        self._bits, self._cen = bits, cen
        self._bv = bits.data.cast("B")
        self._cv = cen.data.cast("B").cast("d")
        self._cut_cache = None

    def _extend(self, tick: int) -> None:
        """Widen ``[_lo, _hi)`` to take ``tick``; a larger ring if the ticks held would then
        share columns (the columns of the ticks held move to their new places)."""
        t8 = tick & ~7
        lo, hi = self._lo, self._hi
        if lo >= hi:  # empty: every column is clear
            self._lo, self._hi = t8, t8 + 8
            return
        new_lo, new_hi = min(lo, t8), max(hi, t8 + 8)
        if new_hi - new_lo > self._cap:
            cap = _round_cap(max(new_hi - new_lo, self._cap + self._cap // 2))
            rows = len(self._bits)
            bits = np.zeros((rows, cap // 8), np.uint8)
            cen = np.zeros((rows, 2 * cap), np.float64)
            b8 = np.arange(lo >> 3, hi >> 3)
            bits[:, b8 % (cap // 8)] = self._bits[:, b8 % self._cap8]
            ticks = np.arange(lo, hi)
            cen.view(np.complex128)[:, ticks % cap] = self._cen.view(np.complex128)[:, ticks % self._cap]
            self._cap, self._cap8 = cap, cap // 8
            self._set_ring(bits, cen)
        self._lo, self._hi = new_lo, new_hi

    def _order(self) -> tuple[list[int], np.ndarray]:
        """The origins ascending, and their rows in that order."""
        ordered = self._sorted
        if ordered is None:
            origins = self._origins
            rows = sorted(range(len(origins)), key=origins.__getitem__)
            ordered = self._sorted = [origins[r] for r in rows]
            self._rows = np.array(rows, np.intp)
        return ordered, self._rows

    def scans(self) -> Iterator[tuple[int, Scan]]:
        """Every scan held, as ``(origin, (t, x, y, r))``, by origin then tick."""
        origins, rows = self._order()
        for origin, row in zip(origins, rows.tolist()):
            recs = self._recs[row]
            for k in sorted(recs):
                yield origin, recs[k]

    def merge(self, other: ScanLog, near: Near | None = None) -> int:
        """The state-based join: add every scan of ``other`` (inside ``near``, if given) to this
        log; returns how many were new. The actor does the same one heard scan at a time
        (:meth:`add`), so a log is the union of what it heard, whatever the order."""
        return sum(self.add(o, *scan) for o, scan in other.scans() if within(scan[1], scan[2], near))

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
        lo, hi = self._lo, self._hi
        if lo >= hi or lo >= k_min:
            return
        end = min(hi, k_min)  # the columns of ticks lo..end - 1 are cleared
        nrows = len(self._origins)
        cols = (np.arange(lo >> 3, end >> 3) % self._cap8)
        sub = self._bits[:nrows, cols]
        if sub.any():
            rows, j = np.nonzero(np.unpackbits(sub, axis=1, bitorder="little"))
            recs = self._recs
            for r, k in zip(rows.tolist(), (j + lo).tolist()):
                del recs[r][k]
            self.count -= len(rows)
            self._bits[:nrows, cols] = 0
        self._lo = end  # (= hi: empty)
        self._version += 1

    def window(self, t_cut: float) -> tuple[int, int]:
        """``(tick0, k_cut)``: the ticks a digest cut at ``t_cut`` covers (tick0 a multiple of 8)."""
        k_cut = math.floor(t_cut / self.dt)
        lo = 0 if math.isinf(self.horizon_ticks) else max(0, k_cut - cast(int, self.horizon_ticks))
        return lo & ~7, k_cut

    def _rows_window(self, tick0: int, k_cut: int, a: int, b: int | None) -> tuple[np.ndarray, int, int] | None:
        """The bits of ticks ``tick0..k_cut`` (``tick0`` a multiple of 8, ``<= k_cut``) of the
        ``a``-th to ``b - 1``-th origins in ascending order (``b`` None: of every row, in row
        order) that can be set, as ``(part, jlo, c0)``: ``part[i, j]`` is the byte of ticks
        ``tick0 + 8 (jlo + j) ..`` of the ``i``-th (bit ``k % 8`` for tick ``k``; ticks after
        ``k_cut`` clear), every byte before ``jlo`` and after ``part`` is clear, and the ring
        column of ``part[:, 0]`` is ``c0``, the others following it (wrapping). A copy. None:
        nothing held there."""
        lo, hi = self._lo, self._hi
        n = ((k_cut - tick0) >> 3) + 1
        jlo, jhi = max(0, (lo - tick0) >> 3), min(n, (hi - tick0) >> 3)
        if lo >= hi or jhi <= jlo or (b is not None and a >= b):
            return None
        c0 = ((tick0 >> 3) + jlo) % self._cap8
        m = jhi - jlo
        rows: slice | np.ndarray = slice(0, len(self._origins)) if b is None else self._order()[1][a:b]
        if c0 + m <= self._cap8:
            part = self._bits[rows, c0:c0 + m]
            if b is None:
                part = part.copy()
        else:
            part = self._bits[rows].take(np.arange(c0, c0 + m) % self._cap8, axis=1)
        if jhi == n:
            part[:, -1] &= (1 << (((k_cut - tick0) & 7) + 1)) - 1  # the last byte's ticks up to k_cut
        return part, jlo, c0

    def _cut(self, tick0: int, k_cut: int) -> tuple[dict[int, bytes], Bitmaps]:
        """Per origin, the bitmap bytes of ticks ``tick0..k_cut`` (bit ``k - tick0``; trailing
        zero bytes dropped, origins with none left out): what a digest with that window
        carries, as a dict and as the digest's tuple. Memoised until the log changes, so the
        digests heard in one tick (same window) are compared against one computation."""
        c = self._cut_cache
        if c is not None and c[0] == tick0 and c[1] == k_cut and c[2] == self._version:
            return c[3], c[4]
        out: dict[int, bytes] = {}
        got = self._rows_window(tick0, k_cut, 0, None)
        if got is not None:
            part, jlo, _ = got
            m = part.shape[1]
            buf = part.tobytes()
            pad = bytes(jlo)
            origins, rows = self._order()
            for origin, r in zip(origins, rows.tolist()):
                b = buf[r * m:r * m + m].rstrip(b"\0")
                if b:
                    out[origin] = pad + b
        items = tuple(out.items())
        self._cut_cache = (tick0, k_cut, self._version, out, items)
        return out, items

    def digest(self, t_cut: float, start: int = 0, max_bytes: int | None = None
               ) -> tuple[int, int, int, Bitmaps, int]:
        """``(tick0, lo, hi, bitmaps, next_start)``: per origin (ascending) in ``[lo, hi]``, the
        bitmap of known scans at ticks ``tick0..t_cut`` (little-endian: bit ``j % 8`` of byte
        ``j // 8`` is tick ``tick0 + j``).

        All origins if they fit in ``max_bytes`` of bitmaps; otherwise those from the
        ``start``-th on that fit, and ``next_start`` says where the next digest should begin,
        so successive digests cover everything. An origin in ``[lo, hi]`` that is not listed is
        one this log knows no scan of in the window.
        """
        tick0, k_cut = self.window(t_cut)
        if k_cut < 0:
            return 0, 0, ORIGIN_MAX, (), 0
        _, items = self._cut(tick0, k_cut)
        if max_bytes is None or sum(len(b) + 8 for _, b in items) <= max_bytes:
            return tick0, 0, ORIGIN_MAX, items, 0
        start = start if 0 <= start < len(items) else 0
        out: list[tuple[int, bytes]] = []
        used = 0
        i = start
        while i < len(items):
            b = items[i][1]
            if out and used + len(b) + 8 > max_bytes:
                break
            out.append(items[i])
            used += len(b) + 8
            i += 1
        lo = 0 if start == 0 else items[start][0]
        hi = ORIGIN_MAX if i == len(items) else items[i][0] - 1
        return tick0, lo, hi, tuple(out), (i if i < len(items) else 0)

    def missing(self, tick0: int, lo: int, hi: int, bitmaps: Bitmaps, t_cut: float, limit: int,
                near: Near | None = None, *, newest: int = 0, share: Share | None = None
                ) -> Iterator[tuple[int, list[float]]]:
        """The scans this log holds at ticks ``tick0..t_cut`` of origins in ``[lo, hi]`` that
        the digest ``bitmaps`` (relative to ``tick0``) lacks, as ``(origin, [t, x, y, r, ...])``
        per origin (ascending), at most ``limit`` scans in all, oldest first within an origin.
        ``near``: only scans centred inside that horizon (the digest sender's: it would not
        keep the others, and would be sent them again at every digest). ``newest`` and
        ``share`` (flow control, :func:`kept`): of those, only this answerer's share, and only
        the ``newest`` latest (0: all), before ``limit`` applies."""
        k_cut = math.floor(t_cut / self.dt)
        if k_cut < 0 or limit <= 0 or not self._row or tick0 < 0 or tick0 & 7 or tick0 > k_cut:
            return
        if lo == 0 and hi == ORIGIN_MAX and len(bitmaps) <= len(self._origins) and bitmaps == self._cut(tick0, k_cut)[1]:
            return  # the usual case on a good radio: the same knowledge, nothing to send (the digests
            # heard in a tick share a window: one _cut, memoised, for all of them)
        origins, rows = self._order()
        a, b = bisect_left(origins, lo), bisect_right(origins, hi)
        got = self._rows_window(tick0, k_cut, a, b)
        if got is None:
            return
        mine, jlo, c0 = got
        # AND-NOT with the digest's bytes for the same origins and ticks (inverted as bytes: a
        # bit clear where the sender knows the scan; an origin it does not list, all set).
        m = mine.shape[1]
        get = dict(bitmaps).get
        end = jlo + m
        unknown = b"".join([get(o, b"")[jlo:end].ljust(m, b"\0") for o in origins[a:b]]).translate(_NOT)
        mine &= np.frombuffer(unknown, np.uint8).reshape(mine.shape)
        if not np.count_nonzero(mine):
            return
        lacks = np.unpackbits(mine, bitorder="little").view(bool).nonzero()[0]  # bit i * 8 m + j: row i, tick
        row, j = np.divmod(lacks, 8 * m)  # tick0 + 8 jlo + j
        if near is not None:
            # The centres of the lacking scans, each (x, y) as one complex x + iy: within() of
            # each, the same operations on the same doubles.
            cap = self._cap
            col = (8 * c0 + j) % cap if 8 * (c0 + m) > cap else 8 * c0 + j
            z = self._cen.view(np.complex128)[rows[a:b].take(row), col]
            z -= complex(near[0], near[1])  # (x - near[0]) + i (y - near[1])
            dx, dy = z.real, z.imag
            inside = dx * dx + dy * dy <= near[2] * near[2]
            row, j = row[inside], j[inside]
        recs, rlist = self._recs, rows.tolist()
        first = tick0 + 8 * jlo
        if newest > 0 or share is not None:
            keep = kept(np.array(origins[a:b], np.int64).take(row), j + first, newest, share)
            if keep is not None:
                row, j = row[keep], j[keep]
        # The first `limit`, by origin then tick (the rows' order, then the bits').
        for i, ticks in groupby(zip(row[:limit].tolist(), j[:limit].tolist()), itemgetter(0)):
            scans = recs[rlist[a + i]]
            yield origins[a + i], [v for _, k in ticks for v in scans[first + k]]


_NOT = bytes(255 - i for i in range(256))  # bytes.translate table: every bit inverted


__all__ = ["ORIGIN_MAX", "Near", "ScanLog", "Share", "kept", "share_hash", "share_hashes", "within"]
