"""The paper's experiments (section 4): runs, figures, and a table of ours next to the paper's.

One function per experiment (:mod:`.runs`; what they measure: :mod:`.measures`; figures:
:mod:`.figures`; the table: :mod:`.table`), and :func:`run_paper` for one or all of them (the Python form of
``swarm paper``):

* ``fig11`` — ``paper-fig11``, DACMP against greedy over seeds (Fig. 10-11), with the reference
  planners (lawnmower, formation, Lévy; not in the paper) beside them: coverage and targets
  found over time (mean, 95% band, min-max spread) and final values with 95% intervals;
* ``case1`` — one ``paper-case1`` run (Fig. 12): distance of every UAV to target 1 over time with
  the handover and mode changes marked, and the trajectories;
* ``case2`` — one ``paper-case2`` run (Fig. 13-15): trajectories with threats, task loads per UAV
  (mode timeline and seconds per mode), coverage over time; optionally statistics over seeds;
* ``case3`` — ``paper-case3`` against ``paper-case2`` over the same seeds (Fig. 18): mean coverage
  with 95% bands, the join time marked, and the paired difference.

Multi-seed parts go through :mod:`swarm.experiments.sweep` (resumable: finished run folders are skipped;
process pool or any ``concurrent.futures`` executor such as a Dask client's). Single runs run
in this process and are written with :func:`swarm.outputs.write_run`; a finished one is kept.

Layout of ``out_dir`` (default ``results/paper``)::

    table.md, table.csv        paper (quoted) next to ours (measured), every experiment
    fig11/   runs/<planner>/default/seed-NNN/, summary.json, summary.csv (a sweep)
             fig11_over_time.png, fig11_final.png, results.json
    case1/   run/ (one run's outputs), case1_distance.png, case1_trajectories.png, results.json
    case2/   run/, seeds/ (a sweep of paper-case2, with --seeds and for case3),
             case2_trajectories.png, case2_task_loads.png, case2_coverage.png, results.json
    case3/   seeds/ (a sweep of paper-case3), case3_coverage.png, results.json

``results.json`` holds what an experiment measured; the table is rebuilt from whichever of them
exist (a missing experiment shows as "not run"), so every experiment rewrites it.

Targets are numbered from 1 in figures and the table, as in the paper (target 1 = event id 0).
"""


from __future__ import annotations

from swarm.experiments.paper.design import (
    CASE3_WINDOW_FROM_S,
    DEFAULT_SEEDS,
    EXPERIMENTS,
    FIG11_PLANNERS,
    FIG11_REFERENCE,
    PAPER,
    PLANNER_COLOUR,
    PLANNER_LABEL,
    SCENARIO,
    ExperimentReport,
    PaperReport,
    ProgressFn,
    fig11_planners,
)
from swarm.experiments.paper.figures import (
    MODE_COLOUR,
    case1_distance,
    case2_coverage,
    case3_coverage,
    fig11_final,
    fig11_over_time,
    task_loads,
)
from swarm.experiments.paper.logs import (
    RunLog,
    band,
    copy_file,
    finished_runs,
    join_time,
    mean_curve,
    read_timeseries,
    stack,
    stays_above_from,
)
from swarm.experiments.paper.measures import (
    CASE2_CONDITIONS,
    CASE2_JUDGE_S,
    CASE2_MIN_HANDOVERS,
    CASE2_SEARCH_PLANNERS,
    case1_measures,
    case2_conditions,
    case2_measures,
    held_at_zone_edge,
    last_seen,
)
from swarm.experiments.paper.runs import (
    RUNNERS,
    run_case1,
    run_case2,
    run_case3,
    run_fig11,
    run_paper,
)
from swarm.experiments.paper.table import (
    MD_HEADER,
    NOT_RUN,
    ROW_BUILDERS,
    table_rows,
    write_table,
)

__all__ = [
    "band",
    "case1_distance",
    "case1_measures",
    "CASE2_CONDITIONS",
    "case2_conditions",
    "case2_coverage",
    "CASE2_JUDGE_S",
    "case2_measures",
    "CASE2_MIN_HANDOVERS",
    "CASE2_SEARCH_PLANNERS",
    "case3_coverage",
    "CASE3_WINDOW_FROM_S",
    "copy_file",
    "DEFAULT_SEEDS",
    "ExperimentReport",
    "EXPERIMENTS",
    "fig11_final",
    "fig11_over_time",
    "FIG11_PLANNERS",
    "fig11_planners",
    "FIG11_REFERENCE",
    "finished_runs",
    "held_at_zone_edge",
    "join_time",
    "last_seen",
    "MD_HEADER",
    "mean_curve",
    "MODE_COLOUR",
    "NOT_RUN",
    "PAPER",
    "PaperReport",
    "PLANNER_COLOUR",
    "PLANNER_LABEL",
    "ProgressFn",
    "read_timeseries",
    "ROW_BUILDERS",
    "run_case1",
    "run_case2",
    "run_case3",
    "run_fig11",
    "run_paper",
    "RunLog",
    "RUNNERS",
    "SCENARIO",
    "stack",
    "stays_above_from",
    "table_rows",
    "task_loads",
    "write_table",
]
