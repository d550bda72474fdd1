"""A run's results assembled from a simulation: the metrics (``metrics.json``), the per-tick
paths, the union scan map and the event log bytes, as one :class:`RunResult`.

Kept apart from the kernel: nothing here changes the run, it only reads it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from agents.actor import UavActor
from agents.knowledge import KnownThreat
from agents.maps.grid import Grid
from comms.radio import Radio
from faults.injector import FaultInjector
from swarm.kernel.metrics import Metrics
from swarm.kernel.observer import Observer
from swarm.kernel.recorder import EventLog
from swarm.kernel.transmission import Transmission
from swarm.kernel.world import Targets, World
from swarm.provenance import versions
from swarm.scenario import Scenario

__all__ = ["RunResult", "radio_totals", "run_metrics", "run_result"]


@dataclass
class RunResult:
    """Everything a finished (or stopped) run produced; :mod:`swarm.outputs` writes it."""

    metrics: dict
    timeseries: list[dict]
    events: bytes
    paths: dict[str, np.ndarray]  # UAV name -> (n, 3) rows of (t, x, y)
    target_paths: dict[int, np.ndarray]
    union_last_seen: np.ndarray
    threats: list[KnownThreat]
    area: tuple[float, float]
    uav_types: dict[str, str] = field(default_factory=dict)
    # The scenario that ran (seed and overrides applied), as ``scenario.json`` holds it.
    scenario: dict = field(default_factory=dict)


class Run(Protocol):
    """What the results read of a simulation (:class:`swarm.kernel.simulation.Simulation` is one):
    its documented parts and the internals the results are made of, so that this module does
    not depend on the kernel."""

    scenario: Scenario
    seed: int
    _grid: Grid
    _world: World
    _targets: Targets
    _metrics: Metrics
    _log: EventLog
    _radio: Radio
    _observer: Observer
    _transmission: Transmission
    _speed_max_by_type: dict[str, float]

    @property
    def now(self) -> float: ...

    @property
    def wall_seconds(self) -> float: ...

    @property
    def actors(self) -> dict[int, UavActor]: ...

    @property
    def injector(self) -> FaultInjector: ...


def radio_totals(sim: Run) -> dict:
    c = sim._radio.counters
    delivered = sum(a.counters.delivered for a in sim.actors.values())
    rejected = sum(a.counters.rejected for a in sim.actors.values())
    rejected_auth = sum(a.counters.rejected_auth for a in sim.actors.values())
    queued = sum(len(a.mailbox) for a in sim.actors.values())
    return {
        "sent": c.sent,
        "delivered": delivered,
        "dropped": c.dropped_total,
        "rejected": rejected,
        "rejected_auth": rejected_auth,  # of the rejected: failed their MAC ([radio] auth)
        "bytes_sent": c.bytes_sent,
        "duplicated": c.duplicated,
        "dropped_by_cause": dict(sorted(c.dropped.items())),
        "in_flight": sim._transmission.in_flight + queued,  # scheduled on the clock or unread in a mailbox
    }


def run_metrics(sim: Run) -> dict:
    """``metrics.json``: the ground-truth measures, radio and fault counters, per-UAV counters."""
    sc = sim.scenario
    t = sim.now
    m = sim._metrics
    radio = radio_totals(sim)
    per_uav = {}
    for uid, b in sorted(sim._world.uavs.items()):
        a = sim.actors[uid]
        per_uav[b.name] = {
            "type": b.kind.name,
            "state": b.state,
            "mode_seconds": m.mode_s.get(uid, {"search": 0.0, "surveil": 0.0}),
            "frames_sent": a.counters.frames_sent,
            "frames_delivered": a.counters.delivered,
            "frames_rejected": a.counters.rejected,
            "frames_rejected_auth": a.counters.rejected_auth,  # of those, failed their MAC
            "mailbox_dropped_full": a.mailbox.stats.dropped_full,
            "mailbox_max_depth": a.mailbox.stats.max_depth,
            "plans": a.counters.plans,
            "scans_known": a.scans.count,  # own and heard scans in its log (agents.maps.scanlog)
            "scans_resent": a.counters.scans_resent,  # answers to neighbours' digests
            "scans_ignored": a.counters.scans_ignored,  # heard scans with absurd values
            "messages_ignored": a.counters.messages_ignored,  # other heard messages with absurd values
        }
    surv = m.surveillance_ratio(t)
    assignment = m.assignment(len(sim._targets), {uid: b.kind.name for uid, b in sim._world.uavs.items()},
                              sim._speed_max_by_type, t)
    for uid, share in assignment.pop("per_uav").items():
        per_uav[sim._world.uavs[uid].name]["time_share"] = share
    return {
        "scenario": sc.name,
        "planner": sc.planner.name,
        "seed": sim.seed,
        "sim_seconds": t,
        "wall_seconds": round(sim.wall_seconds, 3),
        "coverage": m.coverage(),
        "certainty": m.certainty(t),
        "targets_found": len(m.found_t),
        "targets_total": len(sim._targets),
        "surveillance_ratio_mean": float(np.mean(list(surv.values()))) if surv else 0.0,
        "surveillance_ratio": {str(k): v for k, v in surv.items()},
        "handovers": len(m.handovers),
        "handovers_fast_to_slow": m.fast_to_slow_handovers(sim._speed_max_by_type),
        "handover_list": [
            {"t": h.t, "target": h.target, "from": sim._world.uavs[h.from_uav].name,
             "to": sim._world.uavs[h.to_uav].name, "from_type": h.from_type, "to_type": h.to_type,
             "latency_s": h.latency_s, "overlap_s": max(h.latency_s, 0.0), "gap_s": max(-h.latency_s, 0.0)}
            for h in m.handovers
        ],
        **assignment,  # time_to_first_detection_s ... uav_time_share (swarm.kernel.metrics.Metrics.assignment)
        "radio": radio,
        "violations": dict(sim._world.violations),
        "dynamics_violations_by_uav": {
            sim._world.uavs[uid].name: {"count": int(n), "first_s": first, "last_s": last}
            for uid, (n, first, last) in sorted(sim._world.dynamics_by_uav.items())
        },
        "faults_applied": dict(sorted(sim.injector.fired.items())),
        "per_uav": per_uav,
        "events": sim._log.total,
        "event_log_sha256": sim._log.sha256(),
        # Not hashed: the software that ran (swarm.provenance; `swarm rerun` compares them).
        "versions": versions(),
        **_mission_metrics(sim),
    }


def _mission_metrics(sim: Run) -> dict:
    """(issue 26) What a geographic, windy or endurance scenario adds to ``metrics.json``;
    nothing for a scenario without them (their metrics are what they always were)."""
    out: dict = {}
    geo = getattr(sim, "_geography", None)
    if geo is not None and geo.frame is not None:
        out["geo"] = {**geo.frame.describe(), "cells_inside": int(geo.inside.sum()) if geo.inside is not None else None}
    mission = getattr(sim, "_mission", None)
    if mission is not None:
        out.update(mission.metrics())
    return out


def run_result(sim: Run) -> RunResult:
    events = sim._log.to_bytes()
    metrics = run_metrics(sim)
    return RunResult(
        metrics=metrics,
        timeseries=list(sim._metrics.rows),
        events=events,
        paths={sim._world.uavs[u].name: np.array(p, dtype=float).reshape(-1, 3) for u, p in sim._observer.paths.items()},
        target_paths=sim._observer.target_path_arrays(),
        union_last_seen=sim._metrics.union.to_dense(),
        threats=list(sim._world.threats),
        area=(sim._grid.width_m, sim._grid.height_m),
        uav_types={b.name: b.kind.name for b in sim._world.uavs.values()},
        scenario=sim.scenario.to_dict(),
    )
