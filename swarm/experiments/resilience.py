"""Resilience experiments: how coverage and targets found degrade with radio loss, burst loss,
radio range, crashed UAVs, paused and restarted UAVs, clock skew, missed detections, a jammer
and lying UAVs, DACMP and greedy side by side over seeds.

An *axis* is one kind of degradation and the values to try along it:

* ``loss`` — i.i.d. loss of every frame copy, ``radio.loss_base`` = 0, 0.1, ..., 0.9, and 1 (no
  frame gets through: what the radio is worth at all);
* ``burst`` — Gilbert-Elliott burst loss over the whole run (a ``burst`` fault on every link):
  the mean loss is held at ``burst_loss`` (30%) and the mean burst length (frame copies per
  directed link spent in the bad state, which loses every copy) goes 3, 10, 30, 100, 300. With
  ``loss_good = 0`` and ``loss_bad = 1`` the chain is ``p_exit_bad = 1 / L``,
  ``p_enter_bad = p_exit_bad * m / (1 - m)``; i.i.d. loss at rate ``m`` is the case
  ``L = 1 / (1 - m)``;
* ``range`` — radio range limit ``radio.range_m`` = 2, 5, 10, 20 km and unlimited;
* ``crash`` — 0..5 UAVs crash (fail-stop) at ``crash_at_s`` (300 s); the first ``k`` UAVs of the
  scenario that fly from the start and are not already crashed by it, in scenario order (on
  ``paper-fig11``: B1, ..., Bk, the southernmost first);
* ``pause`` — the first :data:`FAULTED_UAVS` (3) of those UAVs pause (their actors stop, the
  airframes fly on with their last command) at ``crash_at_s`` for 0, 60, 200, 600, 1200 s;
* ``restart`` — 0..5 of them restart at ``crash_at_s``: down for :data:`RESTART_DOWNTIME_S`
  (60 s), then back where they went down with an empty memory;
* ``skew`` — the clocks of the first 3 run ahead by 0, 2, 10, 60, 600 s for the whole run (their
  frames and scans are stamped in the others' future, which receivers ignore);
* ``detect`` — every UAV's probability of detecting a target inside its radius, per tick: 1, 0.1,
  0.03, 0.01, 0.003 (a ``sensor`` fault over the whole run; a target stays tens of ticks inside a
  UAV's circle, so larger probabilities still find every target);
* ``jammer`` — a jammer at the centre of the area that loses every frame to or from a UAV within
  0 (none), 5, 10, 15, 20, 25 km of it, over the whole run;
* ``liar`` — 0..3 of those UAVs are Byzantine for the whole run: each broadcasts one scan record a
  second that it never made (:class:`faults.schedule.Liar` defaults).

Each axis is one sweep (:mod:`swarm.experiments.sweep`): every planner x value x seed runs once, in a process
pool or on any ``concurrent.futures`` executor (a Dask client's); a finished run folder is skipped
next time (resumable), a failing run is recorded in its ``error.json`` and counted, not fatal.
From the runs each axis writes a figure of coverage, targets found (and the surveillance ratio
when the scenario has surveillance; ``paper-fig11`` is search only) and the frame copies delivered
(the radio's throughput, to show the degradation took effect) against the axis value, mean and
Student-t 95% interval of the mean per planner, plus a table and the numbers as JSON. The loss
axis also writes the fraction of its loss-free coverage each planner keeps (per seed: coverage at
loss ``p`` / coverage at loss 0, paired by seed); the range and crash tables have the same
fraction against unlimited range and no crash.

Layout of ``out_dir`` (default ``results/resilience``)::

    table.md, table.csv         every axis that has results, one row per value
    <axis>/runs/<planner>/<setting>/seed-NNN/   the sweep's run folders (see swarm.experiments.sweep)
    <axis>/summary.json, summary.csv            the sweep's statistics (see swarm.experiments.sweep.summarize)
    <axis>/<axis>.png           the figure; loss/loss_kept.png: loss-free coverage kept
    <axis>/table.md, table.csv  this axis's rows
    <axis>/results.json         what the axis measured (figures and tables are made from it)
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from swarm.errors import UsageError
from swarm.experiments.common import (
    executor_for,
    expected_duration,
    md_cell,
    no_data,
    save_figure,
    seeds_from,
    subplots,
    write_json,
    write_text,
)
from swarm.experiments.paper import FIG11_PLANNERS, PLANNER_COLOUR, PLANNER_LABEL
from swarm.experiments.sweep import RunSpec, SweepResult, describe, plan_runs, run_folder, run_sweep
from swarm.scenario import Scenario, apply_overrides, load_scenario

AXES = ("loss", "burst", "range", "crash", "pause", "restart", "skew", "detect", "jammer", "liar", "battery")
# Axes whose values count UAVs, taken from crash_candidates in order.
COUNT_AXES = ("crash", "restart", "liar")
PLANNERS = FIG11_PLANNERS  # greedy first: the sweep's paired comparisons are "dacmp - greedy"
DEFAULT_SCENARIO = "paper-fig11"
DEFAULT_SEEDS = 10
DEFAULT_CRASH_AT_S = 300.0
DEFAULT_BURST_LOSS = 0.3
MAX_DEFAULT_CRASHES = 5
# The pause and skew axes degrade this many UAVs (half of paper-fig11's six).
FAULTED_UAVS = 3
RESTART_DOWNTIME_S = 60.0
# The check of issue 4: with 30% i.i.d. loss DACMP keeps at least 90% of its loss-free coverage.
TARGET_LOSS = 0.3
TARGET_KEPT = 0.9

DEFAULT_VALUES: dict[str, tuple] = {
    "loss": tuple(round(0.1 * i, 1) for i in range(11)),  # 1.0: no frame gets through (no radio)
    "burst": (3.0, 10.0, 30.0, 100.0, 300.0),
    "range": (2.0, 5.0, 10.0, 20.0, None),  # km; None = unlimited
    "crash": tuple(range(MAX_DEFAULT_CRASHES + 1)),  # capped to the UAVs the scenario has
    "pause": (0.0, 60.0, 200.0, 600.0, 1200.0),  # s
    "restart": tuple(range(MAX_DEFAULT_CRASHES + 1)),
    "skew": (0.0, 2.0, 10.0, 60.0, 600.0),  # s ahead
    # per tick: a target stays inside a detection circle for tens of ticks, so only small
    # probabilities miss it altogether (0.2 a tick finds as many as 1 does on paper-fig11)
    "detect": (1.0, 0.1, 0.03, 0.01, 0.003),
    "jammer": (0.0, 5.0, 10.0, 15.0, 20.0, 25.0),  # km; 0 = no jammer
    "liar": (0, 1, 2, 3),
    # (issue 26) battery capacity as a fraction of the energy to fly the whole run at full speed;
    # 0 = no budget (the scenario as it is). Below 1 UAVs return to base, land and relaunch.
    "battery": (0.0, 1.0, 0.5, 0.35, 0.25),
}
SETTING = {"loss": "radio.loss_base", "burst": "burst.mean_frames", "range": "radio.range_km",
           "crash": "crashed_uavs", "pause": "pause.length_s", "restart": "restarted_uavs",
           "skew": "clock_skew.offset_s", "detect": "sensor.p_detect", "jammer": "jammer.radius_km",
           "liar": "liars", "battery": "battery.capacity_frac"}
# The undegraded value of each axis; burst has none.
BASELINE = {"loss": 0.0, "range": None, "crash": 0, "pause": 0.0, "restart": 0, "skew": 0.0, "detect": 1.0,
            "jammer": 0.0, "liar": 0, "battery": 0.0}
# Quantities per run (from metrics.json): delivered = radio.delivered (frame copies decoded by
# receivers; the radio's throughput, which range and crashes cut too), delivered_fraction =
# radio.delivered / radio.sent (copies offered to UAVs in range: what loss cuts);
# separation_violations = violations.separation (UAVs that cannot hear each other do not avoid
# each other).
QUANTITIES = ("coverage", "targets_found", "surveillance_ratio_mean", "certainty", "delivered", "delivered_fraction",
              "separation_violations")
KEPT = ("coverage", "targets_found")

ProgressFn = Callable[[str, str, float, float, str], None]
"""``progress(key, description, done, total, info)``: one bar per ``key`` (as ``swarm.experiments.paper``)."""


@dataclass
class AxisReport:
    axis: str
    out_dir: Path
    sweep: SweepResult
    figures: list[Path] = field(default_factory=list)
    results: dict = field(default_factory=dict)

    @property
    def failed(self) -> list[dict]:
        return self.sweep.failed


@dataclass
class ResilienceReport:
    out_dir: Path
    axes: list[AxisReport]
    table_md: Path
    table_csv: Path


# --- axis values ---------------------------------------------------------------------------------

def value_label(axis: str, v: Any) -> str:
    """How a value is written in figures and tables."""
    if axis == "range":
        return "unlimited" if v is None else f"{v:g} km"
    if axis == "burst":
        return f"{v:g}"
    if axis in COUNT_AXES:
        return str(int(v))
    if axis == "jammer":
        return "none" if not v else f"{v:g} km"
    if axis in ("pause", "skew"):
        return f"{v:g} s"
    return f"{v:g}"


AXIS_TITLE = {
    "loss": "i.i.d. frame loss rate (radio.loss_base)",
    "burst": "mean burst length (frame copies per link, Gilbert-Elliott)",
    "range": "radio range",
    "crash": "UAVs crashed",
    "pause": f"pause length of {FAULTED_UAVS} UAVs",
    "restart": f"UAVs restarted ({RESTART_DOWNTIME_S:g} s down, memory lost)",
    "skew": f"clock ahead on {FAULTED_UAVS} UAVs",
    "detect": "probability of detection per tick (all UAVs)",
    "jammer": "jammer radius at the centre of the area",
    "liar": "lying UAVs (fake scan records)",
    "battery": "battery capacity (fraction of the run's energy at full speed; 0: none)",
}


def parse_values(axis: str, text: str) -> list:
    """``--values`` for one axis: comma-separated; loss rates in [0, 1], burst lengths >= 1 frame,
    ranges in km > 0 or ``inf`` / ``unlimited``, crash counts >= 0."""
    if axis not in AXES:
        raise UsageError(f"unknown axis {axis!r}; expected one of {', '.join(AXES)}")
    parts = [p.strip() for p in text.split(",") if p.strip()]
    if not parts:
        raise UsageError(f"--values {text!r}: expected a comma-separated list of values")
    out: list[float | None] = []
    for p in parts:
        if axis == "range" and p.lower() in ("inf", "unlimited", "none"):
            out.append(None)
            continue
        try:
            v = int(p) if axis in COUNT_AXES else float(p)
        except ValueError:
            kind = "whole numbers" if axis in COUNT_AXES else "numbers"
            raise UsageError(f"--values {text!r}: {p!r} is not a number; the {axis} axis takes {kind}") from None
        out.append(v)
    return _check_values(axis, out)


def _check_values(axis: str, values: Sequence) -> list:
    values = list(values)
    if not values:
        raise UsageError(f"the {axis} axis needs at least one value")
    expects = {"loss": ("a loss rate from 0 to 1", lambda v: v is not None and 0.0 <= v <= 1.0),
              "burst": ("a mean burst length >= 1 frame", lambda v: v is not None and math.isfinite(v) and v >= 1.0),
              "range": ("a range in km > 0, or inf for unlimited", lambda v: v is None or (v > 0 and math.isfinite(v))),
              "crash": ("a number of UAVs >= 0", lambda v: v is not None and float(v).is_integer() and v >= 0),
              "pause": ("a pause length in s >= 0", lambda v: v is not None and math.isfinite(v) and v >= 0),
              "skew": ("a clock offset in s (>= -1e6 and <= 1e6)", lambda v: v is not None and -1e6 <= v <= 1e6),
              "detect": ("a probability of detection from 0 to 1", lambda v: v is not None and 0.0 <= v <= 1.0),
              "jammer": ("a jammer radius in km >= 0 (0: none)", lambda v: v is not None and math.isfinite(v) and v >= 0),
              "battery": ("a capacity as a fraction of the run's energy at full speed, >= 0 (0: no budget)",
                          lambda v: v is not None and math.isfinite(v) and v >= 0),
              }
    count = ("a number of UAVs >= 0", lambda v: v is not None and float(v).is_integer() and v >= 0)
    expect = expects.get(axis, count)  # restart, liar: counts like crash
    for v in values:
        try:
            ok = expect[1](v)
        except TypeError:
            ok = False
        if not ok:
            raise UsageError(f"{axis} value {v!r}: expected {expect[0]}")
    if len(set(values)) != len(values):
        raise UsageError(f"{axis} values {values}: a value is repeated")
    return [int(v) for v in values] if axis in COUNT_AXES else values


def crash_candidates(scenario: Scenario) -> list[str]:
    """UAVs the crash axis may crash, in the order it crashes them: those that fly from the start
    (no ``join_s``, no join fault) and that the scenario does not crash itself, in scenario order."""
    joined = {f.uav for f in scenario.faults if f.kind == "join"}
    crashed = {f.uav for f in scenario.faults if f.kind == "crash"}
    return [name for name, u in zip(scenario.uav_names, scenario.uavs) if not u.join_s and name not in joined | crashed]


def battery_point(scenario: Scenario, frac: float, duration_s: float | None = None) -> dict:
    """(issue 26) The overrides giving each UAV type a battery of ``frac`` times the energy it
    would need to fly the whole run at full speed (default power curve, ``[endurance]``), with a
    base at the mean of the launch points; the scenario's own ``[endurance]`` scaled instead if
    it has one; ``frac = 0``: no budget."""
    from swarm.scenario.mission import EnergySpec, min_power_speed, power_w

    if not frac:
        return {"endurance": None} if scenario.endurance is not None else {}
    run_s = duration_s or scenario.duration_s
    if scenario.endurance is not None:
        e = scenario.endurance.model_dump()
        for spec in e["types"].values():
            spec["capacity_wh"] *= frac
        return {"endurance": e}
    types = {}
    for name in sorted({u.type for u in scenario.uavs}):
        t = scenario.uav_types[name]
        spec = EnergySpec(capacity_wh=1.0)
        full = power_w(spec, min_power_speed(spec, t.speed_min, t.speed_max), t.speed_max) * run_s / 3600.0
        types[name] = {"capacity_wh": frac * full}
    xs = [u.x_m for u in scenario.uavs]
    ys = [u.y_m for u in scenario.uavs]
    return {"endurance": {"x_m": sum(xs) / len(xs), "y_m": sum(ys) / len(ys), "types": types, "turnaround_s": 300.0}}


def burst_fault(mean_frames: float, mean_loss: float) -> dict:
    """A whole-run Gilbert-Elliott fault on every link with stationary loss ``mean_loss`` and mean
    bad-state sojourn ``mean_frames`` copies (every copy in the bad state is lost)."""
    p_exit = 1.0 / mean_frames
    p_enter = p_exit * mean_loss / (1.0 - mean_loss)
    if p_enter > 1.0:
        raise UsageError(f"burst value {mean_frames:g}: at {mean_loss:g} mean loss the mean burst length must be "
                         f">= {mean_loss / (1 - mean_loss):g} frames")
    return {"kind": "burst", "start_s": 0.0, "end_s": None, "p_enter_bad": p_enter, "p_exit_bad": p_exit,
            "loss_good": 0.0, "loss_bad": 1.0}


def _point(axis: str, scenario: Scenario, v: Any, *, crash_at_s: float, burst_loss: float
           ) -> tuple[tuple[tuple[str, Any], ...], dict]:
    """(the sweep's settings for this value, the scenario overrides that make it)."""
    faults = [f for f in scenario.to_dict()["faults"]]
    if axis == "loss":
        return ((SETTING[axis], v),), {"radio.loss_base": v}
    if axis == "range":
        return ((SETTING[axis], v),), {"radio.range_m": None if v is None else v * 1000.0}
    if axis == "burst":
        return (((SETTING[axis], v), ("burst.mean_loss", burst_loss)),
                {"faults": faults + [burst_fault(v, burst_loss)]})
    if axis == "battery":  # (issue 26)
        return ((SETTING[axis], v),), battery_point(scenario, v)
    if axis == "crash":
        names = crash_candidates(scenario)[:v]
        return (((SETTING[axis], v), ("crash_at_s", crash_at_s)),
                {"faults": faults + [{"kind": "crash", "uav": n, "at_s": crash_at_s} for n in names]} if names else {})
    new = _fault_point(axis, scenario, v, crash_at_s)
    settings: tuple[tuple[str, Any], ...] = ((SETTING[axis], v),)
    if axis in ("pause", "restart"):
        settings += (("at_s", crash_at_s),)
    return settings, ({"faults": faults + new} if new else {})


def _fault_point(axis: str, scenario: Scenario, v: Any, at_s: float) -> list[dict]:
    """The faults (as ``[[faults]]`` tables) that make value ``v`` of a fault axis."""
    names = crash_candidates(scenario)
    if axis == "pause":
        return [{"kind": "pause", "uav": n, "start_s": at_s, "end_s": at_s + v} for n in names[:FAULTED_UAVS]] if v else []
    if axis == "restart":
        return [{"kind": "restart", "uav": n, "at_s": at_s, "downtime_s": RESTART_DOWNTIME_S} for n in names[:v]]
    if axis == "skew":
        return [{"kind": "clock_skew", "uav": n, "offset_s": v} for n in names[:FAULTED_UAVS]] if v else []
    if axis == "detect":
        return [{"kind": "sensor", "p_detect": v}] if v < 1.0 else []
    if axis == "jammer":
        a = scenario.area
        return [{"kind": "jammer", "x_m": a.width_m / 2, "y_m": a.height_m / 2, "radius_m": v * 1000.0}] if v else []
    assert axis == "liar"
    return [{"kind": "liar", "uav": n} for n in names[:v]]


def plan_axis(axis: str, scenario: Scenario, *, values: Sequence | None = None, seeds: Sequence[int],
              planners: Sequence[str] = PLANNERS, duration_s: float | None = None,
              crash_at_s: float = DEFAULT_CRASH_AT_S, burst_loss: float = DEFAULT_BURST_LOSS) -> list[RunSpec]:
    """The sweep of one axis: every planner x value x seed, in value order. Folders are
    ``runs/<planner>/<settings>/seed-NNN`` as in :func:`swarm.experiments.sweep.plan_runs`."""
    if axis not in AXES:
        raise UsageError(f"unknown axis {axis!r}; expected one of {', '.join(AXES)}")
    run_s = expected_duration(scenario, duration_s)
    if axis in (*COUNT_AXES, "pause", "skew"):
        n = len(crash_candidates(scenario))
        if axis in COUNT_AXES:
            if values is None:
                values = [k for k in DEFAULT_VALUES[axis] if k <= max(n - 1, 0)]
            too_many = [k for k in values if k > n]
            if too_many:
                raise UsageError(f"{axis} value {max(too_many)}: {scenario.name} has {n} UAVs that fly from the start "
                                 f"and do not crash ({', '.join(crash_candidates(scenario))})")
        elif n == 0:
            raise UsageError(f"the {axis} axis needs UAVs that fly from the start; {scenario.name} has none")
    if axis in ("crash", "restart", "pause") and not 0.0 <= crash_at_s < run_s:
        raise UsageError(f"--crash-at {crash_at_s:g}: expected a time from 0 to before the end of the run "
                         f"({run_s:g} s)")
    if axis == "burst" and not 0.0 < burst_loss < 1.0:
        raise UsageError(f"--burst-loss {burst_loss:g}: expected a mean loss rate between 0 and 1 (exclusive)")
    values = _check_values(axis, DEFAULT_VALUES[axis] if values is None else values)
    runs = []
    for v in values:
        settings, overrides = _point(axis, scenario, v, crash_at_s=crash_at_s, burst_loss=burst_loss)
        sc = apply_overrides(scenario, overrides) if overrides else scenario
        for spec in plan_runs(sc, seeds=seeds, planners=planners, duration_s=duration_s):
            runs.append(replace(spec, settings=settings, folder=run_folder(spec.planner, settings, spec.seed)))
    return runs


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


def _plan(axis: str, out_dir: str | Path, *, scenario: str | os.PathLike = DEFAULT_SCENARIO,
          seeds: int | Sequence[int] = DEFAULT_SEEDS, values: Sequence | None = None, duration_s: float | None = None,
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


def run_axis(axis: str, out_dir: str | Path = "results/resilience", *, scenario: str | os.PathLike = DEFAULT_SCENARIO,
             seeds: int | Sequence[int] = DEFAULT_SEEDS, values: Sequence | None = None,
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
    rep.figures.append(axis_figure(results, axis_dir / f"{axis}.png", reference=_loss_reference(Path(out_dir), results)))
    if axis == "loss":
        rep.figures.append(kept_figure(results, axis_dir / "loss_kept.png"))
    write_axis_table(results, axis_dir)
    return rep


def run_resilience(axis: str, out_dir: str | Path = "results/resilience", *, values: Sequence | None = None,
                   executor: Executor | None = None, workers: int | None = None, **kw: Any) -> ResilienceReport:
    """One axis or ``"all"`` (loss, burst, range, crash in that order), then the top-level table.
    ``values`` only with one axis. Other keywords go to :func:`run_axis`."""
    if axis not in (*AXES, "all"):
        raise UsageError(f"unknown axis {axis!r}; expected one of {', '.join(AXES)}, all")
    if axis == "all" and values is not None:
        raise UsageError("--values needs one axis, not all")
    out = Path(out_dir)
    names = AXES if axis == "all" else (axis,)
    for name in names:  # a mistake in any axis is reported before the first run
        _plan(name, out, values=values, **kw)
    reports = []
    with executor_for(executor, workers) as ex:
        for name in names:
            reports.append(run_axis(name, out, values=values, executor=ex, **kw))
    md, csv_path = write_table(out)
    return ResilienceReport(out, reports, md, csv_path)


# --- measuring -----------------------------------------------------------------------------------

def _run_quantities(metrics: dict) -> dict[str, float]:
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


def _describe(vals: Sequence[float]) -> dict | None:
    vals = [v for v in vals if math.isfinite(v)]
    return describe(vals) if vals else None


def measure(axis: str, axis_dir: Path, runs: Sequence[RunSpec], summary: dict, *, scenario: Scenario,
            seeds: Sequence[int], run_s: float, crash_at_s: float, burst_loss: float) -> dict:
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
    values = list(dict.fromkeys(s.settings[0][1] for s in runs))
    baseline = BASELINE.get(axis, "no baseline")
    has_base = baseline in values
    diffs = {json.dumps(c["settings"].get(SETTING[axis])): c for c in summary.get("comparisons", [])
             if c.get("baseline") == "greedy" and c.get("planner") == "dacmp"}
    points = []
    for v in values:
        point: dict[str, Any] = {"value": v, "label": value_label(axis, v), "planners": {}}
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
        "axis": axis, "setting": SETTING[axis], "title": AXIS_TITLE[axis], "scenario": scenario.name,
        "surveillance": bool(scenario.planner.surveillance), "seeds": list(seeds), "duration_s": run_s,
        "planners": list(PLANNERS), "targets_total": targets_total, "baseline": baseline if has_base else None,
        "has_baseline": has_base, "runs_total": len(runs),
        "runs_finished": sum(len(v) for v in per.values()), "runs_failed": sum(failed.values()),
        "errors": summary.get("errors", []), "points": points,
    }
    if axis in ("crash", "restart", "pause"):
        results["crash_at_s"] = crash_at_s
    if axis in (*COUNT_AXES, "pause", "skew"):
        results["crash_order"] = crash_candidates(scenario)
    if axis == "burst":
        results["burst_mean_loss"] = burst_loss
        results["burst_chain"] = {value_label(axis, v): burst_fault(v, burst_loss) for v in values}
    if axis == "loss":
        results["target"] = _target(results)
    return results


def _target(results: dict) -> dict:
    """The issue's check: DACMP keeps >= 90% of its loss-free coverage at 30% i.i.d. loss."""
    point = next((p for p in results["points"] if p["value"] == TARGET_LOSS), None)
    out: dict[str, Any] = {"loss": TARGET_LOSS, "kept_at_least": TARGET_KEPT, "available": False}
    if point is None or not results["has_baseline"]:
        return out
    base = next(p for p in results["points"] if p["value"] == results["baseline"])
    for p in PLANNERS:
        k = point["planners"][p].get("kept_coverage")
        b = base["planners"][p]["coverage"]
        a = point["planners"][p]["coverage"]
        out[p] = {"kept_coverage": k, "coverage_loss_free": b, "coverage_at_loss": a,
                  "ratio_of_means": a["mean"] / b["mean"] if a and b and b["mean"] > 0 else None}
    k = out["dacmp"]["kept_coverage"]
    if k is not None:
        out["available"] = True
        out["met"] = k["mean"] >= TARGET_KEPT
        out["met_with_95_confidence"] = k["ci95"][0] >= TARGET_KEPT if k["n"] > 1 else False
    return out


def _loss_reference(out_dir: Path, results: dict) -> dict | None:
    """For the burst figure: the loss axis's loss-free and i.i.d. 30% means, when that axis ran
    on the same scenario and duration in the same folder."""
    if results["axis"] != "burst":
        return None
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


# --- figures -------------------------------------------------------------------------------------

def _panels(results: dict) -> list[tuple[str, str, tuple[float, float] | None]]:
    tt = results.get("targets_total") or None
    panels = [("coverage", "coverage at end", (0.0, 1.0)),
              ("targets_found", f"targets found at end (of {tt})" if tt else "targets found at end",
               (0.0, float(tt)) if tt else None)]
    if results["surveillance"]:
        panels.append(("surveillance_ratio_mean", "surveillance ratio (mean over found targets)", (0.0, 1.0)))
    panels.append(("delivered", "frame copies delivered (all links)", (0.0, math.inf)))
    return panels


def _errorbars(ax, results: dict, quantity: str, x: np.ndarray, bounds: tuple[float, float] | None = None,
               offset: float = 0.06) -> bool:
    """Mean and 95% interval per value, one colour per planner, slightly apart; ``bounds``: the
    range the quantity can take (the interval of a few seeds is clipped to it)."""
    lo_b, hi_b = bounds if bounds is not None else (-math.inf, math.inf)
    any_data = False
    for i, p in enumerate(PLANNERS):
        means, lo, hi = [], [], []
        for pt in results["points"]:
            d = pt["planners"][p].get(quantity)
            m = d["mean"] if d else math.nan
            means.append(m)
            lo.append(m - max(d["ci95"][0], lo_b) if d else math.nan)
            hi.append(min(d["ci95"][1], hi_b) - m if d else math.nan)
        if not any(math.isfinite(m) for m in means):
            continue
        any_data = True
        n = [pt["planners"][p]["runs"] for pt in results["points"]]
        nlab = f"{min(n)}" if min(n) == max(n) else f"{min(n)}-{max(n)}"
        ax.errorbar(x + (i - (len(PLANNERS) - 1) / 2) * 2 * offset, means, yerr=[lo, hi], fmt="-o", ms=4,
                    capsize=4, lw=1.4, color=PLANNER_COLOUR[p],
                    label=f"{PLANNER_LABEL[p]} (mean, 95% CI, {nlab} seed{'' if nlab == '1' else 's'})")
    return any_data


def _run_note(results: dict) -> str:
    extra = ""
    axis = results["axis"]
    order = results.get("crash_order", [])
    if axis == "crash":
        extra = f"; crash at {results['crash_at_s']:g} s, in order {', '.join(order)}"
    elif axis == "restart":
        extra = f"; restart at {results['crash_at_s']:g} s, {RESTART_DOWNTIME_S:g} s down, in order {', '.join(order)}"
    elif axis == "pause":
        extra = f"; {', '.join(order[:FAULTED_UAVS])} paused from {results['crash_at_s']:g} s"
    elif axis == "skew":
        extra = f"; clocks of {', '.join(order[:FAULTED_UAVS])} ahead"
    elif axis == "liar":
        extra = f"; liars in order {', '.join(order)}, one fake scan a second each"
    if results["axis"] == "burst":
        extra = f"; mean loss {results['burst_mean_loss']:g}, bad state loses every copy"
    fails = f"; {results['runs_failed']} runs failed" if results["runs_failed"] else ""
    search_only = "" if results["surveillance"] else "; search only (no surveillance ratio)"
    return f"{results['scenario']}, {results['duration_s']:g} s runs{extra}{search_only}{fails}"


def axis_figure(results: dict, path: Path, reference: dict | None = None) -> Path:
    """Coverage, targets found (surveillance ratio when the scenario has surveillance) and the
    frame copies delivered against the axis value, DACMP and greedy side by side."""
    panels = _panels(results)
    fig, axes = subplots(1, len(panels), figsize=(4.6 * len(panels), 4.4))
    x = np.arange(len(results["points"]), dtype=float)
    labels = [pt["label"] for pt in results["points"]]
    for ax, (q, ylabel, bounds) in zip(axes, panels):
        if not _errorbars(ax, results, q, x, bounds):
            no_data(ax)
        refs = reference or {}
        for name, ls in zip(refs, (":", "--")):
            for p in PLANNERS:
                v = refs[name][p].get(q)
                if v is not None and math.isfinite(v):
                    ax.axhline(v, color=PLANNER_COLOUR[p], ls=ls, lw=1.0, alpha=0.8,
                               label=f"{PLANNER_LABEL[p]}, {name} (loss axis)")
        ax.set_xticks(x, labels, rotation=0 if sum(len(t) for t in labels) <= 40 else 45)
        ax.set_xlabel(AXIS_TITLE[results["axis"]], fontsize=8)
        ax.set_ylabel(ylabel)
        if bounds is not None:
            ax.set_ylim(bounds[0], bounds[1] * 1.04 if math.isfinite(bounds[1]) else None)
        ax.grid(alpha=0.3)
        ax.set_title(ylabel, fontsize=10)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(f"Resilience: {AXIS_TITLE[results['axis']]}\n{_run_note(results)}", fontsize=10)
    return save_figure(fig, path)


def kept_figure(results: dict, path: Path) -> Path:
    """Fraction of the loss-free coverage each planner keeps (paired by seed) against the loss
    rate, and at 30% loss as bars, with the 90% target."""
    fig, (ax, bx) = subplots(1, 2, figsize=(11, 4.4), gridspec_kw={"width_ratios": [3, 2]})
    pts = results["points"]
    x = np.arange(len(pts), dtype=float)
    if results["has_baseline"] and _errorbars(ax, results, "kept_coverage", x):
        ax.axhline(TARGET_KEPT, color="black", ls="--", lw=1.0, label=f"target: {TARGET_KEPT:.0%} kept at "
                                                                      f"{TARGET_LOSS:g} loss (DACMP)")
        i = next((k for k, pt in enumerate(pts) if pt["value"] == TARGET_LOSS), None)
        if i is not None:
            ax.axvline(x[i], color="grey", lw=0.8, alpha=0.6)
        ax.legend(fontsize=7, loc="lower left")
    else:
        no_data(ax, "needs finished runs at loss 0")
    ax.set_xticks(x, [pt["label"] for pt in pts])
    ax.set_xlabel(AXIS_TITLE["loss"], fontsize=8)
    ax.set_ylabel("coverage / loss-free coverage (same seed)")
    ax.set_ylim(0, 1.1)
    ax.grid(alpha=0.3)
    ax.set_title("share of loss-free coverage kept", fontsize=10)
    t = results.get("target", {})
    if t.get("available"):
        means, errs = [], []
        for p in PLANNERS:
            k = t[p]["kept_coverage"] or {"mean": math.nan, "ci95": [math.nan, math.nan], "n": 0}
            means.append(k["mean"])
            errs.append([k["mean"] - k["ci95"][0], k["ci95"][1] - k["mean"]])
        xb = np.arange(len(PLANNERS))
        bx.bar(xb, means, 0.6, yerr=np.array(errs).T, capsize=6, color=[PLANNER_COLOUR[p] for p in PLANNERS],
               alpha=0.8)
        for i, p in enumerate(PLANNERS):
            k = t[p]["kept_coverage"]
            if k:
                bx.text(xb[i], k["ci95"][1] + 0.02,
                        f"{k['mean']:.3f}\n[{k['ci95'][0]:.3f}, {k['ci95'][1]:.3f}]\nn={k['n']}",
                        ha="center", va="bottom", fontsize=7)
        bx.axhline(TARGET_KEPT, color="black", ls="--", lw=1.0, label=f"target {TARGET_KEPT:.0%} (DACMP)")
        bx.set_xticks(xb, [PLANNER_LABEL[p] for p in PLANNERS])
        bx.legend(fontsize=7, loc="lower center")
    else:
        no_data(bx, f"needs finished runs at loss 0 and {TARGET_LOSS:g}")
    bx.set_ylim(0, 1.35)
    bx.set_ylabel("coverage kept (mean, 95% CI)")
    bx.grid(axis="y", alpha=0.3)
    bx.set_title(f"at {TARGET_LOSS:.0%} i.i.d. loss", fontsize=10)
    fig.suptitle(f"Loss-free coverage kept under i.i.d. loss\n{_run_note(results)}", fontsize=10)
    return save_figure(fig, path)


# --- tables --------------------------------------------------------------------------------------

def _ci(d: dict | None, digits: int, signed: bool = False) -> str:
    if not d or not d.get("n"):
        return "-"
    s = "+" if signed else ""
    if d["n"] < 2:
        return f"{d['mean']:{s}.{digits}f} (1 seed)"
    return f"{d['mean']:{s}.{digits}f} [{d['ci95'][0]:{s}.{digits}f}, {d['ci95'][1]:{s}.{digits}f}]"


def _delivered(d: dict) -> str:
    n, f = d.get("delivered"), d.get("delivered_fraction")
    if not n or not f:
        return "-"
    return f"{n['mean'] / 1000:.1f}k ({f['mean']:.3f})"


def _columns(results: dict) -> list[tuple[str, Callable[[dict], str]]]:
    # A column's cell of one point (pt) is a function of the point; these make them, each bound
    # to its own planner and quantity.
    def planner_ci(p: str, q: str, digits: int) -> Callable[[dict], str]:
        return lambda pt: _ci(pt["planners"][p][q], digits)

    def difference_ci(q: str, digits: int) -> Callable[[dict], str]:
        return lambda pt: _ci((pt["difference"] or {}).get(q), digits, signed=True)

    def kept_ci(p: str) -> Callable[[dict], str]:
        return lambda pt: _ci(pt["planners"][p].get("kept_coverage"), 3)

    def delivered(p: str) -> Callable[[dict], str]:
        return lambda pt: _delivered(pt["planners"][p])

    cols: list[tuple[str, Callable[[dict], str]]] = []
    qs = [("coverage", "coverage", 3), ("targets_found", "targets found", 2)]
    if results["surveillance"]:
        qs.append(("surveillance_ratio_mean", "surveillance ratio", 3))
    for q, label, digits in qs:
        for p in reversed(PLANNERS):  # DACMP first
            cols.append((f"{label}, {PLANNER_LABEL[p]}", planner_ci(p, q, digits)))
        cols.append((f"{label}, DACMP − greedy (paired)", difference_ci(q, digits)))
    if results["has_baseline"]:
        for p in reversed(PLANNERS):
            cols.append((f"coverage kept vs {value_label(results['axis'], results['baseline'])}, {PLANNER_LABEL[p]}",
                         kept_ci(p)))
    for p in reversed(PLANNERS):
        cols.append((f"frames delivered (share of sent), {PLANNER_LABEL[p]}", delivered(p)))
    cols.append(("runs (DACMP / greedy, failed)", lambda pt: " / ".join(
        str(pt["planners"][p]["runs"]) for p in reversed(PLANNERS))
        + (f", {sum(pt['planners'][p]['failed'] for p in PLANNERS)} failed"
           if any(pt["planners"][p]["failed"] for p in PLANNERS) else "")))
    return cols


def _axis_md(results: dict, heading: str = "##") -> list[str]:
    cols = _columns(results)
    seeds = results["seeds"]
    lines = [f"{heading} {results['axis']}: {AXIS_TITLE[results['axis']]}", "",
             f"{_run_note(results)}; seeds {seeds[0]}..{seeds[-1]} ({len(seeds)}); mean [95% CI of the mean].", ""]
    if results["axis"] == "loss" and results.get("target", {}).get("available"):
        t = results["target"]
        k = t["dacmp"]["kept_coverage"]
        lines += [f"Target (issue 4): DACMP keeps >= {TARGET_KEPT:.0%} of its loss-free coverage at "
                  f"{TARGET_LOSS:g} i.i.d. loss: **{'met' if t['met'] else 'not met'}** "
                  f"(kept {_ci(k, 3)}, {k['n']} paired seeds).", ""]
    lines.append("| " + " | ".join([results["title"], *(c for c, _ in cols)]) + " |")
    lines.append("|" + "---|" * (len(cols) + 1))
    for pt in results["points"]:
        lines.append("| " + " | ".join(md_cell(x) for x in [pt["label"], *(f(pt) for _, f in cols)]) + " |")
    return lines


def _csv_rows(results: dict) -> list[dict]:
    rows = []
    for pt in results["points"]:
        for p in PLANNERS:
            for q in (*QUANTITIES, *(f"kept_{k}" for k in KEPT)):
                d = pt["planners"][p].get(q)
                if d:
                    rows.append({"axis": results["axis"], "setting": results["setting"], "value": pt["label"],
                                 "planner": p, "quantity": q, "n": d["n"], "mean": d["mean"], "sd": d["sd"],
                                 "ci95_low": d["ci95"][0], "ci95_high": d["ci95"][1]})
        for q, d in (pt["difference"] or {}).items():
            if q != "paired_seeds" and d:
                rows.append({"axis": results["axis"], "setting": results["setting"], "value": pt["label"],
                             "planner": "dacmp-greedy", "quantity": q, "n": d["n"], "mean": d["mean"], "sd": d["sd"],
                             "ci95_low": d["ci95"][0], "ci95_high": d["ci95"][1]})
    return rows


CSV_COLUMNS = ["axis", "setting", "value", "planner", "quantity", "n", "mean", "sd", "ci95_low", "ci95_high"]


def _csv_text(rows: list[dict]) -> str:
    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=CSV_COLUMNS)
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def write_axis_table(results: dict, axis_dir: Path) -> tuple[Path, Path]:
    md = write_text(axis_dir / "table.md", "\n".join(_axis_md(results, "#")) + "\n")
    return md, write_text(axis_dir / "table.csv", _csv_text(_csv_rows(results)))


def write_table(out_dir: str | Path) -> tuple[Path, Path]:
    """Rewrite ``table.md`` / ``table.csv`` in ``out_dir`` from every axis's ``results.json``."""
    out = Path(out_dir)
    lines = ["# Resilience: DACMP and greedy under radio loss, burst loss, limited range, crashes, pauses, "
             "restarts, clock skew, missed detections, a jammer and liars", "",
             "Written by `swarm resilience` from the results in this folder: per axis value, the mean over seeds",
             "and the Student-t 95% interval of the mean; differences and kept fractions are paired by seed.", ""]
    rows = []
    for axis in AXES:
        p = out / axis / "results.json"
        if not p.is_file():
            lines += [f"## {axis}: {AXIS_TITLE[axis]}", "", "not run", ""]
            continue
        try:
            res = json.loads(p.read_text())
            lines += _axis_md(res) + [""]
            rows += _csv_rows(res)
        except (KeyError, TypeError, ValueError, IndexError):
            lines += [f"## {axis}", "", f"unreadable {axis}/results.json: rerun `swarm resilience {axis}`", ""]
    return (write_text(out / "table.md", "\n".join(lines)), write_text(out / "table.csv", _csv_text(rows)))
