"""Frame records (issue 36 T1, the tick plane): a sender keeps its packed messages keyed by the
bytes (comms.codec.encode_record, DecodeCache with ``records``), and a receiver reads the record
straight into what it accepts (agents.inbox.check_frame of a FrameRecord). That path must give
exactly what decoding the bytes and checking the frame gives (decode + check_frame: the oracle),
or the same error, for any messages a sender may hand the codec: hostile numbers (NaN, infinities,
bools, numpy floats, huge ints), wrong shapes and types, unknown kinds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.inbox import check_frame
from comms.codec import (
    K_DIGEST,
    K_HELLO,
    K_INTENT,
    K_SCAN,
    K_THREATS,
    K_TRACK_DIGEST,
    K_TRACKS,
    AuthError,
    FrameError,
    FrameRecord,
    decode,
    encode,
    pack_hello,
    pack_intent,
    pack_scans,
    read,
)
from comms.framecache import DecodeCache
from comms.messages import Hello, ScanRecords, TrackDigest, TrackItem, Tracks

BOUNDS = (1000.0, 5000.0, 5000.0, 1.0)  # (max scan radius, width, height, dt): check_frame's
T_RECV = 100.0
KEY = b"swarm key"

# --- hostile values ----------------------------------------------------------------------------

nasty_floats = st.sampled_from([math.nan, math.inf, -math.inf, -0.0, 0.0, 1e308, -1e308, 5e-324, 2.0**63])
nasty = st.one_of(
    nasty_floats,
    st.booleans(),
    st.none(),
    st.integers(-(2**63), 2**64 - 1),
    st.floats().map(np.float64),  # a float subclass: written as a float
    st.text(max_size=3),
    st.binary(max_size=3),
    st.lists(st.integers(0, 3), max_size=2),
    st.tuples(st.floats(0, 10)),
)


@st.composite
def frames(draw):
    """``(messages, sender, seq, t)``: a frame's content, each value mostly one an honest sender
    writes (often plausible, sometimes not) and, in frames drawn hostile, sometimes anything."""
    rate = draw(st.sampled_from([0, 0, 0, 8, 30]))  # percent of hostile values

    def v(good: st.SearchStrategy):
        if rate and draw(st.integers(0, 99)) < rate:
            return draw(nasty)
        return draw(good)

    ids = st.integers(-2, 12) | st.sampled_from([2**31, 2**63 - 1])
    coords = st.floats(-1500.0, 6500.0) | st.integers(-10, 6000)
    times = st.floats(-5.0, 150.0) | st.integers(0, 150)
    small = st.floats(-20.0, 1200.0)

    def shaped(items: list) -> list:
        """A message's (or item's) fields, in hostile frames sometimes one too few or too many."""
        how = draw(st.integers(0, 39)) if rate else 9
        if how == 0 and len(items) > 1:
            return items[:-1]
        if how == 1:
            return [*items, draw(nasty)]
        return items

    def message():
        kind = draw(st.sampled_from([K_HELLO, K_INTENT, K_SCAN, K_SCAN, K_TRACKS, K_THREATS, K_DIGEST, K_TRACK_DIGEST]))
        if kind == K_HELLO:
            items = [kind, v(ids), v(st.sampled_from(["A", "B", "B", "x" * 65])), v(coords), v(coords), v(small), v(small)]
            if draw(st.integers(0, 3)) == 0 and type(items[2]) is str:
                return Hello(*items[1:])  # (a Message object, packed by the codec)
        elif kind == K_INTENT:
            items = [kind, v(ids), v(coords), v(coords), v(st.sampled_from([0, 1, 1, 1, 1, 2])), v(ids)]
        elif kind == K_SCAN:
            recs = [v(g) for _ in range(draw(st.integers(0, 4))) for g in (times, coords, coords, small)]
            if rate and draw(st.integers(0, 9)) == 0:
                recs = recs[:-1]  # not a multiple of 4
            if draw(st.booleans()):
                # The forms a sender may hand over: a tuple (read back as a list), a ScanRecords.
                if draw(st.booleans()):
                    return ScanRecords(v(ids), tuple(recs))
                recs = tuple(recs)
            items = [kind, v(ids), recs]
        elif kind == K_TRACKS:
            tracks = [shaped([v(ids), v(coords), v(coords), v(small), v(small), v(times), v(small)])
                      for _ in range(draw(st.integers(0, 3)))]
            if tracks and draw(st.integers(0, 4)) == 0 and all(len(t) == 7 for t in tracks):
                return Tracks(tuple(TrackItem(*t) for t in tracks))
            items = [kind, tracks]
        elif kind == K_THREATS:
            threats = []
            for _ in range(draw(st.integers(0, 2))):
                r = draw(st.floats(1.0, 900.0))
                d = r + draw(st.sampled_from([-10.0, 0.0, 400.0, 1500.0]))  # (some bad: d_max < radius)
                threats.append(shaped([v(ids), v(coords), v(coords), v(st.just(r)), v(st.just(d))]))
            items = [kind, threats]
        elif kind == K_TRACK_DIGEST:  # (issue 36, M1) targets and times that may not pair up
            n = draw(st.integers(0, 3))
            targets = [v(ids) for _ in range(n)]
            stamps = [v(times) for _ in range(n + (draw(st.integers(-1, 1)) if rate else 0))]
            threat_ids = [v(ids) for _ in range(draw(st.integers(0, 2)))]
            if not rate and draw(st.integers(0, 3)) == 0:
                return TrackDigest(v(ids), v(times), tuple(targets), tuple(stamps), tuple(threat_ids))
            items = [kind, v(ids), v(times), targets, stamps, threat_ids]
        else:
            bitmaps = [shaped([v(ids), v(st.binary(max_size=4))]) for _ in range(draw(st.integers(0, 2)))]
            items = [kind, v(ids), v(times), v(st.integers(-3, 3)), v(st.integers(-3, 3)), v(st.integers(0, 12)), bitmaps]
        if rate and draw(st.integers(0, 19)) == 0:
            items = [draw(st.sampled_from([0, 8, -1, True, 3.0])), *items[1:]]  # an unknown kind
        if rate and draw(st.integers(0, 29)) == 0:
            return draw(st.lists(nasty, max_size=2))  # junk
        return shaped(items)

    msgs = [message() for _ in range(draw(st.integers(0, 5)))]
    sender, seq = v(st.integers(0, 2**63 - 1)), v(st.integers(0, 2**63 - 1))
    t = v(st.floats(-1.0, 120.0)) if draw(st.integers(0, 9)) else draw(nasty_floats | st.floats().map(np.float64))
    return msgs, sender, seq, t


def outcome(f, *args):
    """What a call gives: its result's repr (types and -0.0 told apart), or its error's type and message."""
    try:
        return ("ok", repr(f(*args)))
    except FrameError as exc:
        return (type(exc).__name__, str(exc))


def oracle(data: bytes, key: bytes | None) -> tuple[str, str]:
    """decode, then check_frame: the per-actor path."""
    return outcome(lambda: check_frame(decode(data, key=key), T_RECV, BOUNDS))


def heard_of(cache: DecodeCache, data: bytes) -> tuple[str, str]:
    return outcome(cache.derive, data, (T_RECV, BOUNDS), lambda f: check_frame(f, T_RECV, BOUNDS))


@settings(max_examples=examples(600), deadline=None)
@given(frames(), st.sampled_from([None, KEY]))
def test_a_record_gives_what_decoding_and_checking_give(frame, key):
    msgs, sender, seq, t = frame
    try:
        data = encode(sender, seq, t, msgs, key)
    except (TypeError, ValueError, OverflowError):
        return  # (not a frame: the sender's encode raises, whichever path)
    expected = oracle(data, key)
    # The sender's record, held as it was packed (no check at send time).
    cache = DecodeCache(key=key, records=True)
    assert cache.encode(sender, seq, t, msgs) == data
    rec = cache.lookup(data)
    assert type(rec) is FrameRecord and rec.sent
    assert heard_of(cache, data) == expected
    assert heard_of(cache, data) == expected  # (kept, or derived again from what is held)
    # The bytes alone (a receiver whose memo lost them, a delayed copy): read and checked.
    assert heard_of(DecodeCache(key=key, records=True), data) == expected
    assert outcome(check_frame, read(data, key=key), T_RECV, BOUNDS) == expected
    # decode() keeps its contract on a cache holding records.
    assert outcome(DecodeCache(key=key, records=True).decode, data) == outcome(lambda: decode(data, key=key))
    assert outcome(cache.decode, data) == outcome(lambda: decode(data, key=key))
    # A copy corrupted in flight, or one without the key: rejected as decoding rejects it.
    bad = bytearray(data)
    bad[len(bad) // 2] ^= 0x10
    assert heard_of(cache, bytes(bad)) == oracle(bytes(bad), key) and expected[0] != "AuthError"
    if key is not None:
        spoof = encode(sender, seq, t, msgs, None)
        assert heard_of(cache, spoof)[0] == "AuthError" == oracle(spoof, key)[0]


def test_a_senders_record_that_msgpack_reads_back_otherwise_is_replaced_by_the_bytes():
    """A numpy float is written as a float: the sender's record fails a check decoding passes,
    so the bytes decide, and their record is held in its place (read once)."""
    msgs = [pack_hello(3, "B", np.float64(10.0), 20.0, 30.0, 0.5), pack_scans(3, (1.0, 10.0, 20.0, 50.0))]
    cache = DecodeCache(records=True)
    data = cache.encode(3, 1, 2.0, msgs)
    assert cache.lookup(data).sent and cache.decoded == 0
    got = cache.derive(data, (T_RECV, BOUNDS), lambda f: check_frame(f, T_RECV, BOUNDS))
    assert got == check_frame(decode(data), T_RECV, BOUNDS) and len(got.hellos) == 1 and len(got.scans) == 1
    assert type(got.hellos[0].x) is float and cache.decoded == 1 and not cache.lookup(data).sent
    assert cache.derive(data, (T_RECV + 1, BOUNDS), lambda f: check_frame(f, T_RECV + 1, BOUNDS)) == got
    assert cache.decoded == 1


def test_records_are_held_as_frames_are_held():
    """Sent frames held without decoding; bytes read once and held only if they check; a bad
    copy rejected each time, nothing held; the oldest dropped beyond the size, with what was
    derived from them; a frame over the size cap not held (decoding rejects it)."""
    cache = DecodeCache(size=4, records=True, key=KEY)
    sent = [cache.encode(1, k, 1.0, [pack_hello(1, "B", 1.0, 2.0, 3.0, 4.0), pack_intent(1, 5.0, 6.0, 0, -1)])
            for k in range(6)]
    assert len(cache) <= 4 and cache.lookup(sent[0]) is None and cache.lookup(sent[-1]) is not None
    assert cache.decoded == 0
    stranger = encode(2, 1, 1.0, [pack_hello(2, "A", 1.0, 2.0, 3.0, 4.0)], KEY)
    assert cache.decode(stranger) == decode(stranger, key=KEY) and cache.decoded == 1
    assert cache.decode(stranger) == decode(stranger, key=KEY) and cache.decoded == 1  # held
    bad = bytearray(stranger)
    bad[9] ^= 0x01
    for _ in range(2):
        with pytest.raises(FrameError):
            cache.derive(bytes(bad), "k", lambda f: 0)
    assert cache.lookup(bytes(bad)) is None and cache.decoded == 3
    with pytest.raises(AuthError):
        cache.derive(encode(2, 1, 1.0, [pack_hello(2, "A", 1.0, 2.0, 3.0, 4.0)]), "k", lambda f: 0)
    big = DecodeCache(max_bytes=60, records=True)
    data = big.encode(1, 1, 1.0, [pack_scans(1, [1.0, 2.0, 3.0, 4.0] * 5)])
    assert len(data) > 60 and big.lookup(data) is None
    with pytest.raises(FrameError, match="oversized"):
        big.derive(data, "k", lambda f: 0)


@pytest.mark.slow  # two whole runs of demo-all-faults (about 3 s each)
@pytest.mark.parametrize("auth", [True, False])
def test_a_run_with_records_logs_what_the_per_actor_path_logs(auth):
    """Simulation(tick_plane=True) holds records, tick_plane=False frames (the oracle): the same
    event log and the same counters (frames delivered and rejected, auth failures, messages and
    scans ignored) on demo-all-faults, every fault kind (corruption, duplication, delay, a
    spoofer, a liar, ...), with the swarm key (the spoofer's frames fail the MAC) and without
    (the spoofer's frames are read and checked)."""
    from swarm import Simulation
    from swarm.scenario import apply_overrides, load_scenario

    sc = apply_overrides(load_scenario("demo-all-faults"), {"radio.auth": auth})
    runs = []
    for tick_plane in (True, False):
        with Simulation(sc, tick_plane=tick_plane) as sim:
            m = sim.run().metrics
            assert sim._decoder.records is tick_plane
            held = next(iter(sim._decoder._frames.values()))
            assert (type(held) is FrameRecord) is tick_plane
            runs.append((m["event_log_sha256"], m["radio"], m["per_uav"],
                         {u: repr(a.counters) for u, a in sorted(sim.actors.items())}))
    assert runs[0] == runs[1]
    radio = runs[0][1]
    assert radio["rejected"] > 0 and (radio["rejected_auth"] > 0) is auth
