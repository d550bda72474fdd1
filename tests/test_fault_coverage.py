"""Every registered fault kind bites: in a fixed, seeded set of generated scenarios that schedule
it, the injector reports that it changed something.

This is the fault-kind coverage gate. It used to be judged over whatever the session's
property tests happened to generate, which depended on which tests ran before them in each
xdist worker: a pure refactor failed CI twice because ``bridge`` (firing in about 1 run in 100)
happened not to fire. Here each kind gets its own test, with examples drawn by Hypothesis
derandomized (seeded from this test's source, no example database), so it passes or fails the
same way in any order, on any number of workers. A kind registered later joins by being in
:data:`faults.registry.FAULT_KINDS` when the tests are collected; a kind with no strategy in
:mod:`swarm.testing.fault_strategies` fails here, saying so.
"""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, Phase, given, settings

from faults.registry import FAULT_KINDS
from swarm import Simulation
from swarm.testing import scenarios
from swarm.testing.fault_strategies import ALL_KINDS

# Examples drawn per kind (at most; a kind's test stops running simulations once it fired).
EXAMPLES_PER_KIND = 40


def _fires(kind: str) -> tuple[int, int]:
    """(examples run until ``kind`` fired or the draws ran out, times it fired in that run)."""
    tried: list[int] = []
    fired: list[int] = []

    @settings(max_examples=EXAMPLES_PER_KIND, derandomize=True, database=None, deadline=None,
              phases=[Phase.generate], suppress_health_check=list(HealthCheck))
    @given(sc=scenarios(min_uavs=3, max_uavs=4, min_duration_s=40, max_duration_s=60, fault_kinds=(kind,),
                        max_faults=3, late_joiners=False, swarm=False))
    def run(sc):
        if fired or not any(f.kind == kind for f in sc.faults):
            return
        tried.append(1)
        with Simulation(sc) as sim:
            sim.run()
            n = sim.injector.fired.get(kind, 0)
        if n:
            fired.append(n)

    run()
    return len(tried), (fired[0] if fired else 0)


@pytest.mark.slow
@pytest.mark.parametrize("kind", list(FAULT_KINDS))
def test_every_registered_fault_kind_fires_in_its_seeded_examples(kind):
    assert kind in ALL_KINDS, f"fault kind {kind!r} is registered but swarm.testing.fault_strategies draws none"
    runs, fired = _fires(kind)
    assert fired > 0, f"fault kind {kind!r} never changed anything in {runs} generated runs that scheduled it"
