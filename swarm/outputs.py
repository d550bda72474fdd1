"""Writing a run's result files into its output folder.

* ``metrics.json``     — final metrics (keys described in the README);
* ``timeseries.csv``   — one row per ``metrics.sample_s``: coverage, certainty, targets found,
                         radio counters, and each UAV's mode (search / surveil / down / pending);
* ``events.msgpack``   — the event log, after a provenance record (the versions that ran); the
                         SHA-256 of its events is ``metrics.json``'s ``event_log_sha256``
                         (:func:`swarm.events.log_sha256`);
* ``trajectories.png`` — UAV and target paths, threats and the final coverage map;
* ``scenario.json``    — the exact scenario that ran (with seed and overrides applied);
* ``paths.geojson``, ``targets.geojson``, ``zones.geojson`` — a geographic scenario's (``[geo]``)
  tracks and zones in lon/lat (RFC 7946; :mod:`swarm.geo.geojson`).

Every file is written with :func:`atomic_write` (or :func:`atomic_path` for writers that want a
file name), which the experiment commands, reports and animations use too. :func:`read_run_dir`
reads a run folder back (scenario and event log); :func:`swarm.viz.replay.load_run` and
:func:`swarm.testing.invariants.load_run_log` build on it.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from swarm.errors import SwarmError
from swarm.events import with_provenance

if TYPE_CHECKING:
    from swarm.kernel.results import RunResult

__all__ = [
    "RunDirError",
    "RunFolder",
    "atomic_path",
    "atomic_write",
    "check_run_dir",
    "read_json",
    "read_run_dir",
    "run_files",
    "write_files",
    "write_run",
]


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; when the block ends without an exception
    it replaces ``path`` (one rename), otherwise it is removed. So an interrupted write never
    leaves a half-written file under the final name. The temporary name keeps the suffix
    (``animation.part.gif``) for writers that choose the format from it."""
    final = Path(path)
    tmp = final.with_name(final.stem + ".part" + final.suffix)
    try:
        yield tmp
        os.replace(tmp, final)
    finally:
        if tmp.exists():
            tmp.unlink()


def atomic_write(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`); returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def run_files(result: RunResult, scenario_dict: dict[str, Any] | None = None,
              figure: Callable[[RunResult], bytes] | None = None) -> dict[str, bytes]:
    """A run's result files as ``{name: bytes}``, ``metrics.json`` last; with ``figure`` (the
    run drawn as PNG bytes, e.g. :func:`swarm.viz.plots.trajectories_png`), ``trajectories.png``
    too. (The drawing is passed in: this module writes and reads files, the figures are drawn
    above it.)

    Built in memory so a sweep worker on another machine can ship a finished run back to the
    machine that writes the folder (no shared file system needed)."""
    # The events after a provenance record (the versions that ran; not hashed: swarm.events).
    files: dict[str, bytes] = {"events.msgpack": with_provenance(result.events, result.metrics.get("versions") or {})}
    if scenario_dict is None:
        scenario_dict = getattr(result, "scenario", None) or None  # what ran: swarm report needs it
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
    if scenario_dict is not None and scenario_dict.get("geo"):  # (issue 26: paths, targets, zones in lon/lat)
        from swarm.geo.geojson import geojson_files

        files.update(geojson_files(result, scenario_dict))
    if figure is not None:
        files["trajectories.png"] = figure(result)
    # metrics.json last: its presence marks a complete run folder (sweeps rely on it).
    files["metrics.json"] = json.dumps(result.metrics, indent=2).encode()
    return files


def write_files(out_dir: str | Path, files: dict[str, bytes]) -> Path:
    """Write ``files`` atomically one by one, in order (so ``metrics.json`` lands last)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for name, data in files.items():
        atomic_write(out / name, data)
    return out


def write_run(result: RunResult, out_dir: str | Path, scenario_dict: dict[str, Any] | None = None,
              figure: Callable[[RunResult], bytes] | None = None) -> Path:
    """Write a run's folder (:func:`run_files`: ``figure`` draws ``trajectories.png``)."""
    return write_files(out_dir, run_files(result, scenario_dict, figure))


# --- reading a run folder back -------------------------------------------------------------------


class RunDirError(SwarmError, ValueError):
    """A run folder is missing a file (or has one that cannot be read)."""


def check_run_dir(run_dir: str | os.PathLike[str]) -> Path:
    """Raise :class:`RunDirError` naming the first missing file of a run folder."""
    d = Path(run_dir)
    if not d.is_dir():
        raise RunDirError(f"{d}: no such run folder")
    events = d / "events.msgpack"
    if not events.is_file():
        if (d / "sweep.json").is_file():
            raise RunDirError(_sweep_folder_message(d))
        raise RunDirError(f"{events}: missing; {d} is not a run folder (write one with `swarm run SCENARIO --out DIR`)")
    scen = d / "scenario.json"
    if not scen.is_file():
        raise RunDirError(f"{scen}: missing; it gives the area, UAV types, threats and radio range")
    return d


def _sweep_folder_message(d: Path) -> str:
    """What to say when a sweep's folder is given where a run folder is expected."""
    report = d / "report.html"
    where = (f"the sweep's report is {report}" if report.is_file() else
             f"the sweep's report will be {report} (`swarm sweep` writes it when the sweep finishes: run the same "
             f"command again to finish it)")
    example = next(iter(sorted(d.glob("runs/*/*/seed-*/events.msgpack"))), None)
    runs = f", e.g. {example.parent}" if example is not None else ""
    return (f"{d} is a sweep folder, not a run folder: {where}; each of its runs is a run folder under "
            f"{d / 'runs'}/PLANNER/SETTINGS/seed-NNN{runs}")


def read_json(path: Path) -> dict[str, Any]:
    """A JSON file of a run folder; :class:`RunDirError` if it cannot be read."""
    try:
        data: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
        return data
    except (OSError, ValueError) as exc:
        raise RunDirError(f"{path}: cannot be read as JSON ({exc})") from None


@dataclass(frozen=True)
class RunFolder:
    """The two files every run folder has, as written: ``scenario.json`` (a dict, not yet
    validated) and ``events.msgpack`` (bytes, see :func:`swarm.events.read_events`)."""

    path: Path
    scenario: dict[str, Any]
    events: bytes


def read_run_dir(run_dir: str | os.PathLike[str]) -> RunFolder:
    """Read the scenario and the event log of a folder written by ``swarm run --out DIR``;
    :class:`RunDirError` if either is missing or unreadable."""
    d = check_run_dir(run_dir)
    scenario = read_json(d / "scenario.json")
    events = d / "events.msgpack"
    try:
        data = events.read_bytes()
    except OSError as exc:
        raise RunDirError(f"{events}: cannot be read ({exc})") from None
    return RunFolder(d, scenario, data)
