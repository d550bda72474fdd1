"""Faults on what a UAV senses and believes: clock_skew, nav_error, sensor (tick faults)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from typing import ClassVar, Literal

from agents.inputs import SensedTarget
from faults.base import END, PHANTOM_TARGET_ID, PROBABILITY, START, UAV, UAVS, Draws
from faults.registry import register
from faults.tick import TickFault, TickFaults

# False alarms' ids count up from PHANTOM_TARGET_ID, over this span (below 2**31, the largest
# id a receiver accepts; liars' tracks use the next span).
PHANTOM_ID_SPAN = 500_000_000


@register
@dataclass(frozen=True, kw_only=True)
class ClockSkew(TickFault):
    """While active the UAV's clock reads ``t + offset_s + drift * (t - start_s)``: every time
    it stamps (its scans, its frames, the tracks it sees) is skewed. Receivers ignore what is
    stamped later than their own clock (a max-CRDT would keep such cells fresh forever)."""

    uav: str = field(metadata=UAV)
    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(default=math.inf, metadata=END)
    offset_s: float = field(default=0.0, metadata={"ge": -1.0e6, "le": 1.0e6, "note": "s"})
    drift: float = field(default=0.0, metadata={"ge": -0.5, "le": 0.5, "note": "s of error per s"})
    kind: ClassVar[Literal["clock_skew"]] = "clock_skew"
    impairs_control: ClassVar[bool] = True
    tick_order: ClassVar[int] = 2
    shrink_rank: ClassVar[int] = 160
    min_uavs: ClassVar[int] = 1

    @classmethod
    def generate(cls, d: Draws) -> ClockSkew:
        """Off (whole seconds, either way) and/or drifting (within the bounds); never both zero."""
        start, end = d.draw(d.windows())
        offset = d.draw(d.st.one_of(d.st.sampled_from([5.0, -5.0, 30.0, -30.0]), d.st.integers(-120, 120).map(float)))
        drift = d.draw(d.st.one_of(d.st.just(0.0), d.st.sampled_from([0.1, -0.1, 0.5, -0.5]),
                                   d.st.floats(-0.5, 0.5).map(lambda x: round(x, 3))))
        if offset == 0.0 and drift == 0.0:
            offset = 1.0
        return cls(uav=d.draw(d.names()), start_s=start, end_s=end, offset_s=offset, drift=drift)

    def error(self, t: float) -> float:
        """The clock's error at true time ``t`` (while active)."""
        return self.offset_s + self.drift * (t - self.start_s)

    def disturbs_maps(self, t: float) -> bool:
        # Receivers ignore scans from their future: until true time reaches the stamps of its
        # largest lead, nobody else has those cells.
        if t < self.start_s:
            return False
        lead = self.offset_s + (self.drift * (self.end_s - self.start_s) if self.drift > 0 else 0.0)
        return t < self.end_s + max(0.0, lead) + 1e-9

    def on_tick(self, faults: TickFaults, index: int, uid: int) -> None:
        if faults.first(index, uid):
            faults.events.fault_on(t=faults.t, fault=self.kind, uav=uid)
            faults.fired(self.kind, 1)
        faults.readings[uid].t += self.error(faults.t)


@register
@dataclass(frozen=True, kw_only=True)
class NavError(TickFault):
    """The UAV believes it is at its true position plus ``(bias_x_m, bias_y_m)`` plus Gaussian
    noise of ``noise_m`` per axis (drawn each tick): it plans, flies and stamps its scans there,
    while the ground truth senses where it really is."""

    uav: str = field(metadata=UAV)
    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(default=math.inf, metadata=END)
    bias_x_m: float = field(default=0.0, metadata={"ge": -1.0e6, "le": 1.0e6, "note": "m"})
    bias_y_m: float = field(default=0.0, metadata={"ge": -1.0e6, "le": 1.0e6, "note": "m"})
    noise_m: float = field(default=0.0, metadata={"ge": 0, "le": 1.0e6, "note": "m, standard deviation per axis"})
    kind: ClassVar[Literal["nav_error"]] = "nav_error"
    impairs_control: ClassVar[bool] = True
    tick_order: ClassVar[int] = 1
    shrink_rank: ClassVar[int] = 150
    min_uavs: ClassVar[int] = 1

    @classmethod
    def generate(cls, d: Draws) -> NavError:
        """A bias (whole 10 m, up to 1 km) and/or noise (whole metres, up to 200 m); never all zero."""
        start, end = d.draw(d.windows())
        bx = d.draw(d.st.one_of(d.st.sampled_from([100.0, -100.0, 500.0]), d.st.integers(-100, 100).map(lambda b: b * 10.0)))
        by = d.draw(d.st.one_of(d.st.just(0.0), d.st.integers(-100, 100).map(lambda b: b * 10.0)))
        noise = d.draw(d.st.one_of(d.st.just(0.0), d.st.integers(1, 200).map(float)))
        if bx == 0.0 and by == 0.0 and noise == 0.0:
            bx = 100.0
        return cls(uav=d.draw(d.names()), start_s=start, end_s=end, bias_x_m=bx, bias_y_m=by, noise_m=noise)

    def on_tick(self, faults: TickFaults, index: int, uid: int) -> None:
        if faults.first(index, uid):
            faults.events.fault_on(t=faults.t, fault=self.kind, uav=uid)
            faults.fired(self.kind, 1)
        r = faults.readings[uid]
        ex, ey = self.bias_x_m, self.bias_y_m
        if self.noise_m > 0:
            nx, ny = faults.stream(index, self.kind, uid).normal(0.0, self.noise_m, 2).tolist()
            ex, ey = ex + nx, ey + ny
        r.x += ex
        r.y += ey
        r.targets = [replace(s, x=s.x + ex, y=s.y + ey) for s in r.targets]
        if r.uavs:  # (detect and avoid measures the others relative to the UAV)
            r.uavs = [(u, x + ex, y + ey, vx, vy) for u, x, y, vx, vy in r.uavs]


@register
@dataclass(frozen=True, kw_only=True)
class Sensor(TickFault):
    """Detection faults of ``uavs`` (empty: all): each target inside the detection radius is
    seen with probability ``p_detect`` per tick, and phantom targets (false alarms) appear in
    the detection disk at ``false_alarm_rate`` per UAV-second."""

    uavs: tuple[str, ...] = field(default=(), metadata=UAVS)
    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(default=math.inf, metadata=END)
    p_detect: float = field(default=1.0, metadata=PROBABILITY)
    false_alarm_rate: float = field(default=0.0, metadata={"ge": 0, "le": 100, "note": "phantoms per UAV-second"})
    kind: ClassVar[Literal["sensor"]] = "sensor"
    impairs_sensing: ClassVar[bool] = True
    tick_order: ClassVar[int] = 0
    shrink_rank: ClassVar[int] = 140

    @classmethod
    def generate(cls, d: Draws) -> Sensor:
        """Missed detections (``p_detect < 1``, shrinking to 0: blind) and/or false alarms (up to
        one phantom per UAV-second); never a perfect sensor."""
        start, end = d.draw(d.windows())
        scope = d.draw(d.st.one_of(d.st.just(()), d.st.lists(d.names(), min_size=1, max_size=len(d.uavs), unique=True)
                                   .map(tuple))) if d.uavs else ()
        p = d.draw(d.st.one_of(d.st.just(0.0), d.probabilities(0.0, 0.95)))
        far = d.draw(d.st.one_of(d.st.just(0.0), d.st.sampled_from([0.1, 1.0]),
                                 d.st.floats(0.0, 1.0).map(lambda r: round(r, 3))))
        return cls(uavs=scope, start_s=start, end_s=end, p_detect=p, false_alarm_rate=far)

    def on_tick(self, faults: TickFaults, index: int, uid: int) -> None:
        """Misses and false alarms of one UAV this tick (fired: how many)."""
        r = faults.readings[uid]
        g = faults.stream(index, self.kind, uid)
        if uid not in faults.truth:
            faults.truth[uid] = [s.target for s in r.targets if s.target < PHANTOM_TARGET_ID]
        n = 0
        if self.p_detect < 1.0 and r.targets:
            keep = g.random(len(r.targets)) < self.p_detect
            n += int(len(keep) - keep.sum())
            r.targets = [s for s, k in zip(r.targets, keep.tolist()) if k]
        if self.false_alarm_rate > 0:
            k = int(g.poisson(self.false_alarm_rate * faults.dt))
            radius = faults.actors[uid].kind.detect_radius
            for _ in range(k):
                u, phi = g.random(2).tolist()
                d = radius * math.sqrt(u)  # uniform over the disk's area
                tid = faults.serial("phantom", PHANTOM_TARGET_ID, PHANTOM_ID_SPAN)
                r.targets.append(SensedTarget(tid, r.x + d * math.cos(2 * math.pi * phi),
                                              r.y + d * math.sin(2 * math.pi * phi), 0.0, 0.0, 1.0))
            n += k
        if faults.detected is None:
            faults.detected = {}
        faults.detected[uid] = [s.target for s in r.targets if s.target < PHANTOM_TARGET_ID]
        if n:
            faults.fired(self.kind, n)
        if faults.first(index, uid):
            faults.events.fault_on(t=faults.t, fault=self.kind, uav=uid)


def skewed_stamps(faults: Iterable[object], duration_s: float) -> list[tuple[float, float]]:
    """The ranges of times skewed clocks stamped (every clock skew, over its window; skews that
    overlap on one UAV add up). Cells holding such a time are not owed to anyone, ever, by the
    UAV that stamped them or by one that heard it: a record stamped in a receiver's future is
    ignored, and one stamped in the past usually lands in an (origin, tick) slot of the scan log
    that the origin's real scan of that tick already holds, so anti-entropy never resends it
    (agents.maps.scanlog keeps one scan per origin and tick)."""
    by_uav: dict[str, list[ClockSkew]] = {}
    for f in faults:
        if isinstance(f, ClockSkew) and (f.offset_s or f.drift):
            by_uav.setdefault(f.uav, []).append(f)
    out = []
    for skews in by_uav.values():
        # Between two breakpoints the clock's error is linear (a sum of the active skews' lines),
        # so the stamps made there span the values at the two ends.
        cuts = sorted({min(t, duration_s) for f in skews for t in (f.start_s, f.end_s)})
        for lo, hi in zip(cuts, cuts[1:]):
            active = [f for f in skews if f.start_s <= lo and hi <= f.end_s]
            if not active:
                continue
            a_, b_ = lo + sum(f.error(lo) for f in active), hi + sum(f.error(hi) for f in active)
            out.append((min(a_, b_) - 1e-6, max(a_, b_) + 1e-6))
    return out


def max_skew_at_end(faults: Iterable[object]) -> float:
    """The largest clock error (ahead of true time) any ``clock_skew`` fault had when it ended."""
    worst = 0.0
    for f in faults:
        if isinstance(f, ClockSkew) and math.isfinite(f.end_s):
            worst = max(worst, f.error(f.end_s), f.error(f.start_s))
    return worst
