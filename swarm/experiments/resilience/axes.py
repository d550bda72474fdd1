"""The resilience axes, one :class:`Axis` record each: its default values, the sweep setting its
value is recorded under, its undegraded baseline, its title, what a value must be, how a value
is written, and how a value becomes scenario changes. Adding an axis is adding one record to
:data:`AXIS_LIST`; the command line, the runs, the figures and the tables read it from here.
Light on purpose (no plotting, no simulation): the command line reads it to build its help.

An axis that degrades with a fault builds it from the fault kind's class (:mod:`faults.schedule`:
its fields, their defaults) and, where a value is a field of the kind, checks it against the
field's bounds (the class's metadata, as the ``[[faults]]`` table does): nothing of a kind is
written here again.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from faults.base import FaultKind
from faults.registry import fault_to_dict
from faults.schedule import Burst, ClockSkew, Crash, Jammer, Join, Liar, Pause, Restart, Sensor
from swarm.errors import UsageError
from swarm.scenario import Scenario
from swarm.scenario.fields import field_bounds

__all__ = [
    "AXES",
    "AXIS_LIST",
    "BASELINE",
    "NO_BASELINE",
    "Axis",
    "PointContext",
    "axis_named",
    "battery_point",
    "burst_fault",
    "crash_candidates",
]

DEFAULT_CRASH_AT_S = 300.0
DEFAULT_BURST_LOSS = 0.3
MAX_DEFAULT_CRASHES = 5
# The pause and skew axes degrade this many UAVs (half of paper-fig11's six).
FAULTED_UAVS = 3
RESTART_DOWNTIME_S = 60.0
# The check of issue 4: with 30% i.i.d. loss DACMP keeps at least 90% of its loss-free coverage.
TARGET_LOSS = 0.3
TARGET_KEPT = 0.9

# Quantities per run (from metrics.json): delivered = radio.delivered (frame copies decoded by
# receivers; the radio's throughput, which range and crashes cut too), delivered_fraction =
# radio.delivered / radio.sent (copies offered to UAVs in range: what loss cuts);
# separation_violations = violations.separation (UAVs that cannot hear each other do not avoid
# each other).
QUANTITIES = ("coverage", "targets_found", "surveillance_ratio_mean", "certainty", "delivered", "delivered_fraction",
              "separation_violations")
KEPT = ("coverage", "targets_found")  # quantities whose fraction of the baseline's is measured

NO_BASELINE = object()  # an axis with no undegraded value (burst)

Settings = tuple[tuple[str, Any], ...]


@dataclass(frozen=True)
class PointContext:
    """What a point of an axis may depend on besides its value: the command's options."""

    crash_at_s: float = DEFAULT_CRASH_AT_S
    burst_loss: float = DEFAULT_BURST_LOSS


@dataclass(frozen=True)
class Axis:
    """One kind of degradation and the values to try along it."""

    name: str
    title: str  # the value's axis in figures and the tables' first column
    setting: str  # the sweep setting a value is recorded under (runs.csv, folder names)
    values: tuple[Any, ...]  # default values, in order
    expects: str  # what a value must be, for error messages
    valid: Callable[[Any], bool]
    # value -> (the sweep's settings of the point, the scenario overrides that make it)
    point: Callable[[Scenario, Any, PointContext], tuple[Settings, dict[str, Any]]]
    summary: str  # one line of `swarm resilience --help`
    baseline: Any = NO_BASELINE  # the undegraded value (kept fractions are against it)
    counts_uavs: bool = False  # values are numbers of UAVs, taken from crash_candidates in order
    degrades_first_uavs: bool = False  # degrades the first FAULTED_UAVS of crash_candidates
    timed: bool = False  # happens at --crash-at
    label: Callable[[Any], str] = field(default=lambda v: f"{v:g}")
    unlimited_words: tuple[str, ...] = ()  # --values words that mean None (unlimited)
    note: Callable[[dict[str, Any]], str] = field(default=lambda results: "")  # the figure's run note
    # What its results.json holds beside the points: (results, values, context) -> entries.
    extras: Callable[[dict[str, Any], list[Any], PointContext], dict[str, Any]] = field(default=lambda results, values, ctx: {})
    draws_kept: bool = False  # also a figure of the baseline's coverage kept (<axis>_kept.png)
    loss_reference: bool = False  # its figure shows the loss axis's no-loss and same-mean-loss lines

    @property
    def has_baseline(self) -> bool:
        return self.baseline is not NO_BASELINE

    @property
    def needs_uavs(self) -> bool:
        """Acts on UAVs that fly from the start (crash_candidates)."""
        return self.counts_uavs or self.degrades_first_uavs

    def parse(self, text: str) -> Any:
        """One ``--values`` item."""
        if text.lower() in self.unlimited_words:
            return None
        try:
            return int(text) if self.counts_uavs else float(text)
        except ValueError:
            kind = "whole numbers" if self.counts_uavs else "numbers"
            raise UsageError(f"{text!r} is not a number; the {self.name} axis takes {kind}") from None

    def check(self, values: list[Any]) -> list[Any]:
        """The values, checked (one :class:`UsageError` naming the first wrong one)."""
        if not values:
            raise UsageError(f"the {self.name} axis needs at least one value")
        for v in values:
            try:
                ok = self.valid(v)
            except TypeError:
                ok = False
            if not ok:
                raise UsageError(f"{self.name} value {v!r}: expected {self.expects}")
        if len(set(values)) != len(values):
            raise UsageError(f"{self.name} values {values}: a value is repeated")
        return [int(v) for v in values] if self.counts_uavs else list(values)


# --- what the points are made of ------------------------------------------------------------------


def crash_candidates(scenario: Scenario) -> list[str]:
    """UAVs the crash axis may crash, in the order it crashes them: those that fly from the start
    (no ``join_s``, no join fault) and that the scenario does not crash itself, in scenario order."""
    joined = {f.uav for f in scenario.faults if f.kind == Join.kind}
    crashed = {f.uav for f in scenario.faults if f.kind == Crash.kind}
    return [name for name, u in zip(scenario.uav_names, scenario.uavs) if not u.join_s and name not in joined | crashed]


def battery_point(scenario: Scenario, frac: float, duration_s: float | None = None) -> dict[str, Any]:
    """(issue 26) The overrides giving each UAV type a battery of ``frac`` times the energy it
    would need to fly the whole run at full speed (default power curve, ``[endurance]``), with a
    base at the mean of the launch points; the scenario's own ``[endurance]`` scaled instead if
    it has one; ``frac = 0``: no budget."""
    from swarm.scenario.mission import EnergySpec, min_power_speed, power_w

    if not frac:
        return {"endurance": None} if scenario.endurance is not None else {}
    run_s = duration_s or scenario.duration_s
    if scenario.endurance is not None:
        e = scenario.endurance.model_dump()
        for spec in e["types"].values():
            spec["capacity_wh"] *= frac
        return {"endurance": e}
    types = {}
    for name in sorted({u.type for u in scenario.uavs}):
        t = scenario.uav_types[name]
        spec = EnergySpec(capacity_wh=1.0)
        full = power_w(spec, min_power_speed(spec, t.speed_min, t.speed_max), t.speed_max) * run_s / 3600.0
        types[name] = {"capacity_wh": frac * full}
    xs = [u.x_m for u in scenario.uavs]
    ys = [u.y_m for u in scenario.uavs]
    return {"endurance": {"x_m": sum(xs) / len(xs), "y_m": sum(ys) / len(ys), "types": types, "turnaround_s": 300.0}}


def burst_fault(mean_frames: float, mean_loss: float) -> dict[str, Any]:
    """A whole-run Gilbert-Elliott fault on every link with stationary loss ``mean_loss`` and mean
    bad-state sojourn ``mean_frames`` copies (every copy in the bad state is lost)."""
    p_exit = 1.0 / mean_frames
    p_enter = p_exit * mean_loss / (1.0 - mean_loss)
    if p_enter > 1.0:
        raise UsageError(f"burst value {mean_frames:g}: at {mean_loss:g} mean loss the mean burst length must be "
                         f">= {mean_loss / (1 - mean_loss):g} frames")
    return fault_to_dict(Burst(p_enter_bad=p_enter, p_exit_bad=p_exit, loss_good=0.0, loss_bad=1.0))


def _faults(scenario: Scenario) -> list[dict[str, Any]]:
    return list(scenario.to_dict()["faults"])


def _with_faults(scenario: Scenario, new: list[FaultKind]) -> dict[str, Any]:
    """Overrides adding ``new`` faults to the scenario's own (none: no override)."""
    return {"faults": _faults(scenario) + [fault_to_dict(f) for f in new]} if new else {}


def _first(scenario: Scenario, n: int) -> list[str]:
    return crash_candidates(scenario)[:n]


def _is_count(v: Any) -> bool:
    return v is not None and float(v).is_integer() and v >= 0


def _burst_point(sc: Scenario, v: Any, ctx: PointContext) -> tuple[Settings, dict[str, Any]]:
    settings = (("burst.mean_frames", v), ("burst.mean_loss", ctx.burst_loss))
    return settings, {"faults": _faults(sc) + [burst_fault(v, ctx.burst_loss)]}


def _crash_point(sc: Scenario, v: Any, ctx: PointContext) -> tuple[Settings, dict[str, Any]]:
    new: list[FaultKind] = [Crash(uav=n, at_s=ctx.crash_at_s) for n in _first(sc, v)]
    return (("crashed_uavs", v), ("crash_at_s", ctx.crash_at_s)), _with_faults(sc, new)


def _pause_point(sc: Scenario, v: Any, ctx: PointContext) -> tuple[Settings, dict[str, Any]]:
    new: list[FaultKind] = ([Pause(uav=n, start_s=ctx.crash_at_s, end_s=ctx.crash_at_s + v)
                             for n in _first(sc, FAULTED_UAVS)] if v else [])
    return (("pause.length_s", v), ("at_s", ctx.crash_at_s)), _with_faults(sc, new)


def _restart_point(sc: Scenario, v: Any, ctx: PointContext) -> tuple[Settings, dict[str, Any]]:
    new: list[FaultKind] = [Restart(uav=n, at_s=ctx.crash_at_s, downtime_s=RESTART_DOWNTIME_S) for n in _first(sc, v)]
    return (("restarted_uavs", v), ("at_s", ctx.crash_at_s)), _with_faults(sc, new)


def _one(setting: str, overrides: Callable[[Scenario, Any, PointContext], dict[str, Any]]
         ) -> Callable[[Scenario, Any, PointContext], tuple[Settings, dict[str, Any]]]:
    """A point recorded by its value alone under ``setting``."""
    return lambda sc, v, ctx: (((setting, v),), overrides(sc, v, ctx))


def _jammer(sc: Scenario, v: Any, ctx: PointContext) -> dict[str, Any]:
    a = sc.area
    return _with_faults(sc, [Jammer(x_m=a.width_m / 2, y_m=a.height_m / 2, radius_m=v * 1000.0)] if v else [])


def _order(results: dict[str, Any]) -> list[str]:
    order: list[str] = results.get("crash_order", [])
    return order


def _burst_extras(results: dict[str, Any], values: list[Any], ctx: PointContext) -> dict[str, Any]:
    return {"burst_mean_loss": ctx.burst_loss,
            "burst_chain": {AXES["burst"].label(v): burst_fault(v, ctx.burst_loss) for v in values}}


def loss_target(results: dict[str, Any]) -> dict[str, Any]:
    """The loss axis's check (issue 4): DACMP keeps >= 90% of its loss-free coverage at 30% i.i.d. loss."""
    point = next((p for p in results["points"] if p["value"] == TARGET_LOSS), None)
    out: dict[str, Any] = {"loss": TARGET_LOSS, "kept_at_least": TARGET_KEPT, "available": False}
    if point is None or not results["has_baseline"]:
        return out
    base = next(p for p in results["points"] if p["value"] == results["baseline"])
    for p in results["planners"]:
        k = point["planners"][p].get("kept_coverage")
        b = base["planners"][p]["coverage"]
        a = point["planners"][p]["coverage"]
        out[p] = {"kept_coverage": k, "coverage_loss_free": b, "coverage_at_loss": a,
                  "ratio_of_means": a["mean"] / b["mean"] if a and b and b["mean"] > 0 else None}
    k = out["dacmp"]["kept_coverage"]
    if k is not None:
        out["available"] = True
        out["met"] = k["mean"] >= TARGET_KEPT
        out["met_with_95_confidence"] = k["ci95"][0] >= TARGET_KEPT if k["n"] > 1 else False
    return out


def _finite_at_least(low: float) -> Callable[[Any], bool]:
    return lambda v: v is not None and math.isfinite(v) and v >= low


# Axes whose value is a field of a fault kind: what a value must be, from the field's bounds.
_SKEW_WORDS, _SKEW_VALID = field_bounds(ClockSkew, "offset_s", "a clock offset in s")
_DETECT_WORDS, _DETECT_VALID = field_bounds(Sensor, "p_detect", "a probability of detection")


AXIS_LIST: tuple[Axis, ...] = (
    Axis("loss", "i.i.d. frame loss rate (radio.loss_base)", "radio.loss_base",
         tuple(round(0.1 * i, 1) for i in range(11)),  # 1.0: no frame gets through (no radio)
         "a loss rate from 0 to 1", lambda v: v is not None and 0.0 <= v <= 1.0,
         _one("radio.loss_base", lambda sc, v, ctx: {"radio.loss_base": v}),
         "loss (i.i.d. loss 0..1)", baseline=0.0, draws_kept=True,
         extras=lambda results, values, ctx: {"target": loss_target(results)}),
    Axis("burst", "mean burst length (frame copies per link, Gilbert-Elliott)", "burst.mean_frames",
         (3.0, 10.0, 30.0, 100.0, 300.0),
         "a mean burst length >= 1 frame", _finite_at_least(1.0), _burst_point,
         "burst (Gilbert-Elliott bursts at 30%% mean loss)",
         note=lambda r: f"; mean loss {r['burst_mean_loss']:g}, bad state loses every copy", extras=_burst_extras,
         loss_reference=True),
    Axis("range", "radio range", "radio.range_km", (2.0, 5.0, 10.0, 20.0, None),  # km; None = unlimited
         "a range in km > 0, or inf for unlimited", lambda v: v is None or (v > 0 and math.isfinite(v)),
         _one("radio.range_km", lambda sc, v, ctx: {"radio.range_m": None if v is None else v * 1000.0}),
         "range (2..20 km, unlimited)", baseline=None,
         label=lambda v: "unlimited" if v is None else f"{v:g} km", unlimited_words=("inf", "unlimited", "none")),
    Axis("crash", "UAVs crashed", "crashed_uavs", tuple(range(MAX_DEFAULT_CRASHES + 1)),  # capped to the UAVs there are
         "a number of UAVs >= 0", _is_count, _crash_point, "crash (0..5 UAVs crash)", baseline=0,
         counts_uavs=True, timed=True, label=lambda v: str(int(v)),
         note=lambda r: f"; crash at {r['crash_at_s']:g} s, in order {', '.join(_order(r))}"),
    Axis("pause", f"pause length of {FAULTED_UAVS} UAVs", "pause.length_s", (0.0, 60.0, 200.0, 600.0, 1200.0),
         "a pause length in s >= 0", _finite_at_least(0.0), _pause_point, "pause (3 UAVs pause 0..1200 s)",
         baseline=0.0, degrades_first_uavs=True, timed=True, label=lambda v: f"{v:g} s",
         note=lambda r: f"; {', '.join(_order(r)[:FAULTED_UAVS])} paused from {r['crash_at_s']:g} s"),
    Axis("restart", f"UAVs restarted ({RESTART_DOWNTIME_S:g} s down, memory lost)", "restarted_uavs",
         tuple(range(MAX_DEFAULT_CRASHES + 1)), "a number of UAVs >= 0", _is_count, _restart_point,
         "restart (0..5 UAVs restart)", baseline=0, counts_uavs=True, timed=True, label=lambda v: str(int(v)),
         note=lambda r: (f"; restart at {r['crash_at_s']:g} s, {RESTART_DOWNTIME_S:g} s down, in order "
                         f"{', '.join(_order(r))}")),
    Axis("skew", f"clock ahead on {FAULTED_UAVS} UAVs", "clock_skew.offset_s", (0.0, 2.0, 10.0, 60.0, 600.0),  # s ahead
         _SKEW_WORDS, _SKEW_VALID,
         _one("clock_skew.offset_s", lambda sc, v, ctx: _with_faults(
             sc, [ClockSkew(uav=n, offset_s=v) for n in _first(sc, FAULTED_UAVS)] if v else [])),
         "skew (3 clocks 0..600 s ahead)", baseline=0.0, degrades_first_uavs=True, label=lambda v: f"{v:g} s",
         note=lambda r: f"; clocks of {', '.join(_order(r)[:FAULTED_UAVS])} ahead"),
    # per tick: a target stays inside a detection circle for tens of ticks, so only small
    # probabilities miss it altogether (0.2 a tick finds as many as 1 does on paper-fig11)
    Axis("detect", "probability of detection per tick (all UAVs)", "sensor.p_detect", (1.0, 0.1, 0.03, 0.01, 0.003),
         _DETECT_WORDS, _DETECT_VALID,
         _one("sensor.p_detect", lambda sc, v, ctx: _with_faults(sc, [Sensor(p_detect=v)] if v < 1.0 else [])),
         "detect (detection probability per tick 1..0.003)", baseline=1.0),
    Axis("jammer", "jammer radius at the centre of the area", "jammer.radius_km", (0.0, 5.0, 10.0, 15.0, 20.0, 25.0),
         "a jammer radius in km >= 0 (0: none)", _finite_at_least(0.0), _one("jammer.radius_km", _jammer),
         "jammer (radius 0..25 km at the centre)", baseline=0.0, label=lambda v: "none" if not v else f"{v:g} km"),
    Axis("liar", "lying UAVs (fake scan records)", "liars", (0, 1, 2, 3), "a number of UAVs >= 0", _is_count,
         _one("liars", lambda sc, v, ctx: _with_faults(sc, [Liar(uav=n) for n in _first(sc, v)])),
         "liar (0..3 lying UAVs)", baseline=0, counts_uavs=True, label=lambda v: str(int(v)),
         note=lambda r: f"; liars in order {', '.join(_order(r))}, one fake scan a second each"),
    # (issue 26) battery capacity as a fraction of the energy to fly the whole run at full speed;
    # 0 = no budget (the scenario as it is). Below 1 UAVs return to base, land and relaunch.
    Axis("battery", "battery capacity (fraction of the run's energy at full speed; 0: none)", "battery.capacity_frac",
         (0.0, 1.0, 0.5, 0.35, 0.25), "a capacity as a fraction of the run's energy at full speed, >= 0 (0: no budget)",
         _finite_at_least(0.0), _one("battery.capacity_frac", lambda sc, v, ctx: battery_point(sc, v)),
         "battery (capacity 1..0.25 of the run's energy)", baseline=0.0),
)

#: Axis name -> its record, in the order ``swarm resilience all`` runs them.
AXES: dict[str, Axis] = {a.name: a for a in AXIS_LIST}
#: The undegraded value of each axis that has one.
BASELINE: dict[str, Any] = {a.name: a.baseline for a in AXIS_LIST if a.has_baseline}


def axis_named(name: str) -> Axis:
    try:
        return AXES[name]
    except KeyError:
        raise UsageError(f"unknown axis {name!r}; expected one of {', '.join(AXES)}") from None
