"""comms.framecache.DecodeCache: each distinct frame decoded once, shared by its receivers; a
copy corrupted on one link is other bytes, rejected by that receiver alone."""

from __future__ import annotations

import pytest

from comms.codec import FrameError, decode, encode
from comms.framecache import DecodeCache
from comms.messages import Hello, Intent, ScanRecords


def frame(seq: int) -> bytes:
    return encode(3, seq, 1.0 * seq, [Hello(3, "B", 1.0, 2.0, 80.0, 0.1), Intent(3, 5.0, 6.0, 0, -1),
                                      ScanRecords(3, (1.0 * seq, 10.0, 20.0, 2000.0))])


def test_decodes_once_and_returns_what_decode_returns():
    cache = DecodeCache()
    data = frame(1)
    first = cache.decode(data)
    assert first == decode(data)
    assert cache.decode(data) is first and cache.lookup(data) is first
    assert cache.decode(bytes(bytearray(data))) is first  # equal bytes, another object
    assert cache.decoded == 1
    assert cache.decode(bytearray(data)) == first  # not hashable: decoded, not cached


def test_corrupted_copies_are_rejected_every_time_and_never_cached():
    cache = DecodeCache()
    good = frame(2)
    bad = bytearray(good)
    bad[7] ^= 0x5A
    bad = bytes(bad)
    cache.decode(good)
    for _ in range(2):
        with pytest.raises(FrameError):
            cache.decode(bad)
    assert cache.lookup(bad) is None and cache.decoded == 3 and len(cache) == 1
    assert cache.decode(good) == decode(good)  # the good copy is unharmed


def test_size_bound_evicts_oldest_without_changing_results():
    cache = DecodeCache(size=4)
    frames = [frame(k) for k in range(10)]
    for data in frames:
        cache.decode(data)
        assert len(cache) <= 4
    assert cache.lookup(frames[0]) is None and cache.lookup(frames[-1]) is not None
    assert [cache.decode(d) for d in frames] == [decode(d) for d in frames]


def hear(actor, t: float):
    """The actor's inbox merged at ``t`` (agents.inbox.Inbox.merge), as its step does first."""
    return actor.inbox.merge(actor.mailbox.drain(), t, 0.0, 0.0, actor.umap, actor.knowledge, actor.scans,
                             actor.counters)


def test_derive_keeps_one_value_per_frame_for_what_it_was_derived_for():
    """DecodeCache.derive: the value kept for an equal key without deriving again; another key
    derives from the frame held (no decoding) and replaces it; the value goes with its frame;
    a frame that does not decode raises each time and keeps nothing; bytes-like data that is
    not bytes is derived every time."""
    cache = DecodeCache(size=1)
    data = frame(1)
    calls = []

    def derive(f):
        calls.append(f)
        return len(calls)

    assert cache.derive(data, "a", derive) == 1 and calls == [decode(data)] and cache.decoded == 1
    assert cache.derive(data, "a", derive) == 1 and len(calls) == 1  # kept
    assert cache.derive(data, "b", derive) == 2 and cache.decoded == 1  # derived again, not decoded
    assert cache.derive(data, "a", derive) == 3  # one value a frame: the last key's
    cache.decode(frame(9))  # evicts the frame (size 1), and what was kept with it
    assert cache.lookup(data) is None
    assert cache.derive(data, "a", derive) == 4 and cache.decoded == 3
    bad = bytearray(data)
    bad[-1] ^= 0xFF  # the CRC
    for _ in range(2):
        with pytest.raises(FrameError):
            cache.derive(bytes(bad), "a", derive)
    assert len(calls) == 4 and cache.decoded == 5 and cache.lookup(bytes(bad)) is None
    assert cache.derive(bytearray(data), "a", derive) == 5 and cache.derive(bytearray(data), "a", derive) == 6


def test_receivers_sharing_a_cache_count_their_own_rejections():
    import numpy as np

    from agents.actor import UavActor
    from agents.inputs import ActorSettings
    from agents.maps.grid import Grid
    from agents.planners.greedy import GreedyPlanner
    from agents.types import UavType
    from comms.mailbox import Mailbox

    kind = UavType("B", 60.0, 90.0, 0.6, 0.35, 2000.0, 2.0, 2.1, 4000.0)
    grid = Grid(50_000.0, 50_000.0, 100.0)
    cache = DecodeCache()
    actors = [UavActor(u, f"B{u}", kind, grid, 0.005, GreedyPlanner(), np.random.default_rng(u), ActorSettings(),
                       Mailbox(16), decoder=cache) for u in (1, 2)]
    good = frame(5)
    bad = bytearray(good)
    bad[-1] ^= 0xFF  # the CRC
    actors[0].mailbox.put(1.0, 3, bytes(bad))
    actors[1].mailbox.put(1.0, 3, good)
    assert hear(actors[0], 10.0) == [(3, len(good), False)]
    assert hear(actors[1], 10.0) == [(3, len(good), True)]
    assert (actors[0].counters.rejected, actors[0].counters.delivered) == (1, 0)
    assert (actors[1].counters.rejected, actors[1].counters.delivered) == (0, 1)
    assert 3 in actors[1].knowledge.peers and 3 not in actors[0].knowledge.peers
    assert np.isfinite(actors[1].umap.to_dense()).any() and not np.isfinite(actors[0].umap.to_dense()).any()


def test_a_checked_frame_is_reused_only_at_the_clock_it_was_checked_for():
    """agents.inbox: what a receiver accepts of a frame is kept beside it for the tick's time;
    a receiver at another time checks again (a scan from after the first clock is ignored then,
    accepted later), and the kept value goes with its frame."""
    import numpy as np

    from agents.actor import UavActor
    from agents.inputs import ActorSettings
    from agents.maps.grid import Grid
    from agents.planners.greedy import GreedyPlanner
    from agents.types import UavType
    from comms.mailbox import Mailbox

    kind = UavType("B", 60.0, 90.0, 0.6, 0.35, 2000.0, 2.0, 2.1, 4000.0)
    grid = Grid(50_000.0, 50_000.0, 100.0)
    cache = DecodeCache(size=1)
    actors = [UavActor(u, f"B{u}", kind, grid, 0.005, GreedyPlanner(), np.random.default_rng(u), ActorSettings(),
                       Mailbox(16), decoder=cache) for u in (1, 2, 4)]
    # Sent at t = 1 with a scan stamped 1.5 (from the future at t = 1, from the past at t = 2).
    data = encode(3, 1, 1.0, [Hello(3, "B", 1.0, 2.0, 80.0, 0.1), ScanRecords(3, (1.5, 10.0, 20.0, 2000.0))])
    for a in actors:
        a.mailbox.put(1.0, 3, data)
    hear(actors[0], 1.0)
    hear(actors[1], 2.0)
    hear(actors[2], 1.0)
    assert [a.counters.scans_ignored for a in actors] == [1, 0, 1]
    assert [int(np.isfinite(a.umap.to_dense()).any()) for a in actors] == [0, 1, 0]
    assert all(a.knowledge.peers[3].t_pose == 1.0 for a in actors)
    assert cache.decoded == 1


def test_a_sent_frame_is_found_as_decoding_it_would_give():
    """DecodeCache.encode: the sender's bytes, and their frame remembered without decoding."""
    cache = DecodeCache(key=b"k")
    msgs = [Hello(3, "B", 1.0, 2.0, 80.0, 0.1), ScanRecords(3, (1.0, 10.0, 20.0, 2000.0))]
    data = cache.encode(3, 1, 1.0, msgs)
    assert data == encode(3, 1, 1.0, msgs, b"k")
    assert cache.lookup(data) == decode(data, key=b"k") and cache.decoded == 0
