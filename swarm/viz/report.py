"""Self-contained HTML reports: one run (:func:`write_report`) and a sweep (:func:`write_sweep_report`).

A report is one ``.html`` file that opens offline: inline CSS, no scripts, every figure a PNG
``data:`` URI, the run's animation (if one was made) a GIF ``data:`` URI or an MP4 base64
``<video>`` source. Nothing is fetched from anywhere. The pages are Jinja2 templates
(``swarm/viz/templates/``: ``base.html.j2``, ``run_report.html.j2``, ``sweep_report.html.j2``,
``macros.html.j2``, ``report.css``), rendered with autoescaping; this module computes what they
show.

A run report holds the scenario summary, the metrics (``metrics.json``), figures — trajectories
over the first-scan map, coverage and certainty over time (``timeseries.csv``), targets found
and watched over time, task load per UAV (seconds in search vs surveillance, stacked, as in the
paper's Fig. 14), radio counters — a fault timeline (schedule windows, crashes, joins and
every UAV's state over time), the violations (which invariant, who, when: :func:`violation_episodes`)
and the handovers (release and arrival times, overlap and gap: :func:`handover_rows`). Figures
use km axes, one colour per UAV and legends that list types instead of UAVs beyond 12 UAVs.
``swarm animate`` refreshes a run folder's report with the animation it made (:func:`refresh_report`).

A sweep report holds a table of every metric that differs between groups (mean ± sd [95%
interval, clipped to the metric's range by the sweep's summary], in readable units:
:func:`swarm.viz.style.metric_unit`; wide tables scroll inside the page), one panel per such metric,
and the paired differences of the sweep's ``comparisons`` written as "first planner − second"
(``summary.json`` stores them as ``other − first``; the report flips them).
"""

from __future__ import annotations

import base64
import dataclasses
import functools
import io
import math
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from jinja2 import Environment, PackageLoader, StrictUndefined, select_autoescape
from matplotlib import colormaps
from matplotlib.artist import Artist
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch
from matplotlib.ticker import FuncFormatter, MaxNLocator

from comms.messages import MODE_SURVEIL
from comms.radio import LogDistance
from swarm.errors import SwarmError
from swarm.outputs import atomic_write
from swarm.viz.replay import (
    Replay,
    RunDirError,
    fault_events,
    fault_label,
    first_seen_map,
    load_run,
)
from swarm.viz.style import (
    CRASH_MARKER,
    MODE_COLOURS,
    TARGET_FOUND_COLOUR,
    TARGET_NOT_FOUND_COLOUR,
    THIN_SEP,
    format_metric,
    km_axes,
    line_width,
    many_uavs,
    metric_unit,
    natural_key,
    type_markers,
    uav_colours,
)

__all__ = [
    "ReportError",
    "build_run_report",
    "build_sweep_report",
    "constant_metrics",
    "find_animation",
    "handover_rows",
    "paired_differences",
    "refresh_report",
    "render",
    "violation_episodes",
    "write_report",
    "write_sweep_report",
]

ANIMATION_NAMES = ("animation.mp4", "animation.gif")
_DPI = 100
MINUS = "\u2212"  # in "dacmp − greedy"


class ReportError(SwarmError, ValueError):
    """A report cannot be written as asked."""


# --- small helpers ----------------------------------------------------------------------------

def _new_figure(w: float, h: float) -> Figure:
    fig = Figure(figsize=(w, h), dpi=_DPI)
    FigureCanvasAgg(fig)
    return fig


def _png_uri(fig: Figure) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_DPI)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _fmt(value) -> str:
    """A table cell's text: numbers short (``0.7423``, ``12``), None and NaN ``–``."""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if math.isnan(value):
            return "–"
        if math.isinf(value):
            return "∞" if value > 0 else "−∞"
        if value == int(value) and abs(value) < 1e12:
            return f"{value:.0f}"
        return f"{value:.4g}"
    if value is None:
        return "–"
    return str(value)


def _cell(text, cls: str | None = None, title: str | None = None) -> dict:
    """A table cell with a CSS class (``num``: right-aligned) and a tooltip."""
    return {"text": text, "cls": cls, "title": title}


@functools.cache
def _environment() -> Environment:
    env = Environment(
        loader=PackageLoader("swarm.viz", "templates"),
        autoescape=select_autoescape(enabled_extensions=("html.j2", "html"), default_for_string=True, default=True),
        undefined=StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    env.filters["fmt"] = _fmt
    return env


def render(template: str, **context: Any) -> str:
    """Render one of the report templates (``run_report.html.j2``, ``sweep_report.html.j2``)."""
    context.setdefault("written", f"{datetime.now(UTC):%Y-%m-%d %H:%M}")
    return _environment().get_template(template).render(**context)


def _figure(fig: Figure, caption: str, alt: str, width: int | None = None) -> dict:
    return {"uri": _png_uri(fig), "caption": caption, "alt": alt, "width": width}


# --- run figures ------------------------------------------------------------------------------

def _uav_order(rp: Replay) -> list[int]:
    return sorted(range(rp.n_uavs), key=lambda u: (rp.types[u], natural_key(rp.names[u])))


def fig_trajectories(rp: Replay) -> Figure:
    """UAV and target paths over the first-scan map, threats (the paper's Fig. 9 layout)."""
    w, h, _c = rp.area
    fig = _new_figure(8.2, 7.0)
    ax = fig.add_axes((0.08, 0.08, 0.7, 0.85))
    first = first_seen_map(rp)
    img = np.where(np.isfinite(first), first, np.nan)
    cmap = ListedColormap(colormaps["Greys"](np.linspace(0.12, 0.42, 256))).with_extremes(bad="white")
    im = ax.imshow(img, origin="lower", extent=(0, w, 0, h), cmap=cmap, vmin=0, vmax=max(rp.duration, 1.0),
                   interpolation="nearest", zorder=0)
    cax = fig.add_axes((0.82, 0.08, 0.02, 0.4))
    cb = fig.colorbar(im, cax=cax)
    cb.set_label("first scanned at (s); white: never", fontsize=8)
    cb.ax.tick_params(labelsize=7)
    km_axes(ax, w, h)
    colours = uav_colours(rp.names)
    markers = type_markers(rp.types)
    many = many_uavs(rp.n_uavs)
    lw = line_width(rp.n_uavs, 1.0)
    for th in rp.threats:
        ax.add_patch(Circle((th.x, th.y), th.radius, color="red", alpha=0.3, lw=0, zorder=1))
        ax.add_patch(Circle((th.x, th.y), th.d_max, fill=False, color="red", ls=":", lw=0.7, zorder=1))
    crashed = {uid for _t, uid in rp.crashes}
    for u in _uav_order(rp):
        xs, ys = rp.x[:, u], rp.y[:, u]
        ok = np.isfinite(xs)
        if not ok.any():
            continue
        c = colours[rp.names[u]]
        ax.plot(xs[ok], ys[ok], "-", lw=lw, color=c, zorder=3)
        j = np.flatnonzero(ok)
        ax.plot(xs[j[0]], ys[j[0]], "o", ms=3, mfc="white", mec=c, zorder=4)
        if u in crashed:
            ax.plot(xs[j[-1]], ys[j[-1]], CRASH_MARKER, ms=8 if not many else 5, color=c, clip_on=False,
                    mec="black", mew=0.6, zorder=5)
        else:
            ax.plot(xs[j[-1]], ys[j[-1]], markers[rp.types[u]], ms=6 if not many else 4, color=c, clip_on=False,
                    mec="black", mew=0.5, zorder=5)
    n_found = n_lost = 0
    for k in range(rp.n_targets):
        tx, ty = rp.target_x[:, k], rp.target_y[:, k]
        ok = np.isfinite(tx)
        if not ok.any():
            continue
        ax.plot(tx[ok], ty[ok], "--", lw=0.7, color="black", zorder=2)
        found = bool(np.isfinite(rp.found_t[k]))
        n_found += found
        n_lost += not found
        j = np.flatnonzero(ok)[-1]
        ax.plot(tx[j], ty[j], "*", ms=10 if found else 9, mfc=TARGET_FOUND_COLOUR if found else TARGET_NOT_FOUND_COLOUR,
                mec="black", mew=0.6 if found else 1.0, zorder=6, clip_on=False)
    handles: list[Artist] = []
    if many:
        for typ, m in markers.items():
            count = rp.types.count(typ)
            handles.append(Line2D([], [], ls="-", lw=lw, color="0.4", marker=m, mec="black",
                                  label=f"type {typ} ({count} UAVs)"))
        handles.append(Line2D([], [], ls="", label="one colour per UAV"))
    else:
        for u in sorted(range(rp.n_uavs), key=lambda u: natural_key(rp.names[u])):
            handles.append(Line2D([], [], ls="-", lw=lw, color=colours[rp.names[u]], marker=markers[rp.types[u]],
                                  mec="black", label=f"{rp.names[u]} ({rp.types[u]})"
                                  + (", crashed" if u in crashed else "")))
    handles += [Line2D([], [], ls="", marker="o", ms=4, mfc="white", mec="0.3", label="start"),
                Line2D([], [], ls="--", lw=0.7, color="black", label="target path"),
                Line2D([], [], ls="", marker="*", ms=9, mfc=TARGET_FOUND_COLOUR, mec="black", mew=0.6,
                       label=f"target found ({n_found})"),
                Line2D([], [], ls="", marker="*", ms=9, mfc=TARGET_NOT_FOUND_COLOUR, mec="black", mew=1.0,
                       label=f"target not found ({n_lost})")]
    if crashed:
        handles.append(Line2D([], [], ls="", marker=CRASH_MARKER, ms=8, color="0.45", mec="black", mew=0.6,
                              label=f"crashed ({len(crashed)})"))
    if rp.threats:
        handles.append(Patch(color="red", alpha=0.35, label="threat"))
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.8, 0.94), fontsize=7, frameon=False)
    metrics = rp.metrics or {}
    ax.set_title(f"{rp.header.get('scenario', '?')} · {rp.header.get('planner', '?')} · seed "
                 f"{rp.header.get('seed', '?')} · coverage {metrics.get('coverage', float('nan')):.3f}", fontsize=9)
    return fig


def _fault_spans(ax, rp: Replay, label: bool = True) -> None:
    """Partition windows shaded, crashes (red) and joins (green) as vertical lines."""
    first = True
    for f in rp.faults:
        if f.get("kind") == "partition":
            end = f.get("end_s")
            ax.axvspan(float(f.get("start_s", 0.0)), float(end) if end is not None else rp.duration,
                       color="#d62728", alpha=0.08, lw=0, label="partition" if (label and first) else None)
            first = False
    for i, (t, _uid) in enumerate(rp.crashes):
        ax.axvline(t, color="#d62728", ls="--", lw=0.9, label="crash" if (label and i == 0) else None)
    late = [t for t, _u in rp.joins if t > 0]
    for i, t in enumerate(late):
        ax.axvline(t, color="#2ca02c", ls="--", lw=0.9, label="join" if (label and i == 0) else None)


def fig_coverage(rp: Replay) -> Figure | None:
    ts = rp.timeseries
    if not ts or "t" not in ts:
        return None
    fig = _new_figure(8.0, 3.6)
    ax = fig.add_subplot()
    t = np.asarray(ts["t"], dtype=float)
    for col, colour in (("coverage", "#1f77b4"), ("certainty", "#2ca02c")):
        if col in ts:
            ax.plot(t, np.asarray(ts[col], dtype=float), lw=1.6, color=colour, label=col)
    _fault_spans(ax, rp)
    ax.set_xlim(0, max(rp.duration, t.max() if len(t) else 1.0))
    ax.set_ylim(0, 1.0)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("fraction")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title("coverage (cells ever scanned) and certainty (eq. 8)", fontsize=9)
    fig.tight_layout()
    return fig


def watched_count(rp: Replay) -> np.ndarray:
    """(ticks,) number of distinct targets watched by a UAV in surveillance mode."""
    m = np.where(rp.mode == MODE_SURVEIL, rp.target, -1)
    if m.shape[1] == 0:
        return np.zeros(rp.n_ticks, dtype=int)
    s = np.sort(m, axis=1)
    new = np.concatenate([s[:, :1] >= 0, (s[:, 1:] != s[:, :-1]) & (s[:, 1:] >= 0)], axis=1)
    return new.sum(axis=1)


def fig_targets(rp: Replay) -> Figure:
    fig = _new_figure(8.0, 3.4)
    ax = fig.add_subplot()
    found = np.sort(rp.found_t[np.isfinite(rp.found_t)])
    tt = np.concatenate([[0.0], found, [rp.duration]])
    cnt = np.concatenate([[0], np.arange(1, len(found) + 1), [len(found)]])
    ax.step(tt, cnt, where="post", lw=1.8, color="#ff7f0e", label="targets found")
    ax.step(rp.times, watched_count(rp), where="post", lw=1.2, color="#2ca02c", label="targets watched (surveillance)")
    ax.axhline(rp.n_targets, color="0.4", ls=":", lw=1, label=f"targets in the area ({rp.n_targets})")
    _fault_spans(ax, rp, label=False)
    ax.set_xlim(0, rp.duration)
    ax.set_ylim(0, max(rp.n_targets, 1) * 1.08)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("targets")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    return fig


_MODE_LABELS = {"search": "search", "surveil": "surveillance", "not flying": "not flying (pending / crashed)"}


def fig_task_load(rp: Replay) -> Figure:
    """Seconds in search vs surveillance mode per UAV, stacked (the paper's Fig. 14)."""
    order = _uav_order(rp)
    secs = rp.mode_seconds()
    n = len(order)
    fig = _new_figure(min(max(6.0, 0.45 * n + 2.0), 16.0), 3.8)
    ax = fig.add_subplot()
    xs = np.arange(n)
    bottom = np.zeros(n)
    show_idle = any(secs[rp.names[u]]["not flying"] > 0 for u in order)
    for key in ("search", "surveil", "not flying"):
        if key == "not flying" and not show_idle:
            continue
        vals = np.array([secs[rp.names[u]][key] for u in order])
        ax.bar(xs, vals, bottom=bottom, width=0.75 if n <= 40 else 0.9, color=MODE_COLOURS[key],
               edgecolor="white" if n <= 40 else "none", lw=0.5,
               label=_MODE_LABELS[key])
        bottom += vals
    step = max(1, math.ceil(n / 40))
    ax.set_xticks(xs[::step])
    ax.set_xticklabels([rp.names[u] for u in order][::step], rotation=0 if n <= 16 else 90, fontsize=8)
    ax.set_xlim(-0.6, n - 0.4)
    ax.set_ylabel("time (s)")
    ax.set_ylim(0, rp.duration * 1.12)
    ax.legend(fontsize=8, ncol=3, loc="upper right")
    ax.set_title("task load per UAV", fontsize=9)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return fig


def fig_radio(rp: Replay) -> Figure | None:
    ts = rp.timeseries
    if not ts or "t" not in ts or "sent" not in ts:
        return None
    t = np.asarray(ts["t"], dtype=float)
    fig = _new_figure(10.0, 3.5)
    ax1, ax2, ax3 = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1.3, 1.3, 0.9]})
    colours = {"sent": "#1f77b4", "delivered": "#2ca02c", "dropped": "#d62728", "rejected": "#9467bd"}
    for col, c in colours.items():
        if col in ts:
            ax1.plot(t, np.asarray(ts[col], dtype=float), lw=1.4, color=c, label=col)
    ax1.set_xlabel("time (s)")
    ax1.set_ylabel("frame copies (cumulative)")
    ax1.legend(fontsize=7)
    ax1.grid(alpha=0.3)
    ax1.set_title("radio counters", fontsize=9)
    sent = np.diff(np.concatenate([[0.0], np.asarray(ts["sent"], dtype=float)]))
    with np.errstate(invalid="ignore", divide="ignore"):
        for col, c in (("delivered", "#2ca02c"), ("dropped", "#d62728")):
            if col in ts:
                d = np.diff(np.concatenate([[0.0], np.asarray(ts[col], dtype=float)]))
                ax2.plot(t, np.where(sent > 0, d / sent, np.nan), lw=1.2, color=c, label=f"{col} / sent")
    _fault_spans(ax2, rp, label=True)
    ax2.set_ylim(0, 1.05)
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("fraction per sample interval")
    ax2.legend(fontsize=7, loc="best")
    ax2.grid(alpha=0.3)
    ax2.set_title("delivery per interval", fontsize=9)
    causes = ((rp.metrics or {}).get("radio", {}) or {}).get("dropped_by_cause", {}) or {}
    if causes:
        names = list(causes)
        ax3.barh(np.arange(len(names)), [causes[k] for k in names], color="#d62728", alpha=0.8)
        ax3.set_yticks(np.arange(len(names)))
        ax3.set_yticklabels(names, fontsize=8)
        ax3.invert_yaxis()
    else:
        ax3.text(0.5, 0.5, "no drops", ha="center", va="center", transform=ax3.transAxes)
        ax3.set_yticks([])
    ax3.set_xlabel("copies")
    ax3.set_title("dropped by cause", fontsize=9)
    fig.tight_layout()
    return fig


def uav_state_matrix(rp: Replay) -> np.ndarray:
    """(uavs, ticks) codes: 0 pending, 1 search, 2 surveillance, 3 crashed."""
    state = np.where(rp.mode == MODE_SURVEIL, 2, np.where(rp.mode >= 0, 1, 0)).T.astype(np.int8)
    times = rp.times
    for t, uid in rp.crashes:
        state[uid, times >= t - 1e-9] = 3
    return state


def fig_fault_timeline(rp: Replay) -> Figure:
    order = _uav_order(rp)
    windowed = [f for f in rp.faults if f.get("kind") not in ("crash", "join")]
    node = [(t, "crash", rp.names[u]) for t, u in rp.crashes] + [(t, "join", rp.names[u]) for t, u in rp.joins if t > 0]
    n_rows = len(windowed) + (1 if node else 0)
    h_top = 0.35 * max(n_rows, 1) + 0.8
    h_bot = min(0.18 * rp.n_uavs + 1.0, 9.0)
    fig = _new_figure(10.0, h_top + h_bot)
    ax1, ax2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [h_top, h_bot]})
    labels = []
    for i, f in enumerate(windowed):
        start = float(f.get("start_s", 0.0))
        end = f.get("end_s")
        end = rp.duration if end is None else min(float(end), rp.duration)
        colour = "#d62728" if f.get("kind") == "partition" else "#ff7f0e"
        ax1.barh(i, max(end - start, 0.0), left=start, height=0.6, color=colour, alpha=0.75)
        labels.append(fault_label(f))
    if node:
        y = len(windowed)
        for t, kind, name in node:
            c = "#d62728" if kind == "crash" else "#2ca02c"
            ax1.plot(t, y, "X" if kind == "crash" else "P", ms=9, color=c, mec="black", mew=0.5)
            ax1.annotate(f"{kind} {name}", (t, y), xytext=(4, 5), textcoords="offset points", fontsize=7)
        labels.append("crash / join")
    if n_rows:
        ax1.set_yticks(np.arange(n_rows))
        ax1.set_yticklabels(labels, fontsize=8)
        ax1.set_ylim(n_rows - 0.4, -0.6)
    else:
        ax1.set_yticks([])
        ax1.text(0.5, 0.5, "no faults scheduled", ha="center", va="center", transform=ax1.transAxes, color="0.4")
    ax1.grid(axis="x", alpha=0.3)
    ax1.set_title("fault schedule and UAV states", fontsize=9)
    state = uav_state_matrix(rp)[order]
    cmap = ListedColormap(["#ffffff", MODE_COLOURS["search"], MODE_COLOURS["surveil"], "#404040"])
    ax2.imshow(state, aspect="auto", cmap=cmap, vmin=-0.5, vmax=3.5, interpolation="nearest",
               extent=(0, rp.n_ticks * rp.dt, len(order) - 0.5, -0.5))
    step = max(1, math.ceil(len(order) / 40))
    ax2.set_yticks(np.arange(len(order))[::step])
    ax2.set_yticklabels([rp.names[u] for u in order][::step], fontsize=7 if len(order) <= 40 else 6)
    ax2.set_xlim(0, rp.duration)
    ax2.set_xlabel("time (s)")
    handles = [Patch(fc="#ffffff", ec="0.5", label="pending"), Patch(color=MODE_COLOURS["search"], label="search"),
               Patch(color=MODE_COLOURS["surveil"], label="surveillance"), Patch(color="#404040", label="crashed")]
    fig.legend(handles=handles, fontsize=7, ncol=4, loc="lower center", frameon=False)
    fig.tight_layout(rect=(0, 0.3 / (h_top + h_bot), 1, 1))
    return fig


# --- run report -------------------------------------------------------------------------------

def find_animation(run_dir: str | Path) -> Path | None:
    """The newest ``animation.mp4`` / ``animation.gif`` in the run folder, if any."""
    found = [p for p in (Path(run_dir) / n for n in ANIMATION_NAMES) if p.is_file() and p.stat().st_size > 0]
    return max(found, key=lambda p: p.stat().st_mtime) if found else None


def _animation(path: Path | None) -> dict | None:
    """What the template embeds of the animation: its kind, ``data:`` URI, name and size."""
    if path is None:
        return None
    kind = path.suffix.lower().lstrip(".")
    if kind not in ("gif", "mp4"):
        raise ReportError(f"{path}: an animation must be .gif or .mp4")
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    mime = "image/gif" if kind == "gif" else "video/mp4"
    return {"kind": kind, "uri": f"data:{mime};base64,{data}", "name": path.name, "mb": path.stat().st_size / 1e6}


def _scenario_rows(rp: Replay) -> list[tuple]:
    sc = rp.scenario
    w, h, c = rp.area
    types = sc.get("uav_types", {})
    counts: dict[str, int] = {}
    for t in rp.types:
        counts[t] = counts.get(t, 0) + 1
    radio = sc.get("radio", {})
    rng = radio.get("range_m")
    tg = sc.get("targets", {})
    rows = [
        ("scenario", sc.get("name", rp.header.get("scenario"))),
        ("description", sc.get("description", "")),
        ("planner", rp.header.get("planner")),
        ("seed", rp.header.get("seed")),
        ("duration", f"{_fmt(rp.duration)} s (dt {_fmt(rp.dt)} s)"),
        ("area", f"{w / 1000:g} km x {h / 1000:g} km, cells {c:g} m"),
        ("UAVs", ", ".join(f"{n} x {t}" for t, n in sorted(counts.items()))),
    ]
    for t in sorted(counts):
        spec = types.get(t, {})
        if spec:
            rows.append((f"type {t}", f"speed {spec.get('speed_min', '?'):g}-{spec.get('speed_max', '?'):g} m/s, "
                                      f"detection radius {spec.get('detect_radius_m', 0) / 1000:g} km"))
    rows += [
        ("targets", f"{rp.n_targets} ({tg.get('count', 0)} random, {len(tg.get('placed', []))} placed)"),
        ("threats", len(rp.threats)),
        ("radio", _radio_words(radio, rng)),
        ("faults scheduled", len(rp.faults)),
    ]
    return rows



def _radio_words(radio: dict, rng: float | None) -> str:
    """The scenario row of the radio: model, range, loss, latency (and auth when on)."""
    base = radio.get("loss_base", 0)
    if radio.get("model", "disk") == "log_distance":
        ld = {**dataclasses.asdict(LogDistance()), **(radio.get("log_distance") or {})}
        words = (f"log-distance (exponent {ld['exponent']:g}, {ld['tx_power_dbm']:g} dBm, "
                 f"sensitivity {ld['sensitivity_dbm']:g} dBm, shadowing {ld['sigma_db']:g} dB)"
                 f"{'' if rng is None else f', range cap {rng / 1000:g} km'}, loss floor {base:g}")
    else:
        at = radio.get("loss_at_range")
        loss = f"loss {base:g}" if at is None or at == base else f"loss {base:g} near, {at:g} at the range limit"
        words = f"range {'unlimited' if rng is None else f'{rng / 1000:g} km'}, {loss}"
    return words + f", latency {radio.get('latency_s', 0):g} s" + (", authenticated frames" if radio.get("auth") else "")


def _count(m: dict, key: str) -> str:
    return format_metric(key, m.get(key)) if m.get(key) is not None else "–"


def _metrics_rows(m: dict) -> list[tuple]:
    r = m.get("radio", {}) or {}
    v = m.get("violations", {}) or {}
    rows = [
        ("simulated / wall", f"{_fmt(m.get('sim_seconds'))} s / {_fmt(m.get('wall_seconds'))} s"),
        ("coverage", f"{m.get('coverage', float('nan')):.4f}"),
        ("certainty", f"{m.get('certainty', float('nan')):.4f}"),
        ("targets found", f"{m.get('targets_found')} / {m.get('targets_total')}"),
        ("surveillance ratio (mean)", f"{m.get('surveillance_ratio_mean', float('nan')):.3f}"),
        ("handovers (fast to slow)", f"{m.get('handovers')} ({m.get('handovers_fast_to_slow')})"),
        ("radio sent / delivered", f"{_count(r, 'sent')} / {_count(r, 'delivered')}"),
        ("radio dropped / rejected", f"{_count(r, 'dropped')} / {_count(r, 'rejected')}"),
        ("radio dropped by cause",
         ", ".join(f"{k} {format_metric(k, n)}" for k, n in (r.get("dropped_by_cause") or {}).items()) or "none"),
        ("radio bytes sent / duplicated / in flight",
         f"{_count(r, 'bytes_sent')} / {_count(r, 'duplicated')} / {_count(r, 'in_flight')}"),
        ("violations separation / threat / dynamics",
         f"{v.get('separation')} / {v.get('threat')} / {v.get('dynamics')}"),
        ("faults applied", ", ".join(f"{k} {n}" for k, n in (m.get("faults_applied") or {}).items()) or "none"),
        ("event log SHA-256", m.get("event_log_sha256", "")),
    ]
    return rows


def _seconds_or_dash(v) -> str:
    return "–" if v is None else f"{_fmt(v)} s"


def _share_or_dash(v) -> str:
    return "–" if v is None else f"{v:.3f}"


def _detection_watch_rows(m: dict, rp: Replay) -> tuple[list[tuple], list[tuple]]:
    """The "Detection and watch" section (metrics.json, docs/outputs.md): one row per target
    (time to first detection, to a slow watcher, watched share, surveillance ratio), one per UAV
    and the swarm (share of flying time watching and searching). Empty for an older metrics.json."""
    detection = m.get("time_to_first_detection_s")
    if detection is None:
        return [], []
    to_slow = m.get("time_to_slow_watcher_s") or {}
    watched = m.get("watched_share") or {}
    ratio = m.get("surveillance_ratio") or {}
    targets = [(k, detection[k], to_slow.get(k), watched.get(k), ratio.get(k)) for k in sorted(detection, key=int)]
    target_rows = [(k, _seconds_or_dash(d), _seconds_or_dash(s), _share_or_dash(w), _share_or_dash(r))
                   for k, d, s, w, r in targets]
    per = m.get("per_uav", {}) or {}
    uav_rows = []
    for u in _uav_order(rp):
        name = rp.names[u]
        share = (per.get(name) or {}).get("time_share") or {}
        uav_rows.append((name, rp.types[u], _share_or_dash(share.get("watching")), _share_or_dash(share.get("searching"))))
    total = m.get("uav_time_share") or {}
    uav_rows.append(("swarm", "", _share_or_dash(total.get("watching")), _share_or_dash(total.get("searching"))))
    return target_rows, uav_rows


# What each invariant the simulator counts (metrics.json ``violations``) means; the names are
# those of swarm.testing.invariants' checkers of the same invariants.
VIOLATION_MEANINGS = {
    "separation": "two UAVs closer than safety.min_separation_m",
    "threat": "a UAV inside a threat's circle",
    "dynamics": "a command beyond the UAV type's limits (speed, acceleration or turn rate), clipped",
}
MAX_VIOLATION_ROWS = 200


def violation_episodes(rp: Replay) -> list[dict]:
    """The run's violations as episodes, in order of start: one per invariant and party (a pair
    of UAVs, a UAV and a threat, a UAV's dynamics) and stretch of consecutive ticks, as
    ``{"invariant", "who", "start_s", "end_s", "ticks"}``. Separation and threat come from the
    event log's ``violation`` events (one per tick and party); dynamics violations are not
    logged, only counted per UAV (metrics.json ``dynamics_violations_by_uav``: count, first and
    last time), so each UAV's are one row spanning its first to its last."""
    def name(uid: int) -> str:
        return rp.names[uid] if 0 <= uid < len(rp.names) else f"UAV {uid}"

    open_: dict[tuple, dict] = {}
    done: list[dict] = []
    for t, kind, a, b in sorted(rp.violations, key=lambda v: (v[0], v[1], v[2], v[3])):
        key = (kind, a, b)
        ep = open_.get(key)
        if ep is not None and t - ep["end_s"] <= rp.dt * 1.5:
            ep["end_s"] = t
            ep["ticks"] += 1
            continue
        if ep is not None:
            done.append(ep)
        who = f"{name(a)} and {name(b)}" if kind == "separation" else (
            f"{name(a)} in threat {b}" if kind == "threat" else f"{name(a)} ({b})")
        open_[key] = {"invariant": kind, "who": who, "start_s": t, "end_s": t, "ticks": 1}
    done.extend(open_.values())
    for uav, d in ((rp.metrics or {}).get("dynamics_violations_by_uav") or {}).items():
        done.append({"invariant": "dynamics", "who": str(uav), "start_s": _num(d.get("first_s")),
                     "end_s": _num(d.get("last_s")), "ticks": int(_num(d.get("count")))})
    return sorted(done, key=lambda e: (e["start_s"], e["invariant"], e["who"]))


def _violation_section(rp: Replay) -> dict:
    """What the template shows of the violations: rows, totals, and a note on what is missing."""
    counts = (rp.metrics or {}).get("violations") or {}
    episodes = violation_episodes(rp)
    sep = (rp.scenario.get("safety") or {}).get("min_separation_m")
    meanings = dict(VIOLATION_MEANINGS)
    if isinstance(sep, (int, float)):
        meanings["separation"] += f" ({sep:g} m in this run)"
    rows = [(e["invariant"], e["who"], f"{e['start_s']:g} s", f"{e['end_s']:g} s", e["ticks"])
            for e in episodes[:MAX_VIOLATION_ROWS]]
    listed = {k: sum(e["ticks"] for e in episodes if e["invariant"] == k) for k in counts}
    unlisted = {k: int(n) - listed.get(k, 0) for k, n in counts.items() if int(n) > listed.get(k, 0)}
    return {
        "rows": rows,
        "more": max(len(episodes) - MAX_VIOLATION_ROWS, 0),
        "totals": ", ".join(f"{k} {int(n)}" for k, n in counts.items()) or "none counted",
        "any": any(int(n) for n in counts.values()),
        "meanings": [(k, meanings.get(k, "")) for k in counts],
        # e.g. a run folder written before dynamics violations were listed per UAV
        "unlisted": ", ".join(f"{n} {k}" for k, n in unlisted.items()),
    }


def handover_rows(handovers: list[dict]) -> list[tuple]:
    """The handover table's rows: time logged, target, from, to, when the owner stopped
    watching, when the newcomer arrived, and the two non-negative parts of ``latency_s``
    (release minus arrival): *overlap* (both held the target: the newcomer arrived before the
    owner left) and *gap* (nobody held it: the owner left before the newcomer arrived). One of
    them is 0; ``latency_s = overlap - gap``."""
    rows = []
    for h in handovers:
        t, lat = _num(h.get("t")), _num(h.get("latency_s"))
        released, arrived = t + min(lat, 0.0), t - max(lat, 0.0)
        rows.append((f"{t:g} s", h.get("target"), f"{h.get('from')} ({h.get('from_type')})",
                     f"{h.get('to')} ({h.get('to_type')})", f"{released:g} s", f"{arrived:g} s",
                     f"{max(lat, 0.0):g} s", f"{max(-lat, 0.0):g} s"))
    return rows


def build_run_report(rp: Replay, run_dir: Path, animation: Path | None) -> str:
    """The HTML text of a run's report (``run_report.html.j2``)."""
    m = rp.metrics or {}
    hd = rp.header
    title = f"{hd.get('scenario', 'run')} · {hd.get('planner', '?')} · seed {hd.get('seed', '?')}"
    cards = [("coverage", f"{m.get('coverage', float('nan')):.3f}"),
             ("certainty", f"{m.get('certainty', float('nan')):.3f}"),
             ("targets found", f"{m.get('targets_found', '?')} / {m.get('targets_total', rp.n_targets)}"),
             ("surveillance ratio", f"{m.get('surveillance_ratio_mean', float('nan')):.3f}"),
             ("handovers", _fmt(m.get("handovers"))),
             ("UAVs", rp.n_uavs),
             ("simulated", f"{_fmt(rp.duration)} s")]
    specs = [
        (fig_trajectories(rp), "Trajectories: UAV paths (one colour each, end marker by type, a cross where a UAV "
                               "crashed), target paths (dashed; filled star: found, hollow: never found), threats "
                               "(red), over the map of when each cell was first scanned.", "trajectories", 820),
        (fig_coverage(rp), "Coverage and certainty over time (timeseries.csv); shaded: partitions; dashed: "
                           "crashes (red) and late joins (green).", "coverage and certainty", None),
        (fig_targets(rp), "Targets found (first detection) and targets watched by a UAV in surveillance mode.",
         "targets over time", None),
        (fig_task_load(rp), "Task load per UAV: seconds in search and in surveillance mode (from the pose events), "
                            "as in the paper's Fig. 14.", "task load per UAV", None),
        (fig_radio(rp), "Radio: cumulative frame copies sent, delivered, dropped and rejected; per-interval "
                        "delivery; drops by cause (metrics.json).", "radio counters", None),
    ]
    figures = [_figure(fig, caption, alt, width) if fig is not None else {"uri": None, "alt": alt}
               for fig, caption, alt, width in specs]
    timeline = _figure(fig_fault_timeline(rp), "Fault windows from the schedule in the event log's start header "
                       "(orange: link faults, red: partitions), crashes and late joins, and every UAV's state over "
                       "time.", "fault timeline")
    secs = rp.mode_seconds()
    per = m.get("per_uav", {}) or {}
    uav_rows = []
    for u in _uav_order(rp):
        name = rp.names[u]
        p = per.get(name, {})
        s = secs[name]
        uav_rows.append((name, rp.types[u], p.get("state", "–"), s["search"], s["surveil"], s["not flying"],
                         p.get("frames_sent"), p.get("frames_delivered"), p.get("frames_rejected"), p.get("plans")))
    handovers = m.get("handover_list") or []
    watch_target_rows, watch_uav_rows = _detection_watch_rows(m, rp)
    return render(
        "run_report.html.j2",
        title=f"Report: {title}",
        heading=title,
        run_dir=str(run_dir.resolve()),
        nav=[("figures", "figures"), ("animation", "animation"), ("faults", "faults"), ("scenario", "scenario"),
             ("metrics", "metrics"), ("violations", "violations"), ("uavs", "UAVs"), ("watch", "detection and watch")]
            + ([("handovers", "handovers")] if handovers else []),
        card_items=cards,
        figures=figures,
        animation=_animation(animation),
        fault_timeline=timeline,
        fault_rows=[(f"{t:g} s", text) for t, text, _k, _u in fault_events(rp)],
        applied_rows=sorted((m.get("faults_applied") or {}).items()),
        scenario_rows=_scenario_rows(rp),
        metric_rows=_metrics_rows(m) if m else [],
        uav_rows=uav_rows,
        uav_header=("UAV", "type", "final state", "search s", "surveillance s", "not flying s", "frames sent",
                    "frames received", "frames rejected", "plans"),
        handover_rows=handover_rows(handovers),
        handover_header=("time", "target", "from", "to", "owner stopped watching", "newcomer arrived",
                         "overlap", "gap"),
        violations=_violation_section(rp),
        watch_target_rows=watch_target_rows,
        watch_uav_rows=watch_uav_rows,
        slow_types=", ".join(m.get("slow_types") or []),
    )


def write_report(run_dir: str | Path, out: str | Path | None = None, animation: str | Path | None = None) -> Path:
    """Write the HTML report of the run in ``run_dir`` (default ``RUN_DIR/report.html``).

    ``animation``: the animation to embed (default: the newest ``animation.mp4`` / ``.gif`` in
    the run folder, if any). Returns the path written.
    """
    d = Path(run_dir)
    rp = load_run(d)
    if rp.metrics is None:
        raise RunDirError(f"{d / 'metrics.json'}: missing; a complete run folder has it (written last by `swarm run`)")
    anim: Path | None
    if animation is not None:
        anim = Path(animation)
        if not anim.is_file():
            raise ReportError(f"{anim}: no such animation file")
        if anim.suffix.lower() not in (".gif", ".mp4"):
            raise ReportError(f"{anim}: an animation must be .gif or .mp4")
    else:
        anim = find_animation(d)
    out_path = Path(out) if out is not None else d / "report.html"
    if not out_path.parent.is_dir():
        raise ReportError(f"{out_path.parent}: no such folder")
    text = build_run_report(rp, d, anim)
    atomic_write(out_path, text.encode("utf-8"))
    return out_path


def refresh_report(run_dir: str | Path, animation: str | Path) -> Path | None:
    """After an animation is made (``swarm animate``): rewrite ``RUN_DIR/report.html``, if there
    is one, to embed ``animation``; returns its path, or None when the run folder has no report
    (a report written elsewhere with ``--out`` is not touched)."""
    path = Path(run_dir) / "report.html"
    if not path.is_file():
        return None
    return write_report(run_dir, path, animation=animation)


# --- sweep report -----------------------------------------------------------------------------

# Metrics where a higher value is plainly better (+1) or worse (-1); paired differences of the
# others are only marked as differing.
BETTER_DIRECTION = {"coverage": 1, "certainty": 1, "targets_found": 1, "surveillance_ratio_mean": 1,
                    "violations.separation": -1, "violations.threat": -1, "violations.dynamics": -1}


def _num(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def _settings_text(settings: dict | None) -> str:
    return ", ".join(f"{k}={_fmt(v)}" for k, v in (settings or {}).items())


def _group_label(g: dict) -> str:
    s = _settings_text(g.get("settings"))
    return f"{g.get('planner', '?')}" + (f" · {s}" if s else "")


def _metric_names(groups: list[dict]) -> list[str]:
    names: list[str] = []
    for g in groups:
        for k in (g.get("metrics") or {}):
            if k not in names:
                names.append(k)
    return names


def _stat(g: dict, metric: str) -> dict:
    s = (g.get("metrics") or {}).get(metric)
    return s if isinstance(s, dict) else {}


def _ci(s: dict) -> tuple[float, float] | None:
    ci = s.get("ci95")
    if isinstance(ci, (list, tuple)) and len(ci) == 2:
        lo, hi = _num(ci[0]), _num(ci[1])
        if math.isfinite(lo) and math.isfinite(hi):
            return lo, hi
    return None


def constant_metrics(groups: list[dict], metrics: list[str] | None = None) -> dict[str, float]:
    """``{metric: value}`` of the metrics that are the same in every group: every group has a
    finite mean, all means are equal and no group has a spread (sd 0 or none). They carry no
    comparison, so the report lists them in one line instead of a column and a panel each.
    With a single group only all-zero metrics count (one group has nothing to compare with, but
    zero counters are still noise)."""
    out: dict[str, float] = {}
    if not groups:
        return out
    for metric in metrics if metrics is not None else _metric_names(groups):
        stats = [_stat(g, metric) for g in groups]
        if any(not s for s in stats):
            continue
        means = [_num(s.get("mean")) for s in stats]
        sds = [_num(s.get("sd")) for s in stats]
        if not all(math.isfinite(x) for x in means) or any(math.isfinite(sd) and sd != 0 for sd in sds):
            continue
        ref = means[0]
        if all(abs(x - ref) <= 1e-12 * max(1.0, abs(ref)) for x in means) and (len(groups) > 1 or ref == 0):
            out[metric] = ref
    return out


def _column_unit(groups: list[dict], metric: str):
    mags = [abs(_num(_stat(g, metric).get("mean"))) for g in groups]
    mags = [x for x in mags if math.isfinite(x)]
    return metric_unit(metric, max(mags) if mags else 0.0)


def _stat_text(unit, s: dict) -> str:
    """``0.740 ± 0.020 [0.710, 0.770]`` in ``unit`` (spread and interval when there are)."""
    text = unit.number(s.get("mean"))
    sd = _num(s.get("sd"))
    if math.isfinite(sd) and text != "–":
        text += f" ± {unit.number(sd)}"
    ci = _ci(s)
    if ci is not None and text != "–":
        text += f" [{unit.number(ci[0])}, {unit.number(ci[1])}]"
    return text


def _clipped_note(unit, s: dict) -> str | None:
    """A cell's tooltip when its interval ends at a bound of the metric's range (summary.json
    ``bounds``): the Student-t interval went further and was clipped."""
    ci, bounds = _ci(s), s.get("bounds")
    if ci is None or not isinstance(bounds, (list, tuple)) or len(bounds) != 2 or not _num(s.get("sd")) > 0:
        return None
    lo, hi = _num(bounds[0]), _num(bounds[1])
    ends = [f"{unit.number(b)}" for c, b in ((ci[0], lo), (ci[1], hi)) if math.isfinite(b) and c == b]
    return f"interval clipped at {' and '.join(ends)}, the end of the metric's range" if ends else None


def _with_unit(metric: str, unit) -> str:
    return f"{metric} ({unit.suffix})" if unit.suffix else metric


def _tick_formatter() -> FuncFormatter:
    return FuncFormatter(lambda v, _pos: f"{v:,.6g}".replace(",", THIN_SEP))


def fig_sweep(groups: list[dict], metrics: list[str]) -> Figure:
    """One panel per metric: a bar per group at its mean, whiskers its 95% interval, a dot at
    the mean; colour by planner; values in the metric's unit (:func:`metric_unit`)."""
    n_g = len(groups)
    cols = 2 if len(metrics) > 1 else 1
    rows = math.ceil(len(metrics) / cols)
    panel_h = 0.32 * n_g + 1.1
    fig = _new_figure(11.0 if cols == 2 else 7.5, panel_h * rows + 0.4)
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False).ravel())
    planners = sorted({str(g.get("planner", "?")) for g in groups})
    pal = colormaps["tab10"]
    pc = {p: pal(i % 10) for i, p in enumerate(planners)}
    labels = [_group_label(g) for g in groups]
    y = np.arange(n_g)
    for ax, metric in zip(axes, metrics):
        unit = _column_unit(groups, metric)
        mean = np.array([_num(_stat(g, metric).get("mean")) for g in groups]) / unit.scale
        lo = np.full(n_g, np.nan)
        hi = np.full(n_g, np.nan)
        for i, g in enumerate(groups):
            ci = _ci(_stat(g, metric))
            if ci is not None:
                lo[i], hi[i] = ci[0] / unit.scale, ci[1] / unit.scale
        colours = [pc[str(g.get("planner", "?"))] for g in groups]
        ax.barh(y, np.nan_to_num(mean, posinf=0.0, neginf=0.0), color=colours, alpha=0.35, height=0.6)
        err = np.vstack([np.clip(mean - lo, 0, None), np.clip(hi - mean, 0, None)])
        has = np.isfinite(err).all(axis=0)
        ax.errorbar(mean[has], y[has], xerr=err[:, has], fmt="none", ecolor="black", elinewidth=1.2, capsize=3)
        ax.scatter(mean, y, c=colours, edgecolors="black", linewidths=0.5, zorder=3, s=28)
        ax.set_yticks(y)
        ax.set_yticklabels(labels, fontsize=8)
        ax.invert_yaxis()
        ax.set_title(_with_unit(metric, unit), fontsize=9)
        ax.xaxis.set_major_formatter(_tick_formatter())
        ax.grid(axis="x", alpha=0.3)
        finite = np.concatenate([mean[np.isfinite(mean)], lo[np.isfinite(lo)], hi[np.isfinite(hi)]])
        if finite.size:
            top = max(0.0, float(finite.max()))
            left = min(0.0, float(finite.min()))
            pad = 0.08 * (top - left if top > left else 1.0)
            ax.set_xlim(left - (pad if left < 0 else 0.0), top + pad)
    for ax in axes[len(metrics):]:
        ax.set_visible(False)
    fig.legend(handles=[Patch(color=pc[p], label=p) for p in planners], loc="lower center", ncol=len(planners),
               fontsize=8, frameon=False, title="planner (bar / dot: mean; whiskers: 95% interval)",
               title_fontsize=8)
    fig.tight_layout(rect=(0, 0.4 / (panel_h * rows + 0.4) + 0.02, 1, 1))
    return fig


def paired_differences(comparison: dict, first_minus_second: bool = True) -> dict:
    """One entry of ``summary["comparisons"]`` (``planner − baseline``, per metric, as
    :func:`swarm.experiments.sweep.summarize` writes it) turned around to "first − second":
    ``{"first", "second", "settings", "paired_seeds", "difference": {metric: {"mean", "sd",
    "ci95"}}}`` where ``first`` is the sweep's first planner (the summary's ``baseline``).
    ``first_minus_second=False`` keeps the summary's own ``second − first``."""
    base, other = str(comparison.get("baseline", "?")), str(comparison.get("planner", "?"))
    sign = -1.0 if first_minus_second else 1.0
    diffs = {}
    for metric, s in (comparison.get("difference") or {}).items():
        if not isinstance(s, dict):
            continue
        d = dict(s)
        d["mean"] = sign * _num(s.get("mean"))
        ci = _ci(s)
        d["ci95"] = sorted((sign * ci[0], sign * ci[1])) if ci is not None else None
        diffs[metric] = d
    first, second = (base, other) if first_minus_second else (other, base)
    return {"first": first, "second": second, "settings": dict(comparison.get("settings") or {}),
            "paired_seeds": comparison.get("paired_seeds"), "difference": diffs}


def _difference_cell(metric: str, unit, d: dict | None) -> dict:
    if not d:
        return _cell("–", "num")
    mean = _num(d.get("mean"))
    text = unit.number(mean, signed=True)
    ci = _ci(d)
    cls = "num"
    if ci is not None:
        text += f" [{unit.number(ci[0], signed=True)}, {unit.number(ci[1], signed=True)}]"
        if ci[0] > 0 or ci[1] < 0:
            direction = BETTER_DIRECTION.get(metric, 0) * (1 if ci[0] > 0 else -1)
            cls += " better" if direction > 0 else " worse" if direction < 0 else " differs"
    sd = _num(d.get("sd"))
    return _cell(text, cls, f"sd {unit.format(sd)}; {d.get('n', '?')} paired seeds" if math.isfinite(sd) else None)


def _difference_tables(comparisons: list, metrics: list[str], first_minus_second: bool) -> list[dict]:
    """One table per planner pair: a row per metric, a column per setting."""
    pairs: dict[tuple[str, str], list[dict]] = {}
    for c in comparisons:
        if isinstance(c, dict):
            d = paired_differences(c, first_minus_second)
            pairs.setdefault((d["first"], d["second"]), []).append(d)
    tables = []
    for (first, second), ds in pairs.items():
        names = [m for m in metrics if any(m in d["difference"] for d in ds)]
        if not names:
            continue
        header = ["metric"] + [f"{_settings_text(d['settings']) or 'all runs'} ({_fmt(d['paired_seeds'])} paired seeds)"
                               for d in ds]
        rows = []
        for metric in names:
            mags = [abs(_num(d["difference"].get(metric, {}).get("mean"))) for d in ds]
            mags = [x for x in mags if math.isfinite(x)]
            unit = metric_unit(metric, max(mags) if mags else 0.0)
            rows.append([_with_unit(metric, unit)]
                        + [_difference_cell(metric, unit, d["difference"].get(metric)) for d in ds])
        tables.append({"title": f"{first} {MINUS} {second}", "header": header, "rows": rows})
    return tables


def build_sweep_report(sweep_dir: Path, summary: dict, *, first_minus_second: bool = True) -> str:
    """The HTML text of a sweep's report (``sweep_report.html.j2``); see :func:`write_sweep_report`."""
    groups = summary.get("groups")
    if not isinstance(groups, list):
        raise ReportError(f"{sweep_dir}: summary has no 'groups' list")
    every = _metric_names(groups)
    constant = constant_metrics(groups, every)
    metrics = [m for m in every if m not in constant]
    title = f"Sweep: {summary.get('scenario', sweep_dir.name)}"
    settings_rows = [(k, ", ".join(_fmt(x) for x in v) if isinstance(v, list) else _fmt(v)) for k, v in summary.items()
                     if k not in ("groups", "comparisons", "interval")
                     and (isinstance(v, (str, int, float, bool)) or v is None
                          or (isinstance(v, list) and all(isinstance(x, (str, int, float)) for x in v)))]
    units = {m: _column_unit(groups, m) for m in metrics}
    summary_rows = []
    for g in groups:
        row: list = [g.get("planner", "?"), _settings_text(g.get("settings")) or "–", g.get("runs", "–")]
        for metric in metrics:
            s = _stat(g, metric)
            row.append(_cell(_stat_text(units[metric], s) if s else "–", "num", _clipped_note(units[metric], s)))
        summary_rows.append(row)
    left_out = [f"{m} = {format_metric(m, v)}" for m, v in constant.items()]
    sweep_figure = (_figure(fig_sweep(groups, metrics), "Each metric that differs between groups: bar and dot at "
                            "the mean, whiskers the 95% interval; colour by planner.", "sweep comparison")
                    if metrics and groups else None)
    comparisons = summary.get("comparisons") or []
    differences = _difference_tables(comparisons if isinstance(comparisons, list) else [], metrics,
                                     first_minus_second)
    nav = [("summary", "summary"), ("comparison", "comparison")] + ([("differences", "paired differences")]
                                                                    if differences else [])
    n_runs = sum(int(r) for r in (_num(g.get("runs")) for g in groups) if math.isfinite(r))
    return render(
        "sweep_report.html.j2",
        title=title,
        heading=title,
        sweep_dir=str(sweep_dir.resolve()),
        n_groups=len(groups),
        n_runs=n_runs,
        nav=nav,
        settings_rows=settings_rows,
        summary_header=["planner", "settings", "runs", *(_with_unit(m, units[m]) for m in metrics)],
        summary_rows=summary_rows,
        left_out=left_out,
        sweep_figure=sweep_figure,
        differences=differences,
        order_text="first planner minus second" if first_minus_second else "second planner minus first",
        interval_text=str(summary.get("interval") or "Student-t 95% interval of the mean over seeds"),
    )


def write_sweep_report(sweep_dir: str | Path, summary: dict, out_path: str | Path | None = None, *,
                       first_minus_second: bool = True) -> Path:
    """Write the HTML report of a sweep (default ``SWEEP_DIR/report.html``).

    ``summary`` has the shape of the sweep's ``summary.json``: ``{"groups": [{"planner": str,
    "settings": {key: value}, "runs": int, "metrics": {name: {"mean": float, "sd": float,
    "ci95": [lo, hi]}}}], "comparisons": [...], ...}``; other top-level scalar entries are listed
    as settings. Metrics that are the same in every group are named in one line, not tabled or
    drawn. Paired comparisons are shown as "first planner − second" (the summary's baseline
    minus the other planner; ``first_minus_second=False``: the summary's own order).
    """
    d = Path(sweep_dir)
    out = Path(out_path) if out_path is not None else d / "report.html"
    if not out.parent.is_dir():
        raise ReportError(f"{out.parent}: no such folder")
    atomic_write(out, build_sweep_report(d, summary, first_minus_second=first_minus_second).encode("utf-8"))
    return out
