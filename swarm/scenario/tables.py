"""The hand-written tables of a scenario: the world (``[area]``, ``[map]``, ``[uav_types.NAME]``
with Table 1's types, ``[[uavs]]``, ``[[fleet]]``, ``[targets]``, ``[[threats]]``), ``[planner]``
(with ``[planner.greedy]``), ``[safety]``, ``[metrics]`` and ``[recording]``.

Defaults are the paper's where it gives a number (Table 1, section 4.1) and otherwise the
settled defaults of ``DACMP-SPEC.md``. The tables generated from the simulator's dataclasses
(``[radio]``, ``[[faults]]``, ``[planner.dacmp]``, ``[planner.apf]``) are in
:mod:`swarm.scenario.generated`; the checks across tables are :class:`~swarm.scenario.model.Scenario`'s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

from pydantic import Field, ValidationInfo, model_validator

from agents.types import DAA_RANGE_M, UavType
from swarm.scenario.fields import Bool, Int, Num, Problem, Str, Table, fmt, int_field, num_field, raise_if, table_field
from swarm.scenario.generated import ApfSettings, DacmpSettings

__all__ = [
    "DEFAULT_UAV_TYPES",
    "RECORDING_LEVELS",
    "Area",
    "FleetSpec",
    "GreedySettings",
    "MapSettings",
    "MetricsSettings",
    "PlacedTarget",
    "PlannerSettings",
    "RecordingSettings",
    "SafetySettings",
    "TargetSettings",
    "ThreatSpec",
    "UavSpec",
    "UavTypeSpec",
]


# --- the world -----------------------------------------------------------------------------
class Area(Table):
    """The mission area, origin at a corner, x east, y north (paper: 50 km x 50 km, 100 m cells)."""

    width_m: Num = num_field(50_000.0, gt=0)
    height_m: Num = num_field(50_000.0, gt=0)
    cell_m: Num = num_field(100.0, gt=0)

    @model_validator(mode="after")
    def _whole_cells(self) -> Area:
        # The grid must tile the area exactly, otherwise the last row/column of cells would be
        # partly outside it and coverage fractions would be ambiguous.
        raise_if([
            Problem((key,), value, f"a whole multiple of cell_m ({fmt(self.cell_m)})")
            for key, value in (("width_m", self.width_m), ("height_m", self.height_m))
            if not _is_whole_multiple(value, self.cell_m)
        ])
        return self

    @property
    def cols(self) -> int:
        return round(self.width_m / self.cell_m)

    @property
    def rows(self) -> int:
        return round(self.height_m / self.cell_m)

    def contains(self, x_m: float, y_m: float) -> bool:
        return 0.0 <= x_m <= self.width_m and 0.0 <= y_m <= self.height_m


def _is_whole_multiple(value: float, step: float) -> bool:
    ratio = value / step
    if not math.isfinite(ratio):
        return False
    return abs(ratio - round(ratio)) <= 1e-9 * max(1.0, ratio)


class MapSettings(Table):
    """Uncertainty map and pyramid. ``levels`` is the paper's L: pyramid layers G_1..G_L above the
    map G_0 (paper: seven, the seventh being 4 x 4 regions on a 500 x 500 map). ``tau`` is not in
    the paper; see :attr:`Scenario.effective_tau` for the spec's default."""

    levels: Int = int_field(7, ge=1, le=12, note="layers above the map itself")
    prior_target_speed: Num = num_field(10.0, gt=0, note="m/s")
    tau: Num | None = num_field(None, gt=0, note="1/s", optional=True)


class UavTypeSpec(Table):
    """One UAV type (a row of Table 1). Types are data: a new type needs no code."""

    speed_min: Num = num_field(..., gt=0, note="m/s")
    speed_max: Num = num_field(..., gt=0, note="m/s, >= speed_min")
    accel_max: Num = num_field(..., gt=0, note="m/s^2")
    bank_max_deg: Num = num_field(..., gt=0, lt=90)
    detect_radius_m: Num = num_field(..., gt=0)
    w_t: Num = num_field(..., ge=0, note="target attraction weight")
    w_r: Num = num_field(..., ge=0, note="repulsion weight")
    influence_radius_m: Num = num_field(..., gt=0, note="target influence radius D")
    # Not in the paper. Other UAVs within this range are sensed (true position and velocity) for
    # collision avoidance instead of taken from the radio. Default 3000 m: collision avoidance
    # looks planner.apf.lookahead_s = 15 s ahead and Table 1's fastest closing speed is two type B
    # head-on, 180 m/s: 15 x 180 = 2700 m, plus a margin. 0 turns the sensor off (the radio only).
    daa_range_m: Num = num_field(DAA_RANGE_M, ge=0, note="m, detect-and-avoid sensor range; 0 = no sensor")

    def uav_type(self, name: str) -> UavType:
        """This table as the agents' :class:`~agents.types.UavType` named ``name``."""
        return UavType(name=name, speed_min=self.speed_min, speed_max=self.speed_max, accel_max=self.accel_max,
                       bank_max_rad=math.radians(self.bank_max_deg), detect_radius=self.detect_radius_m,
                       w_t=self.w_t, w_r=self.w_r, influence_radius=self.influence_radius_m,
                       daa_range=self.daa_range_m)

    @model_validator(mode="after")
    def _speed_range(self) -> UavTypeSpec:
        if self.speed_min > self.speed_max:
            raise_if([Problem(("speed_min",), self.speed_min, f"a number <= speed_max ({fmt(self.speed_max)})")])
        return self


# Table 1 of the paper.
DEFAULT_UAV_TYPES: dict[str, UavTypeSpec] = {
    "A": UavTypeSpec(speed_min=30.0, speed_max=50.0, accel_max=0.4, bank_max_deg=30.0,
                     detect_radius_m=1500.0, w_t=5.0, w_r=5.1, influence_radius_m=10_000.0),
    "B": UavTypeSpec(speed_min=60.0, speed_max=90.0, accel_max=0.6, bank_max_deg=20.0,
                     detect_radius_m=2000.0, w_t=2.0, w_r=2.1, influence_radius_m=4000.0),
}


class UavSpec(Table):
    """One UAV at the start (or at ``join_s`` for a late joiner)."""

    # None is replaced after validation by f"{type}{k}", k counting from 1 within the type.
    name: Str | None = Field(default=None, description="a string (unique UAV name), or leave it out")
    type: Str = Field(..., description="a UAV type name defined in [uav_types]")
    x_m: Num = num_field(..., note="metres east of the area's corner, inside the area")
    y_m: Num = num_field(..., note="metres north of the area's corner, inside the area")
    heading_deg: Num = num_field(0.0, note="degrees, 0 = east, counter-clockwise")
    # None = the type's speed_max; the range is checked against the type by Scenario.
    speed: Num | None = num_field(None, gt=0, note="m/s within the type's speed range", optional=True)
    join_s: Num | None = num_field(None, ge=0, note="time the UAV enters the world", optional=True)


class FleetSpec(Table):
    """Many UAVs of one type at once, laid out deterministically (large swarms, benchmarks).

    Expanded into ``uavs`` when the scenario loads (after the ``[[uavs]]`` entries, named like
    unnamed UAVs: type + number within the type); the loaded scenario lists every UAV, so
    ``scenario.json`` and ``--set uavs[N]...`` see them like any other.
    """

    type: Str = Field(..., description="a UAV type name defined in [uav_types]")
    count: Int = int_field(..., ge=1, le=100_000)
    # grid: a near-square lattice over the region, row by row from the south-west corner, each
    # UAV at the centre of its lattice cell; random: uniform in the region.
    layout: Literal["grid", "random"] = Field(default="grid", description="one of: grid, random")
    region: list[Num] | None = Field(
        default=None,
        description="[x0_m, y0_m, x1_m, y1_m] inside the area with x0 < x1 and y0 < y1, or leave it out (the whole area)",
    )
    # None: each UAV gets a random heading from the layout stream.
    heading_deg: Num | None = num_field(None, note="degrees, 0 = east; absent = random per UAV", optional=True)
    speed: Num | None = num_field(None, gt=0, note="m/s within the type's speed range", optional=True)
    join_s: Num | None = num_field(None, ge=0, note="time the UAVs enter the world", optional=True)
    # The layout's own random stream (positions, headings): independent of the run's seed, so
    # every seed flies the same fleet.
    layout_seed: Int = int_field(0, ge=0)

    def expand(self, index: int, area: Area, site: Any = None, taken: Sequence[tuple[float, float]] = ()) -> list[UavSpec]:
        """The fleet's UAVs. ``site`` (a :class:`swarm.scenario.placement.Site`): a ``grid``
        lattice keeps to the area polygon; a ``random`` layout to the free space, clear of
        ``taken`` (the UAVs entering with it) and of each other by the separation minimum.
        Raises ValueError when the region leaves no room for them."""
        import numpy as np

        from swarm.scenario.placement import grid_slots, random_slots

        x0, y0, x1, y1 = self.region if self.region is not None else (0.0, 0.0, area.width_m, area.height_m)
        n = self.count
        rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy=self.layout_seed, spawn_key=(index,))))
        headings: list[float] | None = None
        if self.layout == "grid":
            xs, ys = grid_slots(n, (x0, y0, x1, y1), site)
        else:
            xs, ys, headings = random_slots(n, (x0, y0, x1, y1), site, rng, taken, self.heading_deg is None)
        if headings is None:
            headings = rng.uniform(0.0, 360.0, n).tolist() if self.heading_deg is None else [self.heading_deg] * n
        return [
            UavSpec(type=self.type, x_m=min(max(x, 0.0), area.width_m), y_m=min(max(y, 0.0), area.height_m),
                    heading_deg=hd, speed=self.speed, join_s=self.join_s)
            for x, y, hd in zip(xs, ys, headings)
        ]


class PlacedTarget(Table):
    x_m: Num = num_field(..., note="inside the area")
    y_m: Num = num_field(..., note="inside the area")
    heading_deg: Num = num_field(0.0, note="degrees, 0 = east, counter-clockwise")
    speed: Num = num_field(0.0, ge=0, note="m/s, <= targets.speed_max")
    value: Num = num_field(1.0, gt=0)


class TargetSettings(Table):
    """Target motion model (Table 1: 0-20 m/s, +-0.4 m/s^2) and where targets start."""

    count: Int = int_field(0, ge=0, note="targets drawn uniformly in the area from the seed")
    speed_max: Num = num_field(20.0, ge=0, note="m/s")
    accel_max: Num = num_field(0.4, gt=0, note="m/s^2")
    accel_sigma: Num = num_field(0.05, ge=0, note="m/s^2 per sqrt(s)")
    turn_sigma: Num = num_field(0.002, ge=0, note="rad/s per sqrt(s)")
    turn_rate_max: Num = num_field(0.1, gt=0, note="rad/s")
    # Our choice (the paper gives none): the turn rate relaxes to 0 with this time constant, so
    # targets wander over kilometres like the paper's dashed tracks instead of circling in place.
    turn_reversion_s: Num = num_field(30.0, gt=0, note="s")
    value: Num = num_field(1.0, gt=0)
    placed: list[PlacedTarget] = Field(default_factory=list, description="an array of tables [[targets.placed]]")

    @model_validator(mode="after")
    def _placed_speeds(self) -> TargetSettings:
        raise_if([
            Problem(("placed", i, "speed"), t.speed, f"a number in [0, {fmt(self.speed_max)}] (targets.speed_max)")
            for i, t in enumerate(self.placed)
            if t.speed > self.speed_max
        ])
        return self


class ThreatSpec(Table):
    """A circular no-fly zone of radius R_T with a repulsion field out to ``d_max``."""

    x_m: Num = num_field(..., note="inside the area")
    y_m: Num = num_field(..., note="inside the area")
    radius_m: Num = num_field(..., gt=0)
    influence_m: Num | None = num_field(None, gt=0, note="> radius_m, from the centre", optional=True)

    @model_validator(mode="after")
    def _influence_beyond_radius(self) -> ThreatSpec:
        if self.influence_m is not None and self.influence_m <= self.radius_m:
            raise_if([Problem(("influence_m",), self.influence_m, f"a number > radius_m ({fmt(self.radius_m)})")])
        return self

    @property
    def d_max(self) -> float:
        """Repulsion influence radius from the centre (our default: 3 km beyond the edge)."""
        return self.influence_m if self.influence_m is not None else self.radius_m + 3000.0


# --- planner, safety, metrics, recording ------------------------------------------------------
class GreedySettings(Table):
    headings: Int = int_field(15, ge=3, note="candidate headings per decision")


_PLANNER_WORDS = ("a planner: a built-in name (see `swarm list --planners`), package.module:Class, "
                  "or a name registered under the entry-point group swarm.planners")


_ONE_PLANNER = "options for one planner of several (a sweep): planner.options_for.NAME.KEY"


class PlannerSettings(Table):
    # Resolved by agents.planners.registry; a user's class must be importable where the run runs.
    name: Str = Field(default="dacmp", description=_PLANNER_WORDS)
    # Keyword arguments of the planner's constructor (or of its from_context); the built-in
    # planners take theirs from their own tables ([planner.dacmp], [planner.greedy]).
    options: dict[Str, Any] = Field(default_factory=dict, description="a table [planner.options] of the planner's options")
    # Options per planner, by planner name as written ([planner.options_for.levy], or
    # [planner.options_for."pkg.mod:Class"]): the planner that runs is built with `options` and
    # its own entry here over them (options_of); the others wait for a run that picks their
    # planner (a sweep over planners, --planner). When the planner is replaced (--planner,
    # Simulation(planner=...), a sweep: loading.switch_planner), `options` move here under the
    # planner they were written for.
    options_for: dict[Str, dict[Str, Any]] = Field(
        default_factory=dict, description="tables [planner.options_for.NAME] of options, one per planner name")
    replan_s: Num = num_field(10.0, gt=0)
    # False: a sighting ends interest in a target (search only, as in paper-fig11).
    surveillance: Bool = Field(default=True, description="true or false")
    # Our choice (the paper does not say how a watcher flies): it circles its target at radius
    # max(loiter_radius_factor * R_s, loiter_turn_factor * turn radius at minimum speed),
    # following a vector field with approach gain loiter_gain.
    loiter_radius_factor: Num = num_field(0.5, gt=0, note="times the detection radius")
    loiter_turn_factor: Num = num_field(1.25, ge=1, note="times the turn radius at minimum speed")
    loiter_gain: Num = num_field(1.0, gt=0)
    # Our choice: a watcher's threat repulsion (eq. 30) is planner.apf.k_rep times this, so it
    # can follow its target to about 0.75 km of a no-fly zone's edge instead of about 1.7 km (the
    # guard still turns it away inside one turn radius + 300 m).
    loiter_threat_weight: Num = num_field(0.15, gt=0, le=1, note="times planner.apf.k_rep")
    greedy: GreedySettings = table_field(GreedySettings, "planner.greedy")
    dacmp: DacmpSettings = table_field(DacmpSettings, "planner.dacmp")
    apf: ApfSettings = table_field(ApfSettings, "planner.apf")

    def options_of(self, name: str | None = None) -> dict[str, Any]:
        """The options planner ``name`` (default: the one that runs) is built with: ``options``
        (when it is the planner that runs) with ``options_for[name]`` over them."""
        name = self.name if name is None else name
        own = self.options if name == self.name else {}
        return {**own, **self.options_for.get(name, {})}

    @model_validator(mode="after")
    def _known_planner(self, info: ValidationInfo) -> PlannerSettings:
        # Nothing a scenario names is imported unless the user allowed it (swarm.scenario.trust);
        # what is imported is checked to be a planner class, and the options against its
        # signature, before anything in it is called (agents.planners.registry).
        from agents.planners.base import PlannerError
        from agents.planners.registry import option_problems, surveillance_problem
        from swarm.scenario.trust import permits, refusal

        allow = info.context.get("allow_planners") if info.context else None
        if not permits(allow, self.name):
            found, expected, hint = refusal(self.name)
            raise_if([Problem(("name",), self.name, expected, hint=hint, found=found)])
        try:
            problems = option_problems(self.name, self.options_of())
            refused = surveillance_problem(self.name) if self.surveillance else None
        except PlannerError as exc:
            raise_if([Problem(("name",), self.name, _PLANNER_WORDS, hint=str(exc))])
        own = self.options_for.get(self.name, {})
        found_problems = []
        for key, found, expected in problems:
            in_own = key in own
            # An unknown option, not a typo of a known one: perhaps meant for another planner of a sweep.
            hint = _ONE_PLANNER if found.startswith("unknown") and not in_own and "did you mean" not in expected else ""
            found_problems.append(Problem(("options_for", self.name, key) if in_own else ("options", key), None,
                                           expected, found=found, hint=hint))
        for other, options in self.options_for.items():
            if other == self.name or not permits(allow, other):
                continue  # a module:Class nobody allowed is not imported: checked if it is ever run
            try:
                other_problems = option_problems(other, options)
            except PlannerError as exc:
                found_problems.append(Problem(("options_for", other), None, _PLANNER_WORDS, hint=str(exc),
                                               found=f"options for {other!r}, which is not a planner"))
                continue
            found_problems += [Problem(("options_for", other, key), None, expected, found=found)
                               for key, found, expected in other_problems]
        raise_if(found_problems)
        # A planner that declares it only searches (surveils = False) cannot run with surveillance.
        raise_if([Problem(("surveillance",), True, f"false: {refused}")] if refused else [])
        return self


class SafetySettings(Table):
    min_separation_m: Num = num_field(200.0, gt=0)


class MetricsSettings(Table):
    sample_s: Num = num_field(10.0, gt=0, note=">= dt_s")


RECORDING_LEVELS = ("frames", "summary")


class RecordingSettings(Table):
    """What the event log keeps (swarm.kernel.recorder; the README lists each level's events).

    ``"frames"``: every frame copy read (``rx``) or lost (``lost``), one event each, so the log
    grows with radio density (a UAV hearing 250 neighbours logs 250 ``rx`` a second).
    ``"summary"``: instead, one ``radio`` event per tick with the tick's totals (frames read and
    rejected, bytes read, copies and bytes lost per cause): bounded per tick, still deterministic and
    hashed like every event. Every other event is the same at both levels. The ``radio`` invariant
    needs ``"frames"`` (it judges each delivery); on a summary log it says it cannot check."""

    level: Literal["frames", "summary"] = Field(default="frames", description=f"one of: {', '.join(RECORDING_LEVELS)}")
