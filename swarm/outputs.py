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
import io
import json
import os
from pathlib import Path


def _atomic_write(path: Path, data: bytes) -> None:
    # Write then rename, so an interrupted run never leaves a half-written file behind.
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def run_files(result, scenario_dict: dict | None = None, figures: bool = True) -> dict[str, bytes]:
    """A run's result files as ``{name: bytes}``, ``metrics.json`` last.

    Built in memory so a sweep worker on another machine can ship a finished run back to the
    machine that writes the folder (no shared file system needed)."""
    files: dict[str, bytes] = {"events.msgpack": result.events}
    rows = result.timeseries
    if rows:
        columns = list(dict.fromkeys(k for row in rows for k in row))
        buf = io.StringIO(newline="")
        w = csv.DictWriter(buf, fieldnames=columns, restval="pending")
        w.writeheader()
        w.writerows(rows)
        files["timeseries.csv"] = buf.getvalue().encode()
    if scenario_dict is not None:
        files["scenario.json"] = json.dumps(scenario_dict, indent=2).encode()
    if figures:
        from swarm.viz.plots import trajectories_figure

        png = io.BytesIO()
        trajectories_figure(result, png)
        files["trajectories.png"] = png.getvalue()
    # metrics.json last: its presence marks a complete run folder (sweeps rely on it).
    files["metrics.json"] = json.dumps(result.metrics, indent=2).encode()
    return files


def write_files(out_dir: str | Path, files: dict[str, bytes]) -> Path:
    """Write ``files`` atomically one by one, in order (so ``metrics.json`` lands last)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for name, data in files.items():
        _atomic_write(out / name, data)
    return out


def write_run(result, out_dir: str | Path, scenario_dict: dict | None = None, figures: bool = True) -> Path:
    return write_files(out_dir, run_files(result, scenario_dict, figures))
