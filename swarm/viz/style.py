"""Shared figure conventions (the paper's): km axes, one colour per UAV, one marker per UAV
type, and legends that collapse to types when there are too many UAVs to list.

Every figure takes its UAV colours from :func:`uav_colours` (``tab10`` up to 10 UAVs, ``tab20``
up to 20, assigned in sorted-name order) so a UAV has the same colour in every figure of a run;
beyond 20 UAVs they are sampled from a continuous map so neighbours in the legend still differ.
"""

from __future__ import annotations

import re

from matplotlib import colormaps
from matplotlib.ticker import FuncFormatter

LEGEND_MAX_UAVS = 12
TYPE_MARKERS = ("^", "o", "s", "D", "v", "P", "X", "h", "<", ">")
MODE_COLOURS = {"search": "#4c72b0", "surveil": "#dd8452", "not flying": "#d9d9d9"}


def natural_key(name: str) -> list:
    """Sort key that puts B2 before B10."""
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", name)]


def uav_colours(names: list[str]) -> dict[str, tuple]:
    """One RGBA colour per UAV name."""
    order = sorted(names)
    n = len(order)
    if n <= 10:
        cmap = colormaps["tab10"]
        return {name: cmap(i % 10) for i, name in enumerate(order)}
    if n <= 20:
        cmap = colormaps["tab20"]
        return {name: cmap(i % 20) for i, name in enumerate(order)}
    cmap = colormaps["turbo"]
    return {name: cmap(0.05 + 0.9 * i / (n - 1)) for i, name in enumerate(order)}


def type_markers(types: list[str]) -> dict[str, str]:
    """One marker per UAV type, in sorted type order."""
    return {t: TYPE_MARKERS[i % len(TYPE_MARKERS)] for i, t in enumerate(sorted(set(types)))}


def many_uavs(n: int) -> bool:
    """True when legends should list types instead of every UAV."""
    return n > LEGEND_MAX_UAVS


def line_width(n: int, base: float = 1.0) -> float:
    """Thinner lines as the swarm grows, so 100 paths stay readable."""
    if n <= LEGEND_MAX_UAVS:
        return base
    if n <= 40:
        return base * 0.6
    return base * 0.4


KM = FuncFormatter(lambda v, _pos: f"{v / 1000:g}")


def km_axes(ax, width_m: float, height_m: float) -> None:
    """Axes in metres labelled in km, equal aspect, clipped to the area."""
    ax.set_xlim(0, width_m)
    ax.set_ylim(0, height_m)
    ax.set_aspect("equal")
    ax.xaxis.set_major_formatter(KM)
    ax.yaxis.set_major_formatter(KM)
    ax.set_xlabel("x (km)")
    ax.set_ylabel("y (km)")
