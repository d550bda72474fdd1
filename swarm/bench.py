"""``swarm bench``: fixed benchmark cases, one JSON line each.

Each line: ``case``, ``uavs``, ``sim_seconds``, ``wall_seconds``, ``realtime_factor`` (sim/wall),
``peak_rss_mb`` (of this process so far), ``event_log_sha256`` and ``shares``: the fraction of
wall time spent in planning (the planners' ``plan`` calls), the rest of the actors' steps (map
merges, inbox decoding, local planner: "actors"), the radio (topology and per-link decisions),
and everything else (world, metrics, event log: "world"). Timing is measured here, by wrapping
the simulation's phases from the outside; the simulation itself never reads a clock.
"""

from __future__ import annotations

import json
import resource
import sys
import time
from dataclasses import dataclass

from swarm.simulation import Simulation


@dataclass(frozen=True)
class Case:
    name: str
    scenario: str
    planner: str
    duration_s: float | None = None
    quick: bool = False


CASES = [
    Case("paper-fig11-greedy", "paper-fig11", "greedy", quick=True),
    Case("paper-fig11-dacmp", "paper-fig11", "dacmp", quick=True),
    Case("paper-case2-dacmp", "paper-case2", "dacmp"),
]


class _Timer:
    def __init__(self) -> None:
        self.seconds = 0.0

    def wrap(self, fn):
        def timed(*a, **kw):
            t0 = time.perf_counter()
            try:
                return fn(*a, **kw)
            finally:
                self.seconds += time.perf_counter() - t0

        return timed


def run_case(case: Case) -> dict:
    sim = Simulation(case.scenario, planner=case.planner, duration_s=case.duration_s)
    plan_t, step_t, radio_t = _Timer(), _Timer(), _Timer()
    for actor in sim.actors.values():
        actor.planner.plan = plan_t.wrap(actor.planner.plan)
        actor.step = step_t.wrap(actor.step)
    sim.radio.broadcast = radio_t.wrap(sim.radio.broadcast)
    sim.radio.update_topology = radio_t.wrap(sim.radio.update_topology)
    t0 = time.perf_counter()
    result = sim.run()
    wall = time.perf_counter() - t0
    sim.close()
    m = result.metrics
    return {
        "case": case.name,
        "uavs": len(sim.world.uavs),
        "sim_seconds": m["sim_seconds"],
        "wall_seconds": round(wall, 3),
        "realtime_factor": round(m["sim_seconds"] / wall, 1),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "shares": {
            "planning": round(plan_t.seconds / wall, 3),
            "actors": round((step_t.seconds - plan_t.seconds) / wall, 3),
            "radio": round(radio_t.seconds / wall, 3),
            "world": round(max(0.0, wall - step_t.seconds - radio_t.seconds) / wall, 3),
        },
        "coverage": round(m["coverage"], 4),
        "event_log_sha256": m["event_log_sha256"],
    }


def main(quick: bool = False, only: list[str] | None = None, out=sys.stdout) -> int:
    for case in CASES:
        if quick and not case.quick:
            continue
        if only and case.name not in only:
            continue
        print(json.dumps(run_case(case)), file=out, flush=True)
    return 0
