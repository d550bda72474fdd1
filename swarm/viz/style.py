"""Shared figure conventions (the paper's): km axes, one colour per UAV, one marker per UAV
type, and legends that collapse to types when there are too many UAVs to list.

Every figure takes its UAV colours from :func:`uav_colours` (``tab10`` up to 10 UAVs, ``tab20``
up to 20, assigned in sorted-name order) so a UAV has the same colour in every figure of a run;
beyond 20 UAVs they are sampled from a continuous map so neighbours in the legend still differ.

A UAV type's marker is a function of the type's name alone (:func:`type_marker`): the paper's
types A and B (Table 1) always get a triangle and a circle, any other
type a marker picked by a CRC-32 of its name, so a type looks the same in every run and figure
whatever other types fly with it. ``x`` / ``X`` (crashed UAVs) and ``*`` (targets) are never
type markers.
"""

from __future__ import annotations

import math
import re
import zlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from matplotlib import colormaps
from matplotlib.ticker import FuncFormatter

if TYPE_CHECKING:
    from matplotlib.axes import Axes

LEGEND_MAX_UAVS = 12
FIXED_TYPE_MARKERS = {"A": "^", "B": "o"}
# Markers for other types (picked by a stable hash of the name); none of A's or B's, no crash
# cross, no target star.
TYPE_MARKERS = ("s", "D", "v", "P", "h", "<", ">", "p", "d", "H")
MODE_COLOURS = {"search": "#4c72b0", "surveil": "#dd8452", "not flying": "#d9d9d9"}
# Targets at the end of a run (trajectory figures) and in the animation: found filled,
# never found hollow.
TARGET_FOUND_COLOUR = "#ff7f0e"
TARGET_NOT_FOUND_COLOUR = "white"
CRASH_MARKER = "X"
COVERAGE_GREY = "#d4d4d4"  # cells scanned at least once, in the run's trajectories figure


def natural_key(name: str) -> list[int | str]:
    """Sort key that puts B2 before B10."""
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", name)]


def uav_colours(names: list[str]) -> dict[str, tuple[float, float, float, float]]:
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


def type_marker(name: str) -> str:
    """The marker of UAV type ``name``: fixed for A and B, else by a CRC-32 of the name (stable
    across runs, processes and ``PYTHONHASHSEED``, unlike ``hash()``)."""
    fixed = FIXED_TYPE_MARKERS.get(name)
    if fixed is not None:
        return fixed
    return TYPE_MARKERS[zlib.crc32(name.encode("utf-8")) % len(TYPE_MARKERS)]


def type_markers(types: list[str]) -> dict[str, str]:
    """One marker per UAV type present (sorted by type name), each :func:`type_marker`."""
    return {t: type_marker(t) for t in sorted(set(types))}


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


def km_axes(ax: Axes, width_m: float, height_m: float) -> None:
    """Axes in metres labelled in km, equal aspect, clipped to the area."""
    ax.set_xlim(0, width_m)
    ax.set_ylim(0, height_m)
    ax.set_aspect("equal")
    ax.xaxis.set_major_formatter(KM)
    ax.yaxis.set_major_formatter(KM)
    ax.set_xlabel("x (km)")
    ax.set_ylabel("y (km)")


# --- numbers with units -------------------------------------------------------------------------
# One rule set for every table and axis that shows a metric, chosen by the metric's name
# (``radio.bytes_sent``: the part after the last dot): bytes in kB / MB / GB (SI, powers of
# 1000), fractions (coverage, certainty, ratios) with 3 decimals, seconds as s, everything else
# a count: an integer with thin (narrow no-break) thousands separators, or 3 significant digits
# when a mean of a few counts is not whole.

THIN_SEP = "\u202f"  # narrow no-break space: 4 121 000 (SI style), never wrapped
_FRACTION_NAMES = ("coverage", "certainty")
_FRACTION_WORDS = ("ratio", "fraction", "share", "rate")
_BYTE_PREFIXES = ((1e12, "TB"), (1e9, "GB"), (1e6, "MB"), (1e3, "kB"))


def metric_kind(name: str) -> str:
    """``"bytes"``, ``"fraction"``, ``"seconds"`` or ``"count"``, from a metric's name."""
    leaf = name.rsplit(".", 1)[-1].lower()
    words = set(re.split(r"[^a-z0-9]+", leaf))
    if "bytes" in words:
        return "bytes"
    if leaf in _FRACTION_NAMES or words & set(_FRACTION_WORDS):
        return "fraction"
    if leaf.endswith("_s") or words & {"s", "seconds", "latency"}:
        return "seconds"
    return "count"


def _decimals_for(magnitude: float) -> int:
    """Decimals for 3 significant digits at this magnitude (0 from 100 up)."""
    if not math.isfinite(magnitude) or magnitude >= 100:
        return 0
    if magnitude >= 10:
        return 1
    return 2


@dataclass(frozen=True)
class Unit:
    """How to write the numbers of one metric: divide by ``scale``, ``decimals`` places (None:
    by each number's own magnitude), then ``suffix``. Whole counts have no decimals."""

    kind: str
    suffix: str = ""
    scale: float = 1.0
    decimals: int | None = None

    def number(self, value: Any, signed: bool = False) -> str:
        """``value`` in this unit, without the suffix (``4.12``; ``+0.012`` when ``signed``)."""
        try:
            x = float(value)
        except (TypeError, ValueError):
            return "–"
        if math.isnan(x):
            return "–"
        if math.isinf(x):
            return ("+∞" if signed else "∞") if x > 0 else "−∞"
        x /= self.scale
        d = self.decimals
        if d is None:
            d = _decimals_for(abs(x))
        if self.kind == "count" and x == round(x):
            d = 0
        text = f"{x:{'+' if signed else ''},.{d}f}".replace(",", THIN_SEP)
        if float(text.replace(THIN_SEP, "")) == 0:
            text = text.lstrip("+-")  # zero has no sign: not "-0.000"
        return text

    def format(self, value: Any, signed: bool = False) -> str:
        """``value`` with the suffix: ``4.12 MB``, ``0.742``, ``12.5 s``, ``4 121 000``."""
        text = self.number(value, signed)
        return f"{text} {self.suffix}" if self.suffix and text != "–" else text


def metric_unit(name: str, magnitude: float | None = None) -> Unit:
    """The :class:`Unit` for metric ``name`` when its numbers are about ``magnitude`` (e.g. the
    largest absolute mean of a table column, so the column shares one unit)."""
    kind = metric_kind(name)
    mag = abs(float(magnitude)) if magnitude is not None and math.isfinite(float(magnitude)) else 0.0
    if kind == "fraction":
        return Unit(kind, "", 1.0, 3)
    if kind == "bytes":
        for scale, suffix in _BYTE_PREFIXES:
            if mag >= scale * 0.9995:  # 999 600 B is 1.00 MB, not 1000 kB
                return Unit(kind, suffix, scale, _decimals_for(mag / scale))
        return Unit(kind, "B", 1.0, 0)
    if kind == "seconds":
        return Unit(kind, "s", 1.0, _decimals_for(mag))
    return Unit(kind, "", 1.0, _decimals_for(mag) if magnitude is not None else None)


def format_metric(name: str, value: Any, signed: bool = False) -> str:
    """One value of metric ``name`` with its unit: ``format_metric("radio.bytes_sent",
    4_121_000) == "4.12 MB"``; ``coverage`` 0.74 -> ``0.740``; counts ``4 121 000``."""
    try:
        mag = abs(float(value))
    except (TypeError, ValueError):
        mag = 0.0
    return metric_unit(name, mag).format(value, signed)
