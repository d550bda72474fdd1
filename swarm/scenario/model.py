"""The scenario model: the data that describes one run, its checks across tables, and how a
document becomes one.

A scenario is a TOML document (a built-in one from ``swarm/scenario/builtin/`` or a user's file:
:mod:`swarm.scenario.loading`) or a dict. :func:`parse_scenario` validates it into the frozen
pydantic :class:`Scenario`, whose tables are :mod:`swarm.scenario.tables` (hand-written) and
:mod:`swarm.scenario.generated` (generated from the simulator's dataclasses); anything wrong
becomes one :class:`~swarm.errors.ScenarioError` that names the file, the dotted key path, what
was found and what was expected (:mod:`swarm.scenario.translation`). No other exception escapes:
the CLI prints ``str(err)`` and nothing else, so the message must stand on its own.
:func:`apply_overrides` (``--set``, :meth:`Scenario.with_overrides`) edits a scenario's document
(:mod:`swarm.scenario.overrides`) and validates it again as a whole.

This module adds what needs more than one table: names, types and positions of the UAVs, fault
references and joins, the level weights against the map's levels, and whether a run can run.
"""

from __future__ import annotations

import difflib
import math
import typing
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from pydantic import Field, ValidationError, ValidationInfo, field_validator, model_validator
from pydantic.fields import FieldInfo

from faults import schedule as _faults
from swarm.errors import ScenarioError, UsageError
from swarm.scenario.fields import Int, Num, Problem, Str, Table, fmt, int_field, num_field, raise_if, table_field
from swarm.scenario.generated import (
    FAULT_KINDS,
    FAULT_TABLES,
    Fault,
    JoinFault,
    RadioSettings,
    fault_union,
    sync_fault_tables,
)
from swarm.scenario.geo import GeoSettings, NoFlySpec, geo_problems, resolve_geography
from swarm.scenario.mission import EnduranceSettings, WindSettings, endurance_problems
from swarm.scenario.overrides import PLANNER_NAME_KEY, set_keys
from swarm.scenario.placement import Site, placement_problems
from swarm.scenario.positions import found_words
from swarm.scenario.tables import (
    DEFAULT_UAV_TYPES,
    Area,
    FleetSpec,
    MapSettings,
    MetricsSettings,
    PlannerSettings,
    RecordingSettings,
    SafetySettings,
    TargetSettings,
    ThreatSpec,
    UavSpec,
    UavTypeSpec,
)
from swarm.scenario.translation import first_error
from swarm.scenario.trust import allowed, permits, refusal

__all__ = ["MAX_TICKS", "Scenario", "apply_overrides", "parse_scenario"]

# A run has at most this many ticks (duration_s / dt_s): ten million (116 days at dt 1 s).
MAX_TICKS = 10_000_000
_FLOAT32_TINY = 1.1754944e-38  # the smallest normal float32
_FLOAT32_MAX = 3.4028235e38


class Scenario(Table):
    """Everything one run needs. Build it with :func:`~swarm.scenario.loading.load_scenario` or
    :func:`parse_scenario`."""

    name: Str = Field(default="scenario", description="a string")
    description: Str = Field(default="", description="a string")
    seed: Int = int_field(0, ge=0)
    duration_s: Num = num_field(2000.0, gt=0)
    dt_s: Num = num_field(1.0, gt=0, le=10)
    area: Area = table_field(Area, "area")
    map: MapSettings = table_field(MapSettings, "map")
    uav_types: dict[Str, UavTypeSpec] = Field(
        default_factory=lambda: dict(DEFAULT_UAV_TYPES), description="a table of UAV types [uav_types.NAME]"
    )
    uavs: list[UavSpec] = Field(..., description="an array of tables [[uavs]] with at least one UAV (here or in [[fleet]])")
    # Expanded into uavs by the validator, which then empties this list (see FleetSpec).
    fleet: list[FleetSpec] = Field(default_factory=list, description="an array of tables [[fleet]]")
    targets: TargetSettings = table_field(TargetSettings, "targets")
    threats: list[ThreatSpec] = Field(default_factory=list, description="an array of tables [[threats]]")
    radio: RadioSettings = table_field(RadioSettings, "radio")
    faults: list[Fault] = Field(
        default_factory=list, description=f"an array of tables [[faults]], each with kind = one of: {', '.join(FAULT_KINDS)}"
    )
    planner: PlannerSettings = table_field(PlannerSettings, "planner")
    safety: SafetySettings = table_field(SafetySettings, "safety")
    metrics: MetricsSettings = table_field(MetricsSettings, "metrics")
    recording: RecordingSettings = table_field(RecordingSettings, "recording")
    # Geographic scenarios (issue 26, swarm.scenario.geo): the area as a lon/lat polygon, and
    # polygon no-fly zones. Absent (the default), nothing geographic runs or is imported.
    geo: GeoSettings | None = Field(default=None, description="a table [geo]: the area as a polygon in a CRS")
    no_fly: list[NoFlySpec] = Field(default_factory=list, description="an array of tables [[no_fly]] (polygon no-fly zones)")
    # Wind and endurance (issue 26, swarm.scenario.mission, swarm.kernel.mission): absent, nothing runs.
    wind: WindSettings | None = Field(default=None, description="a table [wind]")
    endurance: EnduranceSettings | None = Field(default=None, description="a table [endurance]")

    @model_validator(mode="before")
    @classmethod
    def _fleet_only(cls, data: Any, info: ValidationInfo) -> Any:
        # (issue 26) [geo]: the GeoJSON file read, the area's size from its polygon, lon/lat
        # positions in metres; a document without [geo] comes back as it was.
        data = resolve_geography(data, info.context)
        # A document with [[fleet]] needs no [[uavs]]; without either, "uavs" is missing.
        if isinstance(data, dict) and data.get("fleet") and "uavs" not in data:
            data = {**data, "uavs": []}
        _endurance_types_known(data)
        return data

    @field_validator("uav_types", mode="before")
    @classmethod
    def _over_table1(cls, value: Any) -> Any:
        # Merge by name over Table 1: giving only [uav_types.C] keeps A and B; giving
        # [uav_types.A] replaces A as a whole.
        if isinstance(value, dict):
            return {**DEFAULT_UAV_TYPES, **value}
        return value

    @model_validator(mode="after")
    def _complete_and_cross_check(self, info: ValidationInfo) -> Scenario:
        # Filling in names and folding joins replaces items of lists this model has just built
        # (pydantic copies input lists), so the frozen model's attributes are never reassigned.
        origins: list[tuple[str, int]] = [("uavs", i) for i in range(len(self.uavs))]
        if self.fleet:
            raise_if(self._fleet_problems())
            site = Site.of(self)
            for i, fleet in enumerate(self.fleet):
                taken = [(u.x_m, u.y_m) for u in self.uavs if u.join_s == fleet.join_s]
                try:
                    expanded = fleet.expand(i, self.area, site, taken)
                except ValueError as exc:
                    raise_if([Problem(("fleet", i, "region"), fleet.region, "a region with room for the fleet inside the "
                                      "area (its polygon), outside the no-fly zones", found=f"{exc}")])
                self.uavs.extend(expanded)
                origins += [("fleet", i)] * len(expanded)
            self.fleet.clear()  # consumed: the scenario now lists every UAV in uavs
        if not self.uavs:
            raise_if([Problem(("uavs",), self.uavs,
                                "an array of tables [[uavs]] with at least one UAV (here or in [[fleet]])")])
        per_type: dict[str, int] = {}
        for i, uav in enumerate(self.uavs):
            per_type[uav.type] = per_type.get(uav.type, 0) + 1
            if uav.name is None:
                self.uavs[i] = uav.model_copy(update={"name": f"{uav.type}{per_type[uav.type]}"})

        # A run shortened by Simulation(duration_s=...) / --duration may end before a late joiner
        # joins; a scenario that says so itself is a mistake (judged against the scenario's own
        # duration, "scenario_duration_s", when the caller knows it).
        context = info.context or {}
        truncated = bool(context.get("truncated"))
        join_end = context.get("scenario_duration_s") if truncated else self.duration_s
        problems = self._cross_problems(join_end, origins)
        raise_if(problems)

        for fault in self.faults:
            if isinstance(fault, JoinFault):
                i = self.uav_names.index(fault.uav)
                self.uavs[i] = self.uavs[i].model_copy(update={"join_s": fault.at_s})
        return self

    def _fleet_problems(self) -> list[Problem]:
        problems: list[Problem] = []
        area = self.area
        types_list = ", ".join(self.uav_types)
        for i, fleet in enumerate(self.fleet):
            spec = self.uav_types.get(fleet.type)
            if spec is None:
                problems.append(Problem(("fleet", i, "type"), fleet.type, f"a UAV type defined in [uav_types]: {types_list}",
                                        _did_you_mean(fleet.type, self.uav_types)))
            elif fleet.speed is not None and not spec.speed_min <= fleet.speed <= spec.speed_max:
                problems.append(Problem(("fleet", i, "speed"), fleet.speed,
                                         f"a number in [{fmt(spec.speed_min)}, {fmt(spec.speed_max)}] "
                                         f"(type {fleet.type}'s speed range)"))
            r = fleet.region
            if r is not None and not (len(r) == 4 and 0.0 <= r[0] < r[2] <= area.width_m and 0.0 <= r[1] < r[3] <= area.height_m):
                problems.append(Problem(("fleet", i, "region"), r,
                                         f"[x0_m, y0_m, x1_m, y1_m] with 0 <= x0 < x1 <= {fmt(area.width_m)} "
                                         f"and 0 <= y0 < y1 <= {fmt(area.height_m)} (inside the area)"))
        return problems

    def _cross_problems(self, join_end: float | None, origins: list[tuple[str, int]]) -> list[Problem]:
        """Checks that need more than one table: names, types, positions, fault references."""
        problems: list[Problem] = []
        area = self.area
        inside = {
            "x_m": f"a number in [0, {fmt(area.width_m)}] (inside the area)",
            "y_m": f"a number in [0, {fmt(area.height_m)}] (inside the area)",
        }

        def check_inside(path: tuple[str | int, ...], obj: Any) -> None:
            out = [(key, getattr(obj, key)) for key, limit in (("x_m", area.width_m), ("y_m", area.height_m))
                   if not 0.0 <= getattr(obj, key) <= limit]
            if len(out) == 2:  # one mistake (a point far off, lon/lat mixed up), one line
                problems.append(Problem((*path, "x_m"), obj.x_m, f"a point inside the area ({fmt(area.width_m)} x "
                                        f"{fmt(area.height_m)} m)", found=f"({obj.x_m:g}, {obj.y_m:g}) m"))
            elif out:
                problems.append(Problem((*path, out[0][0]), out[0][1], inside[out[0][0]]))

        types_list = ", ".join(self.uav_types)
        first_with_name: dict[str, int] = {}
        for i, uav in enumerate(self.uavs):
            spec = self.uav_types.get(uav.type)
            if spec is None:
                problems.append(Problem(("uavs", i, "type"), uav.type, f"a UAV type defined in [uav_types]: {types_list}",
                                        _did_you_mean(uav.type, self.uav_types)))
            name = typing.cast(str, uav.name)  # filled in (_complete_and_cross_check) before these checks
            if name in first_with_name:
                problems.append(Problem(("uavs", i, "name"), name,
                                         f"a name not already used by uavs[{first_with_name[name]}] (UAV names are unique)",
                                         "a UAV without a name is called TYPE + its number within the type, e.g. B1"))
            first_with_name.setdefault(name, i)
            check_inside(("uavs", i), uav)
            if spec is not None and uav.speed is not None and not spec.speed_min <= uav.speed <= spec.speed_max:
                problems.append(Problem(("uavs", i, "speed"), uav.speed,
                                         f"a number in [{fmt(spec.speed_min)}, {fmt(spec.speed_max)}] "
                                         f"(type {uav.type}'s speed range)"))

        for i, target in enumerate(self.targets.placed):
            check_inside(("targets", "placed", i), target)
        for i, threat in enumerate(self.threats):
            check_inside(("threats", i), threat)

        names = set(first_with_name)
        valid_names = f"a UAV name defined in [[uavs]]: {', '.join(first_with_name)}"

        # A UAV whose type is unknown may carry a name that type-based naming gave it (Bb1 for a
        # mistyped B1): the fault references that follow from it are not judged (one mistake, one line).
        mistyped = any(u.type not in self.uav_types for u in self.uavs)

        def check_name(path: tuple[str | int, ...], name: str) -> None:
            if name not in names and not mistyped:
                close = difflib.get_close_matches(name, list(first_with_name), n=1)
                problems.append(Problem(path, name, valid_names, f"did you mean {close[0]!r}?" if close else ""))

        joined_at: dict[str, int] = {}
        for f, fault in enumerate(self.faults):
            for path, name in _faults.uav_names(fault):
                check_name(("faults", f, *path), name)
            if isinstance(fault, JoinFault) and fault.uav in names:
                uav = self._uav_by_name(fault.uav)
                if fault.uav in joined_at:
                    problems.append(Problem(("faults", f, "uav"), fault.uav,
                                             f"a UAV not already joined by faults[{joined_at[fault.uav]}]"))
                # join_s equal to at_s is the folded form this validator itself produces, so a
                # dumped scenario loads again.
                elif uav.join_s is not None and uav.join_s != fault.at_s:
                    problems.append(Problem(("faults", f, "uav"), fault.uav,
                                             "a UAV without its own join_s (give the join time in one place)",
                                             found=f"{fault.uav!r} (string), which already has join_s = {fmt(uav.join_s)}"))
                joined_at.setdefault(fault.uav, f)

        weights = self.planner.dacmp.level_weights
        if weights is not None and len(weights) != self.map.levels:
            problems.append(Problem(("planner", "dacmp", "level_weights"), weights,
                                     f"an array of {self.map.levels} numbers "
                                     f"(one per pyramid layer 1..L, map.levels = {self.map.levels})"))
        if self.metrics.sample_s < self.dt_s:
            problems.append(Problem(("metrics", "sample_s"), self.metrics.sample_s, f"a number >= dt_s ({fmt(self.dt_s)})"))
        problems += self._runnable_problems(join_end)
        if self.geo is not None or self.no_fly:  # (issue 26: polygons simple)
            problems += geo_problems(self)
        if not any(p.path[:1] == ("uavs",) and p.path[-1:] == ("type",) for p in problems):
            # (issues 32, 33) inside the area polygon, outside no-fly zones, apart at the start
            joins = {f.uav: f.at_s for f in self.faults if isinstance(f, JoinFault)}
            starts = [joins.get(str(u.name), u.join_s or 0.0) for u in self.uavs]
            problems += placement_problems(self, origins, starts)
        if self.endurance is not None:  # (issue 26: types, the base, budgets that reach the area)
            problems += endurance_problems(self)
        return problems

    def _runnable_problems(self, join_end: float | None) -> list[Problem]:
        """Values that validate one by one but cannot run: a run that would never finish, a
        memory factor float32 cannot hold, a UAV that would join at or after ``join_end`` (the
        scenario's end; None: not judged)."""
        problems: list[Problem] = []
        ticks = self.duration_s / self.dt_s
        if ticks > MAX_TICKS:
            problems.append(Problem(("dt_s",), self.dt_s, f"a number >= duration_s / {MAX_TICKS:,} "
                                     f"({fmt(self.duration_s / MAX_TICKS)}: a run has at most {MAX_TICKS:,} ticks)"))
        # Map times and q are float32: tau must be a normal float32 and tau * duration finite.
        if self.uavs and all(u.type in self.uav_types for u in self.uavs):
            tau = self.effective_tau
            key: tuple[str, ...] = ("map", "tau") if self.map.tau is not None else ("map", "prior_target_speed")
            value = self.map.tau if self.map.tau is not None else self.map.prior_target_speed
            if not (_FLOAT32_TINY <= tau and tau * max(self.duration_s, 1.0) <= _FLOAT32_MAX):
                problems.append(Problem(key, value, f"a value giving a map memory factor tau in [{_FLOAT32_TINY:.3g}, "
                                         f"{_FLOAT32_MAX / max(self.duration_s, 1.0):.3g}] 1/s (float32 map times; "
                                         f"this gives {tau:.3g})"))
        for i, uav in enumerate(self.uavs):
            if join_end is not None and uav.join_s is not None and uav.join_s >= join_end:
                problems.append(Problem(("uavs", i, "join_s"), uav.join_s,
                                         f"a number < duration_s ({fmt(join_end)}: it would join after the end)"))
        for f, fault in enumerate(self.faults):
            if join_end is not None and isinstance(fault, JoinFault) and fault.at_s >= join_end:
                problems.append(Problem(("faults", f, "at_s"), fault.at_s,
                                         f"a number < duration_s ({fmt(join_end)}: the UAV would join after the end)"))
        return problems

    def _uav_by_name(self, name: str) -> UavSpec:
        return next(u for u in self.uavs if u.name == name)

    # --- helpers for the rest of the simulator ---
    def uav_type(self, name: str) -> UavTypeSpec:
        try:
            return self.uav_types[name]
        except KeyError:
            raise UsageError(f"no UAV type {name!r} in this scenario; defined types: {', '.join(self.uav_types)}") from None

    @property
    def uav_names(self) -> list[str]:
        return [u.name for u in self.uavs]  # type: ignore[misc]  # always filled after validation

    @property
    def effective_tau(self) -> float:
        """Memory factor of the uncertainty map: map.tau, or (spec default) the prior target speed
        over the largest detection radius among the types actually flown."""
        if self.map.tau is not None:
            return self.map.tau
        radius = max(self.uav_types[u.type].detect_radius_m for u in self.uavs)
        return self.map.prior_target_speed / radius

    def to_dict(self) -> dict[str, Any]:
        """A JSON-safe dict (infinities become None, which also means 'unlimited' on input)."""
        return _finite_or_none(self.model_dump(mode="json"))

    def with_overrides(self, **changes: Any) -> Scenario:
        """A new validated scenario with top-level fields (or dotted keys) replaced (:func:`apply_overrides`)."""
        return apply_overrides(self, changes)

    def to_document(self) -> dict[str, Any]:
        """This scenario as an input document that validates to itself (what overrides edit):
        joins are unfolded again so the join fault stays the one place that says when."""
        doc = self.model_dump(mode="python")
        if doc.get("geo") is not None:  # (issue 26: the size comes from the polygon again)
            doc["area"].pop("width_m", None)
            doc["area"].pop("height_m", None)
        joins = {f["uav"] for f in doc["faults"] if f["kind"] == "join"}
        for uav in doc["uavs"]:
            if uav["name"] in joins:
                uav["join_s"] = None
        return doc


def _did_you_mean(word: str, known: Iterable[str]) -> str:
    """``did you mean 'B'?`` for a name close to a known one (as for an unknown key), else ""."""
    known = list(known)
    close = difflib.get_close_matches(word, known, n=1) or [k for k in known if k.lower() == word.lower()][:1]
    return f"did you mean {close[0]!r}?" if close else ""


def _finite_or_none(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(v) for v in value]
    return value


def _endurance_types_known(data: Any) -> None:
    """An ``[endurance.types.NAME]`` whose NAME is no UAV type is said as that, before what its
    table may lack (the table of a type that does not exist is not judged)."""
    endurance = data.get("endurance") if isinstance(data, dict) else None
    types = endurance.get("types") if isinstance(endurance, dict) else None
    if not isinstance(types, dict):
        return
    given = data.get("uav_types")
    known = {**DEFAULT_UAV_TYPES, **given} if isinstance(given, dict) else DEFAULT_UAV_TYPES
    for name in types:
        if name not in known:
            raise_if([Problem(("endurance", "types", str(name)), name,
                              f"a UAV type defined in [uav_types]: {', '.join(map(str, known))}",
                              found=f"a table for {name!r}, which is not a UAV type")])


# --- documents ---------------------------------------------------------------------------
def parse_scenario(doc: dict[str, Any], source: str = "<scenario>", *, truncated: bool = False,
                   scenario_duration_s: float | None = None,
                   allow_planner_imports: bool | Iterable[str] = False) -> Scenario:
    """Validate an already-parsed document. ``name`` defaults to the source's file stem.
    ``truncated``: the document's ``duration_s`` is a run cut short on purpose (``--duration``),
    so UAVs may join after its end; they must still join before ``scenario_duration_s``, the
    scenario's own end, if given. ``allow_planner_imports``: ``True``, or the ``module:Class``
    planner names that may be imported (checked); any other ``module:Class`` in the document is
    refused without being imported (:mod:`swarm.scenario.trust`)."""
    if not isinstance(doc, dict):
        raise ScenarioError(source, "", found_words(doc), "a table of scenario settings")
    data = dict(doc)
    data.setdefault("name", _default_name(source))
    allow = allowed(allow_planner_imports)
    # Code the user did not allow is the one thing said about such a document (the model checks
    # it too, for documents validated directly).
    table = data.get("planner")
    name = table.get("name") if isinstance(table, dict) else None
    if isinstance(name, str) and not permits(allow, name):
        raise ScenarioError(source, PLANNER_NAME_KEY, *refusal(name))
    context = {"truncated": truncated, "scenario_duration_s": scenario_duration_s, "allow_planners": allow,
               "source": source}
    _follow_fault_registry()
    try:
        return Scenario.model_validate(data, context=context)
    except ValidationError as exc:
        # from None: our message says everything; pydantic's would only repeat it less clearly.
        raise first_error(exc, doc, source, Scenario) from None


# The [[faults]] tables the Scenario model's `faults` field was last built with.
_FAULTS_BUILT_FROM: list[tuple[type, ...]] = [tuple(FAULT_TABLES.values())]


def _follow_fault_registry() -> None:
    """A fault kind registered since the last document (faults.registry.register) is a valid
    ``[[faults]]`` kind from now on: the scenario model is rebuilt with its table."""
    sync_fault_tables()
    tables = tuple(FAULT_TABLES.values())
    if tables != _FAULTS_BUILT_FROM[0]:
        _FAULTS_BUILT_FROM[0] = tables
        field = Scenario.model_fields["faults"]
        new = FieldInfo.from_annotation(list[fault_union()])  # type: ignore[misc, arg-type]
        new.default_factory, new.description = field.default_factory, field.description
        Scenario.model_fields["faults"] = new
        Scenario.model_rebuild(force=True)


def _default_name(source: str) -> str:
    if not source or source.startswith("<"):
        return "scenario"
    return Path(source).stem or "scenario"


def apply_overrides(scenario: Scenario, overrides: Mapping[str, Any], *, truncated: bool = False,
                    scenario_duration_s: float | None = None,
                    allow_planner_imports: bool | Iterable[str] = False) -> Scenario:
    """A new scenario with dotted keys replaced, e.g. ``{"radio.loss_base": 0.3}`` or
    ``{"uavs[0].x_m": 100}``; the result is validated as a whole. ``truncated``: the
    ``duration_s`` override shortens the run (``--duration``): everything is judged against
    it, except late joiners, which must join before ``scenario_duration_s``, the scenario's
    own end, if given (not judged otherwise); see :func:`parse_scenario`.

    ``planner.name`` is applied first and replaces the planner as
    :func:`~swarm.scenario.overrides.switch_planner` does (its options follow it), so
    ``planner.options.KEY`` overrides are the new planner's.
    ``allow_planner_imports``: as :func:`parse_scenario`; the scenario's own planner stays
    allowed (it was when ``scenario`` was validated), a new ``module:Class`` needs allowing."""
    source = f"{scenario.name} (with overrides)"
    doc = scenario.to_document()
    set_keys(doc, overrides, source)
    allow = allowed(allow_planner_imports, scenario.planner.name)
    try:
        return parse_scenario(doc, source, truncated=truncated, scenario_duration_s=scenario_duration_s,
                              allow_planner_imports=allow)
    except ScenarioError as err:
        if err.key in overrides or err.hint:
            raise
        # The override was fine on its own but broke another key (e.g. a smaller area leaves a
        # UAV outside it): say which override did it.
        changed = ", ".join(f"{k}={v!r}" for k, v in overrides.items())
        raise ScenarioError(err.source, err.key, err.found, err.expected, f"after overriding {changed}") from None
