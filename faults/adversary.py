"""Adversaries: a lying member (liar, a tick fault, with what it fabricates: its actor's
outbox hook) and a spoofing outsider (spoofer, a transmitter of its own)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import ClassVar, Literal

import numpy as np

from agents.actor import UavActor
from comms.codec import FRAME_SLACK, SCAN_BYTES, Packed, encode, pack_scans, pack_tracks
from comms.messages import Hello, Message, ScanRecords, TrackItem, Tracks
from comms.radio import SPOOF_SENDER, Delivery
from faults.base import END, PHANTOM_TARGET_ID, START, UAV, Draws, FaultRng, RadioHost, Transmitter, Windowed
from faults.registry import register
from faults.sensing import PHANTOM_ID_SPAN
from faults.tick import TickFault, TickFaults

# Liars' track ids count up from here (false alarms use the span below it).
LIAR_TRACK_IDS = PHANTOM_TARGET_ID + PHANTOM_ID_SPAN
# Scan records in each spoofed frame.
SPOOF_SCANS = 4
# A liar's fabrications (Lies): bytes of a ScanRecords message's own header (at most), of a
# packed track item, and the made-up origin ids its fake scans carry.
_MSG_BYTES = 16
_TRACK_BYTES = 80
_GHOST_ORIGIN = 1_000_000_000
_GHOSTS_PER_UAV = 4096


@register
@dataclass(frozen=True, kw_only=True)
class Liar(TickFault):
    """A Byzantine member (it holds the swarm key): it broadcasts scan records it never made
    (``scans_per_s``, uniform over the area, stamped now, under made-up origin ids since a
    receiver keeps one scan per origin and tick) and false target tracks (``tracks_per_s``,
    phantom targets at uniform positions), with its beacons."""

    uav: str = field(metadata=UAV)
    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(default=math.inf, metadata=END)
    scans_per_s: float = field(default=1.0, metadata={"ge": 0, "le": 1000, "note": "fake scan records per s"})
    tracks_per_s: float = field(default=0.0, metadata={"ge": 0, "le": 1000, "note": "fake tracks per s"})
    kind: ClassVar[Literal["liar"]] = "liar"
    tick_order: ClassVar[int] = 4
    shrink_rank: ClassVar[int] = 170
    min_uavs: ClassVar[int] = 1

    @classmethod
    def generate(cls, d: Draws) -> Liar:
        """Fake scans and/or fake tracks (never neither)."""
        start, end = d.draw(d.windows())
        scans = d.draw(d.st.one_of(d.st.just(1.0), d.st.sampled_from([0.0, 5.0]), d.st.integers(1, 20).map(lambda k: k / 2)))
        tracks = d.draw(d.st.one_of(d.st.just(0.0), d.st.sampled_from([1.0, 0.2]),
                                    d.st.integers(1, 10).map(lambda k: k / 5)))
        if scans == 0.0 and tracks == 0.0:
            tracks = 1.0
        return cls(uav=d.draw(d.names()), start_s=start, end_s=end, scans_per_s=scans, tracks_per_s=tracks)

    def concerns(self, names: object) -> bool:
        return True  # its tracks reach every UAV

    def on_tick(self, faults: TickFaults, index: int, uid: int) -> None:
        """This tick's fabrications for the liar's actor: scans at uniform points of the area
        with its detection radius, tracks of phantom targets at uniform positions. It fires
        per fabrication sent (:class:`Lies`, the actor's outbox hook), not when it starts."""
        if faults.first(index, uid):
            faults.events.fault_on(t=faults.t, fault=self.kind, uav=uid)
        actor = faults.actors[uid]
        g = faults.stream(index, self.kind, uid)
        w, h = faults.area
        n_scans = faults.owed((index, uid, "scans"), self.scans_per_s)
        n_tracks = faults.owed((index, uid, "tracks"), self.tracks_per_s)
        scans = [(x * w, y * h, actor.kind.detect_radius) for x, y in g.random((n_scans, 2)).tolist()]
        tracks = [(faults.serial("liar", LIAR_TRACK_IDS, PHANTOM_ID_SPAN), x * w, y * h)
                  for x, y in g.random((n_tracks, 2)).tolist()]
        lies = actor.outbox_hook
        if not isinstance(lies, Lies):
            lies = actor.outbox_hook = Lies(uid, partial(faults.fired, self.kind))
        lies.add(scans, tracks)


class Lies:
    """A liar's fabrications on their way out: its actor's outbox hook
    (:class:`agents.actor.OutboxHook`).

    The fake scans of a tick (:meth:`add`) are stamped with the UAV's own time, stamped into
    its own map and scan log as if real (:meth:`observed`: so its map, its log and what it sends
    agree, and anti-entropy spreads them like any scan) and sent with its next beacon; the
    tracks go with that beacon, stamped then (:meth:`beacon`). Receivers keep one scan per
    origin and tick (agents.maps.scanlog), so the j-th fake scan of a tick carries the made-up
    origin ``1_000_000_000 + uid * 4096 + j``, as a member holding the swarm key can. What does
    not fit in the beacon frame is dropped; ``sink`` is told how many were sent."""

    def __init__(self, uid: int, sink: Callable[[int], None]):
        self.ghost = _GHOST_ORIGIN + (uid * _GHOSTS_PER_UAV) % (2**30)
        self.sink = sink
        self.to_make: list[tuple[float, float, float]] = []  # (x, y, radius): claimed at the next step
        self.scans: list[tuple[int, float, float, float, float]] = []  # (origin, t, x, y, radius): to send
        self.tracks: list[tuple[int, float, float]] = []  # (target, x, y): to send

    def add(self, scans: Sequence[tuple[float, float, float]], tracks: Sequence[tuple[int, float, float]]) -> None:
        """This tick's fabrications: scans ``(x, y, radius)`` the UAV never made and sightings
        ``(target, x, y)`` of targets that do not exist (added before the actor wakes; the
        draws are the fault's)."""
        self.to_make.extend(scans)
        self.tracks.extend(tracks)

    def observed(self, actor: UavActor, t: float) -> None:
        ghost = self.ghost
        for j, (x, y, radius) in enumerate(self.to_make):
            origin = ghost + j % _GHOSTS_PER_UAV
            actor.claim_scan(origin, t, x, y, radius)
            self.scans.append((origin, t, x, y, radius))
        self.to_make = []

    def beacon(self, t: float, messages: list[Message | Packed], room: int) -> int:
        sent = 0
        by_origin: dict[int, list[float]] = {}
        for origin, tr, x, y, radius in self.scans:
            flat = by_origin.get(origin)
            cost = SCAN_BYTES + (0 if flat is not None else _MSG_BYTES)
            if room - cost < 2 * FRAME_SLACK:
                break
            if flat is None:
                flat = by_origin[origin] = []
            flat.extend((tr, x, y, radius))
            room -= cost
            sent += 1
        for origin, flat in by_origin.items():
            messages.append(pack_scans(origin, flat))
        items = []
        for target, x, y in self.tracks:
            if room - _TRACK_BYTES < 2 * FRAME_SLACK:
                break
            items.append(TrackItem(target, x, y, 0.0, 0.0, t, 1.0))
            room -= _TRACK_BYTES
        if items:
            messages.append(pack_tracks(items))
            sent += len(items)
        self.scans, self.tracks = [], []
        if sent:
            self.sink(sent)
        return room


@register
@dataclass(frozen=True, kw_only=True)
class Spoofer(Windowed):
    """A transmitter that is not a swarm member: from ``(x_m, y_m)`` it sends ``rate_per_s``
    well-formed frames a second, with a forged sender (``as_uav``; empty: a random member per
    frame) and without the swarm key, to every live UAV within ``range_m``."""

    x_m: float = field(metadata={"note": "m"})
    y_m: float = field(metadata={"note": "m"})
    range_m: float = field(metadata={"gt": 0, "note": "m"})
    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(default=math.inf, metadata=END)
    rate_per_s: float = field(default=1.0, metadata={"gt": 0, "le": 1000, "note": "frames per s"})
    as_uav: str = field(default="", metadata={"expected": "a UAV name defined in [[uavs]], or \"\" (a random member per frame)"})
    kind: ClassVar[Literal["spoofer"]] = "spoofer"
    shrink_rank: ClassVar[int] = 180

    @classmethod
    def generate(cls, d: Draws) -> Spoofer:
        """Inside the area, reaching 500 m up to the area's diagonal (whole 100 m), 0.5-10 frames
        a second, as a named member or as a random one (``as_uav = ""``)."""
        x, y = d.draw(d.points())
        k_max = max(5, int(math.hypot(*d.area)) // 100)
        reach = d.draw(d.st.one_of(d.st.just(float(k_max * 100)), d.st.integers(5, k_max).map(lambda k: k * 100.0)))
        start, end = d.draw(d.windows())
        rate = d.draw(d.st.one_of(d.st.just(1.0), d.st.integers(1, 20).map(lambda k: k / 2)))
        as_uav = d.draw(d.st.one_of(d.st.just(""), d.names())) if d.uavs else ""
        return cls(x_m=x, y_m=y, range_m=reach, start_s=start, end_s=end, rate_per_s=rate, as_uav=as_uav)
    # Its frames (with auth off) put scans in some maps and not others.
    disturbs_links: ClassVar[bool] = True

    def forges_at(self, pos: Sequence[float], t: float) -> bool:
        return self.active(t) and math.hypot(pos[0] - self.x_m, pos[1] - self.y_m) <= self.range_m

    def transmitter(self, fault_rng: FaultRng, rank: int) -> Transmitter:
        return _Spoof(self, fault_rng(self.kind, rank))


class _Spoof(Transmitter):
    """A spoofer's own stream, its fractional frame credit and its frame counter."""

    def __init__(self, fault: Spoofer, rng: np.random.Generator):
        super().__init__(fault)
        self.spoofer = fault
        self.rng = rng
        self.credit = 0.0
        self.seq = 0

    def transmit(self, host: RadioHost, t: float, dt: float, alive: Sequence[int], xy: np.ndarray,
                 out: list[Delivery]) -> int:
        """``rate_per_s * dt`` frames a tick, the fractions carried over (no draw: 0.3 frames a
        tick sends one every third or fourth tick), each to every live UAV within ``range_m``,
        arriving after the radio's latency (no link: the spoofer is not in the radio graph, and
        its copies are neither lost nor faulted). Every draw is from the spoofer's own stream.
        A frame: the forged sender's Hello at the spoofer's position, ScanRecords of
        :data:`SPOOF_SCANS` disks (the forged sender's detection radius) at uniform points of
        the area stamped ``t``, and Tracks of one phantom target (an id from
        :data:`~faults.base.PHANTOM_TARGET_ID` up) at a uniform point; written without the
        swarm key (the spoofer has none). Sender :data:`~comms.radio.SPOOF_SENDER` in the
        deliveries and ``rx`` events (no member has that id): what the checkers tell a spoof by."""
        f, rng = self.spoofer, self.rng
        self.credit += f.rate_per_s * dt
        n = int(self.credit + 1e-9)  # (1e-9: 0.1 * 10 ticks makes one frame, not 0.999...)
        self.credit -= n
        if not n:
            return 0
        seq = self.seq
        self.seq += n
        members = host.members()
        if not members:
            return n
        if len(alive):
            d = np.hypot(xy[:, 0] - f.x_m, xy[:, 1] - f.y_m)
            hearers = [u for u, k in zip(alive, (d <= f.range_m).tolist()) if k]
        else:
            hearers = []
        w, h = host.area
        arrival = t + host.latency_s
        c = host.counters
        for i in range(n):
            forged = host.uid(f.as_uav) if f.as_uav else members[int(rng.integers(len(members)))]
            kind = host.uav_type(forged)
            r = kind.detect_radius
            pts = rng.uniform((0.0, 0.0), (w, h), size=(SPOOF_SCANS, 2))
            records = [v for x, y in pts.tolist() for v in (t, x, y, r)]
            tx, ty = rng.uniform((0.0, 0.0), (w, h)).tolist()
            phantom = PHANTOM_TARGET_ID + int(rng.integers(1_000_000))
            messages: list[Message] = [
                Hello(forged, kind.name, f.x_m, f.y_m, kind.speed_min, float(rng.uniform(-math.pi, math.pi))),
                ScanRecords(forged, tuple(records)),
                Tracks((TrackItem(phantom, tx, ty, 0.0, 0.0, t, 1.0),)),
            ]
            data = encode(forged, seq + i, t, messages, key=None)
            c.sent += len(hearers)
            c.spoofed += len(hearers)
            c.bytes_sent += len(data) * len(hearers)
            out.extend(Delivery(arrival, SPOOF_SENDER, u, data) for u in hearers)
        return n
