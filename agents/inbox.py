"""What a UAV hears: its inbox merged into its map, scan log and knowledge.

A broadcast frame reaches hundreds of UAVs in a dense swarm as the same bytes, decoded once
(:class:`comms.framecache.DecodeCache`). Checking its numbers (:func:`check_frame`) depends only
on the frame, the receiver's clock ``t`` and the area's bounds, which every receiver in a tick
shares, so the result (:class:`Heard`) is kept beside the decoded frame: a receiver makes one
call per frame (:meth:`DecodeCache.derive`, keyed by ``(t, bounds)``) and gets the checked
frame, and :meth:`Inbox.merge` only does what depends on its own state: its knowledge horizon,
its scan log, its map, its peers. A pure function of ``(frame, t, bounds)``: the memo changes
how often it runs, never what a receiver gets. On the tick plane the cache holds frame records
(the sender's packed messages, unchecked) and :func:`check_frame` reads a record into its
Heard in one pass, with decoding's own checks (the same Heard, or the same FrameError).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Iterable, Sequence
from functools import partial
from itertools import compress
from typing import Any, NamedTuple, Protocol

from agents.knowledge import Knowledge, TrackRow
from agents.maps.grid import MISSING as _MISSING  # a memo miss (None is a memoised value: a disk off the grid)
from agents.maps.grid import DiskKey, Grid
from agents.maps.scanlog import ScanLog
from agents.maps.umap import UncertaintyMap
from comms.codec import (
    K_DIGEST,
    K_HELLO,
    K_INTENT,
    K_SCAN,
    K_THREATS,
    K_TRACK_DIGEST,
    K_TRACKS,
    AuthError,
    Frame,
    FrameError,
    FrameRecord,
    decode,
    message_kind,
    read_digest,
    read_header,
    read_hello,
    read_intent,
    read_scans,
    read_threat_items,
    read_track_digest,
    read_track_item,
    read_track_items,
)
from comms.framecache import DecodeCache
from comms.messages import (
    MODE_SEARCH,
    MODE_SURVEIL,
    Hello,
    Intent,
    ScanDigest,
    ScanRecords,
    Threats,
    TrackDigest,
    TrackItem,
    Tracks,
)
from comms.settings import RadioSettings

# What a receiver accepts of heard numbers: ids below 2**31, speeds and velocities within
# 10 km/s, headings within 1000 rad, track values within 1e12, digest cuts no earlier than
# 1e9 s before the start. Far beyond anything honest, far below overflow.
MAX_ID = 2**31
MAX_SPEED = 1.0e4
MAX_ANGLE = 1.0e3
MAX_VALUE = 1.0e12
MAX_TIME = 1.0e9

# A plausible scan of a frame: (origin, tick, (t, x, y, r), (x, y, r)), the last its disk's key
# in the grid's memo (Grid.disk_lookup). Not the disk itself: kept with the frame, disks would
# outlive the grid's bounded memo (a resent frame can carry hundreds of scans).
HeardScan = tuple[int, int, tuple[float, float, float, float], DiskKey]
Bounds = tuple[float, float, float, float]  # (max scan radius, width, height, dt): see check_frame


class Heard(NamedTuple):
    """A frame's messages as a receiver at ``t`` accepts them (in the frame's order per kind).
    (An immutable named tuple: one is built per frame heard, cheaper than a frozen dataclass.)"""

    t_frame: float  # the frame's time (what heard poses and intents are stamped with)
    scans: tuple[HeardScan, ...]
    ignored: int  # implausible scans (counters.scans_ignored)
    strange: int  # other messages no honest UAV sends (counters.messages_ignored)
    hellos: tuple[Hello, ...]
    intents: tuple[Intent, ...]
    tracks: tuple[TrackItem, ...]  # every sane item of every Tracks message, in order
    threats: tuple[tuple[int, float, float, float, float], ...]
    digests: tuple[ScanDigest | TrackDigest, ...]  # (track digests: issue 36, M1)


# --- (issue 36, M1) track digests: the one plausibility rule, for both readers below ---------

def sane_track_digest(dg: TrackDigest, t: float) -> bool:
    """Whether a heard :class:`TrackDigest` is one an honest UAV at or before ``t`` could send:
    ids in range, its time and its sightings' times not after ``t`` (nor before the run)."""
    return (0 <= dg.uav < MAX_ID and 0.0 <= dg.t <= t and all(0 <= g < MAX_ID for g in dg.targets)
            and all(0.0 <= tg <= t for tg in dg.times) and all(0 <= th < MAX_ID for th in dg.threats))

# ---------------------------------------------------------------------------------------------


def check_frame(frame: Frame | FrameRecord, t: float, bounds: Bounds) -> Heard:
    """The messages of ``frame`` a receiver at ``t`` accepts. ``bounds`` = ``(max_r, width,
    height, dt)``: places may lie up to ``max_r`` outside the ``width x height`` area, scan radii
    up to ``max_r``; times not after ``t``; ids and speeds in ranges no arithmetic can overflow.
    A frame stamped in the future (or before the run) is ignored whole. Each plausible scan
    comes with its tick (``round(t / dt)``, the scan log's) and its disk's key (in any grid of
    that size: each receiver looks it up in its own).

    ``frame``: decoded (the per-actor path, the oracle), or its unchecked
    :class:`~comms.codec.FrameRecord` (the tick plane, :class:`~comms.framecache.DecodeCache`
    with ``records``): checked here as :func:`~comms.codec.decode` checks what msgpack gives, by
    the codec's own readers, in the same order, in the same pass as the checks above, with no
    Frame, ScanRecords or Tracks object built; :class:`~comms.codec.FrameError` where decoding
    raises it, else the Heard of the decoded frame."""
    if type(frame) is FrameRecord:
        return _check_record(frame, t, bounds)
    max_r, width, height, dt = bounds
    ft = frame.t
    if not 0.0 <= ft <= t:
        return Heard(ft, (), 0, len(frame.messages), (), (), (), (), ())
    lo_x, hi_x, lo_y, hi_y = -max_r, width + max_r, -max_r, height + max_r
    scans: list[HeardScan] = []
    hellos: list[Hello] = []
    intents: list[Intent] = []
    tracks: list[TrackItem] = []
    threats: list[tuple[int, float, float, float, float]] = []
    digests: list[ScanDigest | TrackDigest] = []
    ignored = strange = 0
    for m in frame.messages:
        if type(m) is ScanRecords:
            origin = m.uav
            it = iter(m.records)
            for tr, x, y, rr in zip(it, it, it, it):
                # A scan from the future would pin cells at q=0: only accept the past.
                if 0.0 <= tr <= t and 0.0 <= rr <= max_r and lo_x <= x <= hi_x and lo_y <= y <= hi_y:
                    scans.append((origin, round(tr / dt), (tr, x, y, rr), (x, y, rr)))
                else:
                    ignored += 1
        elif type(m) is Hello:
            if (0 <= m.uav < MAX_ID and lo_x <= m.x <= hi_x and lo_y <= m.y <= hi_y
                    and 0.0 <= m.v <= MAX_SPEED and -MAX_ANGLE <= m.theta <= MAX_ANGLE):
                hellos.append(m)
            else:
                strange += 1
        elif type(m) is Intent:
            if 0 <= m.uav < MAX_ID and lo_x <= m.wx <= hi_x and lo_y <= m.wy <= hi_y and -1 <= m.target < MAX_ID:
                intents.append(m)
            else:
                strange += 1
        elif type(m) is Tracks:
            items = m.items
            sane = [it for it in items
                    if 0 <= it.target < MAX_ID and lo_x <= it.x <= hi_x and lo_y <= it.y <= hi_y
                    and -MAX_SPEED <= it.vx <= MAX_SPEED and -MAX_SPEED <= it.vy <= MAX_SPEED
                    and 0.0 <= it.t <= t and -MAX_VALUE <= it.value <= MAX_VALUE]
            strange += len(items) - len(sane)
            tracks.extend(sane)
        elif type(m) is Threats:
            for th in m.items:
                if (0 <= th.threat < MAX_ID and lo_x <= th.x <= hi_x and lo_y <= th.y <= hi_y
                        and 0.0 < th.radius < th.d_max <= 2 * max_r):
                    threats.append((th.threat, th.x, th.y, th.radius, th.d_max))
                else:
                    strange += 1
        elif type(m) is ScanDigest:
            if 0 <= m.uav < MAX_ID and -MAX_TIME <= m.t_cut <= t:
                digests.append(m)
            else:
                strange += 1
        elif type(m) is TrackDigest:  # (issue 36, M1)
            if sane_track_digest(m, t):
                digests.append(m)
            else:
                strange += 1
    return Heard(ft, tuple(scans), ignored, strange, tuple(hellos), tuple(intents), tuple(tracks),
                 tuple(threats), tuple(digests))


_FLOAT = {float}
_INF = math.inf
_tuple_new = tuple.__new__


def _check_record(rec: FrameRecord, t: float, bounds: Bounds) -> Heard:
    """:func:`check_frame` of a frame record: ``check_frame(decode(its bytes), t, bounds)`` in
    one pass, a second implementation of the rules above (the property tests compare them).

    Values of the types :func:`~comms.codec.encode` writes (exact ints and floats) take fast
    paths: a plausible number is finite, so the codec's finiteness check is left to the
    implausible ones. Anything else goes through the codec's readers, which raise what decoding
    raises, message by message in the frame's order (the first error decoding meets is the one
    raised)."""
    max_r, width, height, dt = bounds
    sender, seq, ft, messages, _sent = rec
    if not (type(sender) is int and type(seq) is int and type(ft) is float and -_INF < ft < _INF):
        ft = read_header(rec)[2]
    lo_x, hi_x, lo_y, hi_y = -max_r, width + max_r, -max_r, height + max_r
    scans: list[HeardScan] = []
    hellos: list[Hello] = []
    intents: list[Intent] = []
    tracks: list[TrackItem] = []
    threats: list[tuple[int, float, float, float, float]] = []
    digests: list[ScanDigest | TrackDigest] = []
    ignored = strange = 0
    records: Sequence[Any]
    for raw in messages:
        kind = raw[0] if type(raw) is list and raw and type(raw[0]) is int else message_kind(raw)
        if kind == K_SCAN:
            if len(raw) == 3 and type(raw[1]) is int and type(raw[2]) is list and set(map(type, raw[2])) <= _FLOAT:
                origin, records = raw[1], raw[2]
                if len(records) % 4:
                    raise FrameError("scan: record list not a multiple of 4")
                finite = False  # (the records, checked: only if a scan is implausible)
            else:
                origin, records = read_scans(raw)
                finite = True
            it = iter(records)
            for tr, x, y, rr in zip(it, it, it, it):
                # A scan from the future would pin cells at q=0: only accept the past.
                if 0.0 <= tr <= t and 0.0 <= rr <= max_r and lo_x <= x <= hi_x and lo_y <= y <= hi_y:
                    scans.append((origin, round(tr / dt), (tr, x, y, rr), (x, y, rr)))
                else:
                    if not finite:
                        read_scans(raw)  # (raises if a number is not finite)
                        finite = True
                    ignored += 1
        elif kind == K_HELLO:
            if len(raw) == 7:
                _, uav, name, x, y, v, th = raw
                if (type(uav) is int and type(name) is str and len(name) <= 64 and type(x) is float
                        and type(y) is float and type(v) is float and type(th) is float
                        and 0 <= uav < MAX_ID and lo_x <= x <= hi_x and lo_y <= y <= hi_y
                        and 0.0 <= v <= MAX_SPEED and -MAX_ANGLE <= th <= MAX_ANGLE):
                    hellos.append(_tuple_new(Hello, (uav, name, x, y, v, th)))  # (= Hello(uav, name, ...))
                    continue
            m = read_hello(raw)
            if (0 <= m.uav < MAX_ID and lo_x <= m.x <= hi_x and lo_y <= m.y <= hi_y
                    and 0.0 <= m.v <= MAX_SPEED and -MAX_ANGLE <= m.theta <= MAX_ANGLE):
                hellos.append(m)
            else:
                strange += 1
        elif kind == K_INTENT:
            if len(raw) == 6:
                _, uav, wx, wy, mode, target = raw
                if (type(uav) is int and type(wx) is float and type(wy) is float and type(mode) is int
                        and type(target) is int and (mode == 0 or mode == 1)
                        and 0 <= uav < MAX_ID and lo_x <= wx <= hi_x and lo_y <= wy <= hi_y and -1 <= target < MAX_ID):
                    intents.append(_tuple_new(Intent, (uav, wx, wy, mode, target)))  # (= Intent(uav, wx, ...))
                    continue
            i = read_intent(raw)
            if 0 <= i.uav < MAX_ID and lo_x <= i.wx <= hi_x and lo_y <= i.wy <= hi_y and -1 <= i.target < MAX_ID:
                intents.append(i)
            else:
                strange += 1
        elif kind == K_TRACKS:
            if len(raw) != 2 or type(raw[1]) is not list:
                read_track_items(raw)  # (raises what decoding raises: no item list)
            for item in raw[1]:
                if type(item) is list and len(item) == 7:
                    target, x, y, vx, vy, tt, value = item
                    if (type(target) is int and type(x) is float and type(y) is float and type(vx) is float
                            and type(vy) is float and type(tt) is float and type(value) is float):
                        if (0 <= target < MAX_ID and lo_x <= x <= hi_x and lo_y <= y <= hi_y
                                and -MAX_SPEED <= vx <= MAX_SPEED and -MAX_SPEED <= vy <= MAX_SPEED
                                and 0.0 <= tt <= t and -MAX_VALUE <= value <= MAX_VALUE):
                            tracks.append(_tuple_new(TrackItem, item))  # (= TrackItem(*item))
                        else:
                            read_track_item(item)  # (raises if a number is not finite)
                            strange += 1
                        continue
                tr_ = read_track_item(item)
                if (0 <= tr_.target < MAX_ID and lo_x <= tr_.x <= hi_x and lo_y <= tr_.y <= hi_y
                        and -MAX_SPEED <= tr_.vx <= MAX_SPEED and -MAX_SPEED <= tr_.vy <= MAX_SPEED
                        and 0.0 <= tr_.t <= t and -MAX_VALUE <= tr_.value <= MAX_VALUE):
                    tracks.append(tr_)
                else:
                    strange += 1
        elif kind == K_THREATS:
            for th in read_threat_items(raw):
                if (0 <= th.threat < MAX_ID and lo_x <= th.x <= hi_x and lo_y <= th.y <= hi_y
                        and 0.0 < th.radius < th.d_max <= 2 * max_r):
                    threats.append((th.threat, th.x, th.y, th.radius, th.d_max))
                else:
                    strange += 1
        elif kind == K_DIGEST:
            dg = read_digest(raw)
            if 0 <= dg.uav < MAX_ID and -MAX_TIME <= dg.t_cut <= t:
                digests.append(dg)
            else:
                strange += 1
        elif kind == K_TRACK_DIGEST:  # (issue 36, M1)
            td = read_track_digest(raw)
            if sane_track_digest(td, t):
                digests.append(td)
            else:
                strange += 1
        else:
            message_kind(raw)  # (raises: an unknown kind)
    if not 0.0 <= ft <= t:
        return Heard(ft, (), 0, len(messages), (), (), (), (), ())
    return Heard(ft, tuple(scans), ignored, strange, tuple(hellos), tuple(intents), tuple(tracks),
                 tuple(threats), tuple(digests))


class InboxCounters(Protocol):
    """The tallies :meth:`Inbox.merge` adds to (the actor's ``ActorCounters``)."""

    delivered: int
    rejected: int
    rejected_auth: int
    scans_ignored: int
    scans_beyond: int
    messages_ignored: int


Received = list[tuple[int, int, bool]]  # (sender, nbytes, accepted) of each frame drained


# A Heard as the receive service keeps it for the tick (Inbox.take), a plain tuple (cheaper to
# build and to unpack than an object): (t_frame, scans, ignored, strange, hellos, intents,
# tracks, rest, heard), the Heard's content with each hello flattened to (uav, type, x, y, v,
# theta), each intent to (uav, wx, wy, mode, target, asks) (asks: a relief request, issue 33:
# search mode with a target), each track item to a TrackRow; rest: whether it has tracks,
# threats or digests (rare: looked at only then); heard: the Heard itself.
Taken = tuple[float, tuple[HeardScan, ...], int, int, tuple[tuple[int, str, float, float, float, float], ...],
              tuple[tuple[int, float, float, int, int, bool], ...], tuple[TrackRow, ...], bool, Heard]


def taken(h: Heard) -> Taken:
    """``h`` as :data:`Taken`."""
    return (h.t_frame, h.scans, h.ignored, h.strange,
            tuple([(m.uav, m.type, m.x, m.y, m.v, m.theta) for m in h.hellos]),
            tuple([(i.uav, i.wx, i.wy, i.mode, i.target, i.mode == MODE_SEARCH and i.target >= 0) for i in h.intents]),
            tuple([(it.target, it.x, it.y, it.vx, it.vy, it.t, it.value) for it in h.tracks]) if h.tracks else (),
            bool(h.tracks or h.threats or h.digests), h)


# The receive service's memo of one tick (Inbox.take): per (t, bounds), per frame's bytes, what
# it is to a receiver (Taken) or the FrameError decoding it raised.
HeardMemo = dict[Hashable, dict[bytes, Taken | FrameError]]


class Inbox:
    """A UAV's receiving side: decodes, checks and merges the frames it drained.

    Holds what does not change over a run (the UAV's id, grid, bounds, knowledge horizon, the
    age of a resend, how frames are decoded and checked); the state it merges into (map, scan
    log, knowledge, counters) is the actor's, passed in each tick. The digests heard are kept
    in :attr:`digests` until the actor answers them (:meth:`take_digests`).
    """

    __slots__ = ("uid", "grid", "bounds", "horizon2", "fresh_s", "digests", "_heard")

    def __init__(self, uid: int, grid: Grid, max_scan_r: float, dt: float, radio: RadioSettings,
                 decoder: DecodeCache | None, key: bytes | None):
        """``max_scan_r``: how large a plausible scan's radius may be, and how far outside the
        area a place may lie (:func:`check_frame`). ``radio``: the ``[radio]`` settings (the
        knowledge horizon, ``horizon_m``: heard scans centred farther than this from the UAV
        are neither applied nor logged; the beacon period; the frame size cap). ``decoder``: the
        simulation's shared cache (it decodes with the swarm's key); without one, frames are
        decoded with ``key``, each time."""
        self.uid = uid
        self.grid = grid
        self.bounds: Bounds = (max_scan_r, grid.width_m, grid.height_m, dt)
        h = radio.horizon_m
        self.horizon2 = None if math.isinf(h) else h * h
        # Heard scans older than this are anti-entropy resends (a beacon carries the scans of the
        # last beacon period): sent to this UAV alone, their disks are not worth sharing.
        self.fresh_s = radio.beacon_every_s + 2 * dt
        self.digests: list[ScanDigest | TrackDigest] = []  # heard, not yet answered
        # heard(data, key, check) -> the Heard of data's frame for key = (t, bounds), raising
        # FrameError: one call into the shared cache (the value kept beside the frame, or
        # derived and kept), or decode and check.
        self._heard: Callable[[bytes, Hashable, Callable[[Frame | FrameRecord], Heard]], Heard]
        if decoder is not None:
            self._heard = decoder.derive
        else:
            decode_frame = partial(decode, max_bytes=radio.frame_max_bytes, key=key)
            self._heard = lambda data, _key, check: check(decode_frame(data))

    def take_digests(self) -> list[ScanDigest | TrackDigest]:
        """The digests heard since they were last taken (to answer: agents.antientropy, and
        agents.tracksync for track digests)."""
        digests, self.digests = self.digests, []
        return digests

    def take(self, frames: Sequence[tuple[float, int, bytes]], t: float, here_x: float, here_y: float,
             umap: UncertaintyMap, knowledge: Knowledge, scans: ScanLog | None, counters: InboxCounters,
             memo: HeardMemo) -> Received:
        """:meth:`merge`, for the receive service (:mod:`swarm.kernel.receiving`): the same
        rules with the same results, in two steps that do per receiver only what depends on the
        receiver: :meth:`hear` (the frames looked up, counted and merged into its knowledge;
        their scans gathered), then the horizon test and :meth:`apply_scans`; the service runs
        the horizon test of all receivers of a tick at once. ``memo`` is the service's for this
        tick, shared by every receiver it serves: a frame delivered to k receivers is looked up
        in the decode cache (and its messages flattened, :data:`Taken`) once, not k times.
        :meth:`merge` stays the specification (``Simulation(tick_plane=False)`` runs it;
        tests/test_tick_plane.py compares the two tick by tick)."""
        received, heard = self.hear(frames, t, knowledge, counters, memo)
        if heard:
            horizon2 = self.horizon2
            if horizon2 is not None:
                near = [hs for hs in heard if (hs[2][1] - here_x) ** 2 + (hs[2][2] - here_y) ** 2 <= horizon2]
                counters.scans_beyond += len(heard) - len(near)
                heard = near
            self.apply_scans(heard, t, umap, scans)
        return received

    def hear(self, frames: Sequence[tuple[float, int, bytes]], t: float, knowledge: Knowledge,
             counters: InboxCounters, memo: HeardMemo) -> tuple[Received, list[HeardScan]]:
        """The first step of :meth:`take`: each frame of ``frames`` (a mailbox's ``(arrival,
        sender, data)``), heard at ``t``, looked up in the tick's ``memo`` (decoded and checked
        by the first receiver of its bytes); the rejected ones, the delivered ones, their
        ignored scans and strange messages counted; the hellos, intents, tracks, threats and
        digests of the accepted ones merged into ``knowledge`` and the digests to answer, as
        :meth:`merge` merges them. Returns ``(sender, nbytes, accepted)`` per frame, the
        accepted frames' scans in order (for the horizon test and :meth:`apply_scans`)."""
        received: Received = []
        heard: list[HeardScan] = []
        if not frames:
            return received, heard
        append = received.append
        bounds = self.bounds
        key = (t, bounds)
        table = memo.get(key)
        if table is None:
            table = memo[key] = {}
        heard_of = self._heard
        k = knowledge
        peers = k.peers
        peer = k.peer
        me = self.uid
        digests = self.digests
        delivered = ignored = strange = 0
        for _arrival, sender, data in frames:
            rec = table.get(data)
            if rec is None:  # the first receiver of this frame (at this t) this tick
                try:
                    rec = taken(heard_of(data, key, partial(check_frame, t=t, bounds=bounds)))
                except FrameError as exc:  # (the auth failures among them: AuthError)
                    rec = exc
                if type(data) is bytes:
                    table[data] = rec
            if type(rec) is not tuple:  # a FrameError: rejected
                counters.rejected += 1
                if isinstance(rec, AuthError):
                    counters.rejected_auth += 1
                append((sender, len(data), False))
                continue
            ft, heard_scans, n_ignored, n_strange, hellos, intents, tracks, rest, h = rec
            delivered += 1
            append((sender, len(data), True))
            if n_ignored or n_strange:
                ignored += n_ignored
                strange += n_strange
            if heard_scans:
                heard += heard_scans
            for uav, typ, x, y, v, theta in hellos:
                if uav != me:
                    p = peers.get(uav) or peer(uav)
                    if ft >= p.t_pose:
                        p.type, p.x, p.y, p.v, p.theta, p.t_pose = typ, x, y, v, theta, ft
            for uav, wx, wy, mode, target, asks in intents:
                if uav != me:
                    p = peers.get(uav) or peer(uav)
                    if ft >= p.t_intent:
                        p.wx, p.wy, p.mode, p.target, p.t_intent = wx, wy, mode, target, ft
                        if asks:
                            p.mode, p.asks = MODE_SURVEIL, True
                        elif p.asks:
                            p.asks = False
            if rest:
                if tracks:
                    k.merge_track_rows(tracks)
                for th in h.threats:
                    k.add_threat(*th)
                for dg in h.digests:
                    if dg.uav != me:
                        digests.append(dg)
        counters.delivered += delivered
        counters.scans_ignored += ignored
        counters.messages_ignored += strange
        return received, heard

    def apply_scans(self, heard: Sequence[HeardScan], t: float, umap: UncertaintyMap, scans: ScanLog | None) -> None:
        """The heard scans within the knowledge horizon (``heard``, in the order of their frames),
        heard at ``t``: those new to the scan log ``scans`` (all of them when None: not kept;
        :meth:`ScanLog.add_ticks`, the first of a repeated one) logged and stamped into ``umap``,
        in order, as :meth:`merge` stamps them."""
        if not heard:
            return
        new: Iterable[HeardScan] = heard
        if scans is not None:
            new = compress(heard, scans.add_ticks(heard) if type(scans) is ScanLog
                           else [scans.add_tick(origin, tick, scan) for origin, tick, scan, _ in heard])
        stamp = umap.stamp
        grid = self.grid
        disk_stamp = grid.disk_stamp
        known_disk = grid.disk_lookup()
        once = umap.stamp_once if type(umap) is UncertaintyMap and not umap.dense else None
        old = t - self.fresh_s
        for _origin, _tick, scan, disk_key in new:
            d = known_disk(disk_key, _MISSING)
            if d is _MISSING:
                if once is not None and scan[0] < old:
                    once(*disk_key, scan[0])
                    continue
                d = disk_stamp(*disk_key)
            if d is not None:
                stamp(d, scan[0])

    def merge(self, frames: Sequence[tuple[float, int, bytes]], t: float, here_x: float, here_y: float,
              umap: UncertaintyMap, knowledge: Knowledge, scans: ScanLog | None, counters: InboxCounters) -> Received:
        """Merge ``frames`` (a mailbox's ``(arrival, sender, data)``), heard at ``t`` by the UAV
        at ``(here_x, here_y)``, into its map, scan log (None: not kept) and knowledge; count
        them in ``counters``. Returns ``(sender, nbytes, accepted)`` per frame.

        A frame that does not decode (with ``[radio] auth``, one failing its MAC too) is
        rejected. One that decodes can still carry numbers no honest UAV sends (a time of
        1e308 s, a threat with no influence ring): those messages are ignored and counted
        (:func:`check_frame`)."""
        received: Received = []
        if not frames:
            return received
        append = received.append
        k = knowledge
        peers = k.peers
        me = self.uid
        stamp = umap.stamp
        grid = self.grid
        disk_stamp = grid.disk_stamp
        known_disk = grid.disk_lookup()  # disk_stamp's memo, without the call (hot loop)
        # A resent scan missing from the memo is stamped into a tiled map of its own directly
        # (UncertaintyMap.stamp_once: 35 -> 15 us; group maps keep their own bookkeeping).
        once = umap.stamp_once if type(umap) is UncertaintyMap and not umap.dense else None
        old = t - self.fresh_s
        log_add = scans.add_tick if scans is not None else None
        bounds = self.bounds
        key = (t, bounds)  # what a Heard is checked for (and kept beside its frame for)

        def check(frame: Frame | FrameRecord) -> Heard:
            return check_frame(frame, t, bounds)

        heard_of = self._heard
        digests = self.digests
        delivered = ignored = strange = beyond = 0
        horizon2 = self.horizon2
        for _arrival, sender, data in frames:
            try:
                heard = heard_of(data, key, check)
            except AuthError:  # (a FrameError too)
                counters.rejected += 1
                counters.rejected_auth += 1
                append((sender, len(data), False))
                continue
            except FrameError:
                counters.rejected += 1
                append((sender, len(data), False))
                continue
            delivered += 1
            append((sender, len(data), True))
            ignored += heard.ignored
            strange += heard.strange
            for origin, tick, scan, disk_key in heard.scans:
                if horizon2 is not None and (scan[1] - here_x) ** 2 + (scan[2] - here_y) ** 2 > horizon2:
                    beyond += 1  # beyond the knowledge horizon (= not scanlog.within(...))
                elif log_add is None or log_add(origin, tick, scan):  # new to us (else already applied)
                    # = umap.scan(x, y, r, t_rec); the disk is shared by every map applying
                    # this record (grid memo).
                    d = known_disk(disk_key, _MISSING)
                    if d is _MISSING:
                        if once is not None and scan[0] < old:
                            once(*disk_key, scan[0])  # (a resend: this map's cells only, no shared disk)
                            continue
                        d = disk_stamp(*disk_key)
                    if d is not None:
                        stamp(d, scan[0])
            ft = heard.t_frame
            for m in heard.hellos:
                if m.uav != me:
                    p = peers.get(m.uav) or k.peer(m.uav)
                    if ft >= p.t_pose:
                        p.type, p.x, p.y, p.v, p.theta, p.t_pose = m.type, m.x, m.y, m.v, m.theta, ft
            for i in heard.intents:
                if i.uav != me:
                    p = peers.get(i.uav) or k.peer(i.uav)
                    if ft >= p.t_intent:
                        p.wx, p.wy, p.mode, p.target, p.t_intent = i.wx, i.wy, i.mode, i.target, ft
                        if i.mode == MODE_SEARCH and i.target >= 0:  # (issue 33) a relief request
                            p.mode, p.asks = MODE_SURVEIL, True
                        elif p.asks:
                            p.asks = False
            if heard.tracks:
                k.merge_tracks(heard.tracks)
            for th in heard.threats:
                k.add_threat(*th)
            for dg in heard.digests:
                if dg.uav != me:
                    digests.append(dg)
        counters.delivered += delivered
        counters.scans_ignored += ignored
        counters.scans_beyond += beyond
        counters.messages_ignored += strange
        return received


__all__ = ["Bounds", "Heard", "HeardMemo", "HeardScan", "Inbox", "InboxCounters", "Received", "Taken", "check_frame", "taken"]
