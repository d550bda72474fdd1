"""The table: the paper's figures (quoted) next to ours (measured), rebuilt from the
experiments' ``results.json``."""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from swarm.experiments.common import (
    md_cell,
    write_text,
)
from swarm.experiments.paper.design import CASE3_WINDOW_FROM_S, FIG11_PLANNERS, PAPER, PLANNER_LABEL, fig11_planners
from swarm.experiments.paper.measures import CASE2_MIN_HANDOVERS

# --- the table ---------------------------------------------------------------------------------

NOT_RUN = "not run"
MD_HEADER = ("experiment", "quantity", "paper (quoted)", "ours (measured, N seeds, mean [95% CI])")


def _load(out: Path, name: str) -> dict[str, Any] | None:
    p = out / name / "results.json"
    return json.loads(p.read_text()) if p.is_file() else None


def _row(experiment: str, quantity: str, paper: str, ours: str = NOT_RUN, d: dict[str, Any] | None = None,
         note: str = "") -> dict[str, Any]:
    return {"experiment": experiment, "quantity": quantity, "paper_quoted": paper, "ours_measured": ours,
            "n": d["n"] if d else "", "mean": d["mean"] if d else "",
            "ci95_low": d["ci95"][0] if d else "", "ci95_high": d["ci95"][1] if d else "", "note": note}


def _fmt(d: dict[str, Any] | None, digits: int, what: str = "seeds", signed: bool = False) -> str:
    if not d or not d.get("n"):
        return "no finished runs"
    sign = "+" if signed else ""
    mean = f"{d['mean']:{sign}.{digits}f}"
    if d["n"] < 2:
        return f"{mean} (1 {what[:-1] if what.endswith('s') else what}, no interval)"
    return f"{mean} [{d['ci95'][0]:{sign}.{digits}f}, {d['ci95'][1]:{sign}.{digits}f}], {d['n']} {what}"


def _duration_note(res: dict[str, Any] | None, paper_s: float | None) -> str:
    if not res or res.get("duration_s") is None or paper_s is None:
        return ""
    if math.isclose(float(res["duration_s"]), paper_s):
        return ""
    return f"ours at {float(res['duration_s']):g} s, paper at {paper_s:g} s"


def _rows_fig11(res: dict[str, Any] | None) -> list[dict[str, Any]]:
    e = "Fig. 11 (paper-fig11)"
    q = PAPER["fig11"]
    note = _duration_note(res, q["duration_s"])
    rows = []
    # Reference planners: those the results ran (older results have none), else those fig11 would run.
    reference = list(res.get("reference", [])) if res else list(fig11_planners()[len(FIG11_PLANNERS):])
    for key, label, digits in (("coverage", "coverage at end", 3), ("targets_found", "targets found (of 14)", 2)):
        for p in (*FIG11_PLANNERS, *reference):
            d = ((res or {}).get("planners", {}).get(p) or {}).get(key)
            paper = f"{q[key][p]:g} (mean of 30 runs)" if p in q[key] else "— (reference planner, not in the paper)"
            rows.append(_row(e, f"{label}, {PLANNER_LABEL.get(p, p)}", paper,
                             _fmt(d, digits) if res else NOT_RUN, d, note))
    for key, label, digits in (("coverage", "coverage, DACMP − greedy (paired by seed)", 3),
                               ("targets_found", "targets found, DACMP − greedy (paired by seed)", 2)):
        diff = q[key]["dacmp"] - q[key]["greedy"]
        d = ((res or {}).get("difference") or {}).get(key)
        ours = (_fmt(d, digits, "paired seeds", signed=True) if d else "no paired runs") if res else NOT_RUN
        rows.append(_row(e, label, f"{diff:+.{digits}f} (difference of the quoted means; no interval given)",
                         ours, d, note))
    return rows


def _watchers_text(watchers: list[dict[str, Any]], slow: Sequence[str]) -> str:
    if not watchers:
        return "nobody"
    return ", ".join(f"{w['uav']} ({'slow' if w['uav'] in slow else 'fast'}, "
                     f"{'in' if w['in_range'] else 'out of'} detection range at the last tick)" for w in watchers)


def _handover_text(h: dict[str, Any]) -> str:
    text = f"yes: {h['from']} → {h['to']} at {h['t']:g} s"
    extra = []
    if h.get("to_distance_km") is not None:
        extra.append(f"{h['to']} then {h['to_distance_km']:.1f} km from target 1")
    if "to_in_range_t" in h:
        extra.append(f"in its detection range from {h['to_in_range_t']:g} s" if h["to_in_range_t"] is not None
                     else "never in its detection range")
    return text + (f" ({'; '.join(extra)})" if extra else "")


def _rows_case1(res: dict[str, Any] | None) -> list[dict[str, Any]]:
    e = "Case 1 (paper-case1)"
    note = ""
    if res:
        note = f"one run, seed {res['seed']}, {res['duration_s']:g} s (paper's Fig. 12 ends at 350 s)"
    rows = []
    f1 = (res or {}).get("found", {}).get("1")
    rows.append(_row(e, "target 1 first found by", "UAV 1 (fast; our B1), by 50 s (Fig. 12a)",
                     (f"{f1['by']} at {f1['t']:g} s" if f1 else "not found") if res else NOT_RUN, note=note))
    h = (res or {}).get("handover_t1_to_slow")
    rows.append(_row(e, "target 1 handed over to the slow UAV",
                     "yes: UAV 1 → UAV 3 (our B1 → A1), between 250 s and 350 s (Fig. 12b-c)",
                     (_handover_text(h) if h else "no") if res else NOT_RUN, note=note))
    if res:
        ours1 = _watchers_text(res["watchers_end"].get("1", []), res["slow_uavs"])
        ours2 = _watchers_text(res["watchers_end"].get("2", []), res["slow_uavs"])
        b1 = res.get("b1_surveil_t2_s")
        ours3 = f"{b1:g} s" if b1 is not None else "n/a"
    else:
        ours1 = ours2 = ours3 = NOT_RUN
    rows.append(_row(e, "target 1 watched at end by (surveillance mode, assigned to it)", "UAV 3 (slow; our A1)",
                     ours1, note=note))
    rows.append(_row(e, "target 2 watched at end by (surveillance mode, assigned to it)", "UAV 2 (fast; our B2)",
                     ours2, note=note))
    rows.append(_row(e, "time fast UAV B1 spent surveilling target 2 (watched by B2)",
                     "0 s: UAV 1 passes target 2 without being captured (Fig. 12c)", ours3, note=note))
    return rows


def _rows_case2(res: dict[str, Any] | None) -> list[dict[str, Any]]:
    e = "Case 2 (paper-case2)"
    q = PAPER["case2"]
    run = (res or {}).get("run")
    note = f"one run, seed {run['seed']}, {run['duration_s']:g} s" if run else ""
    rows = []

    def single(quantity: str, paper: str, ours: str) -> None:
        rows.append(_row(e, quantity, paper, ours if run else NOT_RUN, note=note))

    single("targets found (of 6)", f"{q['targets_found']} (every target found)",
           f"{run['targets_found']} of {run['targets_total']}" if run else "")
    if run:
        who = "; ".join(f"T{k}: " + "+".join(w["uav"] + ("" if w["in_range"] else " (out of range)") for w in v)
                        for k, v in run["watchers_end"].items() if v)
        w = (f"{run['watched_end']} of {run['targets_total']}, {run['watched_end_in_range']} in detection range "
             f"at the last tick" + (f"; {who}" if who else ""))
    single("targets watched at end (a UAV in surveillance mode assigned to it)",
           f"{q['watched_end']}, each by one UAV (5 by slow UAVs, 1 by fast UAV 2)", w if run else "")
    if run:
        hl = ", ".join(f"{h['from']}→{h['to']} (T{h['target']}, {h['t']:g} s)" for h in run["handover_list"])
    single("fast → slow handovers", f"{q['handovers_fast_to_slow']}: UAV 3→9, 5→10, 4→8, 1→6 (our B3→A4, B5→A5, B4→A3, B1→A1)",
           (f"{run['handovers_fast_to_slow']}" + (f" (all {run['handovers']} handovers: {hl})" if hl else ""))
           if run else "")
    single("threat violations", "0 (threats avoided)", f"{run['threat_violations']}" if run else "")
    single("separation violations", "not stated", f"{run['separation_violations']}" if run else "")
    jd = (res or {}).get("judged")
    if jd and jd.get("seeds"):
        c, n = jd["conditions"], len(jd["seeds"])
        sn = f"seeds {jd['seeds'][0]}..{jd['seeds'][-1]}"
        rows.append(_row(e, f"seeds where Case 2 holds, {sn}, judged at {jd['duration_s']:g} s", "(one run shown)",
                         f"{c['all']} of {n} (found {c['found']}, watched at end {c['watched']}, takeovers and releases "
                         f"in time {c['takeovers']}, >= {CASE2_MIN_HANDOVERS} handovers where offered {c['handovers']}, "
                         f"released UAVs search {c['released']}, no violations {c['safe']})",
                         note="DACMP-SPEC \"Reproduction targets\": at least 18 of 20"))
    af = (res or {}).get("all_found_in_paper_time")
    if af:
        rows.append(_row(e, f"seeds with all six targets found in {af['duration_s']:g} s", "6 found (one run)",
                         ", ".join(f"{k} {v} of {af['seeds']}" for k, v in af["count"].items()),
                         note="the search alone: search-only DACMP and the lawnmower run with surveillance off"))
    st = (res or {}).get("seeds")
    if st:
        sn = f"over seeds {st['seeds'][0]}..{st['seeds'][-1]}" if st["seeds"] else "over seeds"
        seed_note = f"{run['duration_s']:g} s each" if run else ""
        for key, label, paper, digits in (("targets_found", "targets found (of 6)", "6", 2),
                                          ("watched_end", "targets watched at end (assigned)", "6", 2),
                                          ("watched_end_in_range", "targets watched at end, in detection range", "6", 2),
                                          ("handovers_fast_to_slow", "fast → slow handovers", "4", 2),
                                          ("threat_violations", "threat violations", "0", 2),
                                          ("separation_violations", "separation violations", "not stated", 2),
                                          ("coverage", "coverage at end", "not quoted (Fig. 15)", 3)):
            d = st.get(key)
            rows.append(_row(e, f"{label}, {sn}", paper, _fmt(d, digits), d, seed_note))
    return rows


def _rows_case3(res: dict[str, Any] | None) -> list[dict[str, Any]]:
    e = "Case 3 (paper-case3 vs paper-case2)"
    w = CASE3_WINDOW_FROM_S
    rows = []
    if not res:
        for quantity, paper in ((f"mean coverage from {w:g} s on, without / with the joiner",
                                 "not quoted; with joiner higher (Fig. 18)"),
                                (f"mean coverage from {w:g} s on, with − without (paired)",
                                 "positive (Fig. 18), no number given"),
                                ("coverage at end, with − without (paired)", "positive (Fig. 18), no number given"),
                                ("time from which the mean with the joiner stays above", "after the join at 300 s (Fig. 18)")):
            rows.append(_row(e, quantity, paper))
        return rows
    note = f"same seeds both, {res['duration_s']:g} s" + (f", join at {res['join_s']:g} s" if res.get("join_s") else "")
    if not res.get("seeds"):
        rows.append(_row(e, "coverage with vs without the joiner", "with joiner higher (Fig. 18)", "no paired runs", note=note))
        return rows
    wm = res.get("window_mean")
    if wm:
        rows.append(_row(e, f"mean coverage from {w:g} s on, without joiner (10 UAVs)", "not quoted (Fig. 18)",
                         _fmt(wm["case2"], 3), wm["case2"], note))
        rows.append(_row(e, f"mean coverage from {w:g} s on, with joiner (11 UAVs)", "not quoted; higher (Fig. 18)",
                         _fmt(wm["case3"], 3), wm["case3"], note))
        rows.append(_row(e, f"mean coverage from {w:g} s on, with − without (paired)", "positive (Fig. 18), no number given",
                         _fmt(wm["difference"], 4, "paired seeds", signed=True), wm["difference"], note))
    else:
        rows.append(_row(e, f"mean coverage from {w:g} s on, with − without (paired)", "positive (Fig. 18), no number given",
                         f"n/a: runs end at {res['duration_s']:g} s, before {w:g} s", note=note))
    fd = res["final"]["difference"]
    rows.append(_row(e, "coverage at end, with − without (paired)", "positive (Fig. 18), no number given",
                     _fmt(fd, 4, "paired seeds", signed=True), fd, note))
    a = res.get("above_from_s")
    rows.append(_row(e, "time from which the mean with the joiner stays above", "after the join at 300 s (Fig. 18)",
                     f"{a:g} s" if a is not None else "never (within the run)", note=note))
    return rows


ROW_BUILDERS = {"fig11": _rows_fig11, "case1": _rows_case1, "case2": _rows_case2, "case3": _rows_case3}


def table_rows(out_dir: str | Path) -> list[dict[str, Any]]:
    """The table's rows; an experiment without ``results.json`` is "not run", one whose file
    cannot be read (written by another version) says so."""
    out = Path(out_dir)
    rows = []
    for name, build in ROW_BUILDERS.items():
        try:
            rows += build(_load(out, name))
        except (KeyError, TypeError, ValueError, IndexError, AttributeError):
            stale = build(None)
            for r in stale:
                r["ours_measured"] = f"unreadable {name}/results.json: rerun `swarm paper {name}`"
            rows += stale
    return rows


def write_table(out_dir: str | Path) -> tuple[Path, Path, list[dict[str, Any]]]:
    """Rewrite ``table.md`` and ``table.csv`` from the ``results.json`` files in ``out_dir``."""
    out = Path(out_dir)
    rows = table_rows(out)
    lines = [
        "# The paper's experiments: paper (quoted) vs ours (measured)",
        "",
        "Written by `swarm paper` from the results in this folder. **paper (quoted)**: numbers and",
        "statements copied from the paper's section 4 (never computed). **ours (measured, N seeds,",
        "mean [95% CI])**: from our runs: the mean over seeds with the Student-t 95% interval of the",
        "mean, or the value of a single run (seed noted). Differences are paired by seed.",
        "Targets and UAVs numbered as in the paper where noted (target 1 = our first target).",
        "",
        "| " + " | ".join(MD_HEADER) + " | note |",
        "|" + "---|" * (len(MD_HEADER) + 1),
    ]
    for r in rows:
        lines.append("| " + " | ".join(md_cell(r[k]) for k in ("experiment", "quantity", "paper_quoted",
                                                                 "ours_measured", "note")) + " |")
    md = "\n".join(lines) + "\n"
    buf = io.StringIO(newline="")
    cols = ["experiment", "quantity", "paper_quoted", "ours_measured", "n", "mean", "ci95_low", "ci95_high", "note"]
    w = csv.DictWriter(buf, fieldnames=cols)
    w.writeheader()
    w.writerows(rows)
    md_path, csv_path = out / "table.md", out / "table.csv"
    for p, text in ((md_path, md), (csv_path, buf.getvalue())):
        write_text(p, text)
    return md_path, csv_path, rows
