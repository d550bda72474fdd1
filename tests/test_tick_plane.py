"""The tick plane (issue 36) against its oracle: ``Simulation(tick_plane=True)`` runs the tick's
array work in per-tick services, ``tick_plane=False`` the per-actor code they replace. Over
generated scenarios with faults of every registered kind (``FaultKind.generate``, drawn by
:func:`swarm.testing.strategies.scenario_documents`), with and without ``[radio] auth``, with
small mailboxes (overflow), knowledge horizons and anti-entropy periods, both are stepped in
lockstep and every actor's state is compared after every tick: maps bit for bit, scan logs, peers, tracks, threats, counters,
mailboxes, pending digests, plans (:mod:`swarm.testing.oracle`); then the event logs' bytes.

The comparison is itself tested: a state changed on one side only (a map cell, a peer's pose,
a frame left in a mailbox) is found at the tick, UAV and field where it was planted.
"""

from __future__ import annotations

import pytest
from budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from swarm import Simulation
from swarm.scenario import load_scenario, parse_scenario
from swarm.testing.oracle import Difference, assert_lockstep, lockstep
from swarm.testing.strategies import scenario_documents

_HEALTH = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much]


@st.composite
def lockstep_documents(draw: st.DrawFn, max_uavs: int = 6, max_duration_s: int = 60) -> dict:
    """A generated scenario (faults of every kind, lossy radios, small mailboxes among them),
    ``[radio] auth`` on or off (a spoofer's frames rejected, or merged), a knowledge horizon or
    none, anti-entropy at its default period, more often, or off."""
    doc = draw(scenario_documents(min_uavs=2, max_uavs=max_uavs, min_duration_s=20, max_duration_s=max_duration_s,
                                  max_faults=5))
    if draw(st.booleans(), label="auth"):
        doc["radio"]["auth"] = True
    # A knowledge horizon (scans beyond it neither applied nor logged; maps then not in a
    # MapGroup), anti-entropy more often, or none (no scan log kept at all).
    horizon = draw(st.sampled_from([None, 1500.0, 4000.0, 10000.0]), label="sync_horizon_m")
    if horizon is not None:
        doc["radio"]["sync_horizon_m"] = horizon
    every = draw(st.sampled_from([None, 2.0, 0.0]), label="sync_every_s")
    if every is not None:
        doc["radio"]["sync_every_s"] = every
    # Anti-entropy flow control (issue 36, M2): a cap on the scans of an answer, a split between
    # the answerers, both, or neither (the default).
    flow = draw(st.sampled_from([None, (0, True), (3, False), (20, True)]), label="flow control")
    if flow is not None:
        doc["radio"]["sync_resend_cap"], doc["radio"]["sync_split"] = flow
    # Tracks every tracks_every_s (the default), or on change with a digest for repair (M1).
    doc["radio"]["tracks"] = draw(st.sampled_from(["periodic", "on_change"]), label="tracks")
    return doc


@pytest.mark.slow  # 150 examples: about 25 s of CPU in all
@settings(max_examples=examples(150), deadline=None, suppress_health_check=_HEALTH)
@given(lockstep_documents())
def test_tick_plane_is_the_oracle_tick_by_tick(doc):
    assert_lockstep(parse_scenario(doc))


@settings(max_examples=examples(10), deadline=None, suppress_health_check=_HEALTH)
@given(lockstep_documents(max_uavs=4, max_duration_s=30))
def test_tick_plane_is_the_oracle_tick_by_tick_short(doc):
    """The property above on fewer, shorter runs: in the quick loop too (1 example there)."""
    assert_lockstep(parse_scenario(doc))


@pytest.mark.slow  # two runs of 400 s, 8 UAVs, states compared every tick: about 13 s of CPU each
@pytest.mark.parametrize("auth", [True, False])
def test_demo_all_faults_in_lockstep(auth):
    """Every fault kind in one scenario, with ``[radio] auth`` (the spoofer's frames rejected)
    and without (merged into the maps and logs of those that hear them): the whole run agrees."""
    assert_lockstep(load_scenario("demo-all-faults", overrides={"radio.auth": auth}))


def test_demo_all_faults_in_lockstep_short():
    """Its first 100 s (the quick loop's)."""
    assert_lockstep("demo-all-faults", duration_s=100)


@pytest.mark.slow  # two runs of 100 UAVs for 40 s, states compared every tick: about 15 s of CPU each
@pytest.mark.parametrize("flow", [{}, {"radio.sync_resend_cap": 20, "radio.sync_split": True}])
def test_bench_100_in_lockstep(flow):
    """Tiled maps, a knowledge horizon (scans beyond it neither applied nor logged) and
    anti-entropy resends (stamped into one map each): paths the generated scenarios, on small
    dense areas without a horizon, do not take; with and without flow control (issue 36, M2).
    The run must take them for the test to count."""
    seen: dict[str, int] = {}

    def count(sim: Simulation, tick: int) -> None:
        cs = [a.counters for a in sim.actors.values()]
        seen.update(resent=sum(c.scans_resent for c in cs), beyond=sum(c.scans_beyond for c in cs))

    assert_lockstep(load_scenario("bench-100", overrides=flow), planner="greedy", duration_s=40, seed=0, tamper=count)
    assert seen["resent"] > 0 and seen["beyond"] > 0, seen


# --- the comparison finds what differs ---------------------------------------------------------------


def _stamp_a_cell(sim: Simulation, tick: int) -> None:
    if tick == 5:
        sim.actors[1].umap.scan(2000.0, 2000.0, 300.0, 1.0e6)


def _move_a_peer(sim: Simulation, tick: int) -> None:
    if tick == 7:
        peer = next(iter(sim.actors[0].knowledge.peers.values()))
        peer.x += 1e-9


def _leave_a_frame(sim: Simulation, tick: int) -> None:
    if tick == 3:
        sim.actors[2].mailbox.put(3.0, 0, b"not a frame")


@pytest.mark.parametrize(("tamper", "tick", "uav", "field"), [
    (_stamp_a_cell, 5, 1, "map"),
    (_move_a_peer, 7, 0, "peers"),
    (_leave_a_frame, 3, 2, "mailbox"),
])
def test_lockstep_finds_a_planted_difference(tamper, tick, uav, field):
    diff = lockstep("paper-case1", duration_s=12, seed=3, tamper=tamper)
    assert isinstance(diff, Difference)
    assert (diff.tick, diff.uav, diff.field) == (tick, uav, field), str(diff)

