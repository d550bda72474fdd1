"""The figures of a run's report, from its :class:`~swarm.viz.replay.Replay`."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from matplotlib import colormaps
from matplotlib.artist import Artist
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator

from comms.messages import MODE_SURVEIL
from swarm.viz.hazards import draw_hazards, hazards_of
from swarm.viz.replay import (
    Replay,
    fault_label,
    first_seen_map,
)
from swarm.viz.report.html import new_figure
from swarm.viz.style import (
    CRASH_MARKER,
    MODE_COLOURS,
    TARGET_FOUND_COLOUR,
    TARGET_NOT_FOUND_COLOUR,
    km_axes,
    line_width,
    many_uavs,
    natural_key,
    type_markers,
    uav_colours,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes

# --- run figures ------------------------------------------------------------------------------

def uav_order(rp: Replay) -> list[int]:
    return sorted(range(rp.n_uavs), key=lambda u: (rp.types[u], natural_key(rp.names[u])))


def fig_trajectories(rp: Replay) -> Figure:
    """UAV and target paths over the first-scan map, the no-fly zones, the area polygon and the
    base (the paper's Fig. 9 layout)."""
    w, h, _c = rp.area
    fig = new_figure(8.2, 7.0)
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
    hazard_handles = draw_hazards(ax, hazards_of(rp.scenario, rp.threats))[1]
    crashed = {uid for _t, uid in rp.crashes}
    for u in uav_order(rp):
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
    handles += hazard_handles
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.8, 0.94), fontsize=7, frameon=False)
    metrics = rp.metrics or {}
    ax.set_title(f"{rp.header.get('scenario', '?')} · {rp.header.get('planner', '?')} · seed "
                 f"{rp.header.get('seed', '?')} · coverage {metrics.get('coverage', float('nan')):.3f}", fontsize=9)
    return fig


def _fault_spans(ax: Axes, rp: Replay, label: bool = True) -> None:
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
    fig = new_figure(8.0, 3.6)
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
    counts: np.ndarray = new.sum(axis=1)
    return counts


def fig_targets(rp: Replay) -> Figure:
    fig = new_figure(8.0, 3.4)
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


_MODE_LABELS = {"search": "search", "surveil": "surveillance", "not flying": "not flying (pending / landed / crashed)"}


def fig_task_load(rp: Replay) -> Figure:
    """Seconds in search vs surveillance mode per UAV, stacked (the paper's Fig. 14)."""
    order = uav_order(rp)
    secs = rp.mode_seconds()
    n = len(order)
    fig = new_figure(min(max(6.0, 0.45 * n + 2.0), 16.0), 3.8)
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
    fig = new_figure(10.0, 3.5)
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
    """(uavs, ticks) codes: 0 pending, 1 search, 2 surveillance, 3 crashed, 4 landed (at its
    base between two sorties, [endurance])."""
    state = np.where(rp.mode == MODE_SURVEIL, 2, np.where(rp.mode >= 0, 1, 0)).T.astype(np.int8)
    times = rp.times
    for t, uid in rp.landings:
        back = min((t1 for t1, u in rp.launches if u == uid and t1 > t), default=math.inf)
        state[uid, (times >= t - 1e-9) & (times < back - 1e-9)] = 4
    for t, uid in rp.crashes:
        state[uid, times >= t - 1e-9] = 3
    return state


def fig_fault_timeline(rp: Replay) -> Figure:
    order = uav_order(rp)
    windowed = [f for f in rp.faults if f.get("kind") not in ("crash", "join")]
    node = [(t, "crash", rp.names[u]) for t, u in rp.crashes] + [(t, "join", rp.names[u]) for t, u in rp.joins if t > 0]
    n_rows = len(windowed) + (1 if node else 0)
    h_top = 0.35 * max(n_rows, 1) + 0.8
    h_bot = min(0.18 * rp.n_uavs + 1.0, 9.0)
    fig = new_figure(10.0, h_top + h_bot)
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
    cmap = ListedColormap(["#ffffff", MODE_COLOURS["search"], MODE_COLOURS["surveil"], "#404040", "#9ecae1"])
    ax2.imshow(state, aspect="auto", cmap=cmap, vmin=-0.5, vmax=4.5, interpolation="nearest",
               extent=(0, rp.n_ticks * rp.dt, len(order) - 0.5, -0.5))
    step = max(1, math.ceil(len(order) / 40))
    ax2.set_yticks(np.arange(len(order))[::step])
    ax2.set_yticklabels([rp.names[u] for u in order][::step], fontsize=7 if len(order) <= 40 else 6)
    ax2.set_xlim(0, rp.duration)
    ax2.set_xlabel("time (s)")
    handles = [Patch(fc="#ffffff", ec="0.5", label="pending"), Patch(color=MODE_COLOURS["search"], label="search"),
               Patch(color=MODE_COLOURS["surveil"], label="surveillance"), Patch(color="#404040", label="crashed"),
               Patch(color="#9ecae1", label="landed")]
    fig.legend(handles=handles, fontsize=7, ncol=5, loc="lower center", frameon=False)
    fig.tight_layout(rect=(0, 0.3 / (h_top + h_bot), 1, 1))
    return fig
