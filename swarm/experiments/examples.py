"""How many property-test-sized runs a CPU-minute holds (``swarm bench --examples N``).

A Hypothesis test of a task-assignment invariant builds and runs one short simulation per
example, in the test's own process. Issue 36 measures that as paper-case1 (3 UAVs, DACMP,
surveillance and handover) for 300 simulated seconds, in process: build, run, result. One
warm-up example first (imports, the first call's caches), then ``n`` examples on seeds 1..n,
each timed on the process's CPU clock; the figure is ``60 * n / (their CPU seconds)``.
"""

from __future__ import annotations

import json
import sys
import time
from typing import Any, TextIO

SCENARIO = "paper-case1"
DURATION_S = 300.0
TARGET_PER_MINUTE = 400  # issue 36, item 4


def measure(n: int = 20, scenario: str = SCENARIO, duration_s: float = DURATION_S) -> dict[str, Any]:
    """``n`` in-process examples: each one's CPU milliseconds and the examples per CPU-minute."""
    from swarm.kernel.simulation import Simulation

    def one(seed: int) -> float:
        t0 = time.process_time()
        with Simulation(scenario, duration_s=duration_s, seed=seed) as sim:
            sim.run()
        return time.process_time() - t0

    one(0)  # warm-up: not counted
    each = [one(seed) for seed in range(1, n + 1)]
    total = sum(each)
    return {"scenario": scenario, "sim_seconds": duration_s, "examples": n, "cpu_seconds": round(total, 6),
            "cpu_ms_each": [round(1000 * s, 1) for s in each],
            "examples_per_cpu_minute": round(60.0 * n / total, 1) if total > 0 else None,
            "target_per_minute": TARGET_PER_MINUTE}


def main(n: int, out: TextIO = sys.stdout) -> int:
    print(json.dumps(measure(n)), file=out, flush=True)
    return 0
