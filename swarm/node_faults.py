"""The node and sensing faults (pause, clock_skew, nav_error, sensor, liar) while they act.

:class:`NodeFaults` holds the windowed faults of those kinds between their ``start_s`` and
``end_s`` clock events (the simulation schedules them at priority FAULT, as crash and join) and
applies them, tick by tick, to the UAVs that are flying:

* ``pause``: the UAV is not woken (the simulation flies its last command; see
  ``Simulation._wake_actors``);
* ``clock_skew``: the reading's ``t`` is the UAV's clock, ``t + error``;
* ``nav_error``: the reading's ``x, y`` (and the targets and, detect and avoid, UAVs it senses)
  are shifted by the bias plus Gaussian noise: the UAV believes it is there;
* ``sensor``: each sensed target is kept with probability ``p_detect``; phantom targets are
  added at ``false_alarm_rate`` per second (Poisson) at uniform points of the detection disk;
* ``liar``: fabricated scans and tracks are handed to the actor, which sends them with its
  beacons (:meth:`agents.actor.UavActor.lie`).

Every random draw comes from the fault's own stream, ``("fault", kind, index, uav name)``
(``index``: the fault's place in the schedule), so a fault never shifts any other stream and a
run without these faults draws exactly what it drew before. Nothing here runs when no such
fault is active: the tick's fast path is one test of an empty list.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from functools import partial

import numpy as np

from agents.actor import SensedTarget, SensorReading, UavActor
from faults.schedule import PHANTOM_TARGET_ID, ClockSkew, Liar, NavError, Pause, Sensor
from swarm.rng import RngTree

WindowFault = Pause | ClockSkew | NavError | Sensor | Liar
# Phantom target ids: false alarms count up from PHANTOM_TARGET_ID, liars' tracks from
# _LIAR_TRACK_IDS (both below 2**31, the largest id a receiver accepts).
_LIAR_TRACK_IDS = PHANTOM_TARGET_ID + 500_000_000
_ID_SPAN = 500_000_000


class NodeFaults:
    """The active windowed node faults of one simulation (see the module docstring)."""

    def __init__(self, rng: RngTree, names: dict[str, int], area: tuple[float, float], dt: float):
        self._rng = rng
        self._names = names
        self._area = area
        self._dt = dt
        # (schedule index, fault) between its start and end events, in the order they began.
        self.active: list[tuple[int, WindowFault]] = []
        self._streams: dict[tuple[int, int], np.random.Generator] = {}
        self._carry: dict[tuple[int, int, str], float] = {}  # liar: fabrications owed (fractions)
        self._applied: set[tuple[int, int]] = set()  # (index, uid): the fault has acted on the UAV
        self._phantoms = 0  # false alarms so far (their ids)
        self._liar_tracks = 0
        self.paused: set[int] = set()  # UAVs paused this tick
        self.truth: dict[int, list[int]] = {}  # this tick's sensed target ids before a sensor fault
        self.detected: dict[int, list[int]] | None = None  # real target ids its sensor reported
        self._fired: Callable[[str, int], None] = lambda kind, n: None

    def stream(self, index: int, kind: str, uid: int, name: str) -> np.random.Generator:
        g = self._streams.get((index, uid))
        if g is None:
            g = self._streams[(index, uid)] = self._rng.generator("fault", kind, index, name)
        return g

    def _first(self, index: int, uid: int) -> bool:
        """True the first time fault ``index`` acts on UAV ``uid`` (it fired)."""
        key = (index, uid)
        if key in self._applied:
            return False
        self._applied.add(key)
        return True

    def forget(self, index: int, uid: int) -> bool:
        """The fault's window ended or the UAV went down: True if it had acted on the UAV."""
        if (index, uid) in self._applied:
            self._applied.discard((index, uid))
            return True
        return False

    def targets_of(self, f: WindowFault, alive: list[int]) -> list[int]:
        if isinstance(f, Sensor):
            if not f.uavs:
                return alive
            scope = {self._names[n] for n in f.uavs}
            return [u for u in alive if u in scope]
        uid = self._names[f.uav]
        return [uid] if uid in alive else []

    def apply(self, t: float, alive: list[int], readings: dict[int, SensorReading],
              actors: dict[int, UavActor], pausable: Callable[[int], bool],
              emit: Callable[..., None], fired: Callable[[str, int], None]) -> None:
        """Apply the active faults to this tick's readings (in place), in a fixed order:
        sensor (what is seen), then navigation (where the UAV believes it and what it saw are),
        then the clock, then pause and liar (what the actor does with it)."""
        self.paused = set()
        self.truth = {}
        self.detected = None
        self._fired = fired
        order = {"sensor": 0, "nav_error": 1, "clock_skew": 2, "pause": 3, "liar": 4}
        alive_set = set(alive)
        for index, f in sorted(self.active, key=lambda p: (order[p[1].kind], p[0])):
            for uid in self.targets_of(f, alive):
                if uid not in alive_set:
                    continue
                r = readings[uid]
                name = actors[uid].name
                if isinstance(f, Sensor):
                    n = self._sensor(index, f, uid, name, r, actors[uid].kind.detect_radius)
                    if n:
                        fired("sensor", n)
                    if self._first(index, uid):
                        emit("fault_on", t, "sensor", uid)
                    continue
                if isinstance(f, Pause):
                    if not pausable(uid):
                        continue  # never woken yet (just joined or restarted): no last command to fly
                    self.paused.add(uid)
                    if self._first(index, uid):
                        emit("pause", t, uid)
                        fired("pause", 1)
                    continue
                if self._first(index, uid):
                    emit("fault_on", t, f.kind, uid)
                    if not isinstance(f, Liar):  # (a liar fires per fabrication sent: UavActor.lie)
                        fired(f.kind, 1)
                if isinstance(f, NavError):
                    ex, ey = f.bias_x_m, f.bias_y_m
                    if f.noise_m > 0:
                        nx, ny = self.stream(index, f.kind, uid, name).normal(0.0, f.noise_m, 2).tolist()
                        ex, ey = ex + nx, ey + ny
                    r.x += ex
                    r.y += ey
                    r.targets = [replace(s, x=s.x + ex, y=s.y + ey) for s in r.targets]
                    if r.uavs:  # (detect and avoid measures the others relative to the UAV)
                        r.uavs = [(u, x + ex, y + ey, vx, vy) for u, x, y, vx, vy in r.uavs]
                elif isinstance(f, ClockSkew):
                    r.t += f.error(t)
                elif isinstance(f, Liar):
                    self._lie(index, f, uid, name, actors[uid])

    def _sensor(self, index: int, f: Sensor, uid: int, name: str, r: SensorReading, radius: float) -> int:
        """Misses and false alarms of one UAV this tick; returns how many (what fired)."""
        g = self.stream(index, f.kind, uid, name)
        if uid not in self.truth:
            self.truth[uid] = [s.target for s in r.targets if s.target < PHANTOM_TARGET_ID]
        n = 0
        if f.p_detect < 1.0 and r.targets:
            keep = g.random(len(r.targets)) < f.p_detect
            n += int(len(keep) - keep.sum())
            r.targets = [s for s, k in zip(r.targets, keep.tolist()) if k]
        if f.false_alarm_rate > 0:
            k = int(g.poisson(f.false_alarm_rate * self._dt))
            for _ in range(k):
                u, phi = g.random(2).tolist()
                d = radius * math.sqrt(u)  # uniform over the disk's area
                tid = PHANTOM_TARGET_ID + self._phantoms % _ID_SPAN
                self._phantoms += 1
                r.targets.append(SensedTarget(tid, r.x + d * math.cos(2 * math.pi * phi),
                                              r.y + d * math.sin(2 * math.pi * phi), 0.0, 0.0, 1.0))
            n += k
        if self.detected is None:
            self.detected = {}
        self.detected[uid] = [s.target for s in r.targets if s.target < PHANTOM_TARGET_ID]
        return n

    def _owed(self, key: tuple[int, int, str], rate: float) -> int:
        c = self._carry.get(key, 0.0) + rate * self._dt
        n = int(c)
        self._carry[key] = c - n
        return n

    def _lie(self, index: int, f: Liar, uid: int, name: str, actor: UavActor) -> None:
        """This tick's fabrications for the liar's actor: scans at uniform points of the area
        with its detection radius, tracks of phantom targets at uniform positions."""
        g = self.stream(index, f.kind, uid, name)
        w, h = self._area
        n_scans = self._owed((index, uid, "scans"), f.scans_per_s)
        n_tracks = self._owed((index, uid, "tracks"), f.tracks_per_s)
        scans = [(x * w, y * h, actor.kind.detect_radius) for x, y in g.random((n_scans, 2)).tolist()]
        tracks = []
        for x, y in g.random((n_tracks, 2)).tolist():
            tracks.append((_LIAR_TRACK_IDS + self._liar_tracks % _ID_SPAN, x * w, y * h))
            self._liar_tracks += 1
        actor.lie(scans, tracks)
        if actor.lie_sink is None:
            actor.lie_sink = partial(self._fired, "liar")
