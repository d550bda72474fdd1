"""Resilience experiments: how coverage and targets found degrade with radio loss, burst loss,
radio range, crashed UAVs, paused and restarted UAVs, clock skew, missed detections, a jammer
lying UAVs and smaller batteries, DACMP and greedy side by side over seeds.

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
  second that it never made (:class:`faults.schedule.Liar` defaults);
* ``battery`` — each type's battery as a fraction (1, 0.5, 0.35, 0.25) of the energy to fly the
  whole run at full speed; 0 = no budget.

Each axis is one :class:`~swarm.experiments.resilience.axes.Axis` record in
:mod:`~swarm.experiments.resilience.axes` (values, setting, baseline, title, what a value must be,
how a value becomes scenario changes); adding an axis is adding one record. The package, like
:mod:`swarm.experiments.paper`: ``axes`` (the records), ``runs`` (planning, running, measuring),
``figures``, ``tables``.

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

from typing import Any

from swarm.experiments.resilience.axes import (
    AXES,
    AXIS_LIST,
    BASELINE,
    Axis,
    PointContext,
    battery_point,
    burst_fault,
    crash_candidates,
)

# The rest is imported when first used (PEP 562), so that the command line can read the axes'
# records to build its help without loading the runs' plotting and sweeping.
_LAZY = {"AxisReport": "runs", "ResilienceReport": "runs", "PLANNERS": "runs", "measure": "runs",
         "parse_values": "runs", "plan_axis": "runs", "run_axis": "runs", "run_resilience": "runs",
         "write_table": "tables"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"swarm.experiments.resilience.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "AXES",
    "AXIS_LIST",
    "BASELINE",
    "PLANNERS",
    "Axis",
    "AxisReport",
    "PointContext",
    "ResilienceReport",
    "battery_point",
    "burst_fault",
    "crash_candidates",
    "measure",
    "parse_values",
    "plan_axis",
    "run_axis",
    "run_resilience",
    "write_table",
]
