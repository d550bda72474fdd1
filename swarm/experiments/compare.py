"""Two sweep folders compared run by run (``swarm compare OLD NEW``): before and after a change.

A change of code with no setting of its own (or several changes at once) is judged from two
sweeps run with the same planners, settings and seeds, one before it and one after: the runs are
paired by their folder (``runs/<planner>/<settings>/seed-NNN``), each (planner, settings) group
gets the paired differences of every metric and the verdict of :mod:`swarm.experiments.equivalence`,
and the runs whose event logs are byte for byte the same are counted (a refactor: all of them).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from swarm.errors import UsageError
from swarm.experiments.equivalence import MARGINS, equivalence
from swarm.experiments.sweep import describe, paired_differences, strict_json, summary_row

__all__ = ["FolderComparison", "compare_folders"]


@dataclass
class FolderComparison:
    """Two sweep folders (``swarm sweep`` or ``swarm paper`` outputs, e.g. before and after a
    change of code), run by run: ``groups`` per (planner, settings folder) with the paired
    differences and verdict; ``identical``/``paired``: runs whose event logs are byte for byte
    the same / runs finished in both."""

    old: str
    new: str
    groups: list[dict[str, Any]]
    paired: int
    identical: int
    only_old: int
    only_new: int

    @property
    def equivalent(self) -> bool:
        verdicts = [e["equivalent"] for g in self.groups for e in g["equivalence"].values()]
        return bool(verdicts) and all(verdicts)

    def as_dict(self) -> dict[str, Any]:
        """As strict JSON takes it (a non-finite bound written ``"inf"``, as sweeps write them)."""
        out: dict[str, Any] = strict_json({"old": self.old, "new": self.new, "paired": self.paired, "identical": self.identical,
                "only_old": self.only_old, "only_new": self.only_new, "equivalent": self.equivalent,
                "groups": self.groups})
        return out


def _finished_runs(folder: Path) -> dict[str, dict[str, Any]]:
    """``runs/<planner>/<settings>/seed-NNN`` -> its ``metrics.json``, for every finished run."""
    runs = {}
    for p in sorted(folder.glob("runs/*/*/seed-*/metrics.json")):
        try:
            runs[p.parent.relative_to(folder).as_posix()] = json.loads(p.read_text())
        except (OSError, ValueError) as e:
            raise UsageError(f"{p}: not a readable metrics.json ({e})") from None
    return runs


def compare_folders(old: str | Path, new: str | Path) -> FolderComparison:
    """Pair the finished runs of two sweep folders by planner, settings and seed (the same
    relative run folder) and judge each (planner, settings) group as :func:`equivalence` does.
    A folder may be a sweep's or hold one (``swarm paper``'s ``OUT/fig11``)."""
    a, b = _sweep_dir(Path(old)), _sweep_dir(Path(new))
    before, after = _finished_runs(a), _finished_runs(b)
    common = sorted(set(before) & set(after))
    by_group: dict[str, list[str]] = {}
    for run in common:
        by_group.setdefault(run.rsplit("/", 1)[0], []).append(run)
    groups: list[dict[str, Any]] = []
    for group, runs in by_group.items():
        rows_old = {r: summary_row(before[r]) for r in runs}
        total = max(float(before[r].get("targets_total") or 0) for r in runs)
        _, difference = paired_differences(rows_old, {r: summary_row(after[r]) for r in runs}, total)
        old_stats = {m: describe([rows_old[r][m] for r in runs]) for m in difference}
        planner, settings = group.split("/")[1:3]
        groups.append({"group": group, "planner": planner, "settings": settings, "paired_seeds": len(runs),
                       "identical": sum(_same_log(before[r], after[r]) for r in runs),
                       "old": {m: old_stats[m] for m in MARGINS if m in old_stats},
                       "difference": difference, "equivalence": equivalence(difference, old_stats)})
    if not common:
        raise UsageError(f"{old} and {new}: no finished run in both (runs/<planner>/<settings>/seed-NNN/metrics.json)")
    return FolderComparison(str(old), str(new), groups, len(common), sum(g["identical"] for g in groups),
                            len(set(before) - set(after)), len(set(after) - set(before)))


def _same_log(old: Mapping[str, Any], new: Mapping[str, Any]) -> bool:
    h = old.get("event_log_sha256")
    return bool(h) and h == new.get("event_log_sha256")


def _sweep_dir(folder: Path) -> Path:
    """``folder`` if it holds ``runs/``; else its one sub-folder that does (``swarm paper``'s
    ``OUT/fig11``); else a :class:`UsageError` naming what was looked for."""
    if not folder.is_dir():
        raise UsageError(f"{folder}: no such folder")
    if (folder / "runs").is_dir():
        return folder
    inner = [p for p in sorted(folder.iterdir()) if (p / "runs").is_dir()]
    if len(inner) == 1:
        return inner[0]
    if inner:
        raise UsageError(f"{folder}: holds several sweeps ({', '.join(p.name for p in inner)}): name one")
    raise UsageError(f"{folder}: not a sweep folder (no runs/ in it or in a folder inside it)")
