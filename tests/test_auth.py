"""Authenticated frames (``[radio] auth``): the codec's MAC, receivers that reject and count
frames without the right one, and whole runs with auth on.

Checked against: frames built here with and without the key (a spoofer is a sender without it),
byte-for-byte comparisons of runs with auth off and on, and the run's own counters.
"""

from __future__ import annotations

import hashlib
import hmac
import zlib

import pytest

from comms.codec import MAC_BYTES, AuthError, Frame, FrameError, decode, encode, mac
from comms.framecache import DecodeCache
from comms.messages import Hello, Intent, ThreatItem, Threats
from swarm import Simulation
from swarm.errors import ScenarioError
from swarm.kernel import build
from swarm.scenario import apply_overrides, parse_scenario

KEY = b"swarm key"
MSGS = [Hello(3, "B", 100.0, 200.0, 60.0, 0.5), Intent(3, 500.0, 600.0, 0, -1)]


def reseal(payload: bytes) -> bytes:
    """``payload`` with a right CRC (what an attacker who edits a frame can always redo)."""
    return payload + zlib.crc32(payload).to_bytes(4, "little")


# --- the codec ------------------------------------------------------------------------------------


def test_a_frame_with_the_right_mac_is_accepted():
    data = encode(3, 7, 12.5, MSGS, KEY)
    assert decode(data, key=KEY) == Frame(3, 7, 12.5, tuple(MSGS))


def test_the_mac_is_hmac_sha256_truncated_and_counted_in_the_bytes():
    plain = encode(3, 7, 12.5, MSGS)
    signed = encode(3, 7, 12.5, MSGS, KEY)
    assert MAC_BYTES == 16 and len(signed) == len(plain) + MAC_BYTES
    payload = plain[:-4]
    assert signed[:-4] == payload + mac(KEY, payload)
    assert mac(KEY, payload) == hmac.new(KEY, payload, hashlib.sha256).digest()[:16]
    assert signed[-4:] == zlib.crc32(signed[:-4]).to_bytes(4, "little")  # the CRC covers the MAC


@pytest.mark.parametrize("sender_key", [None, b"wrong key", KEY + b"x", b""], ids=["no-mac", "wrong", "longer", "empty"])
def test_a_frame_without_the_right_mac_is_an_auth_error(sender_key):
    data = encode(3, 7, 12.5, MSGS, sender_key)
    with pytest.raises(AuthError):
        decode(data, key=KEY)
    assert issubclass(AuthError, FrameError)  # every receiver already rejects FrameError


def test_a_frame_too_short_to_hold_a_mac_is_an_auth_error():
    for n in range(1, MAC_BYTES + 1):
        with pytest.raises(AuthError, match="no MAC"):
            decode(reseal(b"\x01" * n), key=KEY)


def test_a_corrupted_authenticated_frame_is_rejected():
    data = encode(3, 7, 12.5, MSGS, KEY)
    for i in range(len(data)):
        damaged = bytearray(data)
        damaged[i] ^= 0x40
        with pytest.raises(FrameError):  # the CRC catches damage in flight
            decode(bytes(damaged), key=KEY)
        if i < len(data) - 4:  # a forger who fixes the CRC still fails the MAC
            with pytest.raises(AuthError):
                decode(reseal(bytes(damaged[:-4])), key=KEY)


def test_a_forged_frame_with_a_fixed_crc_is_an_auth_error():
    # A spoofer who knows the format but not the key: the payload of a member's frame, edited.
    data = encode(3, 7, 12.5, MSGS, KEY)
    payload, tag = data[:-4 - MAC_BYTES], data[-4 - MAC_BYTES:-4]
    forged = encode(3, 7, 12.5, [Hello(3, "B", 9999.0, 200.0, 60.0, 0.5)])[:-4]
    with pytest.raises(AuthError):
        decode(reseal(forged + tag), key=KEY)
    assert decode(reseal(payload + tag), key=KEY).messages == tuple(MSGS)


def test_without_a_key_an_authenticated_frame_is_not_understood():
    # A receiver with auth off reads the MAC as trailing garbage: rejected, never misread.
    with pytest.raises(FrameError):
        decode(encode(3, 7, 12.5, MSGS, KEY))


def test_the_decode_cache_checks_the_mac_and_caches_only_good_frames():
    cache = DecodeCache(key=KEY)
    good = encode(1, 1, 0.0, MSGS, KEY)
    bad = encode(1, 1, 0.0, MSGS, b"other")
    assert cache.decode(good) == decode(good, key=KEY) and cache.lookup(good) is not None
    for _ in range(2):
        with pytest.raises(AuthError):
            cache.decode(bad)
    assert cache.lookup(bad) is None and len(cache) == 1 and cache.decoded == 3


# --- the scenario and the key ----------------------------------------------------------------------

DOC = {"name": "auth", "seed": 4, "duration_s": 40.0, "area": {"width_m": 6000.0, "height_m": 6000.0},
       "uavs": [{"type": "B", "x_m": 1000.0, "y_m": 1000.0}, {"type": "A", "x_m": 3000.0, "y_m": 3000.0},
                {"type": "B", "x_m": 5000.0, "y_m": 1000.0}],
       "targets": {"count": 2}, "planner": {"name": "greedy"}}


def scenario(**radio):
    return parse_scenario({**DOC, "radio": radio})


def test_auth_is_off_by_default_and_the_key_is_documented():
    assert scenario().radio.auth is False and build.auth_key(scenario()) is None
    assert build.actor_settings(scenario()).auth_key is None
    # Given: the string as UTF-8. Absent: SHA-256 of a fixed text and the seed (deterministic).
    assert build.auth_key(scenario(auth=True, auth_key="pässwörd")) == "pässwörd".encode()
    derived = build.auth_key(scenario(auth=True))
    assert derived == hashlib.sha256(b"uav-swarm-sim swarm key 4").digest()
    assert build.auth_key(apply_overrides(scenario(auth=True), {"seed": 5})) != derived
    assert build.auth_key(scenario(auth_key="ignored")) is None  # the key is read only with auth on


@pytest.mark.parametrize("radio, key, expected", [
    ({"auth": "yes"}, "radio.auth", "true or false"),
    ({"auth": True, "auth_key": ""}, "radio.auth_key", "a non-empty string"),
    ({"auth": True, "auth_key": 7}, "radio.auth_key", "a non-empty string"),
])
def test_auth_settings_are_validated_with_their_key_path(radio, key, expected):
    with pytest.raises(ScenarioError) as info:
        scenario(**radio)
    assert info.value.key == key and info.value.expected.startswith(expected)


# --- receivers and runs ------------------------------------------------------------------------------


def _inject(sim: Simulation, receiver: int, data: bytes) -> None:
    sim.actors[receiver].mailbox.put(sim.now, 0, data)


def test_a_spoofers_frames_do_nothing_and_are_counted_a_members_get_through():
    sc = scenario(auth=True)
    key = build.auth_key(sc)
    spoof = [Hello(77, "B", 2000.0, 2000.0, 60.0, 0.0), Threats((ThreatItem(5, 2500.0, 2500.0, 300.0, 900.0),))]
    with Simulation(sc) as sim:
        sim.step(2)
        me = sim.actors[1]
        before = me.counters.rejected
        _inject(sim, 1, encode(0, 99, sim.now, spoof))  # no MAC
        _inject(sim, 1, encode(0, 99, sim.now, spoof, b"a guess"))  # a wrong key
        sim.step(1)
        assert 77 not in me.knowledge.peers and 5 not in me.knowledge.threats
        assert me.counters.rejected_auth == 2 and me.counters.rejected - before == 2
        _inject(sim, 1, encode(0, 99, sim.now, spoof, key))  # a member
        sim.step(1)
        assert 77 in me.knowledge.peers and 5 in me.knowledge.threats
        assert me.counters.rejected_auth == 2
        m = sim.run().metrics
    assert m["radio"]["rejected_auth"] == 2 and m["radio"]["rejected"] >= 2
    assert m["per_uav"][sim._world.uavs[1].name]["frames_rejected_auth"] == 2
    assert sum(u["frames_rejected_auth"] for u in m["per_uav"].values()) == 2


def test_auth_on_the_same_run_with_a_mac_on_every_frame():
    # A lossless radio: the MAC changes no decision, only each copy's size (by MAC_BYTES).
    with Simulation(scenario()) as sim:
        off = sim.run().metrics
    with Simulation(scenario(auth=True)) as sim:
        on = sim.run().metrics
    assert on["radio"]["sent"] == off["radio"]["sent"] > 0
    assert on["radio"]["bytes_sent"] - off["radio"]["bytes_sent"] == MAC_BYTES * on["radio"]["sent"]
    assert on["radio"]["delivered"] == off["radio"]["delivered"]
    assert on["radio"]["rejected"] == on["radio"]["rejected_auth"] == off["radio"]["rejected_auth"] == 0
    for k in ("coverage", "certainty", "targets_found"):
        assert on[k] == off[k], k


def test_a_run_with_auth_on_is_deterministic():
    faults = [{"kind": "corrupt", "rate": 0.3, "start_s": 0.0}, {"kind": "drop", "rate": 0.2, "start_s": 0.0}]
    sc = parse_scenario({**DOC, "radio": {"auth": True, "range_m": 4000.0}, "faults": faults})
    hashes = []
    for _ in range(2):
        with Simulation(sc) as sim:
            m = sim.run().metrics
        hashes.append(m["event_log_sha256"])
    assert hashes[0] == hashes[1]
    # corrupted copies fail the CRC (counted as rejected, not as auth failures)
    assert m["radio"]["rejected"] > 0 and m["radio"]["rejected_auth"] == 0
    with Simulation(apply_overrides(sc, {"radio.auth_key": "another key"})) as sim:
        assert sim.run().metrics["event_log_sha256"] == hashes[0]  # the key changes no decision
