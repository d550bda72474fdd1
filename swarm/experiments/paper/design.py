"""What the paper's experiments are: their scenarios, planners, seeds, colours, and the paper's
quoted figures (never computed)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from swarm.experiments.sweep import SweepResult

EXPERIMENTS = ("fig11", "case1", "case2", "case3")
DEFAULT_SEEDS = {"fig11": 30, "case3": 10}
SCENARIO = {"fig11": "paper-fig11", "case1": "paper-case1", "case2": "paper-case2", "case3": "paper-case3"}
FIG11_PLANNERS = ("greedy", "dacmp")  # the paper's pair; greedy first: sweep comparisons are "dacmp - greedy"
# Reference planners (not in the paper) run beside them and bracket the result (DACMP-SPEC.md,
# "Reproduction targets"); each only where the registry has it (agents.planners.registry).
FIG11_REFERENCE = ("lawnmower", "formation", "levy")
PLANNER_LABEL = {"greedy": "greedy", "dacmp": "DACMP", "lawnmower": "lawnmower (reference)",
                 "formation": "formation (reference)", "levy": "Lévy (reference)"}
PLANNER_COLOUR = {"greedy": "tab:blue", "dacmp": "tab:red", "lawnmower": "tab:green", "formation": "tab:purple",
                  "levy": "tab:brown"}


def fig11_planners() -> tuple[str, ...]:
    """The planners ``fig11`` runs: the paper's pair, then the reference planners the registry finds."""
    from agents.planners.base import PlannerError
    from agents.planners.registry import resolve_planner

    found = []
    for name in FIG11_REFERENCE:
        try:
            resolve_planner(name)
        except PlannerError:
            continue
        found.append(name)
    return (*FIG11_PLANNERS, *found)
CASE3_WINDOW_FROM_S = 600.0  # case3 table: mean coverage from this time on

# What the paper reports (section 4), quoted; never computed.
PAPER: dict[str, dict[str, Any]] = {
    "fig11": {"duration_s": 2000.0, "runs": 30, "targets_total": 14,
              "coverage": {"greedy": 0.712, "dacmp": 0.763},
              "targets_found": {"greedy": 12.1, "dacmp": 13.7}},
    "case2": {"targets_total": 6, "targets_found": 6, "watched_end": 6, "handovers_fast_to_slow": 4},
}

ProgressFn = Callable[[str, str, float, float, str], None]
"""``progress(key, description, done, total, info)``: one bar per ``key``."""


@dataclass
class ExperimentReport:
    name: str
    figures: list[Path] = field(default_factory=list)
    sweeps: list[tuple[Path, SweepResult]] = field(default_factory=list)
    single: list[tuple[Path, bool]] = field(default_factory=list)  # (run folder, already finished)
    failed: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class PaperReport:
    out_dir: Path
    experiments: list[ExperimentReport]
    table_md: Path
    table_csv: Path
    rows: list[dict[str, Any]]
