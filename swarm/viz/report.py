"""Self-contained HTML reports: one run (:func:`write_report`) and a sweep (:func:`write_sweep_report`).

A report is one ``.html`` file that opens offline: inline CSS, no scripts, every figure a PNG
``data:`` URI, the run's animation (if one was made) a GIF ``data:`` URI or an MP4 base64
``<video>`` source. Nothing is fetched from anywhere.

A run report holds the scenario summary, the metrics (``metrics.json``), figures — trajectories
over the first-scan map, coverage and certainty over time (``timeseries.csv``), targets found
and watched over time, task load per UAV (seconds in search vs surveillance, stacked, as in the
paper's Fig. 14), radio counters — and a fault timeline (schedule windows, crashes, joins and
every UAV's state over time). Figures use km axes, one colour per UAV and legends that list
types instead of UAVs beyond 12 UAVs.
"""

from __future__ import annotations

import base64
import html
import io
import math
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch
from matplotlib.ticker import MaxNLocator

from comms.messages import MODE_SURVEIL
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
    MODE_COLOURS,
    km_axes,
    line_width,
    many_uavs,
    natural_key,
    type_markers,
    uav_colours,
)

ANIMATION_NAMES = ("animation.mp4", "animation.gif")
_DPI = 100


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


def _e(value) -> str:
    return html.escape(str(value), quote=True)


def _fmt(value) -> str:
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


def _table(rows: list[tuple], header: tuple | None = None, cls: str = "kv") -> str:
    out = [f'<table class="{cls}">' if cls else "<table>"]
    if header:
        out.append("<thead><tr>" + "".join(f"<th>{_e(h)}</th>" for h in header) + "</tr></thead>")
    out.append("<tbody>")
    for row in rows:
        out.append("<tr>" + "".join(f"<td>{_e(_fmt(c))}</td>" for c in row) + "</tr>")
    out.append("</tbody></table>")
    return "".join(out)


_CSS = """
body{font-family:-apple-system,'Segoe UI',Helvetica,Arial,sans-serif;margin:0;background:#f4f5f7;color:#222}
main{max-width:1120px;margin:0 auto;padding:18px 24px 40px}
h1{font-size:1.5em;margin:.2em 0}h2{font-size:1.2em;margin:1.6em 0 .5em;border-bottom:2px solid #dde;padding-bottom:4px}
.sub{color:#555;margin-bottom:10px}
nav a{margin-right:12px;color:#2b5ea7;text-decoration:none;font-size:.9em}
.cards{display:flex;flex-wrap:wrap;gap:10px;margin:12px 0}
.card{background:#fff;border:1px solid #dde;border-radius:6px;padding:8px 14px;min-width:120px}
.card b{display:block;font-size:1.35em}.card span{color:#666;font-size:.8em}
.row{display:flex;flex-wrap:wrap;gap:18px;align-items:flex-start}
.row>div{flex:1 1 340px}
table{border-collapse:collapse;background:#fff;font-size:.85em;margin:4px 0}
th,td{border:1px solid #dde;padding:3px 8px;text-align:left;vertical-align:top}
th{background:#eef1f6}td:not(:first-child){font-variant-numeric:tabular-nums}
figure{background:#fff;border:1px solid #dde;border-radius:6px;margin:10px 0;padding:8px;text-align:center}
figure img,figure video{max-width:100%;height:auto}
figcaption{color:#555;font-size:.85em;margin-top:4px;text-align:left}
.kv td:first-child{white-space:nowrap}.kv td{overflow-wrap:anywhere}
.scroll{overflow-x:auto}.note{color:#777;font-style:italic}
"""


def _page(title: str, body: str) -> str:
    return (f"<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{_e(title)}</title><style>{_CSS}</style></head>\n<body><main>\n{body}\n</main></body></html>\n")


def _figure(uri: str, caption: str, alt: str, width: int | None = None) -> str:
    w = f' width="{width}"' if width else ""
    return f'<figure><img src="{uri}" alt="{_e(alt)}"{w}><figcaption>{_e(caption)}</figcaption></figure>'


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
        end_marker = "x" if u in crashed else markers[rp.types[u]]
        ax.plot(xs[j[-1]], ys[j[-1]], end_marker, ms=6 if not many else 4, color=c, clip_on=False,
                mec="black" if u not in crashed else c, mew=0.5 if u not in crashed else 1.5, zorder=5)
    for k in range(rp.n_targets):
        tx, ty = rp.target_x[:, k], rp.target_y[:, k]
        ok = np.isfinite(tx)
        if not ok.any():
            continue
        ax.plot(tx[ok], ty[ok], "--", lw=0.7, color="black", zorder=2)
        found = np.isfinite(rp.found_t[k])
        j = np.flatnonzero(ok)[-1]
        ax.plot(tx[j], ty[j], "*", ms=9, mfc="#ff7f0e" if found else "white", mec="black", mew=0.6, zorder=6,
                clip_on=False)
    handles = []
    if many:
        for typ, m in markers.items():
            count = rp.types.count(typ)
            handles.append(Line2D([], [], ls="-", lw=lw, color="0.4", marker=m, mec="black",
                                  label=f"type {typ} ({count} UAVs)"))
        handles.append(Line2D([], [], ls="", label="one colour per UAV"))
    else:
        for u in sorted(range(rp.n_uavs), key=lambda u: natural_key(rp.names[u])):
            handles.append(Line2D([], [], ls="-", lw=lw, color=colours[rp.names[u]], marker=markers[rp.types[u]],
                                  mec="black", label=f"{rp.names[u]} ({rp.types[u]})"))
    handles += [Line2D([], [], ls="", marker="o", ms=4, mfc="white", mec="0.3", label="start"),
                Line2D([], [], ls="--", lw=0.7, color="black", marker="*", ms=8, mfc="#ff7f0e", mec="black",
                       label="target (found)"),
                Line2D([], [], ls="", marker="*", ms=8, mfc="white", mec="black", label="target (never found)")]
    if crashed:
        handles.append(Line2D([], [], ls="", marker="x", color="0.2", mew=1.5, label="crashed"))
    if rp.threats:
        handles.append(Patch(color="red", alpha=0.35, label="threat"))
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.8, 0.94), fontsize=7, frameon=False)
    m = rp.metrics or {}
    ax.set_title(f"{rp.header.get('scenario', '?')} · {rp.header.get('planner', '?')} · seed "
                 f"{rp.header.get('seed', '?')} · coverage {m.get('coverage', float('nan')):.3f}", fontsize=9)
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


def _animation_html(path: Path | None) -> str:
    if path is None:
        return ('<p class="note">No animation in this run folder. Make one with <code>swarm animate RUNDIR</code>, '
                'then run <code>swarm report RUNDIR</code> again to embed it.</p>')
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    if path.suffix.lower() == ".gif":
        media = f'<img src="data:image/gif;base64,{data}" alt="animation of the run">'
    elif path.suffix.lower() == ".mp4":
        media = (f'<video controls loop muted playsinline><source src="data:video/mp4;base64,{data}" '
                 'type="video/mp4">Your browser cannot play MP4 video.</video>')
    else:
        raise ReportError(f"{path}: an animation must be .gif or .mp4")
    return f"<figure>{media}<figcaption>{_e(path.name)} ({path.stat().st_size / 1e6:.1f} MB)</figcaption></figure>"


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
        ("radio", f"range {'unlimited' if rng is None else f'{rng / 1000:g} km'}, loss {radio.get('loss_base', 0):g}"
                  f"-{radio.get('loss_at_range', 0):g}, latency {radio.get('latency_s', 0):g} s"),
        ("faults scheduled", len(rp.faults)),
    ]
    return rows


def _metrics_rows(m: dict) -> list[tuple]:
    r = m.get("radio", {})
    v = m.get("violations", {})
    rows = [
        ("simulated / wall", f"{_fmt(m.get('sim_seconds'))} s / {_fmt(m.get('wall_seconds'))} s"),
        ("coverage", f"{m.get('coverage', float('nan')):.4f}"),
        ("certainty", f"{m.get('certainty', float('nan')):.4f}"),
        ("targets found", f"{m.get('targets_found')} / {m.get('targets_total')}"),
        ("surveillance ratio (mean)", f"{m.get('surveillance_ratio_mean', float('nan')):.3f}"),
        ("handovers (fast to slow)", f"{m.get('handovers')} ({m.get('handovers_fast_to_slow')})"),
        ("radio sent / delivered", f"{r.get('sent')} / {r.get('delivered')}"),
        ("radio dropped / rejected", f"{r.get('dropped')} / {r.get('rejected')}"),
        ("radio dropped by cause",
         ", ".join(f"{k} {n}" for k, n in (r.get("dropped_by_cause") or {}).items()) or "none"),
        ("radio bytes sent / duplicated / in flight",
         f"{r.get('bytes_sent')} / {r.get('duplicated')} / {r.get('in_flight')}"),
        ("violations separation / threat / dynamics",
         f"{v.get('separation')} / {v.get('threat')} / {v.get('dynamics')}"),
        ("faults applied", ", ".join(f"{k} {n}" for k, n in (m.get("faults_applied") or {}).items()) or "none"),
        ("event log SHA-256", m.get("event_log_sha256", "")),
    ]
    return rows


def build_run_report(rp: Replay, run_dir: Path, animation: Path | None) -> str:
    """The HTML text of a run's report."""
    m = rp.metrics or {}
    hd = rp.header
    title = f"{hd.get('scenario', 'run')} · {hd.get('planner', '?')} · seed {hd.get('seed', '?')}"
    parts = [f"<h1>{_e(title)}</h1>",
             f'<div class="sub">run folder <code>{_e(run_dir.resolve())}</code> · report written '
             f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC</div>",
             '<nav><a href="#figures">figures</a><a href="#animation">animation</a><a href="#faults">faults</a>'
             '<a href="#scenario">scenario</a><a href="#metrics">metrics</a><a href="#uavs">UAVs</a></nav>']
    cards = [("coverage", f"{m.get('coverage', float('nan')):.3f}"),
             ("certainty", f"{m.get('certainty', float('nan')):.3f}"),
             ("targets found", f"{m.get('targets_found', '?')} / {m.get('targets_total', rp.n_targets)}"),
             ("surveillance ratio", f"{m.get('surveillance_ratio_mean', float('nan')):.3f}"),
             ("handovers", m.get("handovers", "–")),
             ("UAVs", rp.n_uavs),
             ("simulated", f"{_fmt(rp.duration)} s")]
    parts.append('<div class="cards">' + "".join(f"<div class=\"card\"><b>{_e(v)}</b><span>{_e(k)}</span></div>"
                                                 for k, v in cards) + "</div>")
    parts.append('<h2 id="figures">Figures</h2>')
    figs = [
        (fig_trajectories(rp), "Trajectories: UAV paths (one colour each, end marker by type), target paths "
                               "(dashed), threats (red), over the map of when each cell was first scanned.",
         "trajectories", 820),
        (fig_coverage(rp), "Coverage and certainty over time (timeseries.csv); shaded: partitions; dashed: "
                           "crashes (red) and late joins (green).", "coverage and certainty", None),
        (fig_targets(rp), "Targets found (first detection) and targets watched by a UAV in surveillance mode.",
         "targets over time", None),
        (fig_task_load(rp), "Task load per UAV: seconds in search and in surveillance mode (from the pose events), "
                            "as in the paper's Fig. 14.", "task load per UAV", None),
        (fig_radio(rp), "Radio: cumulative frame copies sent, delivered, dropped and rejected; per-interval "
                        "delivery; drops by cause (metrics.json).", "radio counters", None),
    ]
    for fig, caption, alt, width in figs:
        if fig is None:
            parts.append(f'<p class="note">{_e(alt)}: no timeseries.csv in the run folder.</p>')
            continue
        parts.append(_figure(_png_uri(fig), caption, alt, width))
    parts.append('<h2 id="animation">Animation</h2>')
    parts.append(_animation_html(animation))
    parts.append('<h2 id="faults">Fault timeline</h2>')
    parts.append(_figure(_png_uri(fig_fault_timeline(rp)),
                         "Fault windows from the schedule in the event log's start header (orange: link faults, "
                         "red: partitions), crashes and late joins, and every UAV's state over time.",
                         "fault timeline"))
    events = fault_events(rp)
    if events:
        parts.append(_table([(f"{t:g} s", text) for t, text, _k, _u in events], ("time", "event")))
    else:
        parts.append('<p class="note">No faults in this run.</p>')
    applied = m.get("faults_applied") or {}
    if applied:
        parts.append("<p>Times each fault kind changed something (metrics.json <code>faults_applied</code>):</p>")
        parts.append(_table(sorted(applied.items()), ("kind", "times applied")))
    parts.append('<div class="row"><div><h2 id="scenario">Scenario</h2>' + _table(_scenario_rows(rp)) + "</div>"
                 '<div><h2 id="metrics">Metrics</h2>'
                 + (_table(_metrics_rows(m)) if m else '<p class="note">No metrics.json in the run folder.</p>')
                 + "</div></div>")
    parts.append('<h2 id="uavs">UAVs</h2>')
    secs = rp.mode_seconds()
    per = m.get("per_uav", {})
    rows = []
    for u in _uav_order(rp):
        name = rp.names[u]
        p = per.get(name, {})
        s = secs[name]
        rows.append((name, rp.types[u], p.get("state", "–"), s["search"], s["surveil"], s["not flying"],
                     p.get("frames_sent"), p.get("frames_delivered"), p.get("frames_rejected"), p.get("plans")))
    header = ("UAV", "type", "final state", "search s", "surveillance s", "not flying s", "frames sent",
              "frames received", "frames rejected", "plans")
    parts.append('<div class="scroll">' + _table(rows, header, cls="grid") + "</div>")
    handovers = m.get("handover_list") or []
    if handovers:
        parts.append("<h2>Handovers</h2>")
        parts.append(_table([(f"{h['t']:g} s", h["target"], f"{h['from']} ({h['from_type']})",
                              f"{h['to']} ({h['to_type']})", f"{h['latency_s']:g} s") for h in handovers],
                            ("time", "target", "from", "to", "latency")))
    return _page(f"Report: {title}", "\n".join(parts))


def write_report(run_dir: str | Path, out: str | Path | None = None, animation: str | Path | None = None) -> Path:
    """Write the HTML report of the run in ``run_dir`` (default ``RUN_DIR/report.html``).

    ``animation``: the animation to embed (default: the newest ``animation.mp4`` / ``.gif`` in
    the run folder, if any). Returns the path written.
    """
    d = Path(run_dir)
    rp = load_run(d)
    if rp.metrics is None:
        raise RunDirError(f"{d / 'metrics.json'}: missing; a complete run folder has it (written last by `swarm run`)")
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


# --- sweep report -----------------------------------------------------------------------------

def _num(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def _group_label(g: dict) -> str:
    settings = g.get("settings") or {}
    s = ", ".join(f"{k}={_fmt(v)}" for k, v in settings.items())
    return f"{g.get('planner', '?')}" + (f" · {s}" if s else "")


def _metric_names(groups: list[dict]) -> list[str]:
    names: list[str] = []
    for g in groups:
        for k in (g.get("metrics") or {}):
            if k not in names:
                names.append(k)
    return names


def fig_sweep(groups: list[dict], metrics: list[str]) -> Figure:
    """One panel per metric: a bar per group at its mean, whiskers its 95% interval, a dot at
    the mean; colour by planner."""
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
        mean = np.array([_num((g.get("metrics") or {}).get(metric, {}).get("mean")) for g in groups])
        lo = np.full(n_g, np.nan)
        hi = np.full(n_g, np.nan)
        for i, g in enumerate(groups):
            ci = (g.get("metrics") or {}).get(metric, {}).get("ci95")
            if isinstance(ci, (list, tuple)) and len(ci) == 2:
                lo[i], hi[i] = _num(ci[0]), _num(ci[1])
        colours = [pc[str(g.get("planner", "?"))] for g in groups]
        ax.barh(y, np.nan_to_num(mean), color=colours, alpha=0.35, height=0.6)
        err = np.vstack([np.clip(mean - lo, 0, None), np.clip(hi - mean, 0, None)])
        has = np.isfinite(err).all(axis=0)
        ax.errorbar(mean[has], y[has], xerr=err[:, has], fmt="none", ecolor="black", elinewidth=1.2, capsize=3)
        ax.scatter(mean, y, c=colours, edgecolors="black", linewidths=0.5, zorder=3, s=28)
        ax.set_yticks(y)
        ax.set_yticklabels(labels, fontsize=8)
        ax.invert_yaxis()
        ax.set_title(metric, fontsize=9)
        ax.grid(axis="x", alpha=0.3)
        finite = np.concatenate([mean[np.isfinite(mean)], lo[np.isfinite(lo)], hi[np.isfinite(hi)]])
        if finite.size:
            top = float(finite.max())
            left = min(0.0, float(finite.min()))
            ax.set_xlim(left, top + 0.08 * (top - left if top > left else 1.0))
    for ax in axes[len(metrics):]:
        ax.set_visible(False)
    fig.legend(handles=[Patch(color=pc[p], label=p) for p in planners], loc="lower center", ncol=len(planners),
               fontsize=8, frameon=False, title="planner (bar / dot: mean; whiskers: 95% interval)",
               title_fontsize=8)
    fig.tight_layout(rect=(0, 0.4 / (panel_h * rows + 0.4) + 0.02, 1, 1))
    return fig


def build_sweep_report(sweep_dir: Path, summary: dict) -> str:
    groups = summary.get("groups")
    if not isinstance(groups, list):
        raise ReportError(f"{sweep_dir}: summary has no 'groups' list")
    metrics = _metric_names(groups)
    title = f"Sweep: {summary.get('scenario', sweep_dir.name)}"
    parts = [f"<h1>{_e(title)}</h1>",
             f'<div class="sub">sweep folder <code>{_e(sweep_dir.resolve())}</code> · {len(groups)} groups · '
             f"{sum(int(r) for r in (_num(g.get('runs')) for g in groups) if math.isfinite(r))} runs · report written "
             f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC</div>",
             '<nav><a href="#summary">summary</a><a href="#comparison">comparison</a></nav>']
    extra = [(k, ", ".join(_fmt(x) for x in v) if isinstance(v, list) else _fmt(v)) for k, v in summary.items()
             if k != "groups" and (isinstance(v, (str, int, float, bool)) or v is None
                                   or (isinstance(v, list) and all(isinstance(x, (str, int, float)) for x in v)))]
    if extra:
        parts.append(_table(extra, ("setting", "value")))
    parts.append('<h2 id="summary">Summary</h2>')
    rows = []
    for g in groups:
        settings = ", ".join(f"{k}={_fmt(v)}" for k, v in (g.get("settings") or {}).items()) or "–"
        row = [g.get("planner", "?"), settings, g.get("runs", "–")]
        for metric in metrics:
            s = (g.get("metrics") or {}).get(metric)
            if not s:
                row.append("–")
                continue
            ci = s.get("ci95")
            ci_ok = isinstance(ci, (list, tuple)) and len(ci) == 2
            ci_txt = f" [{_fmt(_num(ci[0]))}, {_fmt(_num(ci[1]))}]" if ci_ok else ""
            row.append(f"{_fmt(_num(s.get('mean')))} ± {_fmt(_num(s.get('sd')))}{ci_txt}")
        rows.append(tuple(row))
    header = ("planner", "settings", "runs", *metrics)
    parts.append('<div class="scroll">' + _table(rows, header, cls="grid") + "</div>")
    parts.append('<p class="note">Cells: mean ± standard deviation [95% interval] over the runs of a group.</p>')
    parts.append('<h2 id="comparison">Comparison</h2>')
    if metrics and groups:
        parts.append(_figure(_png_uri(fig_sweep(groups, metrics)),
                             "Each metric per group: bar and dot at the mean, whiskers the 95% interval; colour "
                             "by planner.", "sweep comparison"))
    else:
        parts.append('<p class="note">No metrics to compare.</p>')
    return _page(title, "\n".join(parts))


def write_sweep_report(sweep_dir: str | Path, summary: dict, out_path: str | Path | None = None) -> Path:
    """Write the HTML report of a sweep (default ``SWEEP_DIR/report.html``).

    ``summary`` has the shape of the sweep's ``summary.json``: ``{"groups": [{"planner": str,
    "settings": {key: value}, "runs": int, "metrics": {name: {"mean": float, "sd": float,
    "ci95": [lo, hi]}}}], ...}``; other top-level scalar entries are listed as settings.
    """
    d = Path(sweep_dir)
    out = Path(out_path) if out_path is not None else d / "report.html"
    if not out.parent.is_dir():
        raise ReportError(f"{out.parent}: no such folder")
    atomic_write(out, build_sweep_report(d, summary).encode("utf-8"))
    return out
