"""Every registered fault kind bites: in a fixed, seeded set of generated scenarios that schedule
it, the injector reports that it changed something.

This is the fault-kind coverage gate. It used to be judged over whatever the session's
property tests happened to generate, which depended on which tests ran before them in each
xdist worker: a pure refactor failed CI twice because ``bridge`` (firing in about 1 run in 100)
happened not to fire. Here each kind gets its own test, with examples drawn by Hypothesis
derandomized (seeded from this test's source, no example database), so it passes or fails the
same way in any order, on any number of workers. A kind registered later joins by being in
:data:`faults.registry.FAULT_KINDS` when the tests are collected; a kind whose class does not say
how tests draw it (:meth:`faults.base.FaultKind.generate`) fails here, saying so. A kind
registered by a test is judged by the same function (tests/test_kernel.py).
"""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, Phase, given, settings

from faults.registry import FAULT_KINDS
from swarm import Simulation
from swarm.testing import scenarios

# Examples drawn per kind (at most; a kind's test stops running simulations once it fired).
EXAMPLES_PER_KIND = 40


def fires_in_seeded_examples(kind: str) -> tuple[int, int]:
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
    assert FAULT_KINDS[kind].has_strategy(), f"fault kind {kind!r} is registered but its class has no generate()"
    runs, fired = fires_in_seeded_examples(kind)
    assert fired > 0, f"fault kind {kind!r} never changed anything in {runs} generated runs that scheduled it"
