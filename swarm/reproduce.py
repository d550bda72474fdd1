"""Re-running a run folder: the same scenario and seed again, and whether the event log is the same.

A run folder (``swarm run --out``, a sweep's ``runs/.../seed-NNN``, a paper experiment's run,
:func:`swarm.outputs.write_run` from an embedded run) holds everything that made the run:
``scenario.json`` is the scenario that ran (overrides, ``--planner``, ``--duration`` and the seed
applied), and ``events.msgpack`` the log it gave. :func:`rerun` builds the simulation from them
again, runs it to where the original stopped, writes the new run to another folder and compares
the two event-log hashes; when they differ it names the first tick whose events differ and the
versions that ran each (:mod:`swarm.provenance`). ``swarm rerun RUNDIR`` is the command.

The folder given is only read: nothing is written into it, whatever happens.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

from swarm.errors import SwarmError
from swarm.events import EventLogError, check_log, first_difference_s, log_sha256, read_events, split_provenance
from swarm.outputs import RunDirError, read_json, read_run_dir, write_run
from swarm.provenance import differences, versions

__all__ = ["RerunResult", "rerun"]


@dataclass(frozen=True)
class RerunResult:
    """What :func:`rerun` found. ``equal``: the two event-log hashes are the same."""

    folder: Path  # the run folder re-run
    out: Path  # where the new run was written
    original_sha256: str
    sha256: str
    versions_then: dict[str, str] | None  # as the folder records them (None: not recorded)
    versions_now: dict[str, str]
    first_difference_s: float | None = None  # the first tick whose events differ (None: equal)
    notes: list[str] = field(default_factory=list)

    @property
    def equal(self) -> bool:
        return self.original_sha256 == self.sha256

    @property
    def version_differences(self) -> list[str]:
        """What differs between the versions that ran each (empty: the same software)."""
        return differences(self.versions_then, self.versions_now) if self.versions_then != self.versions_now else []


def rerun(folder: str | Path, out: str | Path | None = None, *, allow_planner_imports: bool | Iterable[str] = False,
          figures: bool = False, progress: Callable[[float, float], None] | None = None) -> RerunResult:
    """Run a run folder's scenario again and compare event logs (see the module's docstring).

    ``out``: the folder for the new run (default: a new temporary folder, named in the result);
    it must not be the folder re-run. ``allow_planner_imports``: as for any scenario file, a
    ``module:Class`` planner the folder names is imported only if allowed
    (:mod:`swarm.scenario.trust`). ``figures``: also draw ``trajectories.png``.

    Raises :class:`swarm.outputs.RunDirError` (a :class:`~swarm.errors.SwarmError`) when the folder
    cannot be re-run: a file missing or damaged, a log cut short."""
    from swarm.kernel.hostlog import schedule_recorded_host_changes
    from swarm.kernel.simulation import Simulation
    from swarm.scenario.model import parse_scenario

    run = read_run_dir(folder)
    scenario_path = run.path / "scenario.json"
    provenance, events = _read_log(run.path / "events.msgpack", run.events)
    metrics = read_json(run.path / "metrics.json") if (run.path / "metrics.json").is_file() else {}
    then = provenance or metrics.get("versions")
    original = log_sha256(events)
    recorded = metrics.get("event_log_sha256")
    if recorded is not None and recorded != original:
        raise RunDirError(f"{run.path / 'events.msgpack'}: its hash {original[:16]}… is not the one metrics.json "
                          f"records ({str(recorded)[:16]}…): the log was changed or cut short, or the folder's "
                          f"files are not of one run")
    try:
        scenario = parse_scenario(run.scenario, str(scenario_path), truncated=True,
                                  allow_planner_imports=allow_planner_imports)
    except SwarmError as exc:
        raise RunDirError(f"{scenario_path} cannot be re-run: {exc}") from None
    end = _end_of(metrics, scenario.duration_s, scenario_path)
    target = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="swarm-rerun-"))
    if target.resolve() == run.path.resolve():
        raise RunDirError(f"--out {target}: the re-run must go to another folder than the one re-run")
    with Simulation(scenario) as sim:  # (its own seed; no overrides, which would judge it afresh)
        # Changes a host made while the original ran (embedded runs): applied again at the same ticks.
        schedule_recorded_host_changes(sim, list(read_events(events)))
        if end >= sim.duration_s:
            result = sim.run(progress=progress)
        else:  # an embedded run written before the scenario's end: stop where it stopped
            while sim.now < end - 1e-9 and not sim.done:
                sim.step()
                if progress is not None:
                    progress(sim.now, end)
            result = sim.result()
    if "settings" in metrics:  # a sweep's run records the settings it was swept with
        result.metrics["settings"] = metrics["settings"]
    write_run(result, target, sim.scenario.to_dict(), figures=figures)
    new = result.metrics["event_log_sha256"]
    first = None if new == original else first_difference_s(events, result.events)
    return RerunResult(run.path, target, original, new, then, versions(), first)


def _read_log(path: Path, data: bytes) -> tuple[dict | None, bytes]:
    """The provenance record and the events of a folder's log, every event checked (a log cut
    short or damaged is said here, before anything runs)."""
    try:
        provenance, events = split_provenance(data)
        check_log(events)
    except EventLogError as exc:
        raise RunDirError(f"{path}: cannot be re-run: {exc}") from None
    return provenance, events


def _end_of(metrics: dict, duration_s: float, scenario_path: Path) -> float:
    """Where the original run stopped: metrics.json's ``sim_seconds`` (an embedded run may stop
    before its scenario's end), else the scenario's duration."""
    end = metrics.get("sim_seconds", duration_s)
    if isinstance(end, bool) or not isinstance(end, (int, float)) or not math.isfinite(end) or end < 0:
        raise RunDirError(f"{scenario_path.parent / 'metrics.json'}: sim_seconds {end!r} is not a time")
    return min(float(end), duration_s)
