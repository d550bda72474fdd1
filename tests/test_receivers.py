"""No well-formed frame crashes a live receiver, whatever the numbers in it.

A frame that decodes (right shape, finite numbers, valid CRC) can still carry values no honest
UAV sends: times of 1e308 s, ids of 2**63, coordinates beyond any area. Every numeric field of
every message kind is drawn from such extremes and sent to a live UAV, which must keep flying.
(Malformed frames are rejected by the codec: tests/test_codec.py and tests/test_fuzz.py.)
"""

from __future__ import annotations

import sys

from budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from comms.codec import encode
from comms.messages import Hello, Intent, ScanDigest, ScanRecords, ThreatItem, Threats, TrackItem, Tracks
from swarm import Simulation
from swarm.scenario import parse_scenario

EXTREME_FLOATS = [0.0, -0.0, 1.0, -1.0, 5e-324, -5e-324, 1e-300, 1e15, -1e15, 1e300, -1e300,
                  sys.float_info.max, -sys.float_info.max, 2.0**63, 2.0**64, 1e19]
EXTREME_INTS = [0, 1, -1, 2, 7, 2**31 - 1, 2**31, -(2**31), 2**53 + 1, 2**62, 2**63 - 1, -(2**63), 2**64 - 1]

floats = st.sampled_from(EXTREME_FLOATS) | st.floats(allow_nan=False, allow_infinity=False)
ints = st.sampled_from(EXTREME_INTS) | st.integers(min_value=-(2**63), max_value=2**64 - 1)
positive = st.sampled_from([5e-324, 1e-300, 1.0, 1e15, 1e300, sys.float_info.max])


@st.composite
def threats(draw) -> Threats:
    items = []
    for _ in range(draw(st.integers(1, 2))):
        radius = draw(positive)
        d_max = draw(st.sampled_from([radius, radius * 2 if radius < 1e300 else radius, sys.float_info.max]))
        items.append(ThreatItem(draw(ints), draw(floats), draw(floats), radius, d_max))
    return Threats(tuple(items))


messages = st.one_of(
    st.builds(Hello, ints, st.sampled_from(["B", "A", "Z", ""]), floats, floats, floats, floats),
    st.builds(Intent, ints, floats, floats, st.sampled_from([0, 1]), ints),
    st.builds(ScanRecords, ints, st.lists(floats, min_size=4, max_size=8).map(lambda v: tuple(v[: len(v) // 4 * 4]))),
    st.builds(Tracks, st.lists(st.builds(TrackItem, ints, floats, floats, floats, floats, floats, floats),
                               min_size=1, max_size=2).map(tuple)),
    threats(),
    st.builds(ScanDigest, ints, floats, ints, ints, ints,
              st.lists(st.tuples(ints, st.binary(max_size=16)), max_size=2).map(tuple)),
)

_DOC = {"name": "receivers", "duration_s": 60.0, "area": {"width_m": 5000.0, "height_m": 5000.0},
        "uavs": [{"type": "B", "x_m": 1000.0, "y_m": 1000.0}, {"type": "A", "x_m": 1500.0, "y_m": 1200.0},
                 {"type": "B", "x_m": 1200.0, "y_m": 1500.0}],
        "radio": {"sync_every_s": 1.0, "sync_settle_s": 0.0}}


@settings(max_examples=examples(150), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(messages, min_size=1, max_size=3), ints, floats, st.sampled_from(["dacmp", "greedy"]))
def test_extreme_values_in_any_message_kind_do_not_crash_a_live_receiver(msgs, sender, t, planner):
    sc = parse_scenario({**_DOC, "planner": {"name": planner}})
    with Simulation(sc) as sim:
        sim.step(2)
        frame = encode(sender if -(2**63) <= sender < 2**64 else 0, 1, t, msgs)
        for uid in (1, 2):
            sim.actors[uid].mailbox.put(sim.now, 0, frame)
        sim.step(4)  # merge, plan, answer digests, send
        assert all(u.state == "alive" for u in sim.snapshot().uavs)
