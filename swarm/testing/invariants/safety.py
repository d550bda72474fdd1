"""Safety invariants: separation, threat clearance, turn-limited dynamics."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

import swarm.events as event_schema
from agents.dynamics import integrate, wrap_angle
from swarm.testing.invariants.checker import Checker, poses_of
from swarm.testing.invariants.context import RECOVER_S


class SeparationChecker(Checker):
    """No two flying UAVs closer than ``min_separation_m`` (default: the scenario's
    ``safety.min_separation_m``) through their own moves; one violation per episode."""

    name = "separation"

    def __init__(self, min_separation_m: float | None = None, excuse_node_faults: bool = True):
        super().__init__()
        self.min_separation_m = min_separation_m
        self.excuse_node_faults = excuse_node_faults  # False: judge impaired UAVs too (known failures)
        self._prev: set[int] = set()
        self._active: set[tuple[int, int]] = set()
        self._excused: set[tuple[int, int]] = set()

    def on_group(self, t: float, events: list[event_schema.Event]) -> None:
        poses = poses_of(events)
        if not poses:
            return
        # (issue 33) A UAV launched from its base is judged from its first pose: the base is no
        # excuse (launch slots keep the pads clear; metrics.json counts the same).
        launched = {e.uav for e in events if isinstance(e, event_schema.Launched)}
        d_min = self.min_separation_m if self.min_separation_m is not None else self.context.min_separation_m
        ids = sorted(poses)
        close: set[tuple[int, int]] = set()
        if len(ids) >= 2:
            xy = np.array([poses[u][:2] for u in ids], dtype=float)
            d = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
            for i, j in zip(*np.nonzero(np.triu(d < d_min, 1))):
                close.add((ids[int(i)], ids[int(j)]))
                pair = (ids[int(i)], ids[int(j)])
                if pair in self._active or pair in self._excused:
                    continue
                new = {u for u in pair if u not in self._prev}
                if new and not new & launched:
                    self._excused.add(pair)  # too close from the moment they were both flying
                    continue
                ctx = self.context
                if self.excuse_node_faults and (ctx.impaired(pair[0], t, after_s=RECOVER_S)
                                                or ctx.impaired(pair[1], t, after_s=RECOVER_S)):
                    self._excused.add(pair)  # a node fault's doing (until they are apart again)
                    continue
                self._active.add(pair)
                ctx = self.context
                self.violate(t, f"{ctx.name(pair[0])} and {ctx.name(pair[1])} are "
                                f"{float(d[i, j]):.1f} m apart (< {d_min:g} m)", pair, distance_m=float(d[i, j]))
        self._active &= close
        self._excused &= close
        self._prev = set(ids)


class ThreatClearanceChecker(Checker):
    """No flying UAV inside a threat circle through its own moves (a UAV that starts or joins
    inside one is excused until it is out)."""

    name = "threat"

    def __init__(self, excuse_node_faults: bool = True) -> None:
        super().__init__()
        self.excuse_node_faults = excuse_node_faults  # False: judge impaired UAVs too (known failures)
        self._prev: set[int] = set()
        self._active: set[tuple[int, int]] = set()
        self._excused: set[tuple[int, int]] = set()

    def on_group(self, t: float, events: list[event_schema.Event]) -> None:
        poses = poses_of(events)
        if not poses:
            return
        ctx = self.context
        inside: set[tuple[int, int]] = set()
        for uid, p in poses.items():
            for k, x, y, r in ctx.threats:
                d = math.hypot(p[0] - x, p[1] - y)
                if d >= r:
                    continue
                self._inside(t, uid, k, inside, f"{r - d:.1f} m inside threat {k} (radius {r:g} m)", r - d)
            for z in ctx.zones:  # (issue 26) polygon zones: the depth is minus the signed clearance
                depth = -z.clearance(p[0], p[1])[0]
                if depth > 0.0:
                    self._inside(t, uid, z.zone, inside, f"{depth:.1f} m inside no-fly polygon {z.zone}", depth)
        self._active &= inside
        self._excused &= inside
        self._prev = set(poses)

    def _inside(self, t: float, uid: int, k: int, inside: set[tuple[int, int]], words: str, depth: float) -> None:
        ctx = self.context
        key = (uid, k)
        inside.add(key)
        if key in self._active or key in self._excused:
            return
        if uid not in self._prev or (self.excuse_node_faults and ctx.impaired(uid, t, after_s=RECOVER_S)):
            self._excused.add(key)  # (a node fault's doing: excused until it is out)
            return
        self._active.add(key)
        self.violate(t, f"{ctx.name(uid)} is {words}", [uid], threat=k, depth_m=depth)


class DynamicsChecker(Checker):
    """Consecutive poses (``t``, ``t + dt``) of each UAV respect its type's hard limits
    (``speed_min <= v <= speed_max``, ``|dv| <= accel_max dt``, ``|dtheta| <= g tan(bank)/v dt``
    at the larger of the two speeds) and the kinematics (eq. 9-10: the position follows from
    speed and heading). ``tol_m``: position tolerance; limits get a relative 1e-9.

    Only bodies the simulator flies are judged: a UAV whose body a host drives (from its
    ``take_control`` to its ``release_control``, ``host`` events) is not, and :attr:`skipped`
    (and :attr:`note`, the monitor's ``notes``) says which UAVs and for how many poses."""

    name = "dynamics"

    def __init__(self, tol_m: float = 1e-6):
        super().__init__()
        self.tol_m = tol_m
        self._prev: dict[int, tuple[Any, ...]] = {}
        self._wind: tuple[float, float] | None = None  # (issue 26) the last group's wind event
        self._driven: set[str] = set()  # UAV names whose bodies the host drives now
        self.skipped: dict[str, int] = {}  # UAV name -> poses not judged (driven from outside)

    def on_group(self, t: float, events: list[event_schema.Event]) -> None:
        released = self._host_control(events)
        poses = poses_of(events)
        if not poses:
            return
        ctx = self.context
        dt = ctx.dt
        # (issue 26) With [wind] the log has the wind of each tick: the position follows from
        # the speed and heading plus the wind of the tick before (the limits are air-relative).
        wind_before = self._wind
        self._wind = next(((e.wx, e.wy) for e in events if isinstance(e, event_schema.Wind)), None)
        for uid, p in poses.items():
            kind = ctx.kind(uid)
            prev = self._prev.get(uid)
            self._prev[uid] = (t, *p)
            if kind is None:
                continue
            name = ctx.name(uid)
            if name in self._driven or name in released:  # (its pose is the host's, not the simulator's)
                self.skipped[name] = self.skipped.get(name, 0) + 1
                continue
            x1, y1, v1, th1 = p[:4]
            rel = 1e-9
            if not (kind.speed_min * (1 - rel) - rel <= v1 <= kind.speed_max * (1 + rel) + rel):
                self.violate(t, f"speed {v1:.6g} m/s outside [{kind.speed_min:g}, {kind.speed_max:g}]", [uid], v=v1)
            if prev is None or abs(t - prev[0] - dt) > 1e-9 * max(1.0, t):
                continue
            _, x0, y0, v0, th0 = prev[:5]
            a = (v1 - v0) / dt
            if abs(a) > kind.accel_max * (1 + rel) + rel:
                self.violate(t, f"acceleration {a:.6g} m/s^2 beyond {kind.accel_max:g}", [uid], a=a)
            omega = wrap_angle(th1 - th0) / dt
            w_max = kind.turn_rate_max(max(v0, v1))
            if abs(omega) > w_max * (1 + rel) + rel:
                self.violate(t, f"turn rate {omega:.6g} rad/s beyond {w_max:.6g} (turn radius below r_min)",
                             [uid], omega=omega)
            px, py, _, _ = integrate(x0, y0, v0, th0, a, omega, dt)
            if wind_before is not None:
                px, py = px + wind_before[0] * dt, py + wind_before[1] * dt
            err = math.hypot(px - x1, py - y1)
            if err > self.tol_m + 1e-9 * (abs(x1) + abs(y1)):
                self.violate(t, f"moved {err:.3g} m away from where its speed and heading take it", [uid], error_m=err)

    def _host_control(self, events: list[event_schema.Event]) -> set[str]:
        """Follow take_control / release_control; returns the UAVs released at this instant
        (their pose now is still where the host put them)."""
        released: set[str] = set()
        for e in events:
            if isinstance(e, event_schema.Host) and e.change in ("take_control", "release_control"):
                name = e.args["uav"]
                if e.change == "take_control":
                    self._driven.add(name)
                else:
                    self._driven.discard(name)
                    released.add(name)
        return released

    @property
    def note(self) -> str | None:
        """Which UAVs it did not judge, and why (None: it judged every pose)."""
        if not self.skipped:
            return None
        return ("not judged while driven from outside (take_control): "
                + ", ".join(f"{n} ({k} poses)" for n, k in sorted(self.skipped.items())))
