"""The paper's Case 1 (section 4.3, Fig. 12): the fast-to-slow handover, from the event log."""

from __future__ import annotations

import pytest

from comms.messages import MODE_SURVEIL
from swarm import Simulation
from swarm.recorder import read_events


@pytest.fixture(scope="module")
def case1():
    with Simulation("paper-case1") as sim:
        result = sim.run()
        names = {uid: b.name for uid, b in sim.world.uavs.items()}
    return result, names, list(read_events(result.events))


def _watch_intervals(events, names):
    """(uav name, target) -> seconds spent in surveillance mode of that target (pose events:
    ``pose, t, uav, x, y, v, theta, mode, target``, one per UAV per 1 s tick)."""
    seconds: dict[tuple[str, int], float] = {}
    for e in events:
        if e[0] == "pose" and e[7] == MODE_SURVEIL:
            key = (names[e[2]], e[8])
            seconds[key] = seconds.get(key, 0.0) + 1.0
    return seconds


def test_case1_slow_uav_takes_target_1_over_and_the_fast_finder_returns_to_search(case1):
    result, names, events = case1
    m = result.metrics
    found = {e[2]: names[e[3]] for e in events if e[0] == "found"}
    assert found[0] == "B1"  # target 1 (id 0) is found by fast UAV 1, as in Fig. 12a
    handovers = [h for h in m["handover_list"] if h["target"] == 0]
    assert handovers and handovers[0]["from"] == "B1" and handovers[0]["to"] == "A1"
    t_hand = handovers[0]["t"]
    last = {}
    for e in events:
        if e[0] == "pose":
            last[names[e[2]]] = (e[7], e[8])
    assert last["A1"] == (MODE_SURVEIL, 0)  # the slow UAV ends up watching target 1
    assert last["B1"][0] != MODE_SURVEIL  # ... and the fast one is searching again
    b1_after = [e for e in events if e[0] == "pose" and names[e[2]] == "B1" and e[1] > t_hand + 30]
    assert b1_after and all(e[7] != MODE_SURVEIL for e in b1_after)
    assert m["surveillance_ratio"]["0"] > 0.5
    assert m["violations"] == {"separation": 0, "threat": 0, "dynamics": 0}


def test_case1_a_fast_uav_does_not_capture_a_target_already_watched(case1):
    _, names, events = case1
    watched = _watch_intervals(events, names)
    # Target 2 (id 1) is watched by B2; B1 never joins it, and no two fast UAVs share a target.
    assert watched.get(("B2", 1), 0.0) > 300
    assert watched.get(("B1", 1), 0.0) == 0.0
    for target in (0, 1):
        fast = [u for (u, t), s in watched.items() if t == target and u.startswith("B") and s > 0]
        assert len(fast) == 1, (target, fast)
