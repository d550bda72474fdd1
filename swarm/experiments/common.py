"""Plumbing shared by the experiment commands (``swarm paper``, ``swarm resilience``): where
their runs execute, how they name seeds, and how they write figures, JSON and table cells."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from swarm.errors import UsageError
from swarm.outputs import atomic_write

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from swarm.scenario import Scenario


class executor_for:
    """The given executor, or a process pool for the block (processes start on first use)."""

    def __init__(self, executor: Executor | None, workers: int | None):
        self.given = executor
        self.workers = workers
        self.own: Executor | None = None

    def __enter__(self) -> Executor:
        if self.given is not None:
            return self.given
        self.own = ProcessPoolExecutor(max_workers=self.workers or os.cpu_count() or 1)
        return self.own

    def __exit__(self, *exc: object) -> None:
        if self.own is not None:
            self.own.shutdown(wait=True, cancel_futures=True)


def expected_duration(scenario: Scenario, duration_s: float | None) -> float:
    return float(duration_s if duration_s is not None else scenario.duration_s)


def seeds_from(seeds: int | Sequence[int]) -> list[int]:
    if isinstance(seeds, int):
        if seeds < 1:
            raise UsageError(f"--seeds {seeds}: expected a whole number >= 1")
        return list(range(seeds))
    return [int(s) for s in seeds]


def subplots(nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float], **kwargs: Any) -> tuple[Figure, Any]:
    """Like ``pyplot.subplots`` but a figure of its own (an Agg canvas, nothing registered with
    pyplot), so the host program's backend and figures are left alone."""
    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols, **kwargs)


def save_figure(fig: Figure, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def no_data(ax: Axes, text: str = "no finished runs") -> None:
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", color="grey")


def write_json(path: Path, data: dict[str, Any]) -> None:
    write_text(path, json.dumps(data, indent=2, default=_json_default))


def write_text(path: Path, text: str) -> Path:
    """Write ``text`` (UTF-8) atomically, making the folder if needed."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(path, text.encode("utf-8"))


def _json_default(o: object) -> object:
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    raise TypeError(type(o))


def md_cell(text: Any) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")
