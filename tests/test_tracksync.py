"""Tracks on change (issue 36, model change M1; ``[radio] tracks``, agents.tracksync): what a UAV
sends of its tracks and threats, its track digest, the answers to the digests it hears, the wire
form of a digest (hostile input included), and, in whole runs, that a UAV that missed a track
gets it (the liveness phase's "tracks spread" obligation, swarm.testing.liveness)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.inbox import check_frame
from agents.knowledge import Knowledge, Peer
from agents.tracksync import TrackSync, digest_every_s, track_delay_s
from comms.codec import K_TRACK_DIGEST, FrameError, decode, encode, pack_track_digest
from comms.messages import Threats, TrackDigest, TrackItem, Tracks
from comms.settings import RadioSettings
from faults.cuts import Partition
from swarm import Simulation
from swarm.scenario import apply_overrides, load_scenario
from swarm.testing.liveness import quiesce, reassign_bound_s, tracks_period_s

ON = RadioSettings(tracks="on_change")
BOUNDS = (1000.0, 5000.0, 5000.0, 1.0)


class Sent:
    """An actor's frame function: encodes as the actor does, and keeps what was sent."""

    def __init__(self, uid: int = 1):
        self.uid = uid
        self.frames: list[bytes] = []

    def __call__(self, t, msgs):
        data = encode(self.uid, len(self.frames) + 1, t, msgs)
        self.frames.append(data)
        return data


def items(data: bytes) -> tuple[list[tuple[int, float]], list[int]]:
    """(target, t) of each track item and the id of each threat item a frame carries."""
    tracks, threats = [], []
    for m in decode(data).messages:
        if type(m) is Tracks:
            tracks += [(i.target, i.t) for i in m.items]
        elif type(m) is Threats:
            threats += [i.threat for i in m.items]
    return tracks, threats


def sent_tracks(frames: list[bytes]) -> list[tuple[int, float]]:
    return [it for f in frames for it in items(f)[0]]


# --- sending ----------------------------------------------------------------------------------------


def test_on_change_sends_a_track_when_new_or_newer_at_most_every_tracks_every_s():
    k, sync, send = Knowledge(), TrackSync(1, ON), Sent()
    assert sync.outbox(0.0, k, send) == []  # nothing known: nothing sent (no empty frame)
    k.see_target(7, 1.0, 2.0, 0.0, 0.0, 0.0, 1.0)
    assert sent_tracks(sync.outbox(0.0, k, send)) == [(7, 0.0)]  # new: at once
    assert sync.outbox(1.0, k, send) == []  # unchanged: not again
    for t in (1.0, 2.0, 3.0, 4.0):  # renewed every tick (a watcher): held back ...
        k.see_target(7, 1.0, 2.0, 0.0, 0.0, t, 1.0)
        assert sync.outbox(t, k, send) == []
    k.see_target(7, 1.0, 2.0, 0.0, 0.0, 5.0, 1.0)
    assert sent_tracks(sync.outbox(5.0, k, send)) == [(7, 5.0)]  # ... until its turn, the newest
    k.see_target(8, 3.0, 4.0, 0.0, 0.0, 6.0, 1.0)  # another target's track is not held back by it
    k.see_target(7, 1.0, 2.0, 0.0, 0.0, 6.0, 1.0)
    assert sent_tracks(sync.outbox(6.0, k, send)) == [(8, 6.0)]
    assert sent_tracks(sync.outbox(10.0, k, send)) == [(7, 6.0)]  # the pending change, at its turn
    k.merge_track_rows([(7, 1.0, 2.0, 0.0, 0.0, 3.0, 1.0)])  # an older heard version: nothing new
    assert sync.outbox(20.0, k, send) == []


def test_on_change_sends_a_threat_once_and_tracks_heard_are_relayed():
    k, sync, send = Knowledge(), TrackSync(1, ON), Sent()
    k.add_threat(3, 100.0, 100.0, 50.0, 80.0)
    assert items(sync.outbox(0.0, k, send)[0]) == ([], [3])
    assert sync.outbox(1.0, k, send) == []
    k.merge_tracks([TrackItem(9, 1.0, 1.0, 0.0, 0.0, 0.5, 1.0)])  # heard: relayed (spreads hop by hop)
    assert sent_tracks(sync.outbox(1.0, k, send)) == [(9, 0.5)]


def test_periodic_sends_every_track_and_threat_every_tracks_every_s():
    k, sync, send = Knowledge(), TrackSync(1, RadioSettings()), Sent()
    k.see_target(2, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    k.see_target(1, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    k.add_threat(3, 100.0, 100.0, 50.0, 80.0)
    assert [items(f) for f in sync.outbox(0.0, k, send)] == [([(1, 0.0), (2, 0.0)], [3])]
    assert sync.outbox(4.0, k, send) == [] and len(sync.outbox(5.0, k, send)) == 1
    assert sync.digest(0.0, k) is None and sync.answer([TrackDigest(2, 0.0, (), (), ())], 0.0, k, {}, 5.0, send) == []


def test_the_digest_lists_every_track_and_threat_every_sync_every_s():
    k, sync = Knowledge(), TrackSync(4, ON)
    assert sync.digest(0.0, k) == [K_TRACK_DIGEST, 4, 0.0, [], [], []]  # (empty: a newcomer says so)
    k.see_target(5, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0)
    k.see_target(2, 1.0, 1.0, 0.0, 0.0, 2.5, 1.0)
    k.add_threat(9, 100.0, 100.0, 50.0, 80.0)
    assert sync.digest(4.0, k) is None
    assert sync.digest(5.0, k) == [K_TRACK_DIGEST, 4, 5.0, [2, 5], [2.5, 1.0], [9]]
    assert digest_every_s(ON) == 5.0 and digest_every_s(RadioSettings(tracks="on_change", sync_every_s=0)) == 5.0


# --- answering --------------------------------------------------------------------------------------


def _knows(*tracks: tuple[int, float], threats: tuple[int, ...] = ()) -> Knowledge:
    k = Knowledge()
    for g, t in tracks:
        k.see_target(g, 1.0, 1.0, 0.0, 0.0, t, 1.0)
    for th in threats:
        k.add_threat(th, 100.0, 100.0, 50.0, 80.0)
    return k


def _peers(n: int, t: float = 10.0) -> dict[int, Peer]:
    return {u: Peer(u, t_pose=t) for u in range(100, 100 + n)}


def test_every_neighbour_answers_with_what_the_sender_lacks():
    k = _knows((1, 9.0), (2, 3.0), threats=(5,))
    dg = TrackDigest(7, 10.0, (1,), (9.0,), ())
    for me in range(20):  # whatever the hash says, among 50 neighbours
        send = Sent(me)
        replies = TrackSync(me, ON).answer([dg], 10.0, k, _peers(50), 5.0, send)
        assert [(r, items(f)) for r, f in replies] == [(7, ([(2, 3.0)], [5]))]


def test_a_track_held_older_is_repaired_by_the_answerers_only_beyond_tracks_every_s():
    k = _knows((1, 9.0))
    # 1 s older: a change on its way, nobody answers; 6 s older: missed, the answerers answer.
    assert TrackSync(1, ON).answer([TrackDigest(7, 10.0, (1,), (8.0,), ())], 10.0, k, _peers(2), 5.0, Sent()) == []
    stale = TrackDigest(7, 10.0, (1,), (3.0,), ())
    answered = [me for me in range(40)
                if TrackSync(me, ON).answer([stale], 10.0, k, _peers(40), 5.0, Sent())]
    assert 0 < len(answered) < 10  # about two of 40 (the hash rule, as for scans)
    assert all(TrackSync(me, ON).answer([stale], 10.0, k, _peers(2), 5.0, Sent()) for me in range(5))  # n <= 2: all


# --- the wire ---------------------------------------------------------------------------------------


def test_a_track_digest_round_trips_and_is_checked():
    dg = TrackDigest(3, 50.0, (1, 4), (20.0, 49.5), (2,))
    frame = decode(encode(3, 1, 50.0, [dg]))
    assert frame.messages == (dg,)
    assert check_frame(frame, 60.0, BOUNDS).digests == (dg,)
    # Sighting times after the receiver's clock, or ids out of range: ignored and counted.
    for bad in (TrackDigest(3, 50.0, (1,), (70.0,), ()), TrackDigest(3, 50.0, (-1,), (1.0,), ()),
                TrackDigest(3, 50.0, (1,), (1.0,), (2**40,))):
        heard = check_frame(decode(encode(3, 1, 50.0, [bad])), 60.0, BOUNDS)
        assert heard.digests == () and heard.strange == 1


@given(st.lists(st.one_of(st.integers(-3, 3), st.floats(allow_nan=True), st.booleans(), st.none(), st.text(max_size=2)),
                max_size=4), st.lists(st.one_of(st.floats(allow_nan=True), st.integers(-3, 3), st.booleans()), max_size=4))
@settings(max_examples=60, deadline=None)
def test_a_hostile_track_digest_decodes_or_is_rejected(targets, times):
    """Whatever a peer puts in a track digest's lists, decoding gives a digest of exact ints and
    finite floats that pair up, or a FrameError."""
    data = encode(3, 1, 50.0, [pack_track_digest(3, 50.0, targets, times, targets)])
    try:
        (dg,) = decode(data).messages
    except FrameError:
        return
    assert isinstance(dg, TrackDigest) and len(dg.targets) == len(dg.times)
    assert all(type(g) is int for g in dg.targets + dg.threats) and all(math.isfinite(x) for x in dg.times)


def test_a_frame_with_mismatched_digest_lists_is_rejected():
    with pytest.raises(FrameError, match="2 targets, 1 times"):
        decode(encode(3, 1, 5.0, [pack_track_digest(3, 5.0, [1, 2], [1.0], [])]))
    with pytest.raises(FrameError):
        decode(encode(3, 1, 5.0, [[K_TRACK_DIGEST, 3, 5.0, [1], [1.0]]]))  # a field short


# --- settings and whole runs ------------------------------------------------------------------------


def test_the_setting_is_validated_with_a_clear_error():
    from swarm.errors import ScenarioError

    with pytest.raises(ScenarioError, match="radio.tracks.*one of: periodic, on_change"):
        load_scenario("paper-case1", overrides={"radio.tracks": "sometimes"})


def test_bounds_follow_the_setting():
    sc = load_scenario("paper-case1")
    on = apply_overrides(sc, {"radio.tracks": "on_change"})
    assert track_delay_s(sc.radio, 1.0) == 5.0 and track_delay_s(on.radio, 1.0) == 5.0 + 1.0 + 2.0
    assert reassign_bound_s(on) - reassign_bound_s(sc) == 3.0
    assert tracks_period_s(on, 3) == 3 * (8.0 + 1.0)


def _partitioned(tracks: str):
    """paper-case1 without surveillance (a track stops changing once its target is out of
    sight), A1 cut off from B1 and B2 for the first 60 s, in which they find the targets."""
    sc = apply_overrides(load_scenario("paper-case1"), {"radio.tracks": tracks, "planner.surveillance": False,
                                                        "duration_s": 200.0})
    sim = Simulation(sc)
    sim.add_fault(Partition(groups=(("A1",), ("B1", "B2")), start_s=0.0, end_s=60.0))
    return sim


@pytest.mark.parametrize("tracks", ["periodic", "on_change"])
def test_a_uav_that_missed_the_tracks_gets_them_within_the_bound(tracks):
    with _partitioned(tracks) as sim:
        sim.step(60)
        a1 = sim.actors[2]
        assert a1.knowledge.tracks == {} and sim.actors[0].knowledge.tracks  # (A1 missed them)
        report = quiesce(sim, faults_end_s=60.0)
        assert not report.violations, report.violations
        assert any(j.startswith("tracks: 6 ordered pair") for j in report.judged), report.judged
        assert set(a1.knowledge.tracks) == set(sim.actors[0].knowledge.tracks)


def test_the_liveness_phase_catches_tracks_never_repaired(monkeypatch):
    """Planted: nobody answers a track digest. The tracks B1 and B2 found while A1 was cut off
    no longer change, so nothing sends them again: A1 never gets them, and the phase says so."""
    monkeypatch.setattr(TrackSync, "answer", lambda self, *a, **kw: [])
    with _partitioned("on_change") as sim:
        report = quiesce(sim, faults_end_s=60.0)
    assert report.violations and all("still has no track" in v.message for v in report.violations)
