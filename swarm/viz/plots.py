"""Figures of a run, in the paper's conventions (km axes, one colour per UAV, legends).

Drawn on a :class:`matplotlib.figure.Figure` with its own Agg canvas (no display needed, and the
host program's pyplot backend is left alone). Colours come from
:func:`swarm.viz.style.uav_colours`, markers from :func:`swarm.viz.style.type_marker`; with many
UAVs the legend lists types instead of every UAV so it stays legible.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import IO, TYPE_CHECKING

import numpy as np
from matplotlib.artist import Artist
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from swarm.viz.hazards import draw_hazards, hazards_of
from swarm.viz.style import (
    COVERAGE_GREY,
    CRASH_MARKER,
    TARGET_FOUND_COLOUR,
    TARGET_NOT_FOUND_COLOUR,
    many_uavs,
    natural_key,
    type_marker,
    uav_colours,
)

if TYPE_CHECKING:
    from swarm.kernel.results import RunResult

__all__ = ["crashed_uavs", "found_targets", "trajectories_figure", "trajectories_plot", "trajectories_png"]


def found_targets(result: RunResult) -> set[int] | None:
    """Ids of the targets found (seen at least once) in a run, or None if the metrics do not say.

    ``metrics.json``'s ``surveillance_ratio`` has one entry per found target (keyed by its id as
    a string), from the same record as ``targets_found``; used only when the two agree.
    """
    m = result.metrics or {}
    ratio = m.get("surveillance_ratio")
    if not isinstance(ratio, dict):
        return None
    try:
        ids = {int(k) for k in ratio}
    except (TypeError, ValueError):
        return None
    if m.get("targets_found") is not None and m["targets_found"] != len(ids):
        return None
    return ids


def crashed_uavs(result: RunResult) -> set[str]:
    """Names of the UAVs whose final state is ``crashed`` (``metrics.json`` ``per_uav``)."""
    per = (result.metrics or {}).get("per_uav") or {}
    return {name for name, p in per.items() if isinstance(p, dict) and p.get("state") == "crashed"}


def trajectories_plot(result: RunResult, title: str | None = None) -> Figure:
    """The figure of :func:`trajectories_figure`, not saved (to inspect or embed)."""
    w, h = result.area
    fig = Figure(figsize=(9.6, 7.0), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    covered = np.isfinite(result.union_last_seen)
    grey = ListedColormap(["white", COVERAGE_GREY])
    ax.imshow(covered.astype(np.uint8), origin="lower", extent=(0, w / 1000, 0, h / 1000), cmap=grey, vmin=0,
              vmax=1, interpolation="nearest", zorder=0)
    colours = uav_colours(list(result.paths))
    many = many_uavs(len(result.paths))
    crashed = crashed_uavs(result)
    types = result.uav_types or {}
    handles: list[Artist] = []
    type_counts: dict[str, int] = {}
    for name, p in sorted(result.paths.items(), key=lambda kv: natural_key(kv[0])):
        typ = types.get(name, "?")
        type_counts[typ] = type_counts.get(typ, 0) + 1
        marker = type_marker(typ)
        colour = colours[name]
        if not many:
            handles.append(Line2D([], [], ls="-", lw=0.9, color=colour, marker=marker, ms=5, mec="black", mew=0.5,
                                  label=f"{name} ({typ})" + (", crashed" if name in crashed else "")))
        if len(p) == 0:
            continue
        ax.plot(p[:, 1] / 1000, p[:, 2] / 1000, "-", lw=0.9 if not many else 0.5, color=colour, zorder=3)
        if name in crashed:
            ax.plot(p[-1, 1] / 1000, p[-1, 2] / 1000, CRASH_MARKER, ms=8 if not many else 5, color=colour,
                    mec="black", mew=0.6, zorder=5, clip_on=False)
        else:
            ax.plot(p[-1, 1] / 1000, p[-1, 2] / 1000, marker, ms=5 if not many else 3.5, color=colour,
                    mec="black", mew=0.5, zorder=5, clip_on=False)
    if many:
        for typ in sorted(type_counts):
            handles.append(Line2D([], [], ls="-", lw=0.5, color="0.4", marker=type_marker(typ), mec="black",
                                  label=f"type {typ} ({type_counts[typ]} UAVs)"))
    if crashed:
        handles.append(Line2D([], [], ls="", marker=CRASH_MARKER, ms=8, color="0.45", mec="black", mew=0.6,
                              label=f"crashed ({len(crashed)})"))

    found = found_targets(result)
    n_found = n_lost = 0
    drew_path = False
    for tid, p in sorted(result.target_paths.items()):
        if len(p) == 0:
            continue
        ax.plot(p[:, 1] / 1000, p[:, 2] / 1000, "--", lw=0.8, color="black", zorder=2)
        drew_path = True
        hit = found is not None and tid in found
        n_found += hit
        n_lost += not hit
        ax.plot(p[-1, 1] / 1000, p[-1, 2] / 1000, "*", ms=11 if hit else 10,
                mfc=TARGET_FOUND_COLOUR if hit else TARGET_NOT_FOUND_COLOUR, mec="black", mew=0.7 if hit else 1.1,
                zorder=6, clip_on=False)
    if drew_path:
        handles.append(Line2D([], [], ls="--", lw=0.8, color="black", label="target path"))
    if found is not None:
        handles.append(Line2D([], [], ls="", marker="*", ms=11, mfc=TARGET_FOUND_COLOUR, mec="black", mew=0.7,
                              label=f"target found ({n_found})"))
        handles.append(Line2D([], [], ls="", marker="*", ms=10, mfc=TARGET_NOT_FOUND_COLOUR, mec="black", mew=1.1,
                              label=f"target not found ({n_lost})"))
    elif drew_path:  # metrics without per-target detection: one neutral symbol
        handles.append(Line2D([], [], ls="", marker="*", ms=10, mfc="0.5", mec="black",
                              label=f"target, end ({n_lost})"))
    # The no-fly zones (circles and polygons), the area polygon and the base (swarm.viz.hazards).
    handles += draw_hazards(ax, hazards_of(result.scenario or {}, result.threats), scale=1e-3)[1]
    handles.append(Patch(fc=COVERAGE_GREY, ec="0.5", lw=0.5, label="scanned at least once"))
    ax.set_xlim(0, w / 1000)
    ax.set_ylim(0, h / 1000)
    ax.set_aspect("equal")
    ax.set_xlabel("x (km)")
    ax.set_ylabel("y (km)")
    m = result.metrics
    ax.set_title(title or f"{m['scenario']} · {m['planner']} · seed {m['seed']} · "
                 f"coverage {m['coverage']:.3f} · targets {m['targets_found']}/{m['targets_total']}",
                 fontsize=9)
    # Beside the map, not over it: nothing of the run is hidden under the legend.
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=7,
              frameon=False, ncol=2 if len(handles) > 30 else 1)
    fig.tight_layout()
    return fig


def trajectories_figure(result: RunResult, path: str | Path | IO[bytes], title: str | None = None) -> None:
    """UAV paths (end marker by type; a cross where a UAV crashed), target paths with found and
    never-found targets apart, no-fly zones (circles and polygons), the area polygon, the base
    and the final coverage map (like the paper's Fig. 9),
    saved to ``path``: a file name (format from its suffix) or a binary file object (PNG)."""
    fig = trajectories_plot(result, title)
    suffix = Path(path).suffix.lstrip(".").lower() if isinstance(path, (str, Path)) else ""
    fig.savefig(path, format=suffix or "png")


def trajectories_png(result: RunResult) -> bytes:
    """:func:`trajectories_figure` as PNG bytes: a run folder's ``trajectories.png``, the figure
    :func:`swarm.outputs.run_files` adds when given it (``figure=trajectories_png``)."""
    png = io.BytesIO()
    trajectories_figure(result, png)
    return png.getvalue()
