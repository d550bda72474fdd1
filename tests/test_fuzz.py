"""Hardened inputs: frames and scenario documents that are wrong in every way we can think of.

* Frames: arbitrary bytes and mutated valid frames (byte flips, truncation, extension, splices,
  some re-sealed with a correct CRC so they reach msgpack and the schema check). ``decode`` may
  only ever raise ``FrameError``; fed to live receivers, every frame ``decode`` rejects is
  counted as rejected by the receiving actor and logged as ``rx ... accepted=false``, and the
  simulation keeps running. A few thousand inputs by default; the slow test runs 120,000.
* Scenario documents: generated valid documents with one thing made wrong (a wrong type, an
  out-of-range value, a missing key, an unknown key, a table replaced by a scalar...) only ever
  produce ``ScenarioError`` naming a key path, never another exception.
"""

from __future__ import annotations

import copy
import datetime
import math
import zlib
from collections.abc import Iterator

import numpy as np
import pytest
from budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from comms.codec import Frame, FrameError, decode, encode
from comms.messages import Hello, Intent, ScanDigest, ScanRecords, ThreatItem, Threats, TrackItem, Tracks
from swarm import Simulation
from swarm.errors import ScenarioError
from swarm.scenario import parse_scenario, scenario_from_toml
from swarm.scenario.positions import key_path as _key
from swarm.testing.strategies import scenario_documents, scenario_toml

# --- frame fuzzing ---------------------------------------------------------------------------------


def _valid_frame(rng: np.random.Generator) -> bytes:
    """A frame as an actor would send it, with random content."""
    def num():
        return float(rng.normal(0, 10_000))

    msgs = []
    for _ in range(int(rng.integers(1, 5))):
        k = int(rng.integers(0, 6))
        uav = int(rng.integers(0, 6))
        if k == 0:
            msgs.append(Hello(uav, "AB"[int(rng.integers(0, 2))], num(), num(), abs(num()), num()))
        elif k == 1:
            msgs.append(Intent(uav, num(), num(), int(rng.integers(0, 2)), int(rng.integers(-1, 5))))
        elif k == 2:
            recs = []
            for _ in range(int(rng.integers(0, 6))):
                recs += [float(rng.uniform(0, 50)), num(), num(), float(rng.uniform(0, 3000))]
            msgs.append(ScanRecords(uav, tuple(recs)))
        elif k == 3:
            msgs.append(Tracks(tuple(TrackItem(int(rng.integers(0, 9)), num(), num(), num(), num(),
                                               float(rng.uniform(0, 50)), 1.0)
                                     for _ in range(int(rng.integers(0, 4))))))
        elif k == 4:
            r = float(rng.uniform(100, 3000))
            msgs.append(Threats((ThreatItem(int(rng.integers(0, 4)), num(), num(), r, r + 3000.0),)))
        else:
            bitmaps = tuple((int(o), rng.bytes(int(rng.integers(0, 12)))) for o in range(int(rng.integers(0, 4))))
            msgs.append(ScanDigest(uav, float(rng.uniform(-10, 100)), 8 * int(rng.integers(-1, 3)), 0,
                                   int(rng.integers(0, 8)), bitmaps))
    return encode(int(rng.integers(0, 6)), int(rng.integers(0, 1 << 20)), float(rng.uniform(0, 100)), msgs)


def _reseal(data: bytes) -> bytes:
    payload = data[:-4] if len(data) > 4 else data
    return payload + zlib.crc32(payload).to_bytes(4, "little")


def _mutate(rng: np.random.Generator, frame: bytes, other: bytes) -> bytes:
    buf = bytearray(frame)
    op = int(rng.integers(0, 7))
    if op == 0 and buf:  # flip 1-8 bytes
        for p in rng.integers(0, len(buf), size=int(rng.integers(1, 9))).tolist():
            buf[p] ^= int(rng.integers(1, 256))
    elif op == 1:  # truncate
        del buf[int(rng.integers(0, len(buf) + 1)):]
    elif op == 2:  # extend with junk
        buf += rng.bytes(int(rng.integers(1, 64)))
    elif op == 3:  # splice with another frame
        cut = int(rng.integers(0, len(buf) + 1))
        buf = buf[:cut] + other[int(rng.integers(0, len(other) + 1)):]
    elif op == 4 and buf:  # delete a range
        a = int(rng.integers(0, len(buf)))
        del buf[a:a + int(rng.integers(1, 16))]
    elif op == 5:  # insert junk
        a = int(rng.integers(0, len(buf) + 1))
        buf[a:a] = rng.bytes(int(rng.integers(1, 16)))
    else:  # overwrite one msgpack type byte with another type marker
        if buf:
            buf[int(rng.integers(0, len(buf)))] = int(rng.choice([0xC0, 0xC2, 0xC3, 0xCB, 0xD9, 0xDC, 0xDE, 0x90, 0x80, 0xFF]))
    out = bytes(buf)
    # Half the mutants get a correct CRC again, so they reach msgpack and the schema check.
    return _reseal(out) if rng.random() < 0.5 and len(out) >= 5 else out


def fuzz_frames(seed: int, n: int) -> Iterator[bytes]:
    """``n`` inputs: a quarter arbitrary bytes, the rest mutated valid frames."""
    rng = np.random.default_rng(seed)
    pool = [_valid_frame(rng) for _ in range(64)]
    for i in range(n):
        if i % 4 == 0:
            yield rng.bytes(int(rng.integers(0, 300)))
        else:
            a, b = pool[int(rng.integers(0, len(pool)))], pool[int(rng.integers(0, len(pool)))]
            data = _mutate(rng, a, b)
            if rng.random() < 0.3:
                data = _mutate(rng, data, b)  # mutate twice
            yield data
        if i % 1000 == 999:
            pool[int(rng.integers(0, len(pool)))] = _valid_frame(rng)


def _decode_all(frames) -> tuple[int, int]:
    rejected = accepted = 0
    for data in frames:
        try:
            f = decode(data)
        except FrameError:
            rejected += 1
            continue
        # Anything accepted is exactly the schema: typed fields, finite numbers.
        assert type(f) is Frame and type(f.sender) is int and math.isfinite(f.t)
        accepted += 1
    return rejected, accepted


def test_fuzzed_frames_only_ever_raise_frame_error():
    rejected, accepted = _decode_all(fuzz_frames(seed=1, n=5_000))
    assert rejected + accepted == 5_000
    assert rejected > 4_000 and accepted > 0  # re-sealed mutants that stay well formed exist too


@pytest.mark.slow
def test_fuzzed_frames_only_ever_raise_frame_error_120k():
    rejected, accepted = _decode_all(fuzz_frames(seed=2, n=120_000))
    assert rejected + accepted == 120_000 and rejected > 100_000


@settings(max_examples=examples(300))
@given(st.binary(max_size=400), st.integers(0, 2**32 - 1))
def test_hypothesis_bytes_and_resealed_bytes_only_raise_frame_error(data, seed):
    for candidate in (data, _reseal(data), _mutate(np.random.default_rng(seed), _valid_frame(np.random.default_rng(seed)), data)):
        try:
            decode(candidate)
        except FrameError:
            pass


def _fuzz_live(n_frames: int, seed: int, planner: str) -> tuple[int, int]:
    """Feed fuzzed frames to every live receiver of a small run; returns (fed, rejected)."""
    doc = {"name": "fuzz", "seed": seed, "duration_s": 60.0,
           "area": {"width_m": 8000.0, "height_m": 8000.0, "cell_m": 200.0},
           "uavs": [{"type": "B", "x_m": 1000.0, "y_m": 1000.0}, {"type": "A", "x_m": 5000.0, "y_m": 5000.0},
                    {"type": "B", "x_m": 7000.0, "y_m": 1000.0, "join_s": 20.0}],
           "targets": {"count": 2}, "planner": {"name": planner}}
    frames = fuzz_frames(seed, n_frames)
    rx_rejected: list = []
    fed = expected_rejects = 0
    with Simulation(parse_scenario(doc)) as sim:
        sim.subscribe(lambda e: rx_rejected.append(e) if e.accepted is False else None, kinds={"rx"})
        before = {u: a.counters.rejected for u, a in sim.actors.items()}
        per_tick = max(1, n_frames // int(sim.duration_s))
        while not sim.done:
            for uid, body in sorted(sim._world.uavs.items()):
                if body.state != "alive":
                    continue
                for _ in range(per_tick):
                    data = next(frames, None)
                    if data is None:
                        break
                    try:
                        decode(data, sim.scenario.radio.frame_max_bytes)
                    except FrameError:
                        # Only frames the codec rejects: a well-formed one would be merged (a
                        # separate test covers what well-formed but absurd content does).
                        sim.actors[uid].mailbox.put(sim.now, (uid + 1) % 3, data)
                        fed += 1
                        expected_rejects += 1
            sim.step()  # must not raise
        poses_at_end = {e.name for e in sim.snapshot().uavs if e.state == "alive"}
        counted = sum(a.counters.rejected - before[u] for u, a in sim.actors.items())
        mailbox_drops = sum(a.mailbox.stats.dropped_full for a in sim.actors.values())
    assert poses_at_end == {"B1", "A1", "B2"}, "every receiver is still flying"
    assert mailbox_drops == 0
    assert counted == expected_rejects == len(rx_rejected) == fed
    return fed, counted


@pytest.mark.parametrize("planner", ["greedy", "dacmp"])
def test_live_receivers_count_fuzzed_frames_as_rejected_and_keep_running(planner):
    fed, rejected = _fuzz_live(3_000, seed=3, planner=planner)
    assert fed == rejected > 2_000


# Well-formed frames with absurd content: the schema accepts any finite number, so the receiver
# itself must cope. A scan record whose centre plus radius overflows to infinity used to crash the
# receiving actor (OverflowError in the map's disk bounds); receivers now ignore (and count)
# scans outside any sane time, place or radius.
ABSURD = {
    "hello_huge": [Hello(0, "B", 1e308, -1e308, 1e308, 1e308)],
    "intent_huge_target": [Intent(0, 1e308, -1e308, 1, 10**18)],
    "tracks_huge": [Tracks((TrackItem(9, 1e308, 1e308, 1e308, -1e308, 0.0, 1e308),))],
    "threat_huge": [Threats((ThreatItem(7, 1e308, 1e308, 1e308, 1e308),))],
    "scan_far_away": [ScanRecords(0, (0.0, 1e300, 1e300, 1.0))],
    "scan_overflowing_disk": [ScanRecords(0, (0.0, 1e308, 0.0, 1e308))],
    "digest_from_the_far_future": [ScanDigest(0, 1e300, 0, -5, 2**62, ((0, b"\xff" * 4000), (2**40, b"")))],
    "digest_with_a_huge_window": [ScanDigest(0, 5.0, -(2**60), 0, 9, ((0, b"\x01"),))],
    "digest_claiming_nothing": [ScanDigest(0, -1e300, 2**40, 0, 0, ())],
}


@pytest.mark.parametrize("messages", list(ABSURD.values()), ids=list(ABSURD))
def test_well_formed_absurd_frames_do_not_harm_the_receiver(messages):
    doc = {"name": "absurd", "duration_s": 30.0, "area": {"width_m": 5000.0, "height_m": 5000.0},
           "uavs": [{"type": "B", "x_m": 1000.0, "y_m": 1000.0}, {"type": "A", "x_m": 3000.0, "y_m": 3000.0}],
           "planner": {"name": "dacmp"}}
    with Simulation(parse_scenario(doc)) as sim:
        sim.step(2)
        sim.actors[1].mailbox.put(sim.now, 0, encode(0, 1, 0.0, messages))
        sim.step(10)
        assert sim.snapshot().uavs[1].state == "alive"
        if messages is ABSURD["scan_overflowing_disk"] or messages is ABSURD["scan_far_away"]:
            assert sim.actors[1].counters.scans_ignored == 1


# --- scenario document fuzzing -----------------------------------------------------------------------

WRONG_TYPES = {
    float: ["fast", True, [1.0], {"a": 1.0}, datetime.date(2024, 1, 1)],
    int: ["3", 3.5, True, [3]],
    str: [3, 2.5, False, ["x"], {"x": "y"}],
    bool: ["yes", 1, 1.0],
    list: ["a", 1, {"k": 1}],
    dict: ["a", 1.5, [1, 2], True],
}
OUT_OF_RANGE = [-1.0, -1e300, 1e300, math.nan, math.inf, -math.inf, 0.0, -1]


def _paths(node, path=()) -> Iterator[tuple[tuple, object]]:
    yield path, node
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, path + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, path + (i,))


def _at(doc, path):
    for p in path:
        doc = doc[p]
    return doc


@st.composite
def broken_documents(draw):
    """(document, what was done, key path) with exactly one thing made wrong."""
    doc = draw(scenario_documents(max_uavs=3, max_faults=3))
    nodes = [(p, v) for p, v in _paths(doc) if p]
    how = draw(st.sampled_from(["type", "range", "missing", "unknown"]))
    bad = copy.deepcopy(doc)
    if how == "type":
        path, value = draw(st.sampled_from(nodes))
        _at(bad, path[:-1])[path[-1]] = draw(st.sampled_from(WRONG_TYPES[type(value)]))
    elif how == "range":
        numeric = [(p, v) for p, v in nodes if type(v) in (int, float)]
        path, _ = draw(st.sampled_from(numeric))
        _at(bad, path[:-1])[path[-1]] = draw(st.sampled_from(OUT_OF_RANGE))
    elif how == "missing":
        keyed = [(p, v) for p, v in nodes if isinstance(p[-1], str)]
        path, _ = draw(st.sampled_from(keyed))
        del _at(bad, path[:-1])[path[-1]]
    else:
        tables = [p for p, v in _paths(doc) if isinstance(v, dict)]
        table = draw(st.sampled_from(tables))
        existing = list(_at(doc, table)) or ["key"]
        name = draw(st.sampled_from([existing[0] + "_", "spam", existing[-1].upper() + "X"]))
        if name in _at(bad, table):
            name += "_unknown"
        path = table + (name,)
        _at(bad, table)[name] = draw(st.sampled_from([1, "x", [], {}]))
    return bad, how, path


@settings(max_examples=examples(400), suppress_health_check=[HealthCheck.too_slow])
@given(broken_documents())
def test_wrong_documents_only_raise_scenario_error_with_a_key_path(case):
    doc, how, path = case
    try:
        parse_scenario(doc, "<fuzz>")
    except ScenarioError as err:
        assert err.key, f"no key path in: {err}"
        assert str(err).startswith("<fuzz>: ") and err.found and err.expected
        if how == "unknown" and path[0] == "uav_types" and len(path) == 2:
            # uav_types is open: a new name there is a new type, and what is wrong may be a
            # setting inside it (a table {} lacks every required one).
            assert err.key == _key(path) or err.key.startswith(_key(path) + "."), (how, _key(path), str(err))
        elif how in ("type", "unknown") or (how == "missing" and err.key == _key(path)):
            assert err.key == _key(path), (how, _key(path), str(err))
    else:
        # Only some mutations can leave a valid document: an optional key removed, a number
        # still in range, a uav_types entry that now is simply another type.
        assert how in ("missing", "range") or path[0] == "uav_types", (how, path)


@settings(max_examples=examples(150), suppress_health_check=[HealthCheck.too_slow])
@given(scenario_documents(max_uavs=3, max_faults=3), st.data())
def test_damaged_toml_text_only_raises_scenario_error(doc, data):
    text = bytearray(scenario_toml(doc).encode())
    for _ in range(data.draw(st.integers(1, 4))):
        pos = data.draw(st.integers(0, len(text) - 1))
        text[pos] = data.draw(st.sampled_from(b"=[]{}\"'#.,\n 0x9-+eE"))
    try:
        scenario_from_toml(text.decode("utf-8", errors="replace"), "damaged.toml")
    except ScenarioError as err:
        assert str(err).startswith("damaged.toml: ")
