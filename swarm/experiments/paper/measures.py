"""What the table measures of a run: case 1's handover, case 2's criterion (docs/paper.md)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from swarm.experiments.paper.logs import RunLog

# --- measurements for the table ----------------------------------------------------------------

def case1_measures(log: RunLog) -> dict[str, Any]:
    """Target 1 (id 0): who found it, handovers to a slow UAV, who watches targets 1 and 2 at
    the end, and how long fast UAV B1 (paper: UAV 1) spent on target 2 (watched by B2)."""
    watchers = log.watchers_at_end()
    name = log.names
    ho: list[dict[str, Any]] = [{"t": e.t, "target": e.target + 1, "from": name.get(e.from_uav, str(e.from_uav)),
           "to": name.get(e.to_uav, str(e.to_uav)), "to_slow": log.is_slow(e.to_uav), "from_fast": not log.is_slow(e.from_uav)}
          for e in log.handovers]
    to_slow_t1 = [h for h in ho if h["target"] == 1 and h["to_slow"]]
    if to_slow_t1 and 0 in log.targets:
        h = to_slow_t1[0]
        uid = log.uid(h["to"])
        p = log.poses.get(uid) if uid is not None else None
        if uid is not None and p is not None:
            txy = log.target_at(0, p[:, 0])
            d = np.hypot(p[:, 1] - txy[:, 0], p[:, 2] - txy[:, 1])
            i = min(int(np.searchsorted(p[:, 0], h["t"])), len(p) - 1)
            h["to_distance_km"] = float(d[i]) / 1000
            r = float(log.type_specs[log.types[uid]]["detect_radius_m"])
            inside = np.nonzero(d <= r)[0]
            h["to_in_range_t"] = float(p[inside[0], 0]) if inside.size else None
    slow_names = sorted(name[u] for u in name if log.is_slow(u))
    b1 = log.uid("B1")
    return {
        "scenario": log.metrics["scenario"], "seed": log.metrics["seed"], "duration_s": log.end_t,
        "found": {str(m + 1): {"t": t, "by": name.get(u, str(u))} for m, (t, u) in sorted(log.found.items())},
        "handovers": ho,
        "handover_t1_to_slow": to_slow_t1[0] if to_slow_t1 else None,
        "watchers_end": {str(m + 1): [{"uav": n, "in_range": r} for n, r in w] for m, w in sorted(watchers.items())},
        "slow_uavs": slow_names,
        "slow_watches_t1_at_end": any(n in slow_names for n, _ in watchers.get(0, [])),
        "b1_surveil_t2_s": log.surveil_seconds(b1, 1) if b1 is not None and 1 in log.targets else None,
        "coverage": log.metrics["coverage"],
    }


def case2_measures(log: RunLog, folder: Path | None = None) -> dict[str, Any]:
    """What the table and the criterion need from one Case 2 run; with the run's ``folder``,
    the handover rules are checked over its event log (:func:`case2_conditions`)."""
    from swarm.testing.invariants import HandoverChecker, check_events, load_run_log

    watchers = log.watchers_at_end()
    m = log.metrics
    name = log.names
    violations: list[Any] = []
    opportunities = 0
    if folder is not None:
        scenario, events = load_run_log(folder)
        checker = HandoverChecker()
        violations = check_events(events, scenario, [checker])
        opportunities = len({m for m, _ in checker.opportunities})  # targets offered (two fast watchers: one)
    return {
        "seed": m["seed"], "duration_s": log.end_t,
        "targets_found": m["targets_found"], "targets_total": m["targets_total"],
        "watched_end": sum(1 for w in watchers.values() if w),
        "watched_end_in_range": sum(1 for w in watchers.values() if any(r for _, r in w)),
        "watched_end_by_more_than_one": sum(1 for w in watchers.values() if len(w) > 1),
        "watchers_end": {str(k + 1): [{"uav": n, "in_range": r} for n, r in w] for k, w in sorted(watchers.items())},
        "handovers": m["handovers"], "handovers_fast_to_slow": m["handovers_fast_to_slow"],
        "handover_list": [{"t": e.t, "target": e.target + 1, "from": name.get(e.from_uav, str(e.from_uav)),
                           "to": name.get(e.to_uav, str(e.to_uav))} for e in log.handovers],
        "threat_violations": m["violations"]["threat"], "separation_violations": m["violations"]["separation"],
        "coverage": m["coverage"],
        "handover_opportunities": opportunities,
        "handover_rule_violations": [str(v) for v in violations],
        "conditions": case2_conditions(log, violations, opportunities),
    }


# Case 2 judged (DACMP-SPEC "Reproduction targets"; tests/test_paper_cases.py): the scenario
# runs the paper's 2000 s, the criterion is judged on the same scenario run this long, over seeds
# 0-19, and must hold on at least 18 of them.
CASE2_JUDGE_S = 4000.0
# Beside the criterion, how often the search alone finds all six in the paper's 2000 s.
CASE2_SEARCH_PLANNERS = ("dacmp", "lawnmower")
# At least this many fast -> slow handovers on a seed that offered that many opportunities (the
# paper's UAV 3->9, 5->10, 4->8, 1->6).
CASE2_MIN_HANDOVERS = 4
CASE2_CONDITIONS = ("found", "watched", "takeovers", "handovers", "released", "safe")


def last_seen(log: RunLog, m: int) -> tuple[float, float, float] | None:
    """``(t, x, y)`` of the last tick at which some UAV had target ``m`` inside its detection
    radius (ground truth), or None if none ever did."""
    rows = log.targets.get(m)
    if rows is None:
        return None
    best: tuple[float, float, float] | None = None
    for uid, p in log.poses.items():
        r = float(log.type_specs.get(log.types.get(uid, "?"), {}).get("detect_radius_m", math.nan))
        txy = log.target_at(m, p[:, 0])
        seen = np.nonzero(np.hypot(p[:, 1] - txy[:, 0], p[:, 2] - txy[:, 1]) <= r)[0]
        if seen.size and (best is None or p[seen[-1], 0] > best[0]):
            i = seen[-1]
            best = (float(p[i, 0]), float(txy[i, 0]), float(txy[i, 1]))
    return best


def held_at_zone_edge(log: RunLog, m: int, uav: str) -> bool:
    """Whether ``uav`` holds target ``m`` the way DACMP-SPEC ("Reproduction targets") counts a
    target inside a no-fly zone as held, read for rule 5 of docs/modelling.md ("Assignment
    rules") as it stands since issue 33 (docs/paper.md, "Case 1 to 3 as tests", says why): at
    the last tick the target is inside a zone deeper than the UAV can see from outside (deeper
    than its detection radius less the UAV's own distance from the edge: from the point of its
    line nearest to the target it would not see it), and the UAV, outside the zone, is at its
    edge: within twice its detection radius of it, anywhere round it (it patrols the boundary;
    the spec's "edge nearest to it" was written when the keeper circled there)."""
    uid = log.uid(uav)
    seen = last_seen(log, m)
    if uid is None or uid not in log.poses or seen is None:
        return False
    x, y = log.poses[uid][-1, 1:3]
    tx, ty = log.target_at(m, np.array([log.poses[uid][-1, 0]]))[0]
    r = float(log.type_specs.get(log.types.get(uid, "?"), {}).get("detect_radius_m", math.nan))
    for th in log.threats:
        cx, cy, rad = float(th["x_m"]), float(th["y_m"]), float(th["radius_m"])
        depth = rad - math.hypot(tx - cx, ty - cy)  # > 0: the target is inside
        clear = math.hypot(x - cx, y - cy) - rad  # >= 0: the UAV is outside
        if depth > 0 and clear >= 0:
            return clear <= 2 * r and depth > r - clear
    return False


def case2_conditions(log: RunLog, handover_violations: Sequence[Any] = (), opportunities: int = 0) -> dict[str, bool]:
    """Case 2's criterion on one run (DACMP-SPEC "Reproduction targets"), and ``all`` of it:

    * ``found``: every target found;
    * ``watched``: at the last tick every target is watched by exactly one UAV (in surveillance
      mode assigned to it) that has it inside its detection radius, or that keeps a target
      inside a no-fly zone from its edge (:func:`held_at_zone_edge`);
    * ``takeovers``: every handover opportunity (a free slower UAV within its ``D`` of a target
      a faster UAV watches, able to talk to it) taken within 60 s, and every release within
      60 s of the slower UAV's arrival: no ``handover`` violation of rules 2-3
      (docs/modelling.md, "Assignment rules");
    * ``handovers``: at least ``min(CASE2_MIN_HANDOVERS, opportunities)`` fast -> slow
      handovers, where ``opportunities`` counts the targets that were offered one (a fast UAV
      watched it with a slower one free within its ``D``, or, being the target's owner, with a
      slower one already on its way: :attr:`HandoverChecker.opportunities`);
    * ``released``: a released fast UAV returns to search or watches a target nobody it can
      talk to holds (rule 4: no violation of it);
    * ``safe``: no separation, threat or dynamics violation.

    ``handover_violations`` and ``opportunities``: from a :class:`~swarm.testing.invariants.HandoverChecker`
    run over the log (:func:`case2_measures` does it)."""
    m = log.metrics
    watchers = log.watchers_at_end()
    rules = [v.data.get("rule") for v in handover_violations]
    fast_to_slow = [h for h in log.handovers if log.speed_max(h.from_uav) > log.speed_max(h.to_uav)]
    out = {
        "found": m["targets_found"] == m["targets_total"],
        "watched": len(watchers) == m["targets_total"]
        and all(len(w) == 1 and (w[0][1] or held_at_zone_edge(log, k, w[0][0])) for k, w in watchers.items()),
        "takeovers": not any(r in (2, 3) for r in rules),
        "handovers": len(fast_to_slow) >= min(CASE2_MIN_HANDOVERS, opportunities),
        "released": 4 not in rules,
        "safe": not any(m["violations"].values()),
    }
    out["all"] = all(out.values())
    return out
