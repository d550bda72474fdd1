"""Running an axis: its sweep planned from the axis's record, run (resumable) on any executor,
and measured: per value and planner, mean and 95% interval over seeds, kept fractions against
the baseline, DACMP - greedy paired by seed (``results.json``)."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from swarm.errors import UsageError
from swarm.experiments.common import executor_for, expected_duration, seeds_from, write_json
from swarm.experiments.paper import FIG11_PLANNERS
from swarm.experiments.resilience.axes import (
    AXES,
    DEFAULT_BURST_LOSS,
    DEFAULT_CRASH_AT_S,
    KEPT,
    QUANTITIES,
    PointContext,
    axis_named,
    crash_candidates,
)
from swarm.experiments.resilience.figures import axis_figure, kept_figure
from swarm.experiments.resilience.tables import write_axis_table, write_table
from swarm.experiments.sweep import RunSpec, SweepResult, describe, plan_runs, run_folder, run_sweep
from swarm.scenario import Scenario, apply_overrides, load_scenario

__all__ = ["AxisReport", "ResilienceReport", "measure", "parse_values", "plan_axis", "run_axis", "run_resilience"]

PLANNERS = FIG11_PLANNERS  # greedy first: the sweep's paired comparisons are "dacmp - greedy"
DEFAULT_SCENARIO = "paper-fig11"
DEFAULT_SEEDS = 10

ProgressFn = Callable[[str, str, float, float, str], None]
"""``progress(key, description, done, total, info)``: one bar per ``key`` (as ``swarm.experiments.paper``)."""


@dataclass
class AxisReport:
    axis: str
    out_dir: Path
    sweep: SweepResult
    figures: list[Path] = field(default_factory=list)
    results: dict[str, Any] = field(default_factory=dict)

    @property
    def failed(self) -> list[dict[str, Any]]:
        return self.sweep.failed


@dataclass
class ResilienceReport:
    out_dir: Path
    axes: list[AxisReport]
    table_md: Path
    table_csv: Path


# --- planning ------------------------------------------------------------------------------------

def plan_axis(axis: str, scenario: Scenario, *, values: Sequence[Any] | None = None, seeds: Sequence[int],
              planners: Sequence[str] = PLANNERS, duration_s: float | None = None,
              crash_at_s: float = DEFAULT_CRASH_AT_S, burst_loss: float = DEFAULT_BURST_LOSS) -> list[RunSpec]:
    """The sweep of one axis: every planner x value x seed, in value order. Folders are
    ``runs/<planner>/<settings>/seed-NNN`` as in :func:`swarm.experiments.sweep.plan_runs`."""
    ax = axis_named(axis)
    run_s = expected_duration(scenario, duration_s)
    if ax.needs_uavs:
        n = len(crash_candidates(scenario))
        if ax.counts_uavs:
            if values is None:
                values = [k for k in ax.values if k <= max(n - 1, 0)]
            too_many = [k for k in values if k > n]
            if too_many:
                raise UsageError(f"{axis} value {max(too_many)}: {scenario.name} has {n} UAVs that fly from the start "
                                 f"and do not crash ({', '.join(crash_candidates(scenario))})")
        elif n == 0:
            raise UsageError(f"the {axis} axis needs UAVs that fly from the start; {scenario.name} has none")
    if ax.timed and not 0.0 <= crash_at_s < run_s:
        raise UsageError(f"--crash-at {crash_at_s:g}: expected a time from 0 to before the end of the run "
                         f"({run_s:g} s)")
    if not 0.0 < burst_loss < 1.0:
        raise UsageError(f"--burst-loss {burst_loss:g}: expected a mean loss rate between 0 and 1 (exclusive)")
    ctx = PointContext(crash_at_s, burst_loss)
    runs = []
    for v in ax.check(list(ax.values if values is None else values)):
        settings, overrides = ax.point(scenario, v, ctx)
        sc = apply_overrides(scenario, overrides) if overrides else scenario
        for spec in plan_runs(sc, seeds=seeds, planners=planners, duration_s=duration_s):
            runs.append(replace(spec, settings=settings, folder=run_folder(spec.planner, settings, spec.seed)))
    return runs


def parse_values(axis: str, text: str) -> list[Any]:
    """``--values`` for one axis: comma-separated (each axis says what its values must be)."""
    ax = axis_named(axis)
    parts = [p.strip() for p in text.split(",") if p.strip()]
    if not parts:
        raise UsageError(f"--values {text!r}: expected a comma-separated list of values")
    out = []
    for p in parts:
        try:
            out.append(ax.parse(p))
        except UsageError as exc:
            raise UsageError(f"--values {text!r}: {exc}") from None
    return ax.check(out)


# --- running -------------------------------------------------------------------------------------

def _check_finished(axis_dir: Path, runs: Sequence[RunSpec], scenario: str, run_s: float) -> None:
    """Finished runs in the folder must be of this scenario and duration (else: another --out)."""
    for spec in runs:
        mp = axis_dir / spec.folder / "metrics.json"
        if not mp.is_file():
            continue
        m = json.loads(mp.read_text())
        if m.get("scenario") != scenario:
            raise UsageError(f"{mp.parent} holds a finished run of scenario {m.get('scenario')!r}, but this asks for "
                             f"{scenario!r}: use another --out or delete the old results")
        if not math.isclose(float(m.get("sim_seconds", math.nan)), run_s, abs_tol=1e-6):
            raise UsageError(f"{mp.parent} holds a finished run of {m.get('sim_seconds')} s, but this asks for "
                             f"{run_s:g} s: use another --out or delete the old results")


def _plan(axis: str, out_dir: str | Path, *, scenario: str | os.PathLike[str] = DEFAULT_SCENARIO,
          seeds: int | Sequence[int] = DEFAULT_SEEDS, values: Sequence[Any] | None = None, duration_s: float | None = None,
          crash_at_s: float = DEFAULT_CRASH_AT_S, burst_loss: float = DEFAULT_BURST_LOSS, **_: Any
          ) -> tuple[Scenario, list[int], float, list[RunSpec]]:
    """Check everything about one axis before anything runs: (scenario, seeds, run seconds, runs)."""
    if duration_s is not None and not duration_s > 0:
        raise UsageError(f"--duration {duration_s:g}: expected a positive number of seconds")
    sc = load_scenario(scenario, planner=PLANNERS[0])  # the axes run their own planners: the file's is never imported
    seed_list = seeds_from(seeds)
    run_s = expected_duration(sc, duration_s)
    runs = plan_axis(axis, sc, values=values, seeds=seed_list, duration_s=duration_s, crash_at_s=crash_at_s,
                     burst_loss=burst_loss)
    _check_finished(Path(out_dir) / axis, runs, sc.name, run_s)
    return sc, seed_list, run_s, runs


def run_axis(axis: str, out_dir: str | Path = "results/resilience", *, scenario: str | os.PathLike[str] = DEFAULT_SCENARIO,
             seeds: int | Sequence[int] = DEFAULT_SEEDS, values: Sequence[Any] | None = None,
             duration_s: float | None = None, crash_at_s: float = DEFAULT_CRASH_AT_S,
             burst_loss: float = DEFAULT_BURST_LOSS, executor: Executor | None = None, workers: int | None = None,
             progress: ProgressFn | None = None) -> AxisReport:
    """Run (or resume) one axis's sweep into ``out_dir/<axis>``, then write its figures, tables
    and ``results.json``."""
    sc, seed_list, run_s, runs = _plan(axis, out_dir, scenario=scenario, seeds=seeds, values=values,
                                       duration_s=duration_s, crash_at_s=crash_at_s, burst_loss=burst_loss)
    axis_dir = Path(out_dir) / axis
    point_values = list(dict.fromkeys(s.settings[0][1] for s in runs))
    desc = f"{axis}: {len(point_values)} values x {len(PLANNERS)} planners x {len(seed_list)} seeds"

    def cb(done: int, total: int, spec: RunSpec, status: str) -> None:
        if progress is not None:
            progress(axis, desc, done, total, f"{status}: {spec.label}")

    if progress is not None:
        progress(axis, desc, 0, len(runs), "")
    with executor_for(executor, workers) as ex:
        res = run_sweep(runs, axis_dir, executor=ex, progress=cb)
    results = measure(axis, axis_dir, runs, res.summary, scenario=sc, seeds=seed_list, run_s=run_s,
                      crash_at_s=crash_at_s, burst_loss=burst_loss)
    write_json(axis_dir / "results.json", results)
    rep = AxisReport(axis, axis_dir, res, results=results)
    reference = loss_reference(Path(out_dir), results) if AXES[axis].loss_reference else None
    rep.figures.append(axis_figure(results, axis_dir / f"{axis}.png", reference=reference))
    if AXES[axis].draws_kept:
        rep.figures.append(kept_figure(results, axis_dir / f"{axis}_kept.png"))
    write_axis_table(results, axis_dir)
    return rep


def run_resilience(axis: str, out_dir: str | Path = "results/resilience", *, values: Sequence[Any] | None = None,
                   executor: Executor | None = None, workers: int | None = None, **kw: Any) -> ResilienceReport:
    """One axis or ``"all"`` (every axis, in the order of :data:`AXES`), then the top-level table.
    ``values`` only with one axis. Other keywords go to :func:`run_axis`."""
    if axis != "all":
        axis_named(axis)
    if axis == "all" and values is not None:
        raise UsageError("--values needs one axis, not all")
    out = Path(out_dir)
    names = tuple(AXES) if axis == "all" else (axis,)
    for name in names:  # a mistake in any axis is reported before the first run
        _plan(name, out, values=values, **kw)
    reports = []
    with executor_for(executor, workers) as ex:
        for name in names:
            reports.append(run_axis(name, out, values=values, executor=ex, **kw))
    md, csv_path = write_table(out)
    return ResilienceReport(out, reports, md, csv_path)


# --- measuring -----------------------------------------------------------------------------------

def _run_quantities(metrics: dict[str, Any]) -> dict[str, float]:
    r = metrics.get("radio", {})
    sent = float(r.get("sent", 0))
    return {
        "coverage": float(metrics["coverage"]),
        "targets_found": float(metrics["targets_found"]),
        "surveillance_ratio_mean": float(metrics.get("surveillance_ratio_mean", math.nan)),
        "certainty": float(metrics.get("certainty", math.nan)),
        "delivered": float(r.get("delivered", 0)),
        "delivered_fraction": float(r.get("delivered", 0)) / sent if sent > 0 else math.nan,
        "separation_violations": float(metrics.get("violations", {}).get("separation", math.nan)),
    }


def _describe(vals: Sequence[float]) -> dict[str, Any] | None:
    vals = [v for v in vals if math.isfinite(v)]
    return describe(vals) if vals else None


def measure(axis: str, axis_dir: Path, runs: Sequence[RunSpec], summary: dict[str, Any], *, scenario: Scenario,
            seeds: Sequence[int], run_s: float, crash_at_s: float, burst_loss: float) -> dict[str, Any]:
    """Per value and planner: mean and 95% interval of every quantity over finished seeds; the
    fraction of the baseline value's coverage and targets kept (per seed, paired); DACMP − greedy
    (paired by seed, from the sweep's summary)."""
    per: dict[tuple[str, Any], dict[int, dict[str, float]]] = {}
    failed: dict[tuple[str, Any], int] = {}
    targets_total = None
    for spec in runs:
        key = (spec.planner, spec.settings[0][1])
        mp = axis_dir / spec.folder / "metrics.json"
        if mp.is_file():
            m = json.loads(mp.read_text())
            targets_total = m.get("targets_total", targets_total)
            per.setdefault(key, {})[spec.seed] = _run_quantities(m)
        elif (axis_dir / spec.folder / "error.json").is_file():
            failed[key] = failed.get(key, 0) + 1
    ax = AXES[axis]
    values = list(dict.fromkeys(s.settings[0][1] for s in runs))
    baseline = ax.baseline
    has_base = ax.has_baseline and baseline in values
    diffs = {json.dumps(c["settings"].get(ax.setting)): c for c in summary.get("comparisons", [])
             if c.get("baseline") == "greedy" and c.get("planner") == "dacmp"}
    points = []
    for v in values:
        point: dict[str, Any] = {"value": v, "label": ax.label(v), "planners": {}}
        for p in PLANNERS:
            seeds_here = per.get((p, v), {})
            d: dict[str, Any] = {"runs": len(seeds_here), "failed": failed.get((p, v), 0)}
            for q in QUANTITIES:
                d[q] = _describe([s[q] for s in seeds_here.values()])
            if has_base:
                base = per.get((p, baseline), {})
                for q in KEPT:
                    common = [s for s in sorted(seeds_here) if s in base and base[s][q] > 0]
                    d[f"kept_{q}"] = _describe([seeds_here[s][q] / base[s][q] for s in common])
            point["planners"][p] = d
        c = diffs.get(json.dumps(v))
        point["difference"] = None if c is None else {
            "paired_seeds": c["paired_seeds"],
            **{q: c["difference"].get(q) for q in ("coverage", "targets_found", "surveillance_ratio_mean")}}
        points.append(point)
    results: dict[str, Any] = {
        "axis": axis, "setting": ax.setting, "title": ax.title, "scenario": scenario.name,
        "surveillance": bool(scenario.planner.surveillance), "seeds": list(seeds), "duration_s": run_s,
        "planners": list(PLANNERS), "targets_total": targets_total, "baseline": baseline if has_base else None,
        "has_baseline": has_base, "runs_total": len(runs),
        "runs_finished": sum(len(v) for v in per.values()), "runs_failed": sum(failed.values()),
        "errors": summary.get("errors", []), "points": points,
    }
    if ax.timed:
        results["crash_at_s"] = crash_at_s
    if ax.needs_uavs:
        results["crash_order"] = crash_candidates(scenario)
    results.update(ax.extras(results, values, PointContext(crash_at_s, burst_loss)))
    return results


def loss_reference(out_dir: Path, results: dict[str, Any]) -> dict[str, Any] | None:
    """For the burst figure: the loss axis's loss-free and same-mean-loss i.i.d. means, when that
    axis ran on the same scenario and duration in the same folder."""
    p = out_dir / "loss" / "results.json"
    if not p.is_file():
        return None
    try:
        loss = json.loads(p.read_text())
        if loss["scenario"] != results["scenario"] or not math.isclose(loss["duration_s"], results["duration_s"]):
            return None
        by = {pt["value"]: pt for pt in loss["points"]}
        ref = {}
        for v, name in ((0.0, "no loss"), (results.get("burst_mean_loss"), f"i.i.d. loss {results.get('burst_mean_loss'):g}")):
            if v in by:
                ref[name] = {pl: {q: (by[v]["planners"][pl].get(q) or {}).get("mean") for q in QUANTITIES}
                             for pl in PLANNERS}
        return ref or None
    except (KeyError, TypeError, ValueError):
        return None


