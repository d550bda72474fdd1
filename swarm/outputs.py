"""Writing a run's result files into its output folder.

* ``metrics.json``     — final metrics (keys described in the README);
* ``timeseries.csv``   — one row per ``metrics.sample_s``: coverage, certainty, targets found,
                         radio counters, and each UAV's mode (search / surveil / down / pending);
* ``events.msgpack``   — the event log; its SHA-256 is ``metrics.json``'s ``event_log_sha256``;
* ``trajectories.png`` — UAV and target paths, threats and the final coverage map;
* ``scenario.json``    — the exact scenario that ran (with seed and overrides applied).
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path


def _atomic_write(path: Path, data: bytes) -> None:
    # Write then rename, so an interrupted run never leaves a half-written file behind.
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def write_run(result, out_dir: str | Path, scenario_dict: dict | None = None, figures: bool = True) -> Path:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _atomic_write(out / "events.msgpack", result.events)
    rows = result.timeseries
    if rows:
        columns = list(dict.fromkeys(k for row in rows for k in row))
        tmp = out / "timeseries.csv.tmp"
        with tmp.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=columns, restval="pending")
            w.writeheader()
            w.writerows(rows)
        os.replace(tmp, out / "timeseries.csv")
    if scenario_dict is not None:
        _atomic_write(out / "scenario.json", json.dumps(scenario_dict, indent=2).encode())
    if figures:
        from swarm.plots import trajectories_figure

        trajectories_figure(result, out / "trajectories.png")
    # metrics.json last: its presence marks a complete run folder (sweeps rely on it).
    _atomic_write(out / "metrics.json", json.dumps(result.metrics, indent=2).encode())
    return out
