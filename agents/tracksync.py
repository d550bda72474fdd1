"""Tracks on change (issue 36, model change M1; ``[radio] tracks = "on_change"``): a UAV's side.

With ``tracks = "periodic"`` a UAV sends every track and threat it knows every
``tracks_every_s`` to every neighbour (:meth:`TrackSync.periodic`): the cost grows with the
tracks known, whether they change or not. With ``"on_change"``:

* **On change** (:meth:`TrackSync.changed`): a track is sent when it is new to the UAV or newer
  than what it last sent of it (its own sighting, or one heard: so tracks spread hop by hop).
  A new one goes out at once; changes wait for the UAV's next turn and go out together, one
  frame at most every ``tracks_every_s`` (a watched target's track, renewed every tick, goes
  out every ``tracks_every_s``, as before); a threat once, when first known.
* **Digest** (:meth:`TrackSync.digest`): every ``sync_every_s`` (``tracks_every_s`` when
  anti-entropy is off) the beacon carries a :class:`~comms.messages.TrackDigest`: the target and
  sighting time of each track the UAV holds, and the ids of its threats.
* **Repair** (:meth:`TrackSync.answer`): a neighbour hearing a digest sends its sender, by
  unicast, every track and threat the sender lacks (every neighbour that knows one does), and
  if it is one of the about two that answer this digest (:func:`agents.antientropy.answer_hash`,
  as for scans) also the tracks the sender holds more than ``tracks_every_s`` older than its own
  (a newer version it missed; a smaller lag is a change on its way).

So on a radio that loses nothing a UAV that lacks a track a neighbour knows gets it within
:func:`track_delay_s`. Docs: docs/scenarios.md, "Tracks".
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

from agents.antientropy import ANSWERERS, answer_hash
from agents.knowledge import Knowledge, Peer
from comms.codec import Packed, ThreatLike, TrackLike, pack_threats, pack_track_digest, pack_tracks
from comms.messages import Message, TrackDigest
from comms.settings import RadioSettings

# Items per Tracks message, so one frame stays far below the size cap (an item is < 80 bytes).
TRACKS_PER_FRAME = 400

Frame = Callable[[float, Sequence[Message | Packed]], bytes]  # the actor's: (t, messages) -> a frame it sends


def digest_every_s(radio: RadioSettings) -> float:
    """How often an on-change UAV's beacon carries its track digest: ``sync_every_s``, or
    ``tracks_every_s`` with anti-entropy off."""
    return radio.sync_every_s if radio.sync_every_s > 0 else radio.tracks_every_s


def track_delay_s(radio: RadioSettings, dt: float) -> float:
    """How long, on a radio that loses nothing, a track a UAV knows may take to reach a
    neighbour that lacks it (or the track's newer version): ``tracks_every_s`` when periodic
    (the next send); on change, the larger of ``tracks_every_s`` (a change waiting its turn) and
    the repair: the lacking UAV's next digest (at most :func:`digest_every_s` plus a beacon
    period away), heard and answered the next tick, the answer merged the tick after; each hop
    ``latency_s + jitter_s`` late."""
    if radio.tracks == "periodic":
        return radio.tracks_every_s
    lat = radio.latency_s + radio.jitter_s
    return max(radio.tracks_every_s, digest_every_s(radio) + radio.beacon_every_s + 2 * dt + 2 * lat)


def _frames(t: float, tracks: Sequence[TrackLike], threats: Sequence[ThreatLike], frame: Frame) -> list[bytes]:
    """Frames of ``tracks`` (:data:`TRACKS_PER_FRAME` a frame) and ``threats`` (in the first)."""
    out: list[bytes] = []
    first = True
    for i in range(0, max(len(tracks), 1), TRACKS_PER_FRAME):
        msgs: list[Message | Packed] = [pack_tracks(tracks[i:i + TRACKS_PER_FRAME])]
        if first and threats:
            msgs.append(pack_threats(threats))
        first = False
        out.append(frame(t, msgs))
    return out


class TrackSync:
    """One UAV's sending of tracks and threats, with the scenario's ``[radio]`` settings."""

    __slots__ = ("uid", "radio", "on_change", "every", "digest_every", "_next_periodic", "_next_digest",
                 "_sent", "_next_ok", "_threats_sent")

    def __init__(self, uid: int, radio: RadioSettings):
        self.uid = uid
        self.radio = radio
        self.on_change = radio.tracks == "on_change"
        self.every = radio.tracks_every_s
        self.digest_every = digest_every_s(radio)
        self._next_periodic = -math.inf
        self._next_digest = -math.inf
        self._sent: dict[int, float] = {}  # target -> the sighting time of the version last sent
        self._next_ok = -math.inf  # when changed tracks may go out again
        self._threats_sent = 0  # of Knowledge.new_threats

    def outbox(self, t: float, k: Knowledge, frame: Frame) -> list[bytes]:
        """The frames of tracks and threats sent at ``t``, as the setting says."""
        return self.changed(t, k, frame) if self.on_change else self.periodic(t, k, frame)

    def periodic(self, t: float, k: Knowledge, frame: Frame) -> list[bytes]:
        """Every track and threat known, every ``tracks_every_s`` (``tracks = "periodic"``)."""
        if not (t >= self._next_periodic and (k.tracks or k.threats)):
            return []
        # Packed straight from the tracks and threats: the bytes of Tracks(TrackItem(...) of
        # each) and Threats(ThreatItem(...) of each).
        out = _frames(t, [tr for _, tr in sorted(k.tracks.items())], [th for _, th in sorted(k.threats.items())],
                      frame)
        self._next_periodic = t + self.every - 1e-9
        return out

    def changed(self, t: float, k: Knowledge, frame: Frame) -> list[bytes]:
        """The tracks new or newer than last sent whose turn it is, and the threats not sent yet."""
        threats = k.new_threats[self._threats_sent:]
        if not (k.changed or threats):
            return []
        items = []
        if k.changed:
            sent, every = self._sent, self.every
            # Changes go out together, at most one frame every tracks_every_s (so at most that
            # often per track); a track new to the UAV goes out at once.
            batch = t >= self._next_ok
            keep = set()
            tracks = k.tracks
            for target in sorted(k.changed):
                tr = tracks[target]
                last = sent.get(target)
                if last is not None and tr.t <= last:
                    continue  # (what it last sent: nothing new)
                if not batch and last is not None:
                    keep.add(target)  # newer, not its turn yet
                    continue
                items.append(tr)
                sent[target] = tr.t
            if batch and items:
                self._next_ok = t + every - 1e-9
            k.changed = keep
        self._threats_sent = len(k.new_threats)
        if not (items or threats):
            return []
        return _frames(t, items, [k.threats[th] for th in threats], frame)

    def digest(self, t: float, k: Knowledge) -> Packed | None:
        """The track digest for the beacon sent at ``t``, if one is due (on change only)."""
        if not (self.on_change and t >= self._next_digest):
            return None
        self._next_digest = t + self.digest_every - 1e-9
        targets = sorted(k.tracks)
        tracks = k.tracks
        return pack_track_digest(self.uid, t, targets, [tracks[g].t for g in targets], sorted(k.threats))

    def answer(self, digests: Sequence[TrackDigest], t: float, k: Knowledge, peers: Mapping[int, Peer],
               timeout_s: float, frame: Frame) -> list[tuple[int, bytes]]:
        """The frames sent at ``t`` in answer to the track ``digests`` heard, as ``(receiver,
        frame)`` (see the module docstring; nothing with ``tracks = "periodic"``, where every
        track goes out anyway)."""
        replies: list[tuple[int, bytes]] = []
        if not self.on_change:
            return replies
        tracks = k.tracks
        n = 0
        every = self.every
        for dg in digests:
            theirs = dict(zip(dg.targets, dg.times))
            lack = sorted(tracks.keys() - theirs.keys())
            threats = sorted(k.threats.keys() - set(dg.threats))
            if theirs and tracks:  # (it may hold some older than ours: if we answer this digest)
                if n == 0:
                    n = sum(1 for p in peers.values() if t - p.t_pose <= timeout_s)
                if n <= ANSWERERS or answer_hash(self.uid, dg.uav, dg.t) % n < ANSWERERS:
                    lack = sorted([*lack, *(g for g, tg in theirs.items() if g in tracks and tracks[g].t > tg + every)])
            if lack or threats:
                for f in _frames(t, [tracks[g] for g in lack], [k.threats[th] for th in threats], frame):
                    replies.append((dg.uav, f))
        return replies


__all__ = ["TRACKS_PER_FRAME", "TrackSync", "digest_every_s", "track_delay_s"]
