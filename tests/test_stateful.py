"""The reusable state machine (swarm.testing.stateful.SwarmMachine): as shipped, subclassed with a rule and
an invariant of our own, and with a planted bug it must catch."""

from __future__ import annotations

import dataclasses
from collections import Counter

import pytest
from budget import examples
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st
from hypothesis.stateful import invariant, rule, run_state_machine_as_test

from faults.schedule import Burst
from swarm.scenario import scenario_from_toml
from swarm.testing.invariants import InvariantViolation
from swarm.testing.stateful import CHECKERS, SwarmMachine
from swarm.testing.strategies import scenario_toml, scenarios


class RecordingMachine(SwarmMachine):
    """SwarmMachine that adds what each example did to the session's fault statistics (after
    the liveness phase) and tallies what the liveness phase judged."""

    stats = None  # set by the fixture below
    liveness_tally: Counter = Counter()

    def teardown(self):
        sim = self.sim
        try:
            super().teardown()
        finally:
            if sim is not None and self.stats is not None:
                self.stats.schedule(sim.injector.schedule.faults)
                self.stats.run(dict(sim.injector.fired))
            r = self.liveness_report
            if r is not None:
                RecordingMachine.liveness_tally["examples"] += 1
                RecordingMachine.liveness_tally["maps judged"] += any(
                    j.startswith("maps") and not j.startswith("maps: 0 ") for j in r.judged)
                RecordingMachine.liveness_tally["targets judged"] += sum(j.startswith("target") for j in r.judged)
                RecordingMachine.liveness_tally["tracks judged"] += any(
                    j.startswith("tracks") and not j.startswith("tracks: 0 ") for j in r.judged)


@pytest.fixture(autouse=True)
def _record_faults(fault_stats):
    RecordingMachine.stats = fault_stats
    yield
    RecordingMachine.stats = None


TestSwarmMachine = RecordingMachine.TestCase
TestSwarmMachine.settings = settings(max_examples=examples(50), stateful_step_count=50,
                                     suppress_health_check=[HealthCheck.too_slow])


def test_the_liveness_phase_judged_something():
    """Runs after TestSwarmMachine (file order): the liveness phase ran at the end of the
    examples and judged map agreement and tracks spread on connected pairs in some of them (it
    cannot pass by never judging)."""
    tally = RecordingMachine.liveness_tally
    if not tally["examples"]:
        pytest.skip("TestSwarmMachine did not run in this session (a -k selection)")
    assert tally["maps judged"] >= 1 and tally["tracks judged"] >= 1, dict(tally)


class CoverageMachine(RecordingMachine):
    """A user's subclass: one more rule (Gilbert-Elliott bursts on every link) and one more
    invariant (ground-truth coverage and targets found never go down)."""

    def __init__(self):
        super().__init__()
        self.last = (0.0, 0)

    @rule(p_enter=st.sampled_from([0.5, 0.1, 1.0]), ticks=st.integers(5, 20))
    def burst(self, p_enter, ticks):
        now = self.now
        self.sim.add_fault(Burst(start_s=now, end_s=now + ticks, p_enter_bad=p_enter, p_exit_bad=0.3))
        self.history.append(f"t={now:g}: burst p_enter_bad={p_enter} for {ticks} s")

    @invariant()
    def coverage_and_finds_never_drop(self):
        if self.sim is None:
            return
        snap = self.sim.snapshot()
        assert snap.coverage >= self.last[0] and snap.targets_found >= self.last[1]
        self.last = (snap.coverage, snap.targets_found)


TestCoverageMachine = CoverageMachine.TestCase
TestCoverageMachine.settings = settings(max_examples=examples(20), stateful_step_count=40,
                                        suppress_health_check=[HealthCheck.too_slow])


class RangeBlindMachine(SwarmMachine):
    """A planted bug the machine must find: a radio that forgets its range limit."""

    def scenario_strategy(self):
        return scenarios(min_uavs=2, max_uavs=3, faults=False, late_joiners=False, lossy_radio=False,
                         min_duration_s=60, max_duration_s=60, area_km=(12, 15)).map(
            lambda sc: sc.model_copy(update={"radio": sc.radio.model_copy(update={"range_m": 1500.0})}))

    def on_start(self):
        self.sim._radio.model = dataclasses.replace(self.sim._radio.model, range_m=None)


def test_machine_catches_a_planted_radio_bug_and_says_how_to_replay_it():
    with pytest.raises(InvariantViolation) as info:
        run_state_machine_as_test(RangeBlindMachine, settings=settings(
            max_examples=20, stateful_step_count=10, phases=[Phase.generate], database=None,
            suppress_health_check=list(HealthCheck)))
    err = info.value
    assert {v.invariant for v in err.violations} == {"radio"}
    assert any("range 1500 m" in v.message for v in err.violations)
    assert any(n.startswith("replay: swarm run ") and "--seed" in n for n in err.__notes__)


@pytest.mark.slow  # every draw below is a find(), shrunk to its simplest: seconds
def test_machine_run_can_be_written_as_a_scenario():
    machine = SwarmMachine()
    # Drive it by hand, as Hypothesis would: a start, some time, each kind of change.
    from hypothesis import find

    scenario = find(machine.scenario_strategy(), lambda s: len(s.uavs) >= 2)

    class _Data:
        def draw(self, strategy, label=None):
            return scenario if label == "scenario" else find(strategy, lambda x: True)

    machine.start(_Data())
    machine.advance(5)
    machine.cut(_Data(), one_way=False)
    machine.change_loss(0.5)
    machine.advance(5)
    machine.heal()
    machine.join(_Data())
    machine.crash(_Data())
    machine.advance_long(10)
    machine.invariants_hold()
    sc = machine.reproduction_scenario()
    kinds = sorted({f.kind for f in sc.faults})
    assert kinds == ["crash", "drop", "partition"]
    assert scenario_from_toml(scenario_toml(sc), "again.toml") == sc
    assert sc.duration_s == machine.now == 20.0
    machine.teardown()


@pytest.mark.slow  # find() and two whole liveness phases: seconds
def test_new_fault_rules_are_in_the_schedule_and_liveness_waits_for_them():
    """The pause, restart, clock_skew and liar rules add their faults at run time with finite
    windows; the liveness phase starts after the last one has ended (a restart: rejoined)."""
    from hypothesis import find

    machine = SwarmMachine()
    scenario = find(machine.scenario_strategy(), lambda s: len(s.uavs) >= 3)

    class _Data:
        def draw(self, strategy, label=None):
            return scenario if label == "scenario" else find(strategy, lambda x: True)

    machine.start(_Data())
    machine.advance(3)
    machine.pause(_Data())
    machine.restart(_Data())
    machine.clock_skew(_Data(), offset=5.0, drift=0.1)
    machine.liar(_Data(), scans=1.0, tracks=1.0)
    kinds = [f.kind for f in machine.sim.injector.schedule.faults]
    assert kinds == ["pause", "restart", "clock_skew", "liar"]
    assert machine.faults_end_s == 5.0  # from 3 s, one tick each (find's simplest); a restart waits a tick to rejoin
    report = machine.check_liveness()
    assert report.t0 >= machine.faults_end_s and report.quiet_s > 0
    assert machine.now >= report.t0 + report.quiet_s - 1e-9 or machine.sim.done
    sc = machine.reproduction_scenario()
    assert sorted({f.kind for f in sc.faults}) == ["clock_skew", "liar", "pause", "restart"]
    assert scenario_from_toml(scenario_toml(sc), "again.toml") == sc
    machine.teardown()


class SilentMapsMachine(SwarmMachine):
    """A planted liveness bug: every UAV throws its inbox away unread, so a map learns only by
    flying; on a lossless radio the liveness phase must see maps disagree."""

    checkers = ("threat", "dynamics", "radio", "map_monotonic")

    def scenario_strategy(self):
        return super().scenario_strategy().map(lambda sc: sc.model_copy(update={"radio": sc.radio.model_copy(
            update={"loss_base": 0.0, "loss_at_range": None, "range_m": None, "bandwidth_bytes_per_s": None,
                    "latency_s": 0.0, "jitter_s": 0.0})}))

    def on_start(self):
        for actor in self.sim.actors.values():
            actor.inbox = _DeafInbox()  # hear nothing


class _DeafInbox:
    """In place of an actor's agents.inbox.Inbox: the frames it drained are thrown away unread."""

    digests = ()

    def merge(self, frames, *state):
        return []

    def take(self, frames, *state):  # (the receive service's merge: issue 36's tick plane)
        return []


def test_liveness_phase_catches_maps_that_never_merge():
    with pytest.raises(InvariantViolation) as info:
        run_state_machine_as_test(SilentMapsMachine, settings=settings(
            max_examples=10, stateful_step_count=5, phases=[Phase.generate], database=None,
            suppress_health_check=list(HealthCheck)))
    assert {v.invariant for v in info.value.violations} == {"liveness"}
    assert any("still misses" in v.message for v in info.value.violations)
    assert any(n.startswith("replay: swarm run ") for n in info.value.__notes__)


def test_checker_names_are_all_known():
    assert set(SwarmMachine.checkers) <= set(CHECKERS)
    with pytest.raises(ValueError, match="unknown checker"):
        type("Bad", (SwarmMachine,), {"checkers": ("nope",)})().make_checkers()
