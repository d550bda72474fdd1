"""The figures of an axis: coverage, targets found (the surveillance ratio when the scenario
has surveillance) and frames delivered against the axis value, per planner; and, for an axis
that draws it, the share of the baseline's coverage kept."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from swarm.experiments.common import no_data, save_figure, subplots
from swarm.experiments.paper import PLANNER_COLOUR, PLANNER_LABEL
from swarm.experiments.resilience.axes import AXES, TARGET_KEPT, TARGET_LOSS

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["axis_figure", "kept_figure"]


def _panels(results: dict[str, Any]) -> list[tuple[str, str, tuple[float, float] | None]]:
    tt = results.get("targets_total") or None
    panels = [("coverage", "coverage at end", (0.0, 1.0)),
              ("targets_found", f"targets found at end (of {tt})" if tt else "targets found at end",
               (0.0, float(tt)) if tt else None)]
    if results["surveillance"]:
        panels.append(("surveillance_ratio_mean", "surveillance ratio (mean over found targets)", (0.0, 1.0)))
    panels.append(("delivered", "frame copies delivered (all links)", (0.0, math.inf)))
    return panels


def _errorbars(ax: Axes, results: dict[str, Any], quantity: str, x: np.ndarray, bounds: tuple[float, float] | None = None,
               offset: float = 0.06) -> bool:
    """Mean and 95% interval per value, one colour per planner, slightly apart; ``bounds``: the
    range the quantity can take (the interval of a few seeds is clipped to it)."""
    lo_b, hi_b = bounds if bounds is not None else (-math.inf, math.inf)
    any_data = False
    for i, p in enumerate(results["planners"]):
        means, lo, hi = [], [], []
        for pt in results["points"]:
            d = pt["planners"][p].get(quantity)
            m = d["mean"] if d else math.nan
            means.append(m)
            lo.append(m - max(d["ci95"][0], lo_b) if d else math.nan)
            hi.append(min(d["ci95"][1], hi_b) - m if d else math.nan)
        if not any(math.isfinite(m) for m in means):
            continue
        any_data = True
        n = [pt["planners"][p]["runs"] for pt in results["points"]]
        nlab = f"{min(n)}" if min(n) == max(n) else f"{min(n)}-{max(n)}"
        ax.errorbar(x + (i - (len(results["planners"]) - 1) / 2) * 2 * offset, means, yerr=[lo, hi], fmt="-o", ms=4,
                    capsize=4, lw=1.4, color=PLANNER_COLOUR[p],
                    label=f"{PLANNER_LABEL[p]} (mean, 95% CI, {nlab} seed{'' if nlab == '1' else 's'})")
    return any_data


def run_note(results: dict[str, Any]) -> str:
    """What the runs were (scenario, duration, what the axis did to whom), under a figure's title."""
    extra = AXES[results["axis"]].note(results)
    fails = f"; {results['runs_failed']} runs failed" if results["runs_failed"] else ""
    search_only = "" if results["surveillance"] else "; search only (no surveillance ratio)"
    return f"{results['scenario']}, {results['duration_s']:g} s runs{extra}{search_only}{fails}"


def axis_figure(results: dict[str, Any], path: Path, reference: dict[str, Any] | None = None) -> Path:
    """Coverage, targets found (surveillance ratio when the scenario has surveillance) and the
    frame copies delivered against the axis value, DACMP and greedy side by side."""
    panels = _panels(results)
    fig, axes = subplots(1, len(panels), figsize=(4.6 * len(panels), 4.4))
    x = np.arange(len(results["points"]), dtype=float)
    labels = [pt["label"] for pt in results["points"]]
    for ax, (q, ylabel, bounds) in zip(axes, panels):
        if not _errorbars(ax, results, q, x, bounds):
            no_data(ax)
        refs = reference or {}
        for name, ls in zip(refs, (":", "--")):
            for p in results["planners"]:
                v = refs[name][p].get(q)
                if v is not None and math.isfinite(v):
                    ax.axhline(v, color=PLANNER_COLOUR[p], ls=ls, lw=1.0, alpha=0.8,
                               label=f"{PLANNER_LABEL[p]}, {name} (loss axis)")
        ax.set_xticks(x, labels, rotation=0 if sum(len(t) for t in labels) <= 40 else 45)
        ax.set_xlabel(AXES[results["axis"]].title, fontsize=8)
        ax.set_ylabel(ylabel)
        if bounds is not None:
            ax.set_ylim(bounds[0], bounds[1] * 1.04 if math.isfinite(bounds[1]) else None)
        ax.grid(alpha=0.3)
        ax.set_title(ylabel, fontsize=10)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(f"Resilience: {AXES[results['axis']].title}\n{run_note(results)}", fontsize=10)
    return save_figure(fig, path)


def kept_figure(results: dict[str, Any], path: Path) -> Path:
    """Fraction of the loss-free coverage each planner keeps (paired by seed) against the loss
    rate, and at 30% loss as bars, with the 90% target."""
    fig, (ax, bx) = subplots(1, 2, figsize=(11, 4.4), gridspec_kw={"width_ratios": [3, 2]})
    pts = results["points"]
    x = np.arange(len(pts), dtype=float)
    if results["has_baseline"] and _errorbars(ax, results, "kept_coverage", x):
        ax.axhline(TARGET_KEPT, color="black", ls="--", lw=1.0, label=f"target: {TARGET_KEPT:.0%} kept at "
                                                                      f"{TARGET_LOSS:g} loss (DACMP)")
        i = next((k for k, pt in enumerate(pts) if pt["value"] == TARGET_LOSS), None)
        if i is not None:
            ax.axvline(x[i], color="grey", lw=0.8, alpha=0.6)
        ax.legend(fontsize=7, loc="lower left")
    else:
        no_data(ax, "needs finished runs at loss 0")
    ax.set_xticks(x, [pt["label"] for pt in pts])
    ax.set_xlabel(AXES[results["axis"]].title, fontsize=8)
    ax.set_ylabel("coverage / loss-free coverage (same seed)")
    ax.set_ylim(0, 1.1)
    ax.grid(alpha=0.3)
    ax.set_title("share of loss-free coverage kept", fontsize=10)
    t = results.get("target", {})
    if t.get("available"):
        means, errs = [], []
        for p in results["planners"]:
            k = t[p]["kept_coverage"] or {"mean": math.nan, "ci95": [math.nan, math.nan], "n": 0}
            means.append(k["mean"])
            errs.append([k["mean"] - k["ci95"][0], k["ci95"][1] - k["mean"]])
        xb = np.arange(len(results["planners"]))
        bx.bar(xb, means, 0.6, yerr=np.array(errs).T, capsize=6, color=[PLANNER_COLOUR[p] for p in results["planners"]],
               alpha=0.8)
        for i, p in enumerate(results["planners"]):
            k = t[p]["kept_coverage"]
            if k:
                bx.text(xb[i], k["ci95"][1] + 0.02,
                        f"{k['mean']:.3f}\n[{k['ci95'][0]:.3f}, {k['ci95'][1]:.3f}]\nn={k['n']}",
                        ha="center", va="bottom", fontsize=7)
        bx.axhline(TARGET_KEPT, color="black", ls="--", lw=1.0, label=f"target {TARGET_KEPT:.0%} (DACMP)")
        bx.set_xticks(xb, [PLANNER_LABEL[p] for p in results["planners"]])
        bx.legend(fontsize=7, loc="lower center")
    else:
        no_data(bx, f"needs finished runs at loss 0 and {TARGET_LOSS:g}")
    bx.set_ylim(0, 1.35)
    bx.set_ylabel("coverage kept (mean, 95% CI)")
    bx.grid(axis="y", alpha=0.3)
    bx.set_title(f"at {TARGET_LOSS:.0%} i.i.d. loss", fontsize=10)
    fig.suptitle(f"Loss-free coverage kept under i.i.d. loss\n{run_note(results)}", fontsize=10)
    return save_figure(fig, path)


