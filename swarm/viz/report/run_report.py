"""A run's HTML report (``swarm report RUN_FOLDER``): scenario, metrics, figures, violations."""

from __future__ import annotations

import base64
import dataclasses
from pathlib import Path
from typing import Any

from comms.radio import LogDistance
from swarm.outputs import atomic_write
from swarm.viz.replay import (
    Replay,
    RunDirError,
    fault_events,
    load_run,
)
from swarm.viz.report.html import ANIMATION_NAMES, ReportError, as_number, figure_item, fmt, render
from swarm.viz.report.run_figures import (
    fig_coverage,
    fig_fault_timeline,
    fig_radio,
    fig_targets,
    fig_task_load,
    fig_trajectories,
    uav_order,
)
from swarm.viz.style import (
    format_metric,
)

# --- run report -------------------------------------------------------------------------------

def find_animation(run_dir: str | Path) -> Path | None:
    """The newest ``animation.mp4`` / ``animation.gif`` in the run folder, if any."""
    found = [p for p in (Path(run_dir) / n for n in ANIMATION_NAMES) if p.is_file() and p.stat().st_size > 0]
    return max(found, key=lambda p: p.stat().st_mtime) if found else None


def _animation(path: Path | None) -> dict[str, Any] | None:
    """What the template embeds of the animation: its kind, ``data:`` URI, name and size."""
    if path is None:
        return None
    kind = path.suffix.lower().lstrip(".")
    if kind not in ("gif", "mp4"):
        raise ReportError(f"{path}: an animation must be .gif or .mp4")
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    mime = "image/gif" if kind == "gif" else "video/mp4"
    return {"kind": kind, "uri": f"data:{mime};base64,{data}", "name": path.name, "mb": path.stat().st_size / 1e6}


def _scenario_rows(rp: Replay) -> list[tuple[Any, ...]]:
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
        ("duration", f"{fmt(rp.duration)} s (dt {fmt(rp.dt)} s)"),
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
        ("no-fly zones", _zone_words(rp)),
        ("radio", _radio_words(radio, rng)),
        ("faults scheduled", len(rp.faults)),
    ]
    return rows



def _zone_words(rp: Replay) -> str:
    """Every hazard UAVs keep out of: threat circles and no-fly polygons (swarm.viz.hazards)."""
    circles, polygons = len(rp.threats), len(rp.scenario.get("no_fly") or [])
    parts = [f"{n} {w}{'' if n == 1 else 's'}" for n, w in ((circles, "threat circle"), (polygons, "polygon")) if n]
    return f"{circles + polygons}" + (f" ({', '.join(parts)})" if parts else "")


def _radio_words(radio: dict[str, Any], rng: float | None) -> str:
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


def _count(m: dict[str, Any], key: str) -> str:
    return format_metric(key, m.get(key)) if m.get(key) is not None else "–"


def _metrics_rows(m: dict[str, Any]) -> list[tuple[Any, ...]]:
    r = m.get("radio", {}) or {}
    v = m.get("violations", {}) or {}
    rows = [
        ("simulated / wall", f"{fmt(m.get('sim_seconds'))} s / {fmt(m.get('wall_seconds'))} s"),
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


def _seconds_or_dash(v: float | None) -> str:
    return "–" if v is None else f"{fmt(v)} s"


def _share_or_dash(v: float | None) -> str:
    return "–" if v is None else f"{v:.3f}"


def _detection_watch_rows(m: dict[str, Any], rp: Replay) -> tuple[list[tuple[Any, ...]], list[tuple[Any, ...]]]:
    """The "Detection and watch" section (metrics.json, docs/outputs.md): one row per target
    (time to first detection, to a slow watcher, watched share, surveillance ratio, watch gaps), one per UAV
    and the swarm (share of flying time watching and searching). Empty for an older metrics.json."""
    detection = m.get("time_to_first_detection_s")
    if detection is None:
        return [], []
    to_slow = m.get("time_to_slow_watcher_s") or {}
    watched = m.get("watched_share") or {}
    ratio = m.get("surveillance_ratio") or {}
    gaps = m.get("watch_continuity") or {}  # (issue 33: absent from an older metrics.json)

    def gap_words(k: str) -> str:
        c = gaps.get(k)
        return "–" if c is None else f"{c['gaps']} ({c['longest_gap_s']:g} s)"

    targets = [(k, detection[k], to_slow.get(k), watched.get(k), ratio.get(k)) for k in sorted(detection, key=int)]
    target_rows = [(k, _seconds_or_dash(d), _seconds_or_dash(s), _share_or_dash(w), _share_or_dash(r), gap_words(k))
                   for k, d, s, w, r in targets]
    per = m.get("per_uav", {}) or {}
    uav_rows = []
    for u in uav_order(rp):
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


def violation_episodes(rp: Replay) -> list[dict[str, Any]]:
    """The run's violations as episodes, in order of start: one per invariant and party (a pair
    of UAVs, a UAV and a threat, a UAV's dynamics) and stretch of consecutive ticks, as
    ``{"invariant", "who", "start_s", "end_s", "ticks"}``. Separation and threat come from the
    event log's ``violation`` events (one per tick and party); dynamics violations are not
    logged, only counted per UAV (metrics.json ``dynamics_violations_by_uav``: count, first and
    last time), so each UAV's are one row spanning its first to its last."""
    def name(uid: int) -> str:
        return rp.names[uid] if 0 <= uid < len(rp.names) else f"UAV {uid}"

    open_: dict[tuple[Any, ...], dict[str, Any]] = {}
    done: list[dict[str, Any]] = []
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
        done.append({"invariant": "dynamics", "who": str(uav), "start_s": as_number(d.get("first_s")),
                     "end_s": as_number(d.get("last_s")), "ticks": int(as_number(d.get("count")))})
    return sorted(done, key=lambda e: (e["start_s"], e["invariant"], e["who"]))


def _violation_section(rp: Replay) -> dict[str, Any]:
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


def handover_rows(handovers: list[dict[str, Any]]) -> list[tuple[Any, ...]]:
    """The handover table's rows: time logged, target, from, to, when the owner stopped
    watching, when the newcomer arrived, and the two non-negative parts of ``latency_s``
    (release minus arrival): *overlap* (both held the target: the newcomer arrived before the
    owner left) and *gap* (nobody held it: the owner left before the newcomer arrived). One of
    them is 0; ``latency_s = overlap - gap``."""
    rows = []
    for h in handovers:
        t, lat = as_number(h.get("t")), as_number(h.get("latency_s"))
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
             ("handovers", fmt(m.get("handovers"))),
             ("UAVs", rp.n_uavs),
             ("simulated", f"{fmt(rp.duration)} s")]
    specs = [
        (fig_trajectories(rp), "Trajectories: UAV paths (one colour each, end marker by type, a cross where a UAV "
                               "crashed), target paths (dashed; filled star: found, hollow: never found), no-fly zones "
                               "(red: threat circles and polygons, influence dotted), the area polygon (outside "
                               "it hatched) and the base (black square), over the map of when each cell was "
                               "first scanned.", "trajectories", 820),
        (fig_coverage(rp), "Coverage and certainty over time (timeseries.csv); shaded: partitions; dashed: "
                           "crashes (red) and late joins (green).", "coverage and certainty", None),
        (fig_targets(rp), "Targets found (first detection) and targets watched by a UAV in surveillance mode.",
         "targets over time", None),
        (fig_task_load(rp), "Task load per UAV: seconds in search and in surveillance mode (from the pose events), "
                            "as in the paper's Fig. 14.", "task load per UAV", None),
        (fig_radio(rp), "Radio: cumulative frame copies sent, delivered, dropped and rejected; per-interval "
                        "delivery; drops by cause (metrics.json).", "radio counters", None),
    ]
    figures = [figure_item(fig, caption, alt, width) if fig is not None else {"uri": None, "alt": alt}
               for fig, caption, alt, width in specs]
    timeline = figure_item(fig_fault_timeline(rp), "Fault windows from the schedule in the event log's start header "
                           "and those a host added while it ran (orange: link faults, red: partitions), crashes and "
                           "late joins, and every UAV's state over time.", "fault timeline")
    secs = rp.mode_seconds()
    per = m.get("per_uav", {}) or {}
    uav_rows = []
    for u in uav_order(rp):
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
        run_dir=run_dir.resolve().name,  # its name, not where it is: the page travels (issue 32)
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
