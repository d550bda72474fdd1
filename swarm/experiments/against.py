"""``swarm bench --against REFERENCE``: the bench cases side by side with a yardstick.

A speed figure on a shared machine only means something next to another made in the same minute
(``../shared/bench/README.md``). This runs each case and its reference alternately, each in a
process of its own (peak memory is per process, and one case must not warm the next one's
caches): project, reference, project, reference, ... ``pairs`` times, and reports each pair's
ratio of UAV-ticks per CPU second, the median ratio, the machine and the load average around
each run. The reference is a script with ``reference_limit.py``'s command line (``--case
fig11|b100|b1000 --duration S``, one JSON line with ``uav_steps_per_cpu_s``), given the built-in
scenario files through ``SWARM_BUILTIN``. A case with no reference (paper-case2, bench-dense-300)
is refused with one ``error:`` line before anything runs.
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from swarm.errors import UsageError
from swarm.experiments.bench import CASES, Case, case_scenario
from swarm.scenario.loading import builtin_folder

# The reference's name for the scenario each case runs.
REFERENCE_CASE = {"paper-fig11": "fig11", "bench-100": "b100", "bench-1000": "b1000"}


def machine() -> dict[str, Any]:
    """What the figures were measured on."""
    return {"cpus": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
            "platform": platform.platform(terse=True)}


def _json_line(cmd: Sequence[str], env: dict[str, str] | None = None) -> dict[str, Any]:
    """The last JSON line ``cmd`` prints; its stderr as the error if it fails."""
    proc = subprocess.run(list(cmd), capture_output=True, text=True, env=env)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    if proc.returncode != 0 or not lines:
        tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        raise UsageError(f"{' '.join(cmd[:4])}... failed (exit {proc.returncode}): {tail}")
    row: dict[str, Any] = json.loads(lines[-1])
    return row


def _selected(quick: bool, only: list[str] | None) -> list[Case]:
    cases = [c for c in CASES if (not quick or c.quick) and (not only or c.name in only)]
    missing = [c.name for c in cases if c.scenario not in REFERENCE_CASE]
    if missing:
        raise UsageError(f"no reference case for {', '.join(missing)}: --against pairs only "
                         f"{', '.join(c.name for c in CASES if c.scenario in REFERENCE_CASE)}")
    return cases


def main(reference: str | Path, pairs: int = 3, quick: bool = False, only: list[str] | None = None,
         out: TextIO | None = None, table_out: TextIO | None = None) -> int:
    """Run each selected case ``pairs`` times alternately with ``reference``; one JSON line per
    case (its runs, the reference's, the ratios and their median), then a table on ``table_out``."""
    out, table_out = out or sys.stdout, table_out or sys.stderr
    ref = Path(reference)
    if not ref.is_file():
        raise UsageError(f"--against {reference}: no such file (the yardstick, e.g. ../shared/bench/reference_limit.py)")
    if pairs < 1:
        raise UsageError(f"--pairs {pairs}: must be at least 1")
    cases = _selected(quick, only)
    env = {**os.environ, "SWARM_BUILTIN": builtin_folder()}
    rows = []
    for case in cases:
        duration = case.duration_s if case.duration_s is not None else case_scenario(case).duration_s
        runs: list[dict[str, Any]] = []
        for _ in range(pairs):
            load0 = os.getloadavg()[0]
            mine = _json_line([sys.executable, "-m", "swarm", "bench", "--case", case.name])
            theirs = _json_line([sys.executable, str(ref), "--case", REFERENCE_CASE[case.scenario],
                                 "--duration", repr(duration)], env=env)
            runs.append({
                "uav_steps_per_cpu_s": mine["uav_steps_per_cpu_s"],
                "reference_uav_steps_per_cpu_s": theirs["uav_steps_per_cpu_s"],
                "ratio": round(mine["uav_steps_per_cpu_s"] / theirs["uav_steps_per_cpu_s"], 3),
                "flatness": mine["flatness"],
                "cpu_seconds": mine["cpu_seconds"],
                "peak_rss_mb": mine["peak_rss_mb"],
                "event_log_sha256": mine["event_log_sha256"],
                "load_avg": [round(load0, 2), round(os.getloadavg()[0], 2)],
            })
        row = {"case": case.name, "reference": ref.name, "sim_seconds": duration, "pairs": runs,
               "ratio_median": round(statistics.median(r["ratio"] for r in runs), 3),
               "flatness_median": statistics.median(r["flatness"] or 0.0 for r in runs),
               "machine": machine()}
        rows.append(row)
        print(json.dumps(row), file=out, flush=True)
    print(table(rows), file=table_out, flush=True)
    return 0


def table(rows: list[dict[str, Any]]) -> str:
    """The cases side by side: medians of the project's and the reference's rates, the ratio."""
    lines = ["| case | project (UAV-ticks/CPU s) | reference | ratio (median; each pair) | flatness | load |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        runs = r["pairs"]
        mine = statistics.median(p["uav_steps_per_cpu_s"] for p in runs)
        theirs = statistics.median(p["reference_uav_steps_per_cpu_s"] for p in runs)
        each = ", ".join(f"{p['ratio']:.2f}" for p in runs)
        loads = [x for p in runs for x in p["load_avg"]]
        lines.append(f"| {r['case']} | {mine:.0f} | {theirs:.0f} | {r['ratio_median']:.2f} ({each}) | "
                     f"{r['flatness_median']:.2f} | {min(loads):.1f}-{max(loads):.1f} |")
    return "\n".join(lines)
