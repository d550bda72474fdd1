"""The paper's figures, ours: Fig. 11, 12, 13-15 and 18."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.artist import Artist
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from comms.messages import MODE_SURVEIL
from swarm.experiments.common import (
    no_data,
    save_figure,
    subplots,
)
from swarm.experiments.paper.design import CASE3_WINDOW_FROM_S, FIG11_PLANNERS, PAPER, PLANNER_COLOUR, PLANNER_LABEL
from swarm.experiments.paper.logs import RunLog, band, read_timeseries, stack
from swarm.experiments.sweep import describe
from swarm.viz.style import uav_colours

if TYPE_CHECKING:
    from matplotlib.axes import Axes

# --- figures -----------------------------------------------------------------------------------

def _draw_band(ax: Axes, t: np.ndarray, values: np.ndarray, colour: str, label: str,
               bounds: tuple[float, float] | None = None) -> None:
    """Mean line, 95% band of the mean and min-max spread over runs; ``bounds``: the range the
    quantity can take (the band of a few runs is clipped to it)."""
    b = band(values)
    if bounds is not None:
        b = {k: np.clip(v, *bounds) for k, v in b.items()}
    n = values.shape[0]
    ax.fill_between(t, b["min"], b["max"], color=colour, alpha=0.10, lw=0,
                    label=f"{label} min-max" if n > 1 else None)
    if n > 1:
        ax.fill_between(t, b["lo"], b["hi"], color=colour, alpha=0.30, lw=0, label=f"{label} 95% CI of mean")
    ax.plot(t, b["mean"], "-", color=colour, lw=1.6, label=f"{label} mean ({n} run{'s' if n != 1 else ''})")


def fig11_over_time(runs: dict[str, list[dict[str, Any]]], path: Path) -> Path:
    """Coverage and targets found over time per planner (paper Fig. 10a-b / 11a-b); reference
    planners (not in the paper) are labelled as such, drawn dashed with their 95% band only (no
    min-max spread), and have no quoted value."""
    fig, axes = subplots(1, 2, figsize=(12, 4.8))
    quoted = PAPER["fig11"]
    for ax, col, ylabel, letter in ((axes[0], "coverage", "coverage rate", "a"),
                                    (axes[1], "targets_found", "number of targets found", "b")):
        any_data = False
        t_end = 0.0
        for p in runs:
            if not runs.get(p):
                continue
            any_data = True
            t, v = stack(runs[p], col)
            t_end = max(t_end, float(t[-1]))
            top = 1.0 if col == "coverage" else float(runs[p][0]["metrics"]["targets_total"])
            colour, label = PLANNER_COLOUR.get(p, "tab:gray"), PLANNER_LABEL.get(p, p)
            if p in FIG11_PLANNERS:
                _draw_band(ax, t, v, colour, label, (0.0, top))
            else:
                b = {k: np.clip(a, 0.0, top) for k, a in band(v).items()}
                if v.shape[0] > 1:
                    ax.fill_between(t, b["lo"], b["hi"], color=colour, alpha=0.25, lw=0)
                ax.plot(t, b["mean"], "--", color=colour, lw=1.4, label=f"{label} mean, 95% CI ({v.shape[0]} runs)")
        if any_data and math.isclose(t_end, quoted["duration_s"]):
            for p in FIG11_PLANNERS:  # the paper quotes only its own pair
                ax.plot([t_end], [quoted[col][p]], marker="D", mfc="none", mec=PLANNER_COLOUR[p], ms=8, ls="none",
                        label=f"{PLANNER_LABEL[p]} paper (quoted): {quoted[col][p]:g}")
        if not any_data:
            no_data(ax)
        ax.set_xlabel("time (s)")
        ax.set_ylabel(ylabel)
        ax.set_title(f"({letter}) {ylabel} over time, paper-fig11 (paper Fig. 11{letter})", fontsize=10)
        ax.grid(alpha=0.3)
        ax.set_xlim(left=0)
        ax.set_ylim(bottom=0)
        if any_data:
            ax.legend(fontsize=6.5, loc="upper left")
    return save_figure(fig, path)


def fig11_final(runs: dict[str, list[dict[str, Any]]], path: Path) -> Path:
    """Final coverage and targets found per planner, ours (mean, 95% interval) next to the
    paper's quoted means (the paper's pair only: reference planners are not in the paper)."""
    planners = list(runs) or list(FIG11_PLANNERS)
    fig, axes = subplots(1, 2, figsize=(max(9.0, 2.2 * len(planners)), 4.5))
    quoted = PAPER["fig11"]
    x = np.arange(len(planners))
    for ax, key, ylabel in ((axes[0], "coverage", "coverage rate at end"),
                            (axes[1], "targets_found", "targets found at end")):
        means: list[float] = []
        errs: list[list[float]] = []
        ns: list[int] = []
        durations: set[float] = set()
        for p in planners:
            vals = [r["metrics"][key] for r in runs.get(p, [])]
            durations |= {r["metrics"]["sim_seconds"] for r in runs.get(p, [])}
            d: dict[str, Any] = describe(vals) if vals else {"n": 0, "mean": math.nan, "ci95": [math.nan, math.nan]}
            means.append(d["mean"])
            errs.append([d["mean"] - d["ci95"][0], d["ci95"][1] - d["mean"]])
            ns.append(d["n"])
        bars = np.array(errs).T  # (2, planners): below and above each mean
        ax.bar(x - 0.2, means, 0.38, yerr=bars, capsize=5, color=[PLANNER_COLOUR.get(p, "tab:gray") for p in planners],
               alpha=0.8, label="ours (measured, mean, 95% CI)")
        paper_i = [i for i, p in enumerate(planners) if p in quoted[key]]
        ax.bar(x[paper_i] + 0.2, [quoted[key][planners[i]] for i in paper_i], 0.38, color="white",
               edgecolor=[PLANNER_COLOUR[planners[i]] for i in paper_i], hatch="//", label="paper (quoted, 2000 s)")
        for i, (m, n) in enumerate(zip(means, ns)):
            if math.isfinite(m):
                top_i = m + (bars[1][i] if math.isfinite(bars[1][i]) else 0.0)
                ax.text(x[i] - 0.2, top_i, f"{m:.3g}\nn={n}", ha="center", va="bottom", fontsize=7)
            if i in paper_i:
                ax.text(x[i] + 0.2, quoted[key][planners[i]], f"{quoted[key][planners[i]]:g}",
                        ha="center", va="bottom", fontsize=7)
            else:
                ax.text(x[i] + 0.2, 0.0, "not in\nthe paper", ha="center", va="bottom", fontsize=6, color="0.4")
        ax.set_xticks(x, [PLANNER_LABEL.get(p, p).replace(" (", "\n(") for p in planners])
        ax.set_ylabel(ylabel)
        dur = ", ".join(f"{d:g} s" for d in sorted(durations)) or "-"
        ax.set_title(f"{ylabel} (ours at {dur})", fontsize=10)
        ax.grid(axis="y", alpha=0.3)
        top = np.nanmax([*(np.array(means) + bars[1]), *(quoted[key][planners[i]] for i in paper_i)])
        ax.set_ylim(0, 1.3 * top)
        ax.legend(fontsize=7, loc="upper center", ncol=2)
    return save_figure(fig, path)


def case1_distance(log: RunLog, path: Path, target: int = 0) -> Path:
    """Distance of every UAV to a target over time (paper Fig. 12d), handovers and mode
    changes marked, thick where the UAV is in surveillance of that target."""
    fig, ax = subplots(figsize=(11, 5))
    names = [log.names[u] for u in log.poses]
    colours = uav_colours(names)
    if target not in log.targets:
        no_data(ax, f"no target {target + 1} in this run")
        return save_figure(fig, path)
    for uid in sorted(log.poses, key=lambda u: log.names[u]):
        p = log.poses[uid]
        name = log.names[uid]
        c = colours[name]
        txy = log.target_at(target, p[:, 0])
        d = np.hypot(p[:, 1] - txy[:, 0], p[:, 2] - txy[:, 1]) / 1000
        ax.plot(p[:, 0], d, "-", color=c, lw=1.2, label=f"{name} (type {log.types.get(uid, '?')})")
        on = (p[:, 3] == MODE_SURVEIL) & (p[:, 4] == target)
        ax.plot(p[:, 0], np.where(on, d, np.nan), "-", color=c, lw=4, alpha=0.45)
        for e in log.modes:
            if e.uav != uid or e.t <= 0:
                continue
            i = min(int(np.searchsorted(p[:, 0], e.t)), len(p) - 1)
            if e.mode == "surveil":
                ax.plot(e.t, d[i], "^", color=c, mec="black", mew=0.6, ms=7)
                ax.annotate(f"T{e.target + 1}", (e.t, d[i]), textcoords="offset points", xytext=(3, 5), fontsize=7,
                            color=c)
            else:
                ax.plot(e.t, d[i], "v", color=c, mec="black", mew=0.6, ms=7)
    styles = iter([(0, (1, 2)), (0, (4, 2)), (0, (6, 2, 1, 2)), (0, (1, 4))])
    for typ, spec in sorted(log.type_specs.items()):
        if any(log.types.get(u) == typ for u in log.poses):
            ax.axhline(spec["detect_radius_m"] / 1000, color="grey", ls=next(styles, ":"), lw=0.9,
                       label=f"detection radius, type {typ} ({spec['detect_radius_m'] / 1000:g} km)")
    if target in log.found:
        t, u = log.found[target]
        ax.axvline(t, color="black", ls="--", lw=0.8)
        ax.annotate(f"target {target + 1} found by {log.names.get(u, u)}", (t, 1), xycoords=("data", "axes fraction"),
                    rotation=90, va="top", ha="right", fontsize=7)
    for ho in log.handovers:
        if ho.target == target:
            ax.axvline(ho.t, color="black", ls=":", lw=1.0)
            ax.annotate(f"handover {log.names.get(ho.from_uav, ho.from_uav)} → {log.names.get(ho.to_uav, ho.to_uav)}",
                        (ho.t, 1),
                        xycoords=("data", "axes fraction"), rotation=90, va="top", ha="right", fontsize=7)
    handles, labels = ax.get_legend_handles_labels()
    handles += [Line2D([], [], color="grey", lw=4, alpha=0.45),
                Line2D([], [], marker="^", color="grey", mec="black", ls="none"),
                Line2D([], [], marker="v", color="grey", mec="black", ls="none")]
    labels += [f"in surveillance of target {target + 1}", "switch to surveillance (of target T#)",
               "switch to search"]
    ax.legend(handles, labels, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"distance to target {target + 1} (km)")
    ax.set_xlim(0, log.end_t)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.set_title(f"{log.metrics['scenario']}: distance between UAVs and target {target + 1} (paper Fig. 12d)",
                 fontsize=10)
    return save_figure(fig, path)


MODE_COLOUR = {"search": "#9ecae1", "surveil": "#fd8d3c", "pending": "#eeeeee", "down": "#636363"}


def task_loads(log: RunLog, path: Path, title: str) -> Path:
    """Per UAV: a timeline coloured by mode (target number on surveillance stretches, handovers
    marked) and the seconds spent in each mode (paper Fig. 14)."""
    uids = sorted(log.names, key=lambda u: (log.is_slow(u), log.names[u]))
    fig, (ax, bx) = subplots(1, 2, figsize=(13, 0.45 * len(uids) + 2.0), sharey=True,
                                 gridspec_kw={"width_ratios": [4, 1]})
    colours = uav_colours([log.names[u] for u in uids])
    ypos = {u: len(uids) - 1 - i for i, u in enumerate(uids)}
    totals = {u: {k: 0.0 for k in MODE_COLOUR} for u in uids}
    for u in uids:
        y = ypos[u]
        for a, b, mode, tg in log.mode_segments(u):
            totals[u][mode] += b - a
            ax.broken_barh([(a, b - a)], (y - 0.35, 0.7), facecolors=MODE_COLOUR[mode], edgecolor="none")
            if mode == "surveil" and tg >= 0 and b - a >= 0.03 * log.end_t:
                ax.text((a + b) / 2, y, f"T{tg + 1}", ha="center", va="center", fontsize=7)
    for e in log.handovers:
        if e.from_uav in ypos and e.to_uav in ypos:
            ax.annotate("", xy=(e.t, ypos[e.to_uav]), xytext=(e.t, ypos[e.from_uav]),
                        arrowprops={"arrowstyle": "->", "color": "black", "lw": 0.8})
    for t, u in log.found.values():
        if u in ypos:
            ax.plot(t, ypos[u] + 0.38, "v", color="black", ms=4)
    labels = [f"{log.names[u]} ({'slow' if log.is_slow(u) else 'fast'}, {log.types.get(u, '?')})" for u in uids]
    ax.set_yticks([ypos[u] for u in uids], labels)
    for tick, u in zip(ax.get_yticklabels(), uids):
        tick.set_color(colours[log.names[u]])
    ax.set_xlim(0, log.end_t)
    ax.set_xlabel("time (s)")
    ax.set_title(title, fontsize=10)
    handles: list[Artist] = [Patch(color=MODE_COLOUR[k], label=k) for k in ("search", "surveil")]
    if any(totals[u]["pending"] for u in uids):
        handles.append(Patch(color=MODE_COLOUR["pending"], label="not joined yet"))
    if any(totals[u]["down"] for u in uids):
        handles.append(Patch(color=MODE_COLOUR["down"], label="down"))
    handles += [Line2D([], [], marker="v", color="black", ls="none", ms=4, label="found a target"),
                Line2D([], [], marker=r"$\uparrow$", color="black", ls="none", label="handover (arrow old → new)")]
    ax.legend(handles=handles, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=len(handles),
              frameon=False)
    left = np.zeros(len(uids))
    ys = np.array([ypos[u] for u in uids])
    for mode in ("search", "surveil", "pending", "down"):
        w = np.array([totals[u][mode] for u in uids])
        if w.any():
            bx.barh(ys, w, left=left, height=0.7, color=MODE_COLOUR[mode], label=mode)
            left += w
    bx.set_xlabel("seconds per mode (s)")
    bx.set_title("task load", fontsize=10)
    bx.grid(axis="x", alpha=0.3)
    return save_figure(fig, path)


def case2_coverage(run_dir: Path, seed_runs: Sequence[dict[str, Any]], path: Path) -> Path:
    """Coverage over time of the Case 2 run (paper Fig. 15), and over seeds if there are any."""
    fig, ax = subplots(figsize=(8, 4.8))
    ts = read_timeseries(run_dir)
    m = json.loads((run_dir / "metrics.json").read_text())
    if len(seed_runs) > 1:
        t, v = stack(seed_runs, "coverage")
        _draw_band(ax, t, v, "tab:grey", "seeds", (0.0, 1.0))
    ax.plot(ts["t"], ts["coverage"], "-", color="tab:green", lw=1.8, label=f"seed {m['seed']} (the run shown in the figures)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("coverage rate")
    ax.set_xlim(0, m["sim_seconds"])
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title(f"{m['scenario']}: coverage rate of the UAV swarm (paper Fig. 15)", fontsize=10)
    return save_figure(fig, path)


def case3_coverage(without: Sequence[dict[str, Any]], with_: Sequence[dict[str, Any]], join_s: float | None, path: Path,
                   joiner: str | None = None) -> Path:
    """Mean coverage over seeds with and without the joining UAV (paper Fig. 18), join time
    marked; below, the paired difference with its 95% interval."""
    fig, (ax, bx) = subplots(2, 1, figsize=(8.5, 7.5), sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    if without and with_:
        t2, v2 = stack(without, "coverage")
        t3, v3 = stack(with_, "coverage")
        n = min(len(t2), len(t3))
        t = t2[:n]
        _draw_band(ax, t, v2[:, :n], "tab:blue", "Case 2, 10 UAVs", (0.0, 1.0))
        _draw_band(ax, t, v3[:, :n], "tab:red", "Case 3, 11 UAVs", (0.0, 1.0))
        _draw_band(bx, t, v3[:, :n] - v2[:, :n], "tab:purple", "Case 3 − Case 2 (paired)", (-1.0, 1.0))
        t_end = float(t[-1])
        ax.set_xlim(0, max(t_end, (join_s or 0) * 1.1))
        bx.axhline(0, color="black", lw=0.8)
        ax.legend(fontsize=7, loc="lower right")
        bx.legend(fontsize=7, loc="upper left")
    else:
        t_end = 0.0
        no_data(ax)
    if join_s is not None:
        for a in (ax, bx):
            a.axvline(join_s, color="black", ls="--", lw=1.0)
        ax.annotate(f"{joiner or 'a UAV'} (paper: UAV 11) joins at {join_s:g} s", (join_s, 0.02),
                    xycoords=("data", "axes fraction"), rotation=90, ha="right", va="bottom", fontsize=8)
    if without and with_ and t_end >= CASE3_WINDOW_FROM_S:
        for a in (ax, bx):
            a.axvspan(CASE3_WINDOW_FROM_S, t_end, color="grey", alpha=0.07, lw=0)
        ax.annotate(f"table: mean from {CASE3_WINDOW_FROM_S:g} s on", (CASE3_WINDOW_FROM_S, 0.98),
                    xycoords=("data", "axes fraction"), ha="left", va="top", fontsize=7, color="grey")
    ax.set_ylabel("coverage rate")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.set_title("Coverage rate with 10 and 11 UAVs, mean over the same seeds (paper Fig. 18)", fontsize=10)
    bx.set_xlabel("time (s)")
    bx.set_ylabel("coverage difference")
    bx.grid(alpha=0.3)
    return save_figure(fig, path)
