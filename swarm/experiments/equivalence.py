"""Is a model change equivalent? Paired differences across the values of a swept setting.

A model change (a cheaper planner budget, tracks sent on change, a cap on resent scans) is kept
behind a setting whose old value stays selectable, so its study is one sweep:
``swarm sweep paper-fig11 --seeds 30 --set KEY=OLD,NEW``. For every planner and every ``--set``
axis, each later value is compared with the axis's first value (the old model) seed by seed,
the other axes held fixed: ``new - old`` per seed, its mean and 95% interval
(:func:`swarm.experiments.sweep.describe`). A change of code with no setting (or several
changes at once) is judged the same way from two sweep folders run before and after it
(``swarm compare OLD NEW``, :func:`compare_folders`), paired by planner, settings and seed.

**Equivalent** means, for each of the quantities in :data:`MARGINS`, that the whole 95% interval
of the paired difference lies within the margin (a two one-sided tests reading at the 2.5%
level each side). The margins are fixed here, once, and quoted by the docs (docs/sweeps.md):
a little wider than what a change meant to leave quality alone showed at 30 seeds on
paper-fig11 (detect-and-avoid beside collision avoidance, docs/paper.md: DACMP +0.014 [+0.005,
+0.023] coverage, +0.07 [-0.32, +0.46] targets found; any change of plans makes the runs differ
chaotically, so even a harmless one has an interval about 0.009 and 0.4 wide each side), so that
"equivalent" accepts what chaos alone makes and rejects what a user of the figures would notice.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from swarm.errors import UsageError

__all__ = ["DETECTION_TIME", "MARGINS", "FolderComparison", "Margin", "censored_detection_time", "compare_folders",
           "equivalence"]

# The one per-run number for "time to detection": every target's time to first detection, a
# target never detected counted as the run's length (so a change that finds fewer targets
# cannot look faster by dropping the hard ones), averaged over the targets.
DETECTION_TIME = "detection_time_censored_s"


@dataclass(frozen=True)
class Margin:
    """How far ``new - old`` may be from 0: ``absolute``, or ``relative`` to the old mean."""

    absolute: float | None = None
    relative: float | None = None

    def of(self, old_mean: float) -> float:
        if self.absolute is not None:
            return self.absolute
        assert self.relative is not None
        return self.relative * abs(old_mean)

    def text(self) -> str:
        return f"±{self.absolute:g}" if self.absolute is not None else f"±{100 * (self.relative or 0):g}%"


MARGINS: Mapping[str, Margin] = {
    "coverage": Margin(absolute=0.02),
    "certainty": Margin(absolute=0.01),
    "targets_found": Margin(absolute=1.0),
    DETECTION_TIME: Margin(relative=0.10),
}


def censored_detection_time(metrics: Mapping[str, Any]) -> float | None:
    """:data:`DETECTION_TIME` of one run's ``metrics.json``; None if it has no targets."""
    times = metrics.get("time_to_first_detection_s")
    length = metrics.get("sim_seconds")
    if not isinstance(times, Mapping) or not times or not isinstance(length, (int, float)):
        return None
    return sum(float(length) if t is None else float(t) for t in times.values()) / len(times)


def equivalence(difference: Mapping[str, Mapping[str, Any]], old: Mapping[str, Mapping[str, Any]]
                ) -> dict[str, dict[str, Any]]:
    """Per quantity of :data:`MARGINS` present in ``difference`` (``describe`` of new - old per
    metric) and ``old`` (``describe`` of the old runs): the margin, the interval, and whether the
    interval lies within it."""
    out = {}
    for name, margin in MARGINS.items():
        d, o = difference.get(name), old.get(name)
        if d is None or o is None or d.get("n", 0) < 2:
            continue
        m = margin.of(float(o["mean"]))
        lo, hi = (float(x) for x in d["ci95"])
        out[name] = {"margin": m, "margin_text": margin.text(), "mean": float(d["mean"]), "ci95": [lo, hi],
                     "equivalent": bool(math.isfinite(lo) and math.isfinite(hi) and -m <= lo and hi <= m)}
    return out


def axis_pairs(settings_list: Sequence[Sequence[tuple[str, Any]]], key_of: Any
               ) -> list[tuple[str, Any, tuple[tuple[str, Any], ...], tuple[tuple[str, Any], ...]]]:
    """For each swept key and each of its values after the first: ``(key, value, old, new)``,
    the settings of the groups that differ only in that key (``old`` holds the key's first
    value). ``key_of`` makes a hashable key of a settings tuple."""
    first: dict[str, Any] = {}
    for settings in settings_list:
        for k, v in settings:
            first.setdefault(k, v)
    index = {key_of(s): tuple(s) for s in settings_list}
    out = []
    for settings in settings_list:
        for i, (k, v) in enumerate(settings):
            if key_of([(k, v)]) == key_of([(k, first[k])]):
                continue
            old = tuple(settings[:i]) + ((k, first[k]),) + tuple(settings[i + 1:])
            if key_of(old) in index:
                out.append((k, v, index[key_of(old)], tuple(settings)))
    return out


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
        from swarm.experiments.sweep import strict_json

        out: dict[str, Any] = strict_json({"old": self.old, "new": self.new, "paired": self.paired, "identical": self.identical,
                "only_old": self.only_old, "only_new": self.only_new, "equivalent": self.equivalent,
                "groups": self.groups})
        return out


def _finished_runs(folder: Path) -> dict[str, dict[str, Any]]:
    """``runs/<planner>/<settings>/seed-NNN`` -> its ``metrics.json``, for every finished run."""
    import json

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
    from swarm.experiments.sweep import describe, difference_bounds, flatten_metrics, metric_bounds

    a, b = _sweep_dir(Path(old)), _sweep_dir(Path(new))
    before, after = _finished_runs(a), _finished_runs(b)
    common = sorted(set(before) & set(after))
    by_group: dict[str, list[str]] = {}
    for run in common:
        by_group.setdefault(run.rsplit("/", 1)[0], []).append(run)
    groups: list[dict[str, Any]] = []
    skip = {"seed", "sim_seconds", "wall_seconds", "events", "targets_total"}
    for group, runs in by_group.items():
        rows_old, rows_new = [], []
        for run in runs:
            mo, mn = before[run], after[run]
            ro = {k: float(v) for k, v in flatten_metrics(mo).items() if k not in skip}
            rn = {k: float(v) for k, v in flatten_metrics(mn).items() if k not in skip}
            for row, m in ((ro, mo), (rn, mn)):
                d = censored_detection_time(m)
                if d is not None:
                    row[DETECTION_TIME] = d
            rows_old.append(ro)
            rows_new.append(rn)
        names = [m for m in rows_old[0] if all(m in r for r in rows_old + rows_new)]
        total = max(float(before[r].get("targets_total") or 0) for r in runs)
        difference = {m: describe([n[m] - o[m] for o, n in zip(rows_old, rows_new)],
                                  difference_bounds(metric_bounds(m, total))) for m in names}
        old_stats = {m: describe([o[m] for o in rows_old]) for m in names}
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
