"""A UAV's side of anti-entropy: the digest its beacon carries and its answers to the digests it hears.

Every ``sync_every_s`` a UAV's beacon carries a digest of the scans its log holds
(:meth:`agents.maps.scanlog.ScanLog.digest`); a neighbour that hears it sends back, addressed to
it alone, the scans it lacks (:meth:`~agents.maps.scanlog.ScanLog.missing`), if it is one of
the few that answer (:func:`answers`). The actor decides when (its outbox; the digests its
inbox heard, :class:`agents.inbox.Inbox`); :class:`AntiEntropy` keeps the bookkeeping and
cuts the answers into frames.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Protocol

from agents.knowledge import Peer
from agents.maps.scanlog import ScanLog
from comms.codec import FRAME_SLACK, SCAN_BYTES, Packed, pack_scans
from comms.messages import Message, ScanDigest
from comms.settings import RadioSettings

# Neighbours expected to answer one digest (see answers).
ANSWERERS = 2


def answer_hash(me: int, sender: int, t_cut: float) -> int:
    """A well-mixed non-negative integer of (me, sender, round): who answers which digest."""
    h = (me * 0x9E3779B97F4A7C15 + sender * 0xC2B2AE3D27D4EB4F + int(t_cut * 16) * 0x165667B19E3779F9)
    h &= 0xFFFFFFFFFFFFFFFF
    h ^= h >> 31
    h = (h * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    return h ^ (h >> 29)


def answer_slot(me: int, digest: ScanDigest, n: int) -> int | None:
    """Whether UAV ``me``, hearing ``n`` neighbours, answers ``digest``, and as which answerer.

    Not every neighbour answers: in a dense swarm a digest is heard by hundreds of UAVs, and
    all answering would send the same scans hundreds of times. Each UAV answers when a hash of
    (itself, the sender, the digest's cut) falls in the first ``2 / n`` of its range: about two
    answer each digest, different ones each round (no random draw: the UAVs' streams are their
    planners'). The hash modulo ``n`` is then its slot, ``0 .. ANSWERERS - 1`` (which share of
    the missing scans it sends under ``[radio] sync_split``). With two or fewer neighbours every
    one answers, with slot ``-1`` (all of them). None: it does not answer."""
    if n <= ANSWERERS:
        return -1
    slot = answer_hash(me, digest.uav, digest.t_cut) % n
    return slot if slot < ANSWERERS else None


def answers(me: int, digest: ScanDigest, n: int) -> bool:
    """Whether UAV ``me``, hearing ``n`` neighbours, answers ``digest`` (:func:`answer_slot`)."""
    return answer_slot(me, digest, n) is not None


class AntiEntropyCounters(Protocol):
    """The tallies :class:`AntiEntropy` adds to (the actor's ``ActorCounters``)."""

    digests_sent: int
    digest_bytes: int
    scans_resent: int
    resent_bytes: int


Frame = Callable[[float, Sequence[Message | Packed]], bytes]  # the actor's: (t, messages) -> a frame it sends


class AntiEntropy:
    """One UAV's digests and answers, over its scan log, with the scenario's ``[radio]`` sync settings."""

    __slots__ = ("uid", "radio", "log", "per_frame", "_next_digest", "_digest_start")

    def __init__(self, uid: int, radio: RadioSettings, log: ScanLog):
        self.uid = uid
        self.radio = radio
        self.log = log
        self.per_frame = max(1, (radio.frame_max_bytes - FRAME_SLACK) // SCAN_BYTES)  # scans in an answer frame
        self._next_digest = -math.inf
        self._digest_start = 0  # where the next digest begins when one frame cannot hold it all

    def digest(self, t: float, room: int, counters: AntiEntropyCounters) -> ScanDigest | None:
        """The digest for the beacon sent at ``t`` with ``room`` bytes left in its frame, if one
        is due (anti-entropy on, ``sync_every_s`` since the last, room beyond the frame's slack);
        a long run's digest is split over several beacons (:meth:`ScanLog.digest`)."""
        s = self.radio
        if not (s.sync_every_s > 0 and t >= self._next_digest and room > FRAME_SLACK):
            return None
        t_cut = t - s.sync_settle_s
        self.log.forget_before(t)
        tick0, lo, hi, bitmaps, self._digest_start = self.log.digest(t_cut, self._digest_start, room)
        counters.digests_sent += 1
        counters.digest_bytes += sum(len(b) + 8 for _, b in bitmaps)
        self._next_digest = t + s.sync_every_s - 1e-9
        return ScanDigest(self.uid, t_cut, tick0, lo, hi, bitmaps)

    def answer(self, digests: Sequence[ScanDigest], t: float, peers: Mapping[int, Peer], timeout_s: float,
               frame: Frame, counters: AntiEntropyCounters) -> list[tuple[int, bytes]]:
        """The frames sent at ``t`` in answer to ``digests``, as ``(receiver, frame)``: each
        digest this UAV answers (:func:`answers`, ``n`` the ``peers`` heard within ``timeout_s``)
        gets the scans of the log its sender lacks, within the knowledge horizon of where its
        Hello put it, at most ``sync_max_records`` scans in all, as many frames as they take.

        Flow control (issue 36, M2): with ``sync_split`` an answerer with a slot sends only its
        share of those scans (a hash of each scan and the digest's round, modulo
        :data:`ANSWERERS`, equal to its slot), so the about two answerers of a digest split the
        work instead of both sending it; with ``sync_resend_cap`` > 0 an answer to one digest
        carries at most that many scans, the latest first (:func:`agents.maps.scanlog.kept`)."""
        replies: list[tuple[int, bytes]] = []
        budget = self.radio.sync_max_records
        cap, split = self.radio.sync_resend_cap, self.radio.sync_split
        per_frame = self.per_frame
        horizon = self.radio.horizon_m
        n = sum(1 for p in peers.values() if t - p.t_pose <= timeout_s)
        for dg in digests:
            slot = answer_slot(self.uid, dg, n)
            if slot is None:
                continue
            near = None
            if not math.isinf(horizon):
                # The sender's horizon, centred where its Hello (on the digest's own beacon) put it.
                p = peers.get(dg.uav)
                if p is None or math.isinf(p.t_pose):
                    continue  # no pose heard: where its horizon lies is unknown
                near = (p.x, p.y, horizon)
            msgs: list[Message | Packed] = []
            room = per_frame  # scans the current frame can still take
            share = (slot, ANSWERERS, answer_hash(0, dg.uav, dg.t_cut)) if split and slot >= 0 else None
            for origin, flat in self.log.missing(dg.tick0, dg.lo, dg.hi, dg.bitmaps, min(dg.t_cut, t), budget, near,
                                                 newest=cap, share=share):
                budget -= len(flat) // 4
                counters.scans_resent += len(flat) // 4
                while flat:
                    take, flat = flat[:4 * room], flat[4 * room:]
                    msgs.append(pack_scans(origin, take))  # (= ScanRecords(origin, tuple(take)), packed)
                    room -= len(take) // 4
                    if room == 0:
                        replies.append((dg.uav, frame(t, msgs)))
                        msgs, room = [], per_frame
            if msgs:
                replies.append((dg.uav, frame(t, msgs)))
            if budget <= 0:
                break
        counters.resent_bytes += sum(len(f) for _, f in replies)
        return replies


__all__ = ["ANSWERERS", "AntiEntropy", "AntiEntropyCounters", "answer_hash", "answer_slot", "answers"]
