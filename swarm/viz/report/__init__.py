"""Self-contained HTML reports: one run (:func:`write_report`) and a sweep (:func:`write_sweep_report`).

A report is one ``.html`` file that opens offline: inline CSS, no scripts, every figure a PNG
``data:`` URI, the run's animation (if one was made) a GIF ``data:`` URI or an MP4 base64
``<video>`` source. Nothing is fetched from anywhere. The pages are Jinja2 templates
(``swarm/viz/templates/``: ``base.html.j2``, ``run_report.html.j2``, ``sweep_report.html.j2``,
``macros.html.j2``, ``report.css``), rendered with autoescaping; this module computes what they
show.

A run report holds the scenario summary, the metrics (``metrics.json``), figures — trajectories
over the first-scan map, coverage and certainty over time (``timeseries.csv``), targets found
and watched over time, task load per UAV (seconds in search vs surveillance, stacked, as in the
paper's Fig. 14), radio counters — a fault timeline (schedule windows, crashes, joins and
every UAV's state over time), the violations (which invariant, who, when: :func:`violation_episodes`)
and the handovers (release and arrival times, overlap and gap: :func:`handover_rows`). Figures
use km axes, one colour per UAV and legends that list types instead of UAVs beyond 12 UAVs.
``swarm animate`` refreshes a run folder's report with the animation it made (:func:`refresh_report`).

A sweep report holds a table of every metric that differs between groups (mean ± sd [95%
interval, clipped to the metric's range by the sweep's summary], in readable units:
:func:`swarm.viz.style.metric_unit`; wide tables scroll inside the page), one panel per such metric,
and the paired differences of the sweep's ``comparisons`` written as "first planner − second"
(``summary.json`` stores them as ``other − first``; the report flips them).
"""


from __future__ import annotations

from swarm.viz.report.html import (
    ANIMATION_NAMES,
    MINUS,
    ReportError,
    as_number,
    cell,
    figure_item,
    fmt,
    new_figure,
    render,
)
from swarm.viz.report.run_figures import (
    fig_coverage,
    fig_fault_timeline,
    fig_radio,
    fig_targets,
    fig_task_load,
    fig_trajectories,
    uav_order,
    uav_state_matrix,
    watched_count,
)
from swarm.viz.report.run_report import (
    MAX_VIOLATION_ROWS,
    VIOLATION_MEANINGS,
    build_run_report,
    find_animation,
    handover_rows,
    refresh_report,
    violation_episodes,
    write_report,
)
from swarm.viz.report.sweep_report import (
    BETTER_DIRECTION,
    build_sweep_report,
    constant_metrics,
    fig_sweep,
    paired_differences,
    write_sweep_report,
)

__all__ = [
    "ANIMATION_NAMES",
    "as_number",
    "BETTER_DIRECTION",
    "build_run_report",
    "build_sweep_report",
    "cell",
    "constant_metrics",
    "fig_coverage",
    "fig_fault_timeline",
    "fig_radio",
    "fig_sweep",
    "fig_targets",
    "fig_task_load",
    "fig_trajectories",
    "figure_item",
    "find_animation",
    "fmt",
    "handover_rows",
    "MAX_VIOLATION_ROWS",
    "MINUS",
    "new_figure",
    "paired_differences",
    "refresh_report",
    "render",
    "ReportError",
    "uav_order",
    "uav_state_matrix",
    "violation_episodes",
    "VIOLATION_MEANINGS",
    "watched_count",
    "write_report",
    "write_sweep_report",
]
