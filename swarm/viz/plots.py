"""Figures of a run, in the paper's conventions (km axes, one colour per UAV, legends).

Drawn on a :class:`matplotlib.figure.Figure` with its own Agg canvas (no display needed, and the
host program's pyplot backend is left alone). Colours come from
:func:`swarm.viz.style.uav_colours`; with many UAVs the legend lists types instead of every UAV
so it stays legible.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from swarm.viz.style import many_uavs, uav_colours


def trajectories_figure(result, path: Path, title: str | None = None) -> None:
    """UAV paths, target paths, threats and the final coverage map (like the paper's Fig. 9)."""
    w, h = result.area
    fig = Figure(figsize=(7.5, 7.0), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    covered = np.isfinite(result.union_last_seen)
    ax.imshow(np.where(covered, 1.0, 0.0), origin="lower", extent=(0, w / 1000, 0, h / 1000),
              cmap="Greys", vmin=0, vmax=4, alpha=0.9, interpolation="nearest")
    colours = uav_colours(list(result.paths))
    many = many_uavs(len(result.paths))
    for name, p in sorted(result.paths.items()):
        if len(p) == 0:
            continue
        colour = colours[name]
        ax.plot(p[:, 1] / 1000, p[:, 2] / 1000, "-", lw=0.9 if not many else 0.5, color=colour,
                label=None if many else f"{name} ({result.uav_types.get(name, '?')})")
        ax.plot(p[-1, 1] / 1000, p[-1, 2] / 1000, "o", ms=4, color=colour)
    for k, (tid, p) in enumerate(sorted(result.target_paths.items())):
        if len(p) == 0:
            continue
        ax.plot(p[:, 1] / 1000, p[:, 2] / 1000, "--", lw=0.8, color="black",
                label="targets" if k == 0 else None)
        ax.plot(p[-1, 1] / 1000, p[-1, 2] / 1000, "*", ms=7, color="black")
    for k, th in enumerate(result.threats):
        ax.add_patch(Circle((th.x / 1000, th.y / 1000), th.radius / 1000, color="red", alpha=0.35,
                            label="threats" if k == 0 else None))
        ax.add_patch(Circle((th.x / 1000, th.y / 1000), th.d_max / 1000, fill=False, color="red",
                            ls=":", lw=0.7))
    ax.set_xlim(0, w / 1000)
    ax.set_ylim(0, h / 1000)
    ax.set_aspect("equal")
    ax.set_xlabel("x (km)")
    ax.set_ylabel("y (km)")
    m = result.metrics
    ax.set_title(title or f"{m['scenario']} · {m['planner']} · seed {m['seed']} · "
                 f"coverage {m['coverage']:.3f} · targets {m['targets_found']}/{m['targets_total']}",
                 fontsize=9)
    ax.legend(loc="upper right", fontsize=7, framealpha=0.8, ncol=2 if not many else 1)
    fig.tight_layout()
    fig.savefig(path)
