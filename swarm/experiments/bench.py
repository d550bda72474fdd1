"""``swarm bench``: fixed benchmark cases, one JSON line each.

Each line: ``case``, ``scenario``, ``planner``, ``uavs``, ``sim_seconds``, ``wall_seconds``,
``realtime_factor`` (sim/wall), ``cpu_seconds`` (this process's CPU time: less sensitive than
wall time to other work on a shared machine), ``peak_rss_mb`` (of this process so far: run the
big cases one per process, ``--case NAME``, for a per-case figure), ``coverage``,
``event_log_sha256``, ``anti_entropy`` (whether the run had it: ``radio.sync_every_s > 0``), three
rates per UAV-tick (a live UAV simulated for one tick: one ``pose`` event, one row of its path;
a UAV-second is a UAV-tick times ``dt_s``):

* ``uav_steps_per_cpu_s``: UAV-ticks simulated per CPU second (the sum over ticks of the UAVs
  alive in the tick, over ``cpu_seconds``): a throughput comparable across swarm sizes;
* ``radio_bytes_per_uav_s``: the radio's ``bytes_sent`` (every frame broadcast, counted once)
  per UAV-second;
* ``event_log_bytes_per_uav_s``: the event log's size (``events.msgpack``) per UAV-second;

``uav_steps_per_cpu_s_by_tenth``: the same rate in each tenth of the simulated time (CPU
time read at the simulation's progress callbacks, UAV-ticks counted from the paths), and
``flatness``: the whole run's rate over its first tenth's (1.0: the cost per tick did not grow
as the run went on; issue 25 asks at least 0.8 of bench-100-greedy over 2000 s against its
first 200 s);

then what anti-entropy costs and holds (:func:`anti_entropy_figures`: the horizon, the mean
digest size, anti-entropy bytes per UAV-second, scans and map storage per UAV at the end);

and ``shares``, the fraction of the run spent in:

* ``planning``: the planners' ``plan`` calls (including the map reads they make);
* ``map``: the actors' other map work: applying their own scans and heard scan records (disk
  geometry, including the simulation's per-tick batch of it, and stamping);
* ``radio``: topology (k-d tree, graph update) and per-link decisions of every broadcast;
* ``actors``: the rest of the actors' steps (inbox decoding, knowledge merges, local planner,
  encoding frames);
* ``world``: everything else (sensing, physics, ground-truth metrics, event log, waking the
  actors' asyncio tasks).

Shares are sampled, not timed: every millisecond of CPU time (``SIGPROF``) the main thread's
Python stack is filed under the phase it is in (the outermost phase boundary on the stack
decides: a map write inside planning is planning, the ground truth's map writes are world).
Nothing is wrapped, so the wall time and realtime factor are those of an unobserved run (the
sampling costs about 1%); with a thousand samples or more a share is good to about +-0.02.
The simulation itself never reads a clock.
"""

from __future__ import annotations

import json
import resource
import signal
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from types import CodeType, FrameType
from typing import Any

import numpy as np

import agents.actor
import agents.maps.grid
import agents.maps.umap
import agents.planners
import comms.radio
from swarm.kernel.results import RunResult
from swarm.kernel.simulation import Simulation
from swarm.scenario import Scenario, load_scenario


@dataclass(frozen=True)
class Case:
    name: str
    scenario: str
    planner: str
    duration_s: float | None = None  # None: the scenario's
    quick: bool = False  # part of `swarm bench --quick` (CI)


CASES = [
    Case("paper-fig11-greedy", "paper-fig11", "greedy", quick=True),
    Case("paper-fig11-dacmp", "paper-fig11", "dacmp", quick=True),
    Case("paper-case2-dacmp", "paper-case2", "dacmp"),
    # The scale scenarios run with anti-entropy on, a knowledge horizon and recording level
    # "summary" (their tomls). The full 2000 s.
    Case("bench-100-dacmp", "bench-100", "dacmp"),
    Case("bench-100-greedy", "bench-100", "greedy"),
    # 42 M cells, 200 s.
    Case("bench-1000-greedy", "bench-1000", "greedy"),
    # The same with DACMP: heavy, run it on its own (--case).
    Case("bench-1000-dacmp", "bench-1000", "dacmp"),
    # ~75 000 link copies per simulated second: 30 s.
    Case("bench-dense-300-dacmp", "bench-dense-300", "dacmp", duration_s=30.0),
]

SHARES = ("planning", "map", "radio", "actors", "world")

# Phases are told apart by the source file of each frame: the modules' own paths, wherever
# the packages are installed.
_MAP_FILES = {agents.maps.umap.__file__, agents.maps.grid.__file__}
_PLANNER_DIR = str(Path(agents.planners.__file__).parent)
_ACTOR_FILE = agents.actor.__file__
_RADIO_FILE = comms.radio.__file__


def classify(frame: FrameType | None) -> str:
    """The phase a stack (innermost frame given) is in; see the module docstring."""
    codes: list[CodeType] = []
    while frame is not None:
        codes.append(frame.f_code)
        frame = frame.f_back
    phase = "world"
    for code in reversed(codes):  # outermost first: the outermost phase boundary decides
        name, path = code.co_name, code.co_filename
        if path.startswith(_PLANNER_DIR):
            return "planning"  # wherever a planner runs (per actor or batched)
        if phase == "world":
            if path == _ACTOR_FILE and name in ("run", "step", "observe", "act"):
                phase = "actors"
            elif path == _RADIO_FILE and name in ("broadcast", "update_topology"):
                return "radio"
            elif name == "prefetch_disks" and path in _MAP_FILES:
                return "map"
        elif path in _MAP_FILES:  # inside an actor's step
            phase = "map"
    return phase


class _Sampler:
    """Counts the phase the main thread is in, on a CPU-time interval timer (``SIGPROF``).

    The handler runs in the main thread at the next bytecode boundary, with the frame that was
    running (a long numpy call is charged to the Python frame that made it), so samples are
    proportional to CPU time. Only possible in the main thread; elsewhere nothing is sampled.
    """

    def __init__(self, interval: float = 0.001):
        self.interval = interval
        self.counts: Counter[str] = Counter()
        # The handler signal.signal replaced (None: one not installed from Python).
        self._saved: Callable[[int, FrameType | None], Any] | int | None = None

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self.counts[classify(frame)] += 1

    def start(self) -> None:
        if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "setitimer"):
            return
        self._saved = signal.signal(signal.SIGPROF, self._on_signal)
        signal.setitimer(signal.ITIMER_PROF, self.interval, self.interval)

    def stop(self) -> dict[str, float]:
        if self._saved is not None:
            signal.setitimer(signal.ITIMER_PROF, 0.0, 0.0)
            signal.signal(signal.SIGPROF, self._saved)
            self._saved = None
        n = sum(self.counts.values())
        return {k: round(self.counts[k] / n, 3) if n else 0.0 for k in SHARES}


def case_scenario(case: Case) -> Scenario:
    """The scenario a case runs (before its planner and duration are applied): the named one, as
    it is (every case runs with its scenario's anti-entropy, horizon and recording level)."""
    return load_scenario(case.scenario)


def uav_ticks(result: RunResult) -> int:
    """The sum over the run's ticks of the UAVs alive in each: a live UAV adds one row to its
    path (and one ``pose`` event to the log) per tick, so this is read after the run."""
    return sum(len(p) for p in result.paths.values())


TENTHS = 10


def rate_by_tenth(result: RunResult, duration_s: float, cpu_at: list[tuple[float, float]]) -> list[float]:
    """UAV-ticks per CPU second in each tenth of the simulated time: ``cpu_at`` holds ``(sim t,
    CPU s since the start)`` pairs read at the progress callbacks (the first ``(0, 0)``); a
    tenth's CPU time is interpolated at its edges, its UAV-ticks are the path rows stamped
    inside it (a row is stamped at the end of its tick)."""
    ts = np.array([t for t, _ in cpu_at])
    cs = np.array([c for _, c in cpu_at])
    edges = np.linspace(0.0, duration_s, TENTHS + 1)
    cpu = np.diff(np.interp(edges, ts, cs))
    stamps = np.concatenate([p[:, 0] for p in result.paths.values()]) if result.paths else np.zeros(0)
    counts = np.histogram(stamps, bins=edges)[0] if len(stamps) else np.zeros(TENTHS)
    return [round(float(n / c), 1) if c > 0 else 0.0 for n, c in zip(counts, cpu)]


def run_case(case: Case) -> dict:
    sim = Simulation(case_scenario(case), planner=case.planner, duration_s=case.duration_s)
    sampler = _Sampler()
    cpu_at: list[tuple[float, float]] = [(0.0, 0.0)]

    def progress(t: float, _end: float) -> None:
        cpu_at.append((t, time.process_time() - c0))

    sampler.start()
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        result = sim.run(progress)
    finally:
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        shares = sampler.stop()
        sim.close()
    m = result.metrics
    ticks = uav_ticks(result)
    uav_s = ticks * sim.dt
    cpu_at.append((m["sim_seconds"], cpu))
    tenths = rate_by_tenth(result, m["sim_seconds"], cpu_at)
    return {
        "case": case.name,
        "scenario": case.scenario,
        "planner": case.planner,
        "uavs": len(sim._world.uavs),
        "sim_seconds": m["sim_seconds"],
        "wall_seconds": round(wall, 3),
        "realtime_factor": round(m["sim_seconds"] / wall, 2),
        "cpu_seconds": round(cpu, 3),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "shares": shares,
        "coverage": round(m["coverage"], 4),
        "event_log_sha256": m["event_log_sha256"],
        "anti_entropy": sim.scenario.radio.sync_every_s > 0,
        "uav_steps_per_cpu_s": round(ticks / cpu, 1) if cpu > 0 else 0.0,
        "uav_steps_per_cpu_s_by_tenth": tenths,
        "flatness": round(ticks / cpu / tenths[0], 3) if cpu > 0 and tenths[0] > 0 else None,
        "radio_bytes_per_uav_s": round(m["radio"]["bytes_sent"] / uav_s, 1) if uav_s else 0.0,
        "event_log_bytes_per_uav_s": round(len(result.events) / uav_s, 1) if uav_s else 0.0,
        **anti_entropy_figures(sim, uav_s),
    }


def anti_entropy_figures(sim: Simulation, uav_s: float) -> dict:
    """What anti-entropy costs and holds, per UAV: ``sync_horizon_m`` (the knowledge horizon, None
    = none), ``digest_bytes_mean`` (a digest's bitmaps, 8 bytes per origin listed included),
    ``anti_entropy_bytes_per_uav_s`` (digests plus the frames answering them, per UAV-second),
    ``scan_log_max`` / ``scan_log_mean`` (scans held in a UAV's log at the end) and
    ``map_mb_max`` / ``map_mb_mean`` (a UAV's map storage at the end; None for maps in a
    :class:`~agents.maps.mapgroup.MapGroup`, which share it)."""
    cs = [a.counters for a in sim.actors.values()]
    digests = sum(c.digests_sent for c in cs)
    digest_bytes = sum(c.digest_bytes for c in cs)
    logs = [a.scans.count for a in sim.actors.values()] or [0]
    h = sim.scenario.radio.horizon_m
    out: dict[str, Any] = {
        "sync_horizon_m": None if h == float("inf") else h,
        "digest_bytes_mean": round(digest_bytes / digests, 1) if digests else 0.0,
        "anti_entropy_bytes_per_uav_s": round((digest_bytes + sum(c.resent_bytes for c in cs)) / uav_s, 1)
        if uav_s else 0.0,
        "scan_log_max": max(logs),
        "scan_log_mean": round(sum(logs) / len(logs), 1),
    }
    out["map_mb_max"] = out["map_mb_mean"] = None  # group maps share storage: no per-UAV figure
    if sim._map_group is None:
        mb = [a.umap.nbytes / 1e6 for a in sim.actors.values()] or [0.0]
        out["map_mb_max"] = round(max(mb), 2)
        out["map_mb_mean"] = round(sum(mb) / len(mb), 2)
    return out


def main(quick: bool = False, only: list[str] | None = None, out=sys.stdout, duration_s: float | None = None,
         as_array: bool = False) -> int:
    """Run the cases (``quick``: the CI subset; ``only``: these names) and print one JSON line
    each as it finishes, or (``as_array``) one JSON array at the end. ``duration_s`` overrides
    every case's simulated duration (tests; the line says it)."""
    rows = []
    for case in CASES:
        if quick and not case.quick:
            continue
        if only and case.name not in only:
            continue
        if duration_s is not None:
            case = replace(case, duration_s=duration_s)
        row = run_case(case)
        rows.append(row)
        if not as_array:
            print(json.dumps(row), file=out, flush=True)
    if as_array:
        print(json.dumps(rows, indent=2), file=out, flush=True)
    return 0
