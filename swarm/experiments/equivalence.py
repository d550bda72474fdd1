"""Is a model change equivalent? Paired differences across the values of a swept setting.

A model change (a cheaper planner budget, tracks sent on change, a cap on resent scans) is kept
behind a setting whose old value stays selectable, so its study is one sweep:
``swarm sweep paper-fig11 --seeds 30 --set KEY=OLD,NEW``. For every planner and every ``--set``
axis, each later value is compared with the axis's first value (the old model) seed by seed,
the other axes held fixed: ``new - old`` per seed, its mean and 95% interval
(:func:`swarm.experiments.sweep.describe`). A change of code with no setting (or several
changes at once) is judged the same way from two sweep folders run before and after it
(``swarm compare OLD NEW``, :mod:`swarm.experiments.compare`), paired by planner, settings and seed.

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
from typing import Any

__all__ = ["DETECTION_TIME", "MARGINS", "Margin", "axis_pairs", "censored_detection_time", "equivalence"]

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

