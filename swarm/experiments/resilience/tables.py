"""The tables of the resilience axes: per axis value, mean and 95% interval per planner, the
paired difference and the kept fractions, as Markdown and CSV (one axis's, and all axes' in
``table.md`` / ``table.csv``, rebuilt from every axis's ``results.json``)."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from swarm.experiments.common import md_cell, write_text
from swarm.experiments.paper import PLANNER_LABEL
from swarm.experiments.resilience.axes import AXES, KEPT, QUANTITIES, TARGET_KEPT, TARGET_LOSS
from swarm.experiments.resilience.figures import run_note

__all__ = ["CSV_COLUMNS", "write_axis_table", "write_table"]


def _ci(d: dict[str, Any] | None, digits: int, signed: bool = False) -> str:
    if not d or not d.get("n"):
        return "-"
    s = "+" if signed else ""
    if d["n"] < 2:
        return f"{d['mean']:{s}.{digits}f} (1 seed)"
    return f"{d['mean']:{s}.{digits}f} [{d['ci95'][0]:{s}.{digits}f}, {d['ci95'][1]:{s}.{digits}f}]"


def _delivered(d: dict[str, Any]) -> str:
    n, f = d.get("delivered"), d.get("delivered_fraction")
    if not n or not f:
        return "-"
    return f"{n['mean'] / 1000:.1f}k ({f['mean']:.3f})"


def _columns(results: dict[str, Any]) -> list[tuple[str, Callable[[dict[str, Any]], str]]]:
    # A column's cell of one point (pt) is a function of the point; these make them, each bound
    # to its own planner and quantity.
    def planner_ci(p: str, q: str, digits: int) -> Callable[[dict[str, Any]], str]:
        return lambda pt: _ci(pt["planners"][p][q], digits)

    def difference_ci(q: str, digits: int) -> Callable[[dict[str, Any]], str]:
        return lambda pt: _ci((pt["difference"] or {}).get(q), digits, signed=True)

    def kept_ci(p: str) -> Callable[[dict[str, Any]], str]:
        return lambda pt: _ci(pt["planners"][p].get("kept_coverage"), 3)

    def delivered(p: str) -> Callable[[dict[str, Any]], str]:
        return lambda pt: _delivered(pt["planners"][p])

    cols: list[tuple[str, Callable[[dict[str, Any]], str]]] = []
    qs = [("coverage", "coverage", 3), ("targets_found", "targets found", 2)]
    if results["surveillance"]:
        qs.append(("surveillance_ratio_mean", "surveillance ratio", 3))
    for q, label, digits in qs:
        for p in reversed(results["planners"]):  # DACMP first
            cols.append((f"{label}, {PLANNER_LABEL[p]}", planner_ci(p, q, digits)))
        cols.append((f"{label}, DACMP − greedy (paired)", difference_ci(q, digits)))
    if results["has_baseline"]:
        for p in reversed(results["planners"]):
            cols.append((f"coverage kept vs {AXES[results['axis']].label(results['baseline'])}, {PLANNER_LABEL[p]}",
                         kept_ci(p)))
    for p in reversed(results["planners"]):
        cols.append((f"frames delivered (share of sent), {PLANNER_LABEL[p]}", delivered(p)))
    cols.append(("runs (DACMP / greedy, failed)", lambda pt: " / ".join(
        str(pt["planners"][p]["runs"]) for p in reversed(results["planners"]))
        + (f", {sum(pt['planners'][p]['failed'] for p in results['planners'])} failed"
           if any(pt["planners"][p]["failed"] for p in results["planners"]) else "")))
    return cols


def _axis_md(results: dict[str, Any], heading: str = "##") -> list[str]:
    cols = _columns(results)
    seeds = results["seeds"]
    lines = [f"{heading} {results['axis']}: {AXES[results['axis']].title}", "",
             f"{run_note(results)}; seeds {seeds[0]}..{seeds[-1]} ({len(seeds)}); mean [95% CI of the mean].", ""]
    if results["axis"] == "loss" and results.get("target", {}).get("available"):
        t = results["target"]
        k = t["dacmp"]["kept_coverage"]
        lines += [f"Target (issue 4): DACMP keeps >= {TARGET_KEPT:.0%} of its loss-free coverage at "
                  f"{TARGET_LOSS:g} i.i.d. loss: **{'met' if t['met'] else 'not met'}** "
                  f"(kept {_ci(k, 3)}, {k['n']} paired seeds).", ""]
    lines.append("| " + " | ".join([results["title"], *(c for c, _ in cols)]) + " |")
    lines.append("|" + "---|" * (len(cols) + 1))
    for pt in results["points"]:
        lines.append("| " + " | ".join(md_cell(x) for x in [pt["label"], *(f(pt) for _, f in cols)]) + " |")
    return lines


def _csv_rows(results: dict[str, Any]) -> list[dict[str, Any]]:
    rows = []
    for pt in results["points"]:
        for p in results["planners"]:
            for q in (*QUANTITIES, *(f"kept_{k}" for k in KEPT)):
                d = pt["planners"][p].get(q)
                if d:
                    rows.append({"axis": results["axis"], "setting": results["setting"], "value": pt["label"],
                                 "planner": p, "quantity": q, "n": d["n"], "mean": d["mean"], "sd": d["sd"],
                                 "ci95_low": d["ci95"][0], "ci95_high": d["ci95"][1]})
        for q, d in (pt["difference"] or {}).items():
            if q != "paired_seeds" and d:
                rows.append({"axis": results["axis"], "setting": results["setting"], "value": pt["label"],
                             "planner": "dacmp-greedy", "quantity": q, "n": d["n"], "mean": d["mean"], "sd": d["sd"],
                             "ci95_low": d["ci95"][0], "ci95_high": d["ci95"][1]})
    return rows


CSV_COLUMNS = ["axis", "setting", "value", "planner", "quantity", "n", "mean", "sd", "ci95_low", "ci95_high"]


def _csv_text(rows: list[dict[str, Any]]) -> str:
    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=CSV_COLUMNS)
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def write_axis_table(results: dict[str, Any], axis_dir: Path) -> tuple[Path, Path]:
    md = write_text(axis_dir / "table.md", "\n".join(_axis_md(results, "#")) + "\n")
    return md, write_text(axis_dir / "table.csv", _csv_text(_csv_rows(results)))


def write_table(out_dir: str | Path) -> tuple[Path, Path]:
    """Rewrite ``table.md`` / ``table.csv`` in ``out_dir`` from every axis's ``results.json``."""
    out = Path(out_dir)
    lines = ["# Resilience: DACMP and greedy under radio loss, burst loss, limited range, crashes, pauses, "
             "restarts, clock skew, missed detections, a jammer and liars", "",
             "Written by `swarm resilience` from the results in this folder: per axis value, the mean over seeds",
             "and the Student-t 95% interval of the mean; differences and kept fractions are paired by seed.", ""]
    rows = []
    for axis in AXES:
        p = out / axis / "results.json"
        if not p.is_file():
            lines += [f"## {axis}: {AXES[axis].title}", "", "not run", ""]
            continue
        try:
            res = json.loads(p.read_text())
            lines += _axis_md(res) + [""]
            rows += _csv_rows(res)
        except (KeyError, TypeError, ValueError, IndexError):
            lines += [f"## {axis}", "", f"unreadable {axis}/results.json: rerun `swarm resilience {axis}`", ""]
    return (write_text(out / "table.md", "\n".join(lines)), write_text(out / "table.csv", _csv_text(rows)))
