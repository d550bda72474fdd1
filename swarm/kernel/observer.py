"""The tick's observe phase: ground truth into the metrics, the event log and the paths.

After the actors answered, the observer records, in UAV-id order, each one's mode changes,
scan and sightings (ground truth, into :class:`swarm.kernel.metrics.Metrics`), pose and frames read;
then the metrics' events (found, release, handover, ...), every target's position and the
safety violations. It also keeps what the run's results read: each UAV's and target's path,
the sampled time series, and, at recording level ``"summary"``, the per-tick count of frame
copies read and lost (one ``radio`` event a tick instead of one event per copy).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

import swarm.events as ev
from agents.actor import ActorOutput
from agents.inputs import SensorReading
from agents.planners.base import Plan
from faults.tick import TickFaults
from swarm.events import Wire, pack_target_events
from swarm.kernel.metrics import Metrics
from swarm.kernel.recorder import EventLog
from swarm.kernel.world import World

# From this many targets on, a tick's ``target`` events are packed from the positions' array
# (pack_target_events) instead of tuple by tuple: 10^5 targets cost 50 ms a tick that way.
_PACK_MIN = 256


class Observer:
    """What the run records of itself, tick by tick."""

    def __init__(self, world: World, metrics: Metrics, log: EventLog, dt: float, summary: bool,
                 min_separation_m: float):
        self.world = world
        self.metrics = metrics
        self.log = log
        self.dt = dt
        self.min_separation_m = min_separation_m
        # Flat (t, x, y, t, x, y, ...) per UAV: an array is made from a flat list of floats
        # several times faster than from a list of tuples (swarm.kernel.results).
        self.paths: dict[int, list[float]] = {}
        # The targets' positions, one (n, 2) array per tick (the world's own, which it replaces
        # rather than changes): per-target lists cost 10^5 list appends a tick and 32 bytes a
        # float (issue 25); target_path_arrays() cuts them into paths.
        self._target_t: list[float] = []
        self._target_xy: list[np.ndarray] = []
        # Recording level "summary": rx / lost frame copies are counted per tick and logged as
        # one "radio" event at the end of the tick, not one event each.
        self.summary = summary
        self._rx = [0, 0, 0]  # frames read, of them rejected, bytes read
        self._lost: dict[str, list[int]] = {}  # cause -> [copies, bytes]

    def lost(self, t: float, src: int, dst: int, nbytes: int, cause: str) -> None:
        """A frame copy lost: a ``lost`` event, or (recording level "summary") counted."""
        if self.summary:
            c = self._lost.get(cause)
            if c is None:
                c = self._lost[cause] = [0, 0]
            c[0] += 1
            c[1] += nbytes
        else:
            self.log.emit(ev.lost(t=t, src=src, dst=dst, bytes=nbytes, cause=cause))

    def observe(self, t: float, alive: list[int], outputs: Mapping[int, ActorOutput],
                readings: Mapping[int, SensorReading], xy: np.ndarray, last_plans: dict[int, Plan],
                faults: TickFaults, speed_max_by_type: dict[str, float]) -> None:
        """Ground truth at ``t`` (positions as the agents saw them): modes, scans, sightings,
        poses, frames read, target positions, then safety violations; all into the log.
        ``last_plans``: each UAV's previous plan (updated here); ``faults``: what this tick's
        tick faults did (paused UAVs sense nothing; a sensing fault's truth)."""
        world = self.world
        plans: dict[int, tuple[int, int]] = {}
        sensed: dict[int, list[int]] = {}
        uavs = world.uavs
        metrics_scan = self.metrics.scan
        paths = self.paths
        # The tick's many events are gathered and logged with one extend() per batch (the same
        # events in the same order as one emit() each, subscribers included).
        events: list[Wire] = []
        add = events.append
        paused, truth = faults.paused, faults.truth
        summary, rx = self.summary, self._rx
        pose, rx_many = ev.pose, ev.rx_many
        for uid in alive:
            b = uavs[uid]
            out = outputs[uid]
            plan = out.plan
            prev = last_plans.get(uid)
            last_plans[uid] = plan
            if prev is None or prev.mode != plan.mode or prev.target != plan.target:
                add(ev.mode(t=t, uav=uid, mode=plan.mode, target=plan.target))
            plans[uid] = (plan.mode, plan.target)
            if paused and uid in paused:
                sensed[uid] = []  # a paused process reads no sensor: it scans and sees nothing
                if faults.detected is not None:
                    faults.detected.pop(uid, None)
            else:
                metrics_scan(b.x, b.y, b.kind.detect_radius, t)
                # The truth inside its detection radius (a sensor fault's misses and phantoms
                # are what the UAV believes, not what is there; see Metrics.observe).
                sensed[uid] = truth[uid] if truth and uid in truth else [s.target for s in readings[uid].targets]
            add(pose(t=t, uav=uid, x=b.x, y=b.y, v=b.v, theta=b.theta, mode=plan.mode, target=plan.target))
            paths[uid].extend((t, b.x, b.y))
            if summary:
                for _sender, nbytes, ok in out.received:
                    rx[0] += 1
                    rx[1] += not ok
                    rx[2] += nbytes
            else:
                events += rx_many(t=t, dst=uid, received=out.received)
        types = {u: uavs[u].kind.name for u in alive}
        events += self.metrics.observe(t, self.dt, plans, sensed, types, speed_max_by_type, faults.detected)
        tg = world.targets
        txy = tg.xy
        self._target_t.append(t)
        self._target_xy.append(txy)
        log = self.log
        n = len(txy)
        if n < _PACK_MIN or type(t) is not float:
            events += [ev.target(t=t, target=i, x=x, y=y) for i, (x, y) in enumerate(txy.tolist())]
            log.extend(events)
        else:  # every target's event of the tick packed from the arrays at once (the same bytes)
            log.extend(events)
            log.extend_packed(pack_target_events(t, txy), n, lambda: [ev.target(t=t, target=i, x=x, y=y)
                                                                       for i, (x, y) in enumerate(txy.tolist())])
        for kind, a, b2 in world.check_safety(alive, xy, self.min_separation_m):
            log.emit(ev.violation(t=t, invariant=kind, uav=a, other=b2))

    def target_path_arrays(self) -> dict[int, np.ndarray]:
        """Each target's path so far: ``(ticks, 3)`` rows of ``(t, x, y)`` from the first tick
        observed with it (targets added later start later)."""
        ts, snaps = self._target_t, self._target_xy
        out: dict[int, np.ndarray] = {}
        k0 = 0
        while k0 < len(snaps):
            # the targets first observed at tick k0, and the ticks until more were added
            i0, i1 = (len(snaps[k0 - 1]) if k0 else 0), len(snaps[k0])
            k1 = k0 + 1
            while k1 < len(snaps) and len(snaps[k1]) == i1:
                k1 += 1
            if i1 > i0:
                rows = np.empty((i1 - i0, len(snaps) - k0, 3))
                rows[:, :, 0] = np.asarray(ts[k0:])
                for k in range(k0, len(snaps)):
                    rows[:, k - k0, 1:] = snaps[k][i0:i1]
                out.update(zip(range(i0, i1), rows))
            k0 = k1
        return out

    def end_tick(self, t: float) -> None:
        """Recording level "summary": the tick's one ``radio`` event, ``[t, read, rejected,
        bytes_read, {cause: [copies, bytes]}]`` (causes sorted), covering every frame copy read
        or lost since the previous one; none for a tick with neither."""
        if not self.summary:
            return
        rx, lost = self._rx, self._lost
        if rx[0] or lost:
            self.log.emit(ev.radio(t=t, read=rx[0], rejected=rx[1], bytes_read=rx[2], lost={c: lost[c] for c in sorted(lost)}))
            self._rx = [0, 0, 0]
            self._lost = {}

    def sample(self, t: float, radio: dict[str, Any], modes: Callable[[], dict[str, str]]) -> None:
        """One row of the time series (``timeseries.csv``) at ``t``."""
        m = self.metrics
        row = {
            "t": t,
            "coverage": m.coverage(),
            "certainty": m.certainty(t),
            "targets_found": len(m.found_t),
            "alive": len(self.world.alive_ids()),
            **{k: radio[k] for k in ("sent", "delivered", "dropped", "rejected", "bytes_sent")},
        }
        for name, mode in modes().items():
            row[f"mode_{name}"] = mode
        m.rows.append(row)
