"""A sweep's HTML report (``swarm report SWEEP_FOLDER``): per-group statistics, a panel per
metric that differs, paired differences."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.ticker import FuncFormatter

from swarm.outputs import atomic_write
from swarm.viz.report.html import MINUS, ReportError, as_number, cell, figure_item, fmt, new_figure, render
from swarm.viz.style import (
    THIN_SEP,
    format_metric,
    metric_unit,
)

if TYPE_CHECKING:
    from swarm.viz.style import Unit

# --- sweep report -----------------------------------------------------------------------------

# Metrics where a higher value is plainly better (+1) or worse (-1); paired differences of the
# others are only marked as differing.
BETTER_DIRECTION = {"coverage": 1, "certainty": 1, "targets_found": 1, "surveillance_ratio_mean": 1,
                    "violations.separation": -1, "violations.threat": -1, "violations.dynamics": -1}



def _settings_text(settings: dict[str, Any] | None) -> str:
    return ", ".join(f"{k}={fmt(v)}" for k, v in (settings or {}).items())


def _group_label(g: dict[str, Any]) -> str:
    s = _settings_text(g.get("settings"))
    return f"{g.get('planner', '?')}" + (f" · {s}" if s else "")


def _metric_names(groups: list[dict[str, Any]]) -> list[str]:
    names: list[str] = []
    for g in groups:
        for k in (g.get("metrics") or {}):
            if k not in names:
                names.append(k)
    return names


def _split_breakdowns(names: list[str], prefixes: object) -> tuple[list[str], dict[str, int]]:
    """``(shown, {prefix: count})``: the metrics outside the summary's ``breakdowns`` (its
    tables kept per UAV or per target), and how many metrics each breakdown holds. The report
    shows the swarm's metrics; a per-UAV column for each of 300 UAVs would bury them (the
    breakdowns stay in summary.json, summary.csv and runs.csv)."""
    tables = [str(p) for p in prefixes] if isinstance(prefixes, list) else []
    counts = dict.fromkeys(tables, 0)
    shown = []
    for name in names:
        owner = next((p for p in tables if name.startswith(f"{p}.")), None)
        if owner is None:
            shown.append(name)
        else:
            counts[owner] += 1
    return shown, {p: n for p, n in counts.items() if n}


def _stat(g: dict[str, Any], metric: str) -> dict[str, Any]:
    s = (g.get("metrics") or {}).get(metric)
    return s if isinstance(s, dict) else {}


def _ci(s: dict[str, Any]) -> tuple[float, float] | None:
    ci = s.get("ci95")
    if isinstance(ci, (list, tuple)) and len(ci) == 2:
        lo, hi = as_number(ci[0]), as_number(ci[1])
        if math.isfinite(lo) and math.isfinite(hi):
            return lo, hi
    return None


def constant_metrics(groups: list[dict[str, Any]], metrics: list[str] | None = None) -> dict[str, float]:
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
        means = [as_number(s.get("mean")) for s in stats]
        sds = [as_number(s.get("sd")) for s in stats]
        if not all(math.isfinite(x) for x in means) or any(math.isfinite(sd) and sd != 0 for sd in sds):
            continue
        ref = means[0]
        if all(abs(x - ref) <= 1e-12 * max(1.0, abs(ref)) for x in means) and (len(groups) > 1 or ref == 0):
            out[metric] = ref
    return out


def _column_unit(groups: list[dict[str, Any]], metric: str) -> Unit:
    mags = [abs(as_number(_stat(g, metric).get("mean"))) for g in groups]
    mags = [x for x in mags if math.isfinite(x)]
    return metric_unit(metric, max(mags) if mags else 0.0)


def _stat_text(unit: Unit, s: dict[str, Any]) -> str:
    """``0.740 ± 0.020 [0.710, 0.770]`` in ``unit`` (spread and interval when there are)."""
    text = unit.number(s.get("mean"))
    sd = as_number(s.get("sd"))
    if math.isfinite(sd) and text != "–":
        text += f" ± {unit.number(sd)}"
    ci = _ci(s)
    if ci is not None and text != "–":
        text += f" [{unit.number(ci[0])}, {unit.number(ci[1])}]"
    return text


def _clipped_note(unit: Unit, s: dict[str, Any]) -> str | None:
    """A cell's tooltip when its interval ends at a bound of the metric's range (summary.json
    ``bounds``): the Student-t interval went further and was clipped."""
    ci, bounds = _ci(s), s.get("bounds")
    if ci is None or not isinstance(bounds, (list, tuple)) or len(bounds) != 2 or not as_number(s.get("sd")) > 0:
        return None
    lo, hi = as_number(bounds[0]), as_number(bounds[1])
    ends = [f"{unit.number(b)}" for c, b in ((ci[0], lo), (ci[1], hi)) if math.isfinite(b) and c == b]
    return f"interval clipped at {' and '.join(ends)}, the end of the metric's range" if ends else None


def _with_unit(metric: str, unit: Unit) -> str:
    return f"{metric} ({unit.suffix})" if unit.suffix else metric


def _tick_formatter() -> FuncFormatter:
    return FuncFormatter(lambda v, _pos: f"{v:,.6g}".replace(",", THIN_SEP))


def fig_sweep(groups: list[dict[str, Any]], metrics: list[str]) -> Figure:
    """One panel per metric: a bar per group at its mean, whiskers its 95% interval, a dot at
    the mean; colour by planner; values in the metric's unit (:func:`metric_unit`)."""
    n_g = len(groups)
    cols = 2 if len(metrics) > 1 else 1
    rows = math.ceil(len(metrics) / cols)
    panel_h = 0.32 * n_g + 1.1
    fig = new_figure(11.0 if cols == 2 else 7.5, panel_h * rows + 0.4)
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False).ravel())
    planners = sorted({str(g.get("planner", "?")) for g in groups})
    pal = colormaps["tab10"]
    pc = {p: pal(i % 10) for i, p in enumerate(planners)}
    labels = [_group_label(g) for g in groups]
    y = np.arange(n_g)
    for ax, metric in zip(axes, metrics):
        unit = _column_unit(groups, metric)
        mean = np.array([as_number(_stat(g, metric).get("mean")) for g in groups]) / unit.scale
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


def paired_differences(comparison: dict[str, Any], first_minus_second: bool = True) -> dict[str, Any]:
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
        d["mean"] = sign * as_number(s.get("mean"))
        ci = _ci(s)
        d["ci95"] = sorted((sign * ci[0], sign * ci[1])) if ci is not None else None
        diffs[metric] = d
    first, second = (base, other) if first_minus_second else (other, base)
    return {"first": first, "second": second, "settings": dict(comparison.get("settings") or {}),
            "paired_seeds": comparison.get("paired_seeds"), "difference": diffs}


def _difference_cell(metric: str, unit: Unit, d: dict[str, Any] | None) -> dict[str, Any]:
    if not d:
        return cell("–", "num")
    mean = as_number(d.get("mean"))
    text = unit.number(mean, signed=True)
    ci = _ci(d)
    cls = "num"
    if ci is not None:
        text += f" [{unit.number(ci[0], signed=True)}, {unit.number(ci[1], signed=True)}]"
        if ci[0] > 0 or ci[1] < 0:
            direction = BETTER_DIRECTION.get(metric, 0) * (1 if ci[0] > 0 else -1)
            cls += " better" if direction > 0 else " worse" if direction < 0 else " differs"
    sd = as_number(d.get("sd"))
    return cell(text, cls, f"sd {unit.format(sd)}; {d.get('n', '?')} paired seeds" if math.isfinite(sd) else None)


def _difference_tables(comparisons: list[Any], metrics: list[str], first_minus_second: bool) -> list[dict[str, Any]]:
    """One table per planner pair: a row per metric, a column per setting."""
    pairs: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for c in comparisons:
        if isinstance(c, dict):
            d = paired_differences(c, first_minus_second)
            pairs.setdefault((d["first"], d["second"]), []).append(d)
    tables = []
    for (first, second), ds in pairs.items():
        names = [m for m in metrics if any(m in d["difference"] for d in ds)]
        if not names:
            continue
        header = ["metric"] + [f"{_settings_text(d['settings']) or 'all runs'} ({fmt(d['paired_seeds'])} paired seeds)"
                               for d in ds]
        rows = []
        for metric in names:
            mags = [abs(as_number(d["difference"].get(metric, {}).get("mean"))) for d in ds]
            mags = [x for x in mags if math.isfinite(x)]
            unit = metric_unit(metric, max(mags) if mags else 0.0)
            rows.append([_with_unit(metric, unit)]
                        + [_difference_cell(metric, unit, d["difference"].get(metric)) for d in ds])
        tables.append({"title": f"{first} {MINUS} {second}", "header": header, "rows": rows})
    return tables


def _equivalence_tables(setting_comparisons: list[Any]) -> list[dict[str, Any]]:
    """One table per (planner, setting change): a row per quantity of the equivalence margins."""
    tables = []
    for c in setting_comparisons:
        if not isinstance(c, dict) or not isinstance(c.get("equivalence"), dict):
            continue
        rows = []
        for name, e in c["equivalence"].items():
            if not isinstance(e, dict):
                continue
            lo, hi = (as_number(x) for x in (e.get("ci95") or [math.nan, math.nan]))
            ok = bool(e.get("equivalent"))
            rows.append([name, cell(f"{as_number(e.get('mean')):+.4g} [{lo:+.4g}, {hi:+.4g}]", "num"),
                         cell(f"±{as_number(e.get('margin')):.4g} ({e.get('margin_text', '')})", "num"),
                         cell("yes" if ok else "no", "num" if ok else "num worse")])
        if rows:
            tables.append({"title": f"{c.get('planner', '?')}: {c.get('key', '?')} {fmt(c.get('old'))} \u2192 "
                                    f"{fmt(c.get('new'))} ({fmt(c.get('paired_seeds'))} paired seeds)",
                           "header": ["quantity", f"new {MINUS} old", "margin", "equivalent"], "rows": rows})
    return tables


def build_sweep_report(sweep_dir: Path, summary: dict[str, Any], *, first_minus_second: bool = True) -> str:
    """The HTML text of a sweep's report (``sweep_report.html.j2``); see :func:`write_sweep_report`."""
    groups = summary.get("groups")
    if not isinstance(groups, list):
        raise ReportError(f"{sweep_dir}: summary has no 'groups' list")
    every, per_entity = _split_breakdowns(_metric_names(groups), summary.get("breakdowns"))
    constant = constant_metrics(groups, every)
    metrics = [m for m in every if m not in constant]
    title = f"Sweep: {summary.get('scenario', sweep_dir.name)}"
    settings_rows = [(k, ", ".join(fmt(x) for x in v) if isinstance(v, list) else fmt(v)) for k, v in summary.items()
                     if k not in ("groups", "comparisons", "setting_comparisons", "interval", "breakdowns")
                     and (isinstance(v, (str, int, float, bool)) or v is None
                          or (isinstance(v, list) and all(isinstance(x, (str, int, float)) for x in v)))]
    units = {m: _column_unit(groups, m) for m in metrics}
    summary_rows = []
    for g in groups:
        row: list[Any] = [g.get("planner", "?"), _settings_text(g.get("settings")) or "–", g.get("runs", "–")]
        for metric in metrics:
            s = _stat(g, metric)
            row.append(cell(_stat_text(units[metric], s) if s else "–", "num", _clipped_note(units[metric], s)))
        summary_rows.append(row)
    left_out = [f"{m} = {format_metric(m, v)}" for m, v in constant.items()]
    sweep_figure = (figure_item(fig_sweep(groups, metrics), "Each metric that differs between groups: bar and dot at "
                            "the mean, whiskers the 95% interval; colour by planner.", "sweep comparison")
                    if metrics and groups else None)
    comparisons = summary.get("comparisons") or []
    differences = _difference_tables(comparisons if isinstance(comparisons, list) else [], metrics,
                                     first_minus_second)
    setting_comparisons = summary.get("setting_comparisons") or []
    equivalence = _equivalence_tables(setting_comparisons if isinstance(setting_comparisons, list) else [])
    nav = ([("summary", "summary"), ("comparison", "comparison")]
           + ([("differences", "paired differences")] if differences else [])
           + ([("equivalence", "setting changes")] if equivalence else []))
    n_runs = sum(int(r) for r in (as_number(g.get("runs")) for g in groups) if math.isfinite(r))
    return render(
        "sweep_report.html.j2",
        title=title,
        heading=title,
        sweep_dir=sweep_dir.resolve().name,  # its name, not where it is: the page travels (issue 32)
        n_groups=len(groups),
        n_runs=n_runs,
        nav=nav,
        settings_rows=settings_rows,
        summary_header=["planner", "settings", "runs", *(_with_unit(m, units[m]) for m in metrics)],
        summary_rows=summary_rows,
        left_out=left_out,
        breakdowns=[f"{prefix}.* ({n})" for prefix, n in per_entity.items()],
        sweep_figure=sweep_figure,
        differences=differences,
        equivalence=equivalence,
        minus=MINUS,
        order_text="first planner minus second" if first_minus_second else "second planner minus first",
        interval_text=str(summary.get("interval") or "Student-t 95% interval of the mean over seeds"),
    )


def write_sweep_report(sweep_dir: str | Path, summary: dict[str, Any], out_path: str | Path | None = None, *,
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
