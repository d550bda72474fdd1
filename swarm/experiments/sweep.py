"""Monte Carlo sweeps: every combination of planner x setting x seed, on any executor.

A sweep is a list of :class:`RunSpec` (one simulation each). Runs go to a
``concurrent.futures``-style executor: a local process pool by default, or a Dask distributed
cluster through ``Client(address).get_executor()`` (``swarm sweep --scheduler``). A worker runs the
simulation and sends the result files back as bytes; the process that called :func:`run_sweep`
writes each run's folder, so workers on other machines need no shared file system.

Layout of ``out_dir``::

    runs/<planner>/<setting>/seed-<n>/   one run's outputs (see swarm.outputs); metrics.json last
    runs/.../error.json                  a run that raised: the error and its traceback
    summary.json, summary.csv            statistics per planner and setting (see summarize)
    runs.csv                             one row per run: planner, seed, each swept setting, every
                                         numeric metric flattened, status, error (see load_runs)
    report.html                          the summary as a page with figures (``swarm sweep``)
    sweep.json                           what each run folder holds (scenario, seed, duration)

A run folder with ``metrics.json`` is finished, so running the same sweep again skips it: an
interrupted sweep keeps the runs it finished and resumes where it stopped. Stopping well (no new
run, the runs in progress finished and kept) or at once: see :func:`run_sweep`'s ``stop`` and
:func:`graceful_interrupts` (``swarm sweep``: first and second Ctrl-C). A run that raises is
recorded and does not stop the others; it is tried again on the next invocation. A finished
folder is only reused for the very run that made it: ``sweep.json`` keeps a fingerprint of each
run (scenario document, planner, seed, duration), and asking the same folder for a different run
(another ``--duration``, an edited scenario) is refused with an error naming the folder.

Swept values may be anything ``--set`` takes: numbers, ``inf``, strings, booleans, arrays and
tables. Every JSON file a sweep writes is strict JSON: a non-finite number is written as the
string ``"inf"``, ``"-inf"`` or ``"nan"`` (the TOML spelling, which ``--set`` reads back).
"""

from __future__ import annotations

import contextlib
import csv
import functools
import hashlib
import io
import json
import math
import os
import re
import sys
import traceback
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Executor, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from itertools import product
from pathlib import Path
from typing import Any

import numpy as np

from swarm.errors import UsageError
from swarm.experiments.equivalence import DETECTION_TIME, axis_pairs, censored_detection_time, equivalence
from swarm.outputs import run_files, write_files
from swarm.scenario import Scenario, apply_overrides, load_scenario, parse_scenario
from swarm.scenario.trust import allowed

# What metrics.json says of how a run ran rather than of its mission: columns of runs.csv (as
# every number of metrics.json is), not summarised (the seed is what a group varies over; the
# simulated and wall seconds and the count of events describe the run; targets_total bounds
# targets_found).
_NOT_SUMMARISED = frozenset({"seed", "sim_seconds", "wall_seconds", "events", "targets_total"})


def strict_json(value: Any) -> Any:
    """``value`` with every non-finite float replaced by ``"inf"``, ``"-inf"`` or ``"nan"``
    (and tuples by lists), so ``json.dumps(..., allow_nan=False)`` accepts it."""
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {str(k): strict_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict_json(v) for v in value]
    if isinstance(value, np.generic):
        return strict_json(value.item())
    return value


def _dumps(value: Any, **kw: Any) -> str:
    return json.dumps(strict_json(value), allow_nan=False, **kw)


def _settings_key(settings: Sequence[tuple[str, Any]]) -> str:
    """A hashable, exact key for a combination of swept values (lists and tables included)."""
    return _dumps(list(settings), sort_keys=True)


@dataclass(frozen=True)
class RunSpec:
    """One simulation of a sweep. ``scenario`` is the scenario as a plain dict (picklable, so it
    travels to any worker), overrides already applied."""

    scenario: dict[str, Any]
    planner: str
    seed: int
    settings: tuple[tuple[str, Any], ...]
    folder: str  # relative to the sweep's out_dir
    duration_s: float | None = None
    figures: bool = False
    # Which module:Class planners this run may import (swarm.scenario.trust): True, or these
    # names. Decided where the sweep was asked for (the planners the user named, an opt-in) and
    # carried to the worker, which honours it without an opt-in of its own.
    allow_planner_imports: bool | tuple[str, ...] = ()

    @property
    def label(self) -> str:
        s = ", ".join(f"{k}={v}" for k, v in self.settings)
        return f"{self.planner} seed {self.seed}" + (f" ({s})" if s else "")


@dataclass
class SweepResult:
    out_dir: Path
    total: int
    skipped: int  # finished before this invocation
    ran: int
    failed: list[dict[str, Any]] = field(default_factory=list)
    summary: dict[str, Any] = field(default_factory=dict)


def slug(settings: Sequence[tuple[str, Any]]) -> str:
    """A folder name for a combination of swept values: readable (``radio.range_m=inf``), safe
    on every file system, and unique (long or unusual values get a short hash of the exact
    combination appended)."""
    if not settings:
        return "default"
    text = ",".join(f"{k}={_dumps(v, separators=(',', ':'))}" for k, v in settings)
    text = text.replace('"', "")
    safe = re.sub(r"[^A-Za-z0-9._=,+-]", "_", text)
    if safe != text or len(safe) > 80:
        digest = hashlib.sha256(_settings_key(settings).encode()).hexdigest()[:8]
        safe = f"{safe[:80]}-{digest}"
    return safe


def planner_folder(planner: str) -> str:
    """The folder name of a planner's runs: the name itself when it is portable (built-in and
    most entry-point names), otherwise its other characters replaced by ``_`` and a short hash
    of the full name appended, so names stay distinct
    (``examples.random_waypoint:RandomWaypoint`` -> ``examples.random_waypoint_RandomWaypoint-<hash>``):
    no ``:`` (refused by Windows, shown as ``/`` by macOS) nor any other character a file system
    may refuse. The full name stays in ``runs.csv``, ``summary.json`` and the run's
    ``scenario.json``."""
    safe = re.sub(r"[^A-Za-z0-9._-]", "_", planner)
    if safe != planner or len(safe) > 80 or not safe.strip("."):
        digest = hashlib.sha256(planner.encode()).hexdigest()[:8]
        safe = f"{safe[:80]}-{digest}"
    return safe


def run_folder(planner: str, settings: Sequence[tuple[str, Any]], seed: int) -> str:
    """``runs/<planner>/<settings>/seed-NNN``: where a sweep keeps a run (relative to its folder)."""
    return f"runs/{planner_folder(planner)}/{slug(settings)}/seed-{int(seed):03d}"


def plan_runs(scenario: Scenario, *, seeds: Iterable[int], planners: Sequence[str],
              grid: Mapping[str, Sequence[Any]] | None = None, duration_s: float | None = None,
              figures: bool = False, allow_planner_imports: bool | Iterable[str] = False) -> list[RunSpec]:
    """Every combination of ``planners`` x the cartesian product of ``grid`` x ``seeds``.

    ``grid`` maps a dotted scenario key to the values to try, e.g.
    ``{"radio.loss_base": [0.0, 0.3]}``. Each combination is validated here, so a bad key or
    value fails before anything runs, naming the key. Each planner replaces the scenario's as
    ``--planner`` does (options follow their planner: ``planner.options_for.NAME.KEY`` gives
    one planner an option, ``planner.options.KEY`` gives it to every planner of the sweep).

    ``planners`` are named by the caller, so a ``module:Class`` among them may be imported;
    ``allow_planner_imports`` allows more (``True``: any, e.g. a grid value of ``planner.name``).
    The decision is stored in each :class:`RunSpec` for its worker.
    """
    grid = dict(grid or {})
    keys = list(grid)
    # The duration applies before validation, as --duration does in `swarm run`: a setting that
    # only fits the shortened run (dt_s=1e-5 for a 1 s run) is not refused against the
    # scenario's own duration. The run's document keeps the scenario's duration_s (execute
    # applies spec.duration_s), so fingerprints of earlier sweeps still match.
    seeds = list(seeds)
    if not seeds:
        raise UsageError("a sweep needs at least one seed")
    if not planners:
        raise UsageError("a sweep needs at least one planner")
    allow = allowed(allow_planner_imports, planners)
    carried: bool | tuple[str, ...] = True if allow is True else tuple(sorted(allow))
    runs = []
    for planner in planners:
        for values in product(*(grid[k] for k in keys)):
            settings = tuple(zip(keys, values))
            overrides = {"planner.name": planner, **dict(settings)}
            if duration_s is not None:
                overrides["duration_s"] = duration_s  # what runs (execute applies it last)
            own = dict(settings).get("duration_s", scenario.duration_s)  # late joiners still join before it
            sc = apply_overrides(scenario, overrides, truncated=duration_s is not None, scenario_duration_s=own,
                                 allow_planner_imports=allow)
            doc = sc.to_dict()
            if duration_s is not None:
                doc["duration_s"] = dict(settings).get("duration_s", scenario.duration_s)
            for seed in seeds:
                runs.append(RunSpec(doc, planner, int(seed), settings, run_folder(planner, settings, seed),
                                    duration_s, figures, carried))
    return runs


def execute(spec: RunSpec) -> dict[str, Any]:
    """Run one simulation (in a worker). Returns ``{"files": {name: bytes}}`` or, if it raised,
    ``{"error": text, "traceback": text}``: an error is data, so one bad run cannot take the
    sweep down."""
    from swarm.kernel.simulation import Simulation

    try:
        doc = spec.scenario if spec.duration_s is None else {**spec.scenario, "duration_s": spec.duration_s}
        sc = parse_scenario(doc, source=f"sweep run {spec.folder}", truncated=spec.duration_s is not None,
                            allow_planner_imports=spec.allow_planner_imports)
        with Simulation(sc, seed=spec.seed, duration_s=spec.duration_s) as sim:
            result = sim.run()
            # A run's metrics.json records the swept settings it ran with.
            result.metrics["settings"] = strict_json(dict(spec.settings))
            if spec.figures:
                from swarm.viz.plots import trajectories_png

                return {"files": run_files(result, sim.scenario.to_dict(), figure=trajectories_png)}
            return {"files": run_files(result, sim.scenario.to_dict())}
    except Exception as exc:  # recorded in error.json, reported, retried next time
        return {"error": f"{type(exc).__name__}: {exc}", "traceback": portable_traceback()}


def portable_traceback() -> str:
    """The exception being handled, formatted as ``traceback.format_exc()`` does but with each
    frame's file named from the import root it was found under (``swarm/kernel/simulation.py``,
    ``numpy/...``), not by where this machine installed it: ``error.json`` holds no absolute
    path of the machine (docs/outputs.md, portable artifacts)."""
    roots = sorted({os.path.abspath(p) for p in sys.path if p}, key=len, reverse=True)
    lines = []
    for line in traceback.format_exc().splitlines(keepends=True):
        head = '  File "'
        if line.startswith(head):
            for root in roots:
                if line.startswith(head + root + os.sep):
                    line = head + line[len(head + root + os.sep):]
                    break
        lines.append(line)
    return "".join(lines)


def is_finished(out_dir: Path, spec: RunSpec) -> bool:
    return (out_dir / spec.folder / "metrics.json").is_file()


def fingerprint(spec: RunSpec) -> str:
    """What makes a run what it is (not how it is executed)."""
    scenario = spec.scenario
    planner = scenario.get("planner")
    if isinstance(planner, dict) and planner.get("options_for") == {}:
        # As before planner.options_for existed, so finished folders of older sweeps resume.
        scenario = {**scenario, "planner": {k: v for k, v in planner.items() if k != "options_for"}}
    doc = _dumps([scenario, spec.planner, spec.seed, spec.duration_s], sort_keys=True, default=str)
    return hashlib.sha256(doc.encode()).hexdigest()


def _check_manifest(out: Path, runs: Sequence[RunSpec]) -> None:
    """Refuse to reuse a finished folder made by a different run; record these runs."""
    path = out / "sweep.json"
    known: dict[str, str] = {}
    if path.is_file():
        try:
            known = json.loads(path.read_text())["runs"]
        except (ValueError, KeyError, TypeError):
            raise UsageError(f"{path}: not a sweep manifest (delete it, or use another output folder)") from None
    for spec in runs:
        fp = fingerprint(spec)
        old = known.get(spec.folder)
        if old is not None and old != fp and is_finished(out, spec):
            raise UsageError(
                f"{out / spec.folder} holds a finished run of a different configuration (scenario, "
                f"seed or duration changed since it ran); use another output folder, or delete that "
                f"folder to run it again")
        known[spec.folder] = fp
    write_files(out, {"sweep.json": json.dumps({"runs": dict(sorted(known.items()))}, indent=1).encode()})


ProgressFn = Callable[[int, int, RunSpec, str], None]


class SweepInterrupted(KeyboardInterrupt):
    """A sweep stopped before its end. ``graceful``: it was asked to stop (``stop()`` turned
    true) and waited for the runs in progress, keeping them; otherwise it was interrupted at
    once (a ``KeyboardInterrupt`` or an exception from ``progress``) and the runs in progress
    were abandoned. Either way every finished run is on disk, with the summary of them, and
    running the same sweep again resumes it. ``result``: what this invocation did."""

    def __init__(self, result: SweepResult, graceful: bool):
        super().__init__(f"sweep interrupted ({'after the runs in progress' if graceful else 'at once'})")
        self.result = result
        self.graceful = graceful


def _ignore_first_sigint() -> None:
    """Initializer of a sweep's own worker processes. A Ctrl-C at a terminal reaches every
    process of the foreground group, workers included: the first must not kill the runs in
    progress (the sweep finishes them), a second one stops them at once."""
    import signal

    count = 0

    def handler(signum: int, frame: Any) -> None:
        nonlocal count
        count += 1
        if count > 1:
            raise KeyboardInterrupt

    signal.signal(signal.SIGINT, handler)


@contextlib.contextmanager
def graceful_interrupts(on_first: Callable[[], None] | None = None) -> Iterator[Callable[[], bool]]:
    """While the block runs, a first Ctrl-C (SIGINT) asks the sweep to stop well instead of
    raising: give the yielded function as ``run_sweep(stop=...)``. ``on_first()`` is called when
    it arrives (e.g. to say so); a second Ctrl-C raises ``KeyboardInterrupt`` as usual (the sweep
    stops at once). The previous handler is restored on exit. Only in the main thread (signals
    are delivered there); elsewhere it changes nothing and ``stop()`` stays false."""
    import signal
    import threading

    asked = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield asked.is_set
        return

    def handler(signum: int, frame: Any) -> None:
        if asked.is_set():
            raise KeyboardInterrupt
        asked.set()
        if on_first is not None:
            on_first()

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield asked.is_set
    finally:
        signal.signal(signal.SIGINT, previous)


def _terminate_workers(executor: Executor) -> None:
    """Stop a process pool's workers now (Python 3.11 has no public way: the pool's own
    process table, if it has one)."""
    for proc in list((getattr(executor, "_processes", None) or {}).values()):
        with contextlib.suppress(Exception):
            proc.terminate()


def run_sweep(runs: Sequence[RunSpec], out_dir: str | Path, *, executor: Executor | None = None,
              workers: int | None = None, progress: ProgressFn | None = None,
              stop: Callable[[], bool] | None = None, baseline: str | None = None) -> SweepResult:
    """Run what is not finished yet, write each run's folder as it completes, then the summary
    (paired differences against ``baseline``, one of the runs' planners; default the first).

    ``executor``: any ``concurrent.futures.Executor`` (``submit`` returning futures), e.g. a
    Dask ``Client(...).get_executor()``; by default a local process pool of ``workers``
    processes (default: the CPU count), fed one run per free worker. ``progress(done, total,
    spec, status)`` is called after each run with status ``"ok"`` or ``"error"`` (and once with
    ``"skipped"`` per finished run).

    Stopping (both raise :class:`SweepInterrupted`, a ``KeyboardInterrupt``, after writing the
    summary of what finished; running the same sweep again resumes it):

    * well: once ``stop()`` returns true (polled a few times a second; see
      :func:`graceful_interrupts`), no new run starts, runs not yet started are cancelled, and
      the runs in progress are waited for and kept (with a given executor: those it no longer
      lets cancel); if no run was left out, the sweep simply ends as usual;
    * at once: on ``KeyboardInterrupt`` (a second Ctrl-C, or raised by ``progress``), pending
      runs are cancelled, the workers of the sweep's own pool are terminated, runs in progress
      are lost; finished ones stay on disk. (Any other exception from ``progress`` is cleaned up
      after the same way and propagates as it is.)
    """
    check_baseline((s.planner for s in runs), baseline)  # before anything is written
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _check_manifest(out, runs)
    todo = [s for s in runs if not is_finished(out, s)]
    result = SweepResult(out, len(runs), len(runs) - len(todo), 0)
    done = result.skipped
    if progress is not None:
        for s in runs:
            if s not in todo:
                progress(done, len(runs), s, "skipped")
    own = executor is None and bool(todo)
    n_workers = workers or os.cpu_count() or 1
    if own:
        executor = ProcessPoolExecutor(max_workers=n_workers, initializer=_ignore_first_sigint)
    # Our own pool gets one run per worker at a time, so that stopping starts no queued run;
    # a given executor (Dask) gets them all and schedules them itself.
    window = n_workers if own else len(todo)
    queue = iter(todo)
    futures: dict[Future[dict[str, Any]], RunSpec] = {}
    stopping = False
    unstarted = 0  # runs a stop left out

    def submit_next() -> None:
        spec = next(queue, None)
        if spec is not None and executor is not None:
            futures[executor.submit(execute, spec)] = spec

    try:
        for _ in range(window):
            submit_next()
        while futures:
            if not stopping and stop is not None and stop():
                stopping = True
                unstarted = sum(1 for _ in queue)
                for f in [f for f in futures if f.cancel()]:
                    del futures[f]  # never started
                    unstarted += 1
                if not futures:
                    break
            finished, _ = wait(futures, timeout=0.2 if stop is not None and not stopping else None,
                               return_when=FIRST_COMPLETED)
            for fut in finished:
                spec = futures.pop(fut)
                if fut.cancelled():
                    continue
                if not stopping:
                    submit_next()  # before writing this one's files: keep the worker busy
                status = _record(out, spec, fut, result)
                result.ran += 1
                done += 1
                if progress is not None:
                    progress(done, len(runs), spec, status)
    except BaseException as exc:
        for f in futures:
            f.cancel()
        if own and executor is not None:
            _terminate_workers(executor)
            executor.shutdown(wait=False, cancel_futures=True)
        result.summary = write_summary(out, runs, baseline)
        if isinstance(exc, KeyboardInterrupt) and not isinstance(exc, SweepInterrupted):
            raise SweepInterrupted(result, graceful=False) from exc
        raise
    finally:
        if own and executor is not None:
            executor.shutdown(wait=True, cancel_futures=True)
    result.summary = write_summary(out, runs, baseline)
    if unstarted:
        raise SweepInterrupted(result, graceful=True)
    return result


def _record(out: Path, spec: RunSpec, fut: Future[dict[str, Any]], result: SweepResult) -> str:
    """Write a finished run's folder (or its error.json); ``"ok"`` or ``"error"``."""
    try:
        outcome = fut.result()
    except Exception as exc:  # the worker itself died (e.g. killed, out of memory)
        outcome = {"error": f"{type(exc).__name__}: {exc}", "traceback": portable_traceback()}
    folder = out / spec.folder
    if "files" in outcome:
        (folder / "error.json").unlink(missing_ok=True)
        write_files(folder, outcome["files"])
        return "ok"
    write_files(folder, {"error.json": _dumps(
        {"run": spec.label, "folder": spec.folder, **outcome}, indent=2).encode()})
    result.failed.append({"run": spec.label, "folder": spec.folder, "error": outcome["error"]})
    return "error"


# --- statistics --------------------------------------------------------------------------------

def flatten_metrics(metrics: Mapping[str, Any], prefix: str = "") -> dict[str, int | float]:
    """Every number of a run's ``metrics.json`` under its dotted name, in the file's order:
    tables are flattened (``radio.sent``, ``faults_applied.drop``, ``endurance.sorties``,
    ``time_to_first_detection_s.3`` for target 3, ``per_uav.B1.mode_seconds.search``). Booleans,
    strings, nulls (a target never detected) and arrays (``handover_list``'s records, the
    wind's vectors) are not numbers of their own and are left out. The one definition of a
    sweep's metric names: ``runs.csv`` has a column for each, ``summary.json`` summarises each
    but the few :data:`_NOT_SUMMARISED`; a metric added to ``metrics.json`` joins both. A
    sweep's ``settings`` (what the run was given, recorded in its ``metrics.json``) are not
    metrics: ``runs.csv`` has each as a column of its own, named by its key."""
    flat: dict[str, int | float] = {}
    for k, v in metrics.items():
        if not prefix and k == "settings":
            continue
        name = f"{prefix}{k}"
        if isinstance(v, Mapping):
            flat.update(flatten_metrics(v, f"{name}."))
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            flat[name] = v
    return flat


def breakdowns(metrics: Mapping[str, Any]) -> list[str]:
    """The dotted names of the tables of ``metrics.json`` kept per UAV or per target: those
    whose keys are all UAV names (the keys of ``per_uav``) or target ids (``0`` to
    ``targets_total - 1``): ``per_uav``, ``surveillance_ratio``, ``time_to_first_detection_s``,
    ``endurance.per_uav``... A new table keyed so is one too. Their metrics are in the tables
    (``runs.csv``, ``summary.json``, ``summary.csv``); the sweep's report shows the others."""
    uavs = metrics.get("per_uav")
    total = metrics.get("targets_total")
    entities = set(uavs) if isinstance(uavs, Mapping) else set()
    if isinstance(total, int) and not isinstance(total, bool):
        entities |= {str(i) for i in range(total)}
    found: list[str] = []

    def walk(table: Mapping[str, Any], prefix: str) -> None:
        for k, v in table.items():
            if isinstance(v, Mapping) and v:
                if set(map(str, v)) <= entities:
                    found.append(f"{prefix}{k}")
                else:
                    walk(v, f"{prefix}{k}.")

    walk(metrics, "")
    return found


INTERVAL_METHOD = ("Student-t 95% interval of the mean over seeds, clipped to the range the metric can take "
                   "(fractions 0-1, counts and durations from 0, targets found up to the targets in the area)")

# The range each metric of metrics.json can take, by its flattened name (flatten_metrics).
# Fractions: a name part that is a share or a ratio (watched_share_mean, uav_time_share.watching,
# surveillance_ratio.3, per_uav.B1.time_share.searching), coverage and certainty, in [0, 1].
# Counts and durations, from 0: what the tables below hold, and the top-level counters.
# targets_found: at most the run's targets_total (filled in per group, see summarize). A metric
# none of these name is left unbounded (its plain t interval): a new metric is never clipped
# wrongly, only not clipped until named here.
_FRACTION_PART = re.compile(r"(^|_)(share|ratio)(_mean)?$")
_FRACTIONS = frozenset({"coverage", "certainty"})
_COUNTS = frozenset({"handovers", "handovers_fast_to_slow"})
_NONNEGATIVE_TABLES = frozenset({"radio", "violations", "faults_applied", "dynamics_violations_by_uav", "per_uav",
                                 "time_to_first_detection_s", "time_to_slow_watcher_s"})
_NONNEGATIVE_ENDURANCE = frozenset({"sorties", "lost_to_energy", "time_on_station_s"})


def metric_bounds(name: str, targets_total: float = math.inf) -> tuple[float, float]:
    """``(low, high)``: the values metric ``name`` (flattened, e.g. ``radio.sent``) can take;
    ``targets_total``: the most targets a run of the group has, the bound of ``targets_found``."""
    parts = name.split(".")
    if name in _FRACTIONS or any(_FRACTION_PART.search(p) for p in parts):
        return 0.0, 1.0
    if name == "targets_found":
        return 0.0, float(targets_total)
    if (name in _COUNTS or (len(parts) > 1 and parts[0] in _NONNEGATIVE_TABLES)
            or (parts[0] == "endurance" and parts[-1] in _NONNEGATIVE_ENDURANCE)):
        return 0.0, math.inf
    return -math.inf, math.inf


def difference_bounds(bounds: tuple[float, float]) -> tuple[float, float]:
    """The range of ``x - y`` for ``x`` and ``y`` both within ``bounds``."""
    lo, hi = bounds
    width = hi - lo
    return -width, width


@functools.lru_cache(maxsize=256)
def _t975(dof: int) -> float:
    """Student's t 97.5% quantile (a sweep describes thousands of metrics over the same seeds)."""
    from scipy import stats

    return float(stats.t.ppf(0.975, dof))


def describe(values: Sequence[float], bounds: tuple[float, float] | None = None) -> dict[str, Any]:
    """Mean, sample standard deviation and the Student-t 95% interval of the mean.

    ``bounds``: the range the values can take (:func:`metric_bounds`); the interval is clipped
    to it and the result gets ``"bounds": [low, high]``. Clipping never loses the true mean
    (it lies within the range too), so the interval keeps its coverage; with 2-3 seeds the
    t interval is wide (t = 12.7 for 2 seeds) and clipped it says, honestly, how little so
    few seeds tell. A bootstrap or percentile interval would stay inside the range too, but
    from 2 seeds it is [min, max], which holds the mean only half the time."""
    x = np.asarray(values, dtype=np.float64)
    n = x.size
    mean = float(x.mean()) if n else math.nan
    if n > 1:
        sd = float(x.std(ddof=1))
        half = _t975(n - 1) * sd / math.sqrt(n)
    else:
        sd, half = 0.0, math.nan
    ci = [mean - half, mean + half] if math.isfinite(half) else [mean, mean]
    out: dict[str, Any] = {"n": int(n), "mean": mean, "sd": sd, "ci95": ci}
    if bounds is not None:
        # never clip off a value that was seen (a metric outside its range is a bug to see, not hide)
        lo, hi = float(bounds[0]), float(bounds[1])
        if n:
            lo, hi = min(lo, float(x.min())), max(hi, float(x.max()))
        out["ci95"] = [min(max(c, lo), hi) if math.isfinite(c) else c for c in ci]
        out["bounds"] = [lo, hi]
    return out


def check_baseline(planners: Iterable[str], baseline: str | None) -> str | None:
    """``baseline`` if it is one of the sweep's ``planners`` (or None); otherwise a
    :class:`UsageError` naming them."""
    planners = list(dict.fromkeys(planners))
    if baseline is not None and baseline not in planners:
        raise UsageError(f"--baseline {baseline!r}: not a planner of this sweep (its planners: {', '.join(planners)})")
    return baseline


def summary_row(metrics: Mapping[str, Any]) -> dict[str, float]:
    """One finished run's numbers as the summary reads them: every metric of its ``metrics.json``
    (:func:`flatten_metrics`) but :data:`_NOT_SUMMARISED`, and the censored mean time to detection
    (:data:`~swarm.experiments.equivalence.DETECTION_TIME`) when it has targets."""
    row = {k: float(v) for k, v in flatten_metrics(metrics).items() if k not in _NOT_SUMMARISED}
    detection = censored_detection_time(metrics)
    if detection is not None:
        row[DETECTION_TIME] = detection
    return row


def paired_differences(before: Mapping[Any, Mapping[str, float]], after: Mapping[Any, Mapping[str, float]],
                       targets_total: float) -> tuple[list[Any], dict[str, dict[str, Any]]]:
    """Runs paired by key (a seed, a run folder): the keys in both, sorted, and per metric every
    one of them has, :func:`describe` of ``after - before`` (clipped as a difference of two values
    of the metric; ``targets_total`` bounds ``targets_found``). No key in both: ``([], {})``."""
    common = sorted(set(before) & set(after))
    if not common:
        return [], {}
    shared = set.intersection(*(set(before[k]) & set(after[k]) for k in common))
    names = [m for m in before[common[0]] if m in shared]
    return common, {m: describe([after[k][m] - before[k][m] for k in common],
                                difference_bounds(metric_bounds(m, targets_total))) for m in names}


def summarize(out_dir: str | Path, runs: Sequence[RunSpec], baseline: str | None = None) -> dict[str, Any]:
    """Per planner and setting: mean, sd and 95% interval of every metric over finished seeds
    (every number of ``metrics.json``, flattened by :func:`flatten_metrics`, but
    :data:`_NOT_SUMMARISED`); and, for each setting, each other planner compared with the
    ``baseline`` planner (default: the sweep's first) seed by seed (paired differences
    ``other - baseline`` with their 95% interval). Intervals are clipped to the range a metric
    (or a difference of two of its values) can take: :data:`INTERVAL_METHOD`, :func:`describe`;
    ``"interval"`` says so in the summary. ``"breakdowns"``: the tables kept per UAV or per
    target (:func:`breakdowns`), whose metrics the sweep's report leaves to the tables."""
    out = Path(out_dir)
    groups: dict[tuple[Any, ...], dict[str, Any]] = {}
    per_seed: dict[tuple[Any, ...], dict[int, dict[str, float]]] = {}
    targets: dict[tuple[Any, ...], float] = {}  # the most targets in a run of the group: targets_found's bound
    per_entity: dict[str, None] = {}
    errors = []
    for spec in runs:
        key = (spec.planner, _settings_key(spec.settings))
        g = groups.setdefault(key, {"planner": spec.planner, "settings": dict(spec.settings),
                                    "runs": 0, "failed": 0, "metrics": {}})
        mpath = out / spec.folder / "metrics.json"
        if mpath.is_file():
            g["runs"] += 1
            metrics = json.loads(mpath.read_text())
            per_seed.setdefault(key, {})[spec.seed] = summary_row(metrics)
            per_entity.update(dict.fromkeys(breakdowns(metrics)))
            if isinstance(metrics.get("targets_total"), (int, float)):
                targets[key] = max(targets.get(key, 0.0), float(metrics["targets_total"]))
        elif (out / spec.folder / "error.json").is_file():
            g["failed"] += 1
            errors.append(json.loads((out / spec.folder / "error.json").read_text()).get("error", "?"))
    for key, g in groups.items():
        seeds = per_seed.get(key, {})
        names = list(dict.fromkeys(m for v in seeds.values() for m in v))
        g["metrics"] = {m: describe([v[m] for v in seeds.values() if m in v], metric_bounds(m, targets.get(key, math.inf)))
                        for m in names}
    comparisons = []
    planners = list(dict.fromkeys(s.planner for s in runs))
    base_name = check_baseline(planners, baseline) or (planners[0] if planners else None)
    settings_list = list({_settings_key(s.settings): s.settings for s in runs}.items())
    for skey, settings in settings_list:
        base = per_seed.get((base_name, skey), {})
        for other in planners:
            if other == base_name:
                continue
            theirs = per_seed.get((other, skey), {})
            common, difference = paired_differences(
                base, theirs, max(targets.get((base_name, skey), 0.0), targets.get((other, skey), 0.0)))
            if common:
                comparisons.append({"settings": dict(settings), "planner": other, "baseline": base_name,
                                    "paired_seeds": len(common), "difference": difference})
    return {
        "runs_total": len(runs),
        "runs_finished": sum(g["runs"] for g in groups.values()),
        "runs_failed": sum(g["failed"] for g in groups.values()),
        "errors": errors,
        "interval": INTERVAL_METHOD,
        "baseline": base_name,
        "breakdowns": list(per_entity),
        "groups": list(groups.values()),
        "comparisons": comparisons,
        "setting_comparisons": _setting_comparisons(per_seed, planners, settings_list, targets),
    }


def _setting_comparisons(per_seed: Mapping[tuple[Any, ...], Mapping[int, Mapping[str, float]]],
                         planners: Sequence[str],
                         settings_list: Sequence[tuple[str, Sequence[tuple[str, Any]]]],
                         targets: Mapping[tuple[Any, ...], float]) -> list[dict[str, Any]]:
    """Per planner and ``--set`` axis, each later value against the axis's first, seed by seed,
    with the equivalence verdict of :mod:`swarm.experiments.equivalence`."""
    out = []
    for key, value, old, new in axis_pairs([s for _, s in settings_list], _settings_key):
        okey, nkey = _settings_key(old), _settings_key(new)
        for planner in planners:
            before, after = per_seed.get((planner, okey), {}), per_seed.get((planner, nkey), {})
            bound = max(targets.get((planner, okey), 0.0), targets.get((planner, nkey), 0.0))
            common, difference = paired_differences(before, after, bound)
            if not common:
                continue
            old_metrics = {m: describe([before[s][m] for s in common]) for m in difference}
            out.append({"planner": planner, "key": key, "old": dict(old).get(key), "new": value,
                        "settings": dict(new), "paired_seeds": len(common), "difference": difference,
                        "equivalence": equivalence(difference, old_metrics)})
    return out


def _csv(summary: dict[str, Any]) -> str:
    keys = sorted({k for g in summary["groups"] for k in g["settings"]})
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(["planner", *keys, "metric", "runs", "mean", "sd", "ci95_low", "ci95_high"])
    for g in summary["groups"]:
        for m, d in g["metrics"].items():
            w.writerow([g["planner"], *(_dumps(g["settings"].get(k)) for k in keys), m, d["n"],
                        repr(d["mean"]), repr(d["sd"]), repr(d["ci95"][0]), repr(d["ci95"][1])])
    return buf.getvalue()


def _cell(value: Any) -> str:
    """A CSV cell: numbers as Python writes them (inf included), other values as strict JSON."""
    if isinstance(value, bool) or value is None or isinstance(value, (list, dict, tuple)):
        return _dumps(value)
    if isinstance(value, float):
        return repr(value)
    return str(value)


def run_rows(out_dir: str | Path, runs: Sequence[RunSpec]) -> list[dict[str, Any]]:
    """One record per run: planner, seed, folder, each swept setting (its own column, named by
    its key), ``status`` (ok / error / not run), ``error``, and every number of the run's
    ``metrics.json`` under its dotted name (:func:`flatten_metrics`: ``radio.sent``,
    ``faults_applied.drop``, ``per_uav.B1.plans``)."""
    out = Path(out_dir)
    rows = []
    for spec in runs:
        row: dict[str, Any] = {"planner": spec.planner, "seed": spec.seed, "folder": spec.folder}
        row.update(dict(spec.settings))
        mpath, epath = out / spec.folder / "metrics.json", out / spec.folder / "error.json"
        if mpath.is_file():
            metrics = json.loads(mpath.read_text())
            row.update({"status": "ok", "error": ""})
            row.update({k: v for k, v in flatten_metrics(metrics).items() if k != "seed"})
        elif epath.is_file():
            row.update({"status": "error", "error": json.loads(epath.read_text()).get("error", "?")})
        else:
            row.update({"status": "not run", "error": ""})
        rows.append(row)
    return rows


def _runs_csv(rows: list[dict[str, Any]]) -> str:
    columns = list(dict.fromkeys(k for row in rows for k in row))
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(columns)
    for row in rows:
        w.writerow([_cell(row[c]) if c in row else "" for c in columns])
    return buf.getvalue()


def load_runs(out_dir: str | Path) -> Any:
    """A sweep folder's ``runs.csv``, one row per run: a pandas DataFrame when pandas is
    installed, otherwise a list of dicts (numbers parsed, ``inf`` included)."""
    path = Path(out_dir) / "runs.csv"
    if not path.is_file():
        raise UsageError(f"{path}: no such file (is {out_dir} a sweep folder written by this version?)")
    try:
        import pandas as pd  # type: ignore[import-untyped]  # optional, and the gate installs no pandas-stubs
    except ImportError:
        with path.open(newline="") as fh:
            return [{k: _parse_cell(v) for k, v in row.items()} for row in csv.DictReader(fh)]
    return pd.read_csv(path)


def _parse_cell(text: str) -> Any:
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def write_summary(out_dir: str | Path, runs: Sequence[RunSpec], baseline: str | None = None) -> dict[str, Any]:
    summary = summarize(out_dir, runs, baseline)
    write_files(out_dir, {"summary.csv": _csv(summary).encode(),
                          "runs.csv": _runs_csv(run_rows(out_dir, runs)).encode(),
                          "summary.json": _dumps(summary, indent=2).encode()})
    return summary


def sweep(scenario: str | os.PathLike[str] | Scenario, out_dir: str | Path, *, seeds: int | Iterable[int] = 30,
          planners: Sequence[str] = ("dacmp", "greedy"), grid: Mapping[str, Sequence[Any]] | None = None,
          executor: Executor | None = None, workers: int | None = None, duration_s: float | None = None,
          figures: bool = False, progress: ProgressFn | None = None,
          allow_planner_imports: bool | Iterable[str] = False, baseline: str | None = None) -> SweepResult:
    """Plan and run a sweep in one call (the Python form of ``swarm sweep``).

    ``seeds``: a count (seeds 0..n-1) or the seeds themselves. ``allow_planner_imports``: a
    ``module:Class`` named by the scenario file or the grid (not by ``planners``) is imported
    only if allowed (:mod:`swarm.scenario.trust`). ``baseline``: the planner the others are
    compared with (default: the first). See :func:`plan_runs` and :func:`run_sweep` for the rest.
    """
    first = planners[0] if planners else None
    sc = (scenario if isinstance(scenario, Scenario)
          else load_scenario(scenario, planner=first, allow_planner_imports=allow_planner_imports))
    seed_list = range(seeds) if isinstance(seeds, int) else list(seeds)
    runs = plan_runs(sc, seeds=seed_list, planners=planners, grid=grid, duration_s=duration_s, figures=figures,
                     allow_planner_imports=allow_planner_imports)
    return run_sweep(runs, out_dir, executor=executor, workers=workers, progress=progress, baseline=baseline)


def split_values(text: str) -> list[str]:
    """Split ``v1,v2,[1,2]`` at top-level commas (commas inside brackets or quotes stay)."""
    parts: list[str] = []
    cur: list[str] = []
    depth, quote = 0, None
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append("".join(cur))
            cur = []
            continue
        cur.append(ch)
    parts.append("".join(cur))
    return [p.strip() for p in parts if p.strip()]
