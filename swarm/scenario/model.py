"""Scenario: the data that describes one run, and its validation.

A scenario is a TOML document (a built-in one from ``swarm/scenario/builtin/`` or a user's file).
It is validated into frozen pydantic models; anything wrong becomes one
:class:`~swarm.errors.ScenarioError` that names the file, the dotted key path, what was found
and what was expected. No other exception escapes the loader: the CLI prints ``str(err)`` and
nothing else, so the message must stand on its own.

Defaults are the paper's where it gives a number (Table 1, section 4.1) and otherwise the
settled defaults of ``DACMP-SPEC.md``; every one of them can be overridden from the file or with
:func:`apply_overrides` (``--set key=value``).

The fault kinds (``[[faults]]``), ``[planner.apf]`` and ``[planner.dacmp]`` are not defined here:
their tables are generated from the simulator's own dataclasses (:mod:`faults.schedule`,
:class:`agents.apf.ApfSettings`, :class:`agents.planners.dacmp.settings.DacmpSettings`), with
their fields, defaults and bounds (see :func:`_table_of`). This module adds what needs more than
one field: fault windows, partition groups, the level weights' sum, and the cross-table checks.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import math
import types
import typing
from collections.abc import Sequence
from typing import TYPE_CHECKING, Annotated, Any, Literal, NamedTuple, Protocol, Union, get_args, get_origin

from pydantic import (
    AllowInfNan,
    BaseModel,
    ConfigDict,
    Field,
    Strict,
    ValidationInfo,
    create_model,
    field_validator,
    model_validator,
)

from agents import apf as _apf
from agents.planners.dacmp import settings as _dacmp
from agents.types import DAA_RANGE_M, UavType
from comms import settings as _radio
from faults import schedule as _faults
from swarm.errors import UsageError
from swarm.scenario.positions import found_words, key_path

__all__ = [
    "Area",
    "MapSettings",
    "UavTypeSpec",
    "UavSpec",
    "FleetSpec",
    "PlacedTarget",
    "TargetSettings",
    "ThreatSpec",
    "RadioSettings",
    "DropFault",
    "BurstFault",
    "PartitionFault",
    "DelayFault",
    "DuplicateFault",
    "CorruptFault",
    "CrashFault",
    "JoinFault",
    "PauseFault",
    "RestartFault",
    "ClockSkewFault",
    "NavErrorFault",
    "SensorFault",
    "JammerFault",
    "BridgeFault",
    "SwizzleFault",
    "LiarFault",
    "SpooferFault",
    "Fault",
    "FAULT_KINDS",
    "GreedySettings",
    "DacmpSettings",
    "ApfSettings",
    "PlannerSettings",
    "SafetySettings",
    "MetricsSettings",
    "RecordingSettings",
    "Scenario",
    "DEFAULT_UAV_TYPES",
]

# --- value types -------------------------------------------------------------------------
# Strict scalars: a TOML integer is fine where a float is wanted (pydantic's strict float takes
# ints), but a string ("fast") or a boolean (true) never silently becomes a number, and a float
# never becomes an integer. Infinity and NaN are refused everywhere (model config) except where
# a field says otherwise (the radio range).
Num = Annotated[float, Strict()]
Int = Annotated[int, Strict()]
Bool = Annotated[bool, Strict()]
Str = Annotated[str, Strict()]


def _fmt(x: float) -> str:
    """A bound or value as a person would write it: 50000 rather than 50000.0."""
    if isinstance(x, float) and x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def _range_words(noun: str, gt: float | None, ge: float | None, lt: float | None, le: float | None) -> str:
    low = (f"({_fmt(gt)}", f"> {_fmt(gt)}") if gt is not None else (f"[{_fmt(ge)}", f">= {_fmt(ge)}") if ge is not None else None
    high = (f"{_fmt(lt)})", f"< {_fmt(lt)}") if lt is not None else (f"{_fmt(le)}]", f"<= {_fmt(le)}") if le is not None else None
    if low and high:
        return f"{noun} in {low[0]}, {high[0]}"
    if low or high:
        return f"{noun} {(low or high)[1]}"  # type: ignore[index]
    return noun


def _num(default: Any = ..., *, gt: float | None = None, ge: float | None = None, lt: float | None = None,
         le: float | None = None, note: str = "", optional: bool = False) -> Any:
    """A float field whose ``description`` is the human 'expected' text used in errors."""
    words = _range_words("a number", gt, ge, lt, le)
    if note:
        words += f" ({note})"
    if optional:
        words += ", or leave it out"
    return Field(default, gt=gt, ge=ge, lt=lt, le=le, description=words)


def _int(default: Any = ..., *, ge: int | None = None, le: int | None = None, note: str = "") -> Any:
    words = _range_words("a whole number", None, ge, None, le)
    if note:
        words += f" ({note})"
    return Field(default, ge=ge, le=le, description=words)


def _table(factory: Any, name: str) -> Any:
    return Field(default_factory=factory, description=f"a table [{name}]")


# --- problems found by our own checks ----------------------------------------------------
class _Problem(NamedTuple):
    """One thing wrong, found by a cross-field check. ``path`` is relative to the model that
    found it; pydantic prefixes the model's own location when it reports the error. ``value`` is
    the validated value; the error shows the document's own value where there is one (``60000``
    as written, not ``60000.0``), or ``found`` verbatim if given."""

    path: tuple[str | int, ...]
    value: Any
    expected: str
    hint: str = ""
    found: str | None = None


class _Invalid(ValueError):
    """Raised inside validators with every problem found, so the loader can report the first one
    in document order (pydantic itself only knows field order). A ValueError so that pydantic
    wraps it into its ValidationError like any other validator failure."""

    def __init__(self, problems: list[_Problem]):
        self.problems = problems
        super().__init__("; ".join(f"{key_path(p.path)}: found {p.found or found_words(p.value)}; expected {p.expected}"
                                   for p in problems))


def _raise_if(problems: list[_Problem]) -> None:
    if problems:
        raise _Invalid(problems)


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


# --- tables generated from the simulator's dataclasses ---------------------------------------
# Metadata a dataclass field may carry: bounds (gt, ge, lt, le), a note for the error words, the
# bounds of each item of an array (each), inf (a number that may be infinite: TOML can write
# `inf`), the least length of a string (min_length), and the whole 'expected' text of a field
# that is not a number (a Literal's is "one of: ..." unless given). Anything else is a typo in
# the dataclass and fails at import.
_METADATA_KEYS = frozenset({"gt", "ge", "lt", "le", "note", "each", "inf", "min_length", "expected"})
# A float that may be infinite (the model config refuses infinity everywhere else).
_NumOrInf = Annotated[float, Strict(), AllowInfNan(True)]


def _strict_type(tp: Any, each: dict[str, Any] | None = None, inf: bool = False) -> Any:
    """The strict scenario type of a dataclass annotation; tuples are TOML arrays, a Literal is
    itself.

    The types are built at run time, so ``list[x]`` and ``tuple[x, y]`` are spelled as the
    ``types.GenericAlias`` they evaluate to (which mypy reads as a value, not a type)."""
    if tp is float and inf:
        return _NumOrInf
    simple = {float: Num, int: Int, bool: Bool, str: Str}
    if tp in simple:
        return simple[tp]
    origin, args = get_origin(tp), get_args(tp)
    if origin is Literal:
        return tp
    if origin in (Union, types.UnionType) and type(None) in args:
        (inner,) = [a for a in args if a is not type(None)]
        return _strict_type(inner, each, inf) | None
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
        item = _strict_type(args[0])
        return types.GenericAlias(list, (Annotated[item, Field(**each)] if each else item,))
    if origin is tuple:
        return types.GenericAlias(tuple, tuple(_strict_type(a) for a in args))
    raise TypeError(f"no scenario type for the dataclass annotation {tp!r}")


def _table_field(f: dataclasses.Field[Any], tp: Any) -> tuple[Any, Any]:
    """``(type, FieldInfo)`` of the scenario field for dataclass field ``f`` (annotation ``tp``).

    No default: required. ``math.inf``: absent from the scenario (``None``, "leave it out"), as a
    fault's ``end_s``. Numbers get their ``description`` (the 'expected' words of an error) from
    :func:`_num` / :func:`_int`, booleans "true or false", other fields from ``expected``."""
    meta = dict(f.metadata)
    unknown = set(meta) - _METADATA_KEYS
    if unknown:
        raise TypeError(f"{f.name}: unknown field metadata {sorted(unknown)}; known: {sorted(_METADATA_KEYS)}")
    if f.default is not dataclasses.MISSING:
        default = f.default
    elif f.default_factory is not dataclasses.MISSING:
        default = f.default_factory()
    else:
        default = ...
    if isinstance(default, float) and default == math.inf:
        tp, default = tp | None, None
    bounds = {k: meta[k] for k in ("gt", "ge", "lt", "le") if k in meta}
    note = meta.get("note", "")
    annotation = _strict_type(tp, meta.get("each"), meta.get("inf", False))
    optional = get_origin(tp) in (Union, types.UnionType)
    value_type = next(a for a in get_args(tp) if a is not type(None)) if optional else tp
    if value_type is float:
        return annotation, _num(default, **bounds, note=note, optional=default is None)
    if value_type is int:
        if set(bounds) - {"ge", "le"}:
            raise TypeError(f"{f.name}: a whole number takes only ge / le bounds")
        return annotation, _int(default, **bounds, note=note)
    if value_type is bool:
        return annotation, Field(default, description="true or false")
    if get_origin(value_type) is Literal and "expected" not in meta:
        return annotation, Field(default, description=f"one of: {', '.join(map(str, get_args(value_type)))}")
    if "expected" not in meta:
        raise TypeError(f"{f.name}: a field that is not a number needs metadata 'expected' (the words of an error)")
    if isinstance(default, tuple):  # an array: a fresh list each time
        return annotation, Field(default_factory=functools.partial(list, default), description=meta["expected"])
    if "min_length" in meta:
        return annotation, Field(default, min_length=meta["min_length"], description=meta["expected"])
    return annotation, Field(default, description=meta["expected"])


def _table_of(source: type, name: str, *, base: type[_Model] = _Model, exclude: tuple[str, ...] = (),
              order: list[str] | None = None, extra: dict[str, Any] | None = None) -> type[_Model]:
    """A frozen, strict pydantic model named ``name`` with the fields of dataclass ``source``
    (less ``exclude``), in ``order`` (default: the dataclass's), plus ``extra`` definitions
    (``name: (type, default)``, placed by ``order``). ``base`` adds validators."""
    hints = typing.get_type_hints(source)
    defs: dict[str, Any] = {f.name: _table_field(f, hints[f.name])
                            for f in dataclasses.fields(source) if f.name not in exclude}
    defs.update(extra or {})
    order = order if order is not None else list(defs)
    if sorted(order) != sorted(defs):
        raise TypeError(f"{name}: the order {order} does not list exactly the fields {sorted(defs)}")
    return create_model(name, __base__=base, __module__=__name__, __doc__=source.__doc__,
                        **{k: defs[k] for k in order})


# --- the world -----------------------------------------------------------------------------
class Area(_Model):
    """The mission area, origin at a corner, x east, y north (paper: 50 km x 50 km, 100 m cells)."""

    width_m: Num = _num(50_000.0, gt=0)
    height_m: Num = _num(50_000.0, gt=0)
    cell_m: Num = _num(100.0, gt=0)

    @model_validator(mode="after")
    def _whole_cells(self) -> Area:
        # The grid must tile the area exactly, otherwise the last row/column of cells would be
        # partly outside it and coverage fractions would be ambiguous.
        _raise_if([
            _Problem((key,), value, f"a whole multiple of cell_m ({_fmt(self.cell_m)})")
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


class MapSettings(_Model):
    """Uncertainty map and pyramid. ``levels`` is the paper's L: pyramid layers G_1..G_L above the
    map G_0 (paper: seven, the seventh being 4 x 4 regions on a 500 x 500 map). ``tau`` is not in
    the paper; see :attr:`Scenario.effective_tau` for the spec's default."""

    levels: Int = _int(7, ge=1, le=12, note="layers above the map itself")
    prior_target_speed: Num = _num(10.0, gt=0, note="m/s")
    tau: Num | None = _num(None, gt=0, note="1/s", optional=True)


class UavTypeSpec(_Model):
    """One UAV type (a row of Table 1). Types are data: a new type needs no code."""

    speed_min: Num = _num(..., gt=0, note="m/s")
    speed_max: Num = _num(..., gt=0, note="m/s, >= speed_min")
    accel_max: Num = _num(..., gt=0, note="m/s^2")
    bank_max_deg: Num = _num(..., gt=0, lt=90)
    detect_radius_m: Num = _num(..., gt=0)
    w_t: Num = _num(..., ge=0, note="target attraction weight")
    w_r: Num = _num(..., ge=0, note="repulsion weight")
    influence_radius_m: Num = _num(..., gt=0, note="target influence radius D")
    # Not in the paper. Other UAVs within this range are sensed (true position and velocity) for
    # collision avoidance instead of taken from the radio. Default 3000 m: collision avoidance
    # looks planner.apf.lookahead_s = 15 s ahead and Table 1's fastest closing speed is two type B
    # head-on, 180 m/s: 15 x 180 = 2700 m, plus a margin. 0 turns the sensor off (the radio only).
    daa_range_m: Num = _num(DAA_RANGE_M, ge=0, note="m, detect-and-avoid sensor range; 0 = no sensor")

    def uav_type(self, name: str) -> UavType:
        """This table as the agents' :class:`~agents.types.UavType` named ``name``."""
        return UavType(name=name, speed_min=self.speed_min, speed_max=self.speed_max, accel_max=self.accel_max,
                       bank_max_rad=math.radians(self.bank_max_deg), detect_radius=self.detect_radius_m,
                       w_t=self.w_t, w_r=self.w_r, influence_radius=self.influence_radius_m,
                       daa_range=self.daa_range_m)

    @model_validator(mode="after")
    def _speed_range(self) -> UavTypeSpec:
        if self.speed_min > self.speed_max:
            _raise_if([_Problem(("speed_min",), self.speed_min, f"a number <= speed_max ({_fmt(self.speed_max)})")])
        return self


# Table 1 of the paper.
DEFAULT_UAV_TYPES: dict[str, UavTypeSpec] = {
    "A": UavTypeSpec(speed_min=30.0, speed_max=50.0, accel_max=0.4, bank_max_deg=30.0,
                     detect_radius_m=1500.0, w_t=5.0, w_r=5.1, influence_radius_m=10_000.0),
    "B": UavTypeSpec(speed_min=60.0, speed_max=90.0, accel_max=0.6, bank_max_deg=20.0,
                     detect_radius_m=2000.0, w_t=2.0, w_r=2.1, influence_radius_m=4000.0),
}


class UavSpec(_Model):
    """One UAV at the start (or at ``join_s`` for a late joiner)."""

    # None is replaced after validation by f"{type}{k}", k counting from 1 within the type.
    name: Str | None = Field(default=None, description="a string (unique UAV name), or leave it out")
    type: Str = Field(..., description="a UAV type name defined in [uav_types]")
    x_m: Num = _num(..., note="metres east of the area's corner, inside the area")
    y_m: Num = _num(..., note="metres north of the area's corner, inside the area")
    heading_deg: Num = _num(0.0, note="degrees, 0 = east, counter-clockwise")
    # None = the type's speed_max; the range is checked against the type by Scenario.
    speed: Num | None = _num(None, gt=0, note="m/s within the type's speed range", optional=True)
    join_s: Num | None = _num(None, ge=0, note="time the UAV enters the world", optional=True)


class FleetSpec(_Model):
    """Many UAVs of one type at once, laid out deterministically (large swarms, benchmarks).

    Expanded into ``uavs`` when the scenario loads (after the ``[[uavs]]`` entries, named like
    unnamed UAVs: type + number within the type); the loaded scenario lists every UAV, so
    ``scenario.json`` and ``--set uavs[N]...`` see them like any other.
    """

    type: Str = Field(..., description="a UAV type name defined in [uav_types]")
    count: Int = _int(..., ge=1, le=100_000)
    # grid: a near-square lattice over the region, row by row from the south-west corner, each
    # UAV at the centre of its lattice cell; random: uniform in the region.
    layout: Literal["grid", "random"] = Field(default="grid", description="one of: grid, random")
    region: list[Num] | None = Field(
        default=None,
        description="[x0_m, y0_m, x1_m, y1_m] inside the area with x0 < x1 and y0 < y1, or leave it out (the whole area)",
    )
    # None: each UAV gets a random heading from the layout stream.
    heading_deg: Num | None = _num(None, note="degrees, 0 = east; absent = random per UAV", optional=True)
    speed: Num | None = _num(None, gt=0, note="m/s within the type's speed range", optional=True)
    join_s: Num | None = _num(None, ge=0, note="time the UAVs enter the world", optional=True)
    # The layout's own random stream (positions, headings): independent of the run's seed, so
    # every seed flies the same fleet.
    layout_seed: Int = _int(0, ge=0)

    def expand(self, index: int, area: Area) -> list[UavSpec]:
        import numpy as np

        x0, y0, x1, y1 = self.region if self.region is not None else (0.0, 0.0, area.width_m, area.height_m)
        w, h = x1 - x0, y1 - y0
        n = self.count
        rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy=self.layout_seed, spawn_key=(index,))))
        if self.layout == "grid":
            cols = max(1, min(n, math.ceil(math.sqrt(n * w / h))))
            rows = math.ceil(n / cols)
            xs = [x0 + (k % cols + 0.5) * w / cols for k in range(n)]
            ys = [y0 + (k // cols + 0.5) * h / rows for k in range(n)]
        else:
            xs = rng.uniform(x0, x1, n).tolist()
            ys = rng.uniform(y0, y1, n).tolist()
        if self.heading_deg is None:
            headings = rng.uniform(0.0, 360.0, n).tolist()
        else:
            headings = [self.heading_deg] * n
        return [
            UavSpec(type=self.type, x_m=min(max(x, 0.0), area.width_m), y_m=min(max(y, 0.0), area.height_m),
                    heading_deg=hd, speed=self.speed, join_s=self.join_s)
            for x, y, hd in zip(xs, ys, headings)
        ]


class PlacedTarget(_Model):
    x_m: Num = _num(..., note="inside the area")
    y_m: Num = _num(..., note="inside the area")
    heading_deg: Num = _num(0.0, note="degrees, 0 = east, counter-clockwise")
    speed: Num = _num(0.0, ge=0, note="m/s, <= targets.speed_max")
    value: Num = _num(1.0, gt=0)


class TargetSettings(_Model):
    """Target motion model (Table 1: 0-20 m/s, +-0.4 m/s^2) and where targets start."""

    count: Int = _int(0, ge=0, note="targets drawn uniformly in the area from the seed")
    speed_max: Num = _num(20.0, ge=0, note="m/s")
    accel_max: Num = _num(0.4, gt=0, note="m/s^2")
    accel_sigma: Num = _num(0.05, ge=0, note="m/s^2 per sqrt(s)")
    turn_sigma: Num = _num(0.002, ge=0, note="rad/s per sqrt(s)")
    turn_rate_max: Num = _num(0.1, gt=0, note="rad/s")
    # Our choice (the paper gives none): the turn rate relaxes to 0 with this time constant, so
    # targets wander over kilometres like the paper's dashed tracks instead of circling in place.
    turn_reversion_s: Num = _num(30.0, gt=0, note="s")
    value: Num = _num(1.0, gt=0)
    placed: list[PlacedTarget] = Field(default_factory=list, description="an array of tables [[targets.placed]]")

    @model_validator(mode="after")
    def _placed_speeds(self) -> TargetSettings:
        _raise_if([
            _Problem(("placed", i, "speed"), t.speed, f"a number in [0, {_fmt(self.speed_max)}] (targets.speed_max)")
            for i, t in enumerate(self.placed)
            if t.speed > self.speed_max
        ])
        return self


class ThreatSpec(_Model):
    """A circular no-fly zone of radius R_T with a repulsion field out to ``d_max``."""

    x_m: Num = _num(..., note="inside the area")
    y_m: Num = _num(..., note="inside the area")
    radius_m: Num = _num(..., gt=0)
    influence_m: Num | None = _num(None, gt=0, note="> radius_m, from the centre", optional=True)

    @model_validator(mode="after")
    def _influence_beyond_radius(self) -> ThreatSpec:
        if self.influence_m is not None and self.influence_m <= self.radius_m:
            _raise_if([_Problem(("influence_m",), self.influence_m, f"a number > radius_m ({_fmt(self.radius_m)})")])
        return self

    @property
    def d_max(self) -> float:
        """Repulsion influence radius from the centre (our default: 3 km beyond the edge)."""
        return self.influence_m if self.influence_m is not None else self.radius_m + 3000.0


class _RadioChecks(_Model):
    """Checks of ``[radio]`` beyond each field's bounds, and what the table implies (each from
    :class:`comms.settings.RadioSettings`, the dataclass the table is generated from)."""

    @model_validator(mode="after")
    def _loss_never_falls(self: _LossAtRange) -> _LossAtRange:
        at = self.loss_at_range
        if at is not None and self.model == "log_distance":
            _raise_if([_Problem(("loss_at_range",), at, 'to be left out with model = "log_distance" '
                                                        "(the link budget gives the loss; loss_base is a floor)")])
        if _radio.loss_falls(self.loss_base, at):
            _raise_if([_Problem(("loss_at_range",), at,
                                f"a number in [{_fmt(self.loss_base)}, 1] (>= loss_base: loss never falls with distance), "
                                "or leave it out")])
        return self

    def settings(self) -> _radio.RadioSettings:
        """This table as the radio's :class:`~comms.settings.RadioSettings` (what the actors and the
        radio are built with)."""
        values = self.model_dump()
        return _radio.RadioSettings(**{**values, "log_distance": _radio.LogDistance(**values["log_distance"])})

    @property
    def effective_loss_at_range(self) -> float:
        """The disk model's loss at the range limit (``loss_base`` when ``loss_at_range`` is absent)."""
        return self.settings().effective_loss_at_range

    def log_distance_model(self) -> _radio.LogDistance | None:
        """``[radio.log_distance]`` as the radio's :class:`~comms.settings.LogDistance` when
        ``model = "log_distance"``; None for the disk model."""
        return self.settings().link_model().log_distance

    @property
    def horizon_m(self) -> float:
        """The knowledge horizon as a number: ``sync_horizon_m``, math.inf when absent (none)."""
        return self.settings().horizon_m

    @property
    def range_limit_m(self) -> float:
        """How far links reach, as a number (math.inf when unlimited): ``range_m``, and with the
        log-distance model at most its link budget's range (:attr:`comms.settings.LinkModel.radius_m`)."""
        return self.settings().range_limit_m


class _LossAtRange(Protocol):
    @property
    def model(self) -> str: ...
    @property
    def loss_base(self) -> float: ...
    @property
    def loss_at_range(self) -> float | None: ...


if TYPE_CHECKING:  # the static view of generated tables: see DropFault
    class LogDistanceSettings(_Model, _radio.LogDistance, frozen=True): ...  # type: ignore[misc]
    class RadioSettings(_RadioChecks, _radio.RadioSettings, frozen=True): ...  # type: ignore[misc]
else:
    # [radio.log_distance] and [radio]: generated from comms.settings.LogDistance and
    # comms.settings.RadioSettings (their fields, defaults, bounds).
    LogDistanceSettings = _table_of(_radio.LogDistance, "LogDistanceSettings")
    RadioSettings = _table_of(_radio.RadioSettings, "RadioSettings", base=_RadioChecks, exclude=("log_distance",),
                              extra={"log_distance": (LogDistanceSettings, _table(LogDistanceSettings, "radio.log_distance"))})


# --- faults --------------------------------------------------------------------------------
# The checks below are mixins of generated tables: each reads fields it does not define, so its
# ``self`` is typed by the protocol of what it reads (mypy's idiom for a mixin).
class _Window(Protocol):
    @property
    def start_s(self) -> float: ...
    @property
    def end_s(self) -> float | None: ...  # None: until the end


class _Groups(Protocol):
    @property
    def groups(self) -> Sequence[Sequence[str]]: ...


class _WindowedFault(_Model):
    """Checks of a fault with a window (the fields come from :mod:`faults.schedule`)."""

    @model_validator(mode="after")
    def _window(self: _Window) -> _Window:
        if self.end_s is not None and self.end_s <= self.start_s:
            _raise_if([_Problem(("end_s",), self.end_s, f"a number > start_s ({_fmt(self.start_s)})")])
        return self


class _LinkFault(_WindowedFault):
    """A fault on frame copies (:class:`faults.schedule.LinkFault`)."""


class _PartitionChecks(_WindowedFault):
    """Checks of a partition's groups: at least two, none empty, a UAV in at most one."""

    @model_validator(mode="after")
    def _groups(self: _Groups) -> _Groups:
        problems: list[_Problem] = []
        if len(self.groups) < 2:
            problems.append(_Problem(("groups",), self.groups, "at least 2 groups of UAV names"))
        seen: dict[str, int] = {}
        for g, group in enumerate(self.groups):
            if not group:
                problems.append(_Problem(("groups", g), group, "a non-empty array of UAV names"))
            for k, name in enumerate(group):
                if name in seen:
                    problems.append(_Problem(("groups", g, k), name,
                                             f"a UAV name not already in groups[{seen[name]}] (a UAV is in at most one group)"))
                seen.setdefault(name, g)
        _raise_if(problems)
        return self


# Keys in the order a [[faults]] table shows them (scenario.json, the 'valid keys' of an error):
# the window and scope first, then kind, then the kind's own keys (a node fault's at_s first).
_COMMON_FAULT_KEYS = ("start_s", "end_s", "uavs", "links")


def _fault_table(cls: type[_faults.Fault]) -> type[_Model]:
    """The ``[[faults]]`` table of the fault kind ``cls`` (a :mod:`faults.schedule` class)."""
    names = [f.name for f in dataclasses.fields(cls)]
    common = [n for n in _COMMON_FAULT_KEYS if n in names]
    own = sorted((n for n in names if n not in common), key=lambda n: n != "at_s")
    base = (_PartitionChecks if "groups" in names else _LinkFault if issubclass(cls, _faults.LinkFault)
            else _WindowedFault if "end_s" in names else _Model)
    return _table_of(cls, f"{cls.__name__}Fault", base=base, order=[*common, "kind", *own],
                     extra={"kind": (Literal[cls.kind], cls.kind)})


# One table per kind of faults.schedule, in its order (the order error messages list them).
_FAULT_CLASSES: dict[str, type[_Model]] = {kind: _fault_table(cls) for kind, cls in _faults.FAULT_KINDS.items()}
FAULT_KINDS: tuple[str, ...] = tuple(_FAULT_CLASSES)

if TYPE_CHECKING:
    # What mypy sees of the generated tables (here and for [planner.dacmp], [planner.apf]). It
    # cannot see the fields of a class made by create_model, so each table is declared, for type
    # checking only, as what it is: a model with the checks it is built on (its first base, as
    # _fault_table picks it: the pydantic API, model_dump, model_copy, ...) and the fields of the
    # dataclass it is generated from (its second base). Still one definition: the fields are the
    # dataclass's, not repeated here. Where the two differ the static view is the dataclass's:
    # arrays are lists at run time (typed as the dataclass's tuples); a field whose default is
    # math.inf (end_s) is None when left out; the dataclass's methods (active, separates) and
    # ApfSettings' excluded fields are not on the table. ``kind`` is the dataclass's class
    # variable, a literal that tags the union. The ignores: mypy reads the dataclasses as frozen
    # and the models as not (pydantic's frozen is in model_config, where mypy does not look).
    class DropFault(_LinkFault, _faults.Drop, frozen=True): ...  # type: ignore[misc]
    class BurstFault(_LinkFault, _faults.Burst, frozen=True): ...  # type: ignore[misc]
    class PartitionFault(_PartitionChecks, _faults.Partition, frozen=True): ...  # type: ignore[misc]
    class DelayFault(_LinkFault, _faults.Delay, frozen=True): ...  # type: ignore[misc]
    class DuplicateFault(_LinkFault, _faults.Duplicate, frozen=True): ...  # type: ignore[misc]
    class CorruptFault(_LinkFault, _faults.Corrupt, frozen=True): ...  # type: ignore[misc]
    class CrashFault(_Model, _faults.Crash, frozen=True): ...  # type: ignore[misc]
    class JoinFault(_Model, _faults.Join, frozen=True): ...  # type: ignore[misc]
    class PauseFault(_WindowedFault, _faults.Pause, frozen=True): ...  # type: ignore[misc]
    class RestartFault(_Model, _faults.Restart, frozen=True): ...  # type: ignore[misc]
    class ClockSkewFault(_WindowedFault, _faults.ClockSkew, frozen=True): ...  # type: ignore[misc]
    class NavErrorFault(_WindowedFault, _faults.NavError, frozen=True): ...  # type: ignore[misc]
    class SensorFault(_WindowedFault, _faults.Sensor, frozen=True): ...  # type: ignore[misc]
    class JammerFault(_WindowedFault, _faults.Jammer, frozen=True): ...  # type: ignore[misc]
    class BridgeFault(_PartitionChecks, _faults.Bridge, frozen=True): ...  # type: ignore[misc]
    class SwizzleFault(_WindowedFault, _faults.Swizzle, frozen=True): ...  # type: ignore[misc]
    class LiarFault(_WindowedFault, _faults.Liar, frozen=True): ...  # type: ignore[misc]
    class SpooferFault(_WindowedFault, _faults.Spoofer, frozen=True): ...  # type: ignore[misc]

    Fault = (DropFault | BurstFault | PartitionFault | DelayFault | DuplicateFault | CorruptFault | CrashFault
             | JoinFault | PauseFault | RestartFault | ClockSkewFault | NavErrorFault | SensorFault | JammerFault
             | BridgeFault | SwizzleFault | LiarFault | SpooferFault)
else:
    DropFault = _FAULT_CLASSES["drop"]
    BurstFault = _FAULT_CLASSES["burst"]
    PartitionFault = _FAULT_CLASSES["partition"]
    DelayFault = _FAULT_CLASSES["delay"]
    DuplicateFault = _FAULT_CLASSES["duplicate"]
    CorruptFault = _FAULT_CLASSES["corrupt"]
    CrashFault = _FAULT_CLASSES["crash"]
    JoinFault = _FAULT_CLASSES["join"]
    PauseFault = _FAULT_CLASSES["pause"]
    RestartFault = _FAULT_CLASSES["restart"]
    ClockSkewFault = _FAULT_CLASSES["clock_skew"]
    NavErrorFault = _FAULT_CLASSES["nav_error"]
    SensorFault = _FAULT_CLASSES["sensor"]
    JammerFault = _FAULT_CLASSES["jammer"]
    BridgeFault = _FAULT_CLASSES["bridge"]
    SwizzleFault = _FAULT_CLASSES["swizzle"]
    LiarFault = _FAULT_CLASSES["liar"]
    SpooferFault = _FAULT_CLASSES["spoofer"]

    Fault = Annotated[Union[tuple(_FAULT_CLASSES.values())], Field(discriminator="kind")]  # noqa: UP007


# --- planner, safety, metrics --------------------------------------------------------------
class GreedySettings(_Model):
    headings: Int = _int(15, ge=3, note="candidate headings per decision")


class _LevelWeights(Protocol):
    @property
    def level_weights(self) -> Sequence[float] | None: ...


class _DacmpChecks(_Model):
    """Checks of [planner.dacmp] beyond each field's bounds."""

    @model_validator(mode="after")
    def _positive_sum(self: _LevelWeights) -> _LevelWeights:
        # The length is checked against map.levels by Scenario.
        if self.level_weights is not None and not sum(self.level_weights) > 0:
            _raise_if([_Problem(("level_weights",), self.level_weights, "weights with a positive sum")])
        return self


if TYPE_CHECKING:  # the static view of generated tables: see DropFault
    class DacmpSettings(_DacmpChecks, _dacmp.DacmpSettings, frozen=True): ...  # type: ignore[misc]
    class ApfSettings(_Model, _apf.ApfSettings, frozen=True): ...  # type: ignore[misc]
else:
    DacmpSettings = _table_of(_dacmp.DacmpSettings, "DacmpSettings", base=_DacmpChecks)
    # Not in [planner.apf]: min_separation_m is [safety]'s (the simulation passes it; the invariant
    # checkers read it too), and threat_margin_m is not a scenario setting (its default holds).
    ApfSettings = _table_of(_apf.ApfSettings, "ApfSettings", exclude=("min_separation_m", "threat_margin_m"))


_PLANNER_WORDS = ("a planner: a built-in name (see `swarm list --planners`), package.module:Class, "
                  "or a name registered under the entry-point group swarm.planners")


_ONE_PLANNER = "options for one planner of several (a sweep): planner.options_for.NAME.KEY"


class PlannerSettings(_Model):
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
    replan_s: Num = _num(10.0, gt=0)
    # False: a sighting ends interest in a target (search only, as in paper-fig11).
    surveillance: Bool = Field(default=True, description="true or false")
    # Our choice (the paper does not say how a watcher flies): it circles its target at radius
    # max(loiter_radius_factor * R_s, loiter_turn_factor * turn radius at minimum speed),
    # following a vector field with approach gain loiter_gain.
    loiter_radius_factor: Num = _num(0.5, gt=0, note="times the detection radius")
    loiter_turn_factor: Num = _num(1.25, ge=1, note="times the turn radius at minimum speed")
    loiter_gain: Num = _num(1.0, gt=0)
    # Our choice: a watcher's threat repulsion (eq. 30) is planner.apf.k_rep times this, so it
    # can follow its target to about 0.75 km of a no-fly zone's edge instead of about 1.7 km (the
    # guard still turns it away inside one turn radius + 300 m).
    loiter_threat_weight: Num = _num(0.15, gt=0, le=1, note="times planner.apf.k_rep")
    greedy: GreedySettings = _table(GreedySettings, "planner.greedy")
    dacmp: DacmpSettings = _table(DacmpSettings, "planner.dacmp")
    apf: ApfSettings = _table(ApfSettings, "planner.apf")

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
        from agents.planners.registry import PlannerError, option_problems, surveillance_problem
        from swarm.scenario.trust import permits, refusal

        allow = info.context.get("allow_planners") if info.context else None
        if not permits(allow, self.name):
            found, expected, hint = refusal(self.name)
            _raise_if([_Problem(("name",), self.name, expected, hint=hint, found=found)])
        try:
            problems = option_problems(self.name, self.options_of())
            refused = surveillance_problem(self.name) if self.surveillance else None
        except PlannerError as exc:
            _raise_if([_Problem(("name",), self.name, _PLANNER_WORDS, hint=str(exc))])
        own = self.options_for.get(self.name, {})
        found_problems = []
        for key, found, expected in problems:
            in_own = key in own
            # An unknown option, not a typo of a known one: perhaps meant for another planner of a sweep.
            hint = _ONE_PLANNER if found.startswith("unknown") and not in_own and "did you mean" not in expected else ""
            found_problems.append(_Problem(("options_for", self.name, key) if in_own else ("options", key), None,
                                           expected, found=found, hint=hint))
        for other, options in self.options_for.items():
            if other == self.name or not permits(allow, other):
                continue  # a module:Class nobody allowed is not imported: checked if it is ever run
            try:
                other_problems = option_problems(other, options)
            except PlannerError as exc:
                found_problems.append(_Problem(("options_for", other), None, _PLANNER_WORDS, hint=str(exc),
                                               found=f"options for {other!r}, which is not a planner"))
                continue
            found_problems += [_Problem(("options_for", other, key), None, expected, found=found)
                               for key, found, expected in other_problems]
        _raise_if(found_problems)
        # A planner that declares it only searches (surveils = False) cannot run with surveillance.
        _raise_if([_Problem(("surveillance",), True, f"false: {refused}")] if refused else [])
        return self


class SafetySettings(_Model):
    min_separation_m: Num = _num(200.0, gt=0)


class MetricsSettings(_Model):
    sample_s: Num = _num(10.0, gt=0, note=">= dt_s")


RECORDING_LEVELS = ("frames", "summary")


class RecordingSettings(_Model):
    """What the event log keeps (swarm.recorder; the README lists each level's events).

    ``"frames"``: every frame copy read (``rx``) or lost (``lost``), one event each, so the log
    grows with radio density (a UAV hearing 250 neighbours logs 250 ``rx`` a second).
    ``"summary"``: instead, one ``radio`` event per tick with the tick's totals (frames read and
    rejected, bytes read, copies and bytes lost per cause): bounded per tick, still deterministic and
    hashed like every event. Every other event is the same at both levels. The ``radio`` invariant
    needs ``"frames"`` (it judges each delivery); on a summary log it says it cannot check."""

    level: Literal["frames", "summary"] = Field(default="frames", description=f"one of: {', '.join(RECORDING_LEVELS)}")


# --- the scenario --------------------------------------------------------------------------
# A run has at most this many ticks (duration_s / dt_s): ten million (116 days at dt 1 s).
MAX_TICKS = 10_000_000
_FLOAT32_TINY = 1.1754944e-38  # the smallest normal float32
_FLOAT32_MAX = 3.4028235e38

class Scenario(_Model):
    """Everything one run needs. Build it with :func:`load_scenario` or :func:`parse_scenario`."""

    name: Str = Field(default="scenario", description="a string")
    description: Str = Field(default="", description="a string")
    seed: Int = _int(0, ge=0)
    duration_s: Num = _num(2000.0, gt=0)
    dt_s: Num = _num(1.0, gt=0, le=10)
    area: Area = _table(Area, "area")
    map: MapSettings = _table(MapSettings, "map")
    uav_types: dict[Str, UavTypeSpec] = Field(
        default_factory=lambda: dict(DEFAULT_UAV_TYPES), description="a table of UAV types [uav_types.NAME]"
    )
    uavs: list[UavSpec] = Field(..., description="an array of tables [[uavs]] with at least one UAV (here or in [[fleet]])")
    # Expanded into uavs by the validator, which then empties this list (see FleetSpec).
    fleet: list[FleetSpec] = Field(default_factory=list, description="an array of tables [[fleet]]")
    targets: TargetSettings = _table(TargetSettings, "targets")
    threats: list[ThreatSpec] = Field(default_factory=list, description="an array of tables [[threats]]")
    radio: RadioSettings = _table(RadioSettings, "radio")
    faults: list[Fault] = Field(
        default_factory=list, description=f"an array of tables [[faults]], each with kind = one of: {', '.join(FAULT_KINDS)}"
    )
    planner: PlannerSettings = _table(PlannerSettings, "planner")
    safety: SafetySettings = _table(SafetySettings, "safety")
    metrics: MetricsSettings = _table(MetricsSettings, "metrics")
    recording: RecordingSettings = _table(RecordingSettings, "recording")

    @model_validator(mode="before")
    @classmethod
    def _fleet_only(cls, data: Any) -> Any:
        # A document with [[fleet]] needs no [[uavs]]; without either, "uavs" is missing.
        if isinstance(data, dict) and data.get("fleet") and "uavs" not in data:
            data = {**data, "uavs": []}
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
        if self.fleet:
            _raise_if(self._fleet_problems())
            for i, fleet in enumerate(self.fleet):
                self.uavs.extend(fleet.expand(i, self.area))
            self.fleet.clear()  # consumed: the scenario now lists every UAV in uavs
        if not self.uavs:
            _raise_if([_Problem(("uavs",), self.uavs,
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
        problems = self._cross_problems(join_end)
        _raise_if(problems)

        for fault in self.faults:
            if isinstance(fault, JoinFault):
                i = self.uav_names.index(fault.uav)
                self.uavs[i] = self.uavs[i].model_copy(update={"join_s": fault.at_s})
        return self

    def _fleet_problems(self) -> list[_Problem]:
        problems: list[_Problem] = []
        area = self.area
        types_list = ", ".join(self.uav_types)
        for i, fleet in enumerate(self.fleet):
            spec = self.uav_types.get(fleet.type)
            if spec is None:
                problems.append(_Problem(("fleet", i, "type"), fleet.type, f"a UAV type defined in [uav_types]: {types_list}"))
            elif fleet.speed is not None and not spec.speed_min <= fleet.speed <= spec.speed_max:
                problems.append(_Problem(("fleet", i, "speed"), fleet.speed,
                                         f"a number in [{_fmt(spec.speed_min)}, {_fmt(spec.speed_max)}] "
                                         f"(type {fleet.type}'s speed range)"))
            r = fleet.region
            if r is not None and not (len(r) == 4 and 0.0 <= r[0] < r[2] <= area.width_m and 0.0 <= r[1] < r[3] <= area.height_m):
                problems.append(_Problem(("fleet", i, "region"), r,
                                         f"[x0_m, y0_m, x1_m, y1_m] with 0 <= x0 < x1 <= {_fmt(area.width_m)} "
                                         f"and 0 <= y0 < y1 <= {_fmt(area.height_m)} (inside the area)"))
        return problems

    def _cross_problems(self, join_end: float | None) -> list[_Problem]:
        """Checks that need more than one table: names, types, positions, fault references."""
        problems: list[_Problem] = []
        area = self.area
        inside = {
            "x_m": f"a number in [0, {_fmt(area.width_m)}] (inside the area)",
            "y_m": f"a number in [0, {_fmt(area.height_m)}] (inside the area)",
        }

        def check_inside(path: tuple[str | int, ...], obj: Any) -> None:
            for key, limit in (("x_m", area.width_m), ("y_m", area.height_m)):
                value = getattr(obj, key)
                if not 0.0 <= value <= limit:
                    problems.append(_Problem((*path, key), value, inside[key]))

        types_list = ", ".join(self.uav_types)
        first_with_name: dict[str, int] = {}
        for i, uav in enumerate(self.uavs):
            spec = self.uav_types.get(uav.type)
            if spec is None:
                problems.append(_Problem(("uavs", i, "type"), uav.type, f"a UAV type defined in [uav_types]: {types_list}"))
            name = typing.cast(str, uav.name)  # filled in (_complete_and_cross_check) before these checks
            if name in first_with_name:
                problems.append(_Problem(("uavs", i, "name"), name,
                                         f"a name not already used by uavs[{first_with_name[name]}] (UAV names are unique)",
                                         "a UAV without a name is called TYPE + its number within the type, e.g. B1"))
            first_with_name.setdefault(name, i)
            check_inside(("uavs", i), uav)
            if spec is not None and uav.speed is not None and not spec.speed_min <= uav.speed <= spec.speed_max:
                problems.append(_Problem(("uavs", i, "speed"), uav.speed,
                                         f"a number in [{_fmt(spec.speed_min)}, {_fmt(spec.speed_max)}] "
                                         f"(type {uav.type}'s speed range)"))

        for i, target in enumerate(self.targets.placed):
            check_inside(("targets", "placed", i), target)
        for i, threat in enumerate(self.threats):
            check_inside(("threats", i), threat)

        names = set(first_with_name)
        valid_names = f"a UAV name defined in [[uavs]]: {', '.join(first_with_name)}"

        def check_name(path: tuple[str | int, ...], name: str) -> None:
            if name not in names:
                close = difflib.get_close_matches(name, list(first_with_name), n=1)
                problems.append(_Problem(path, name, valid_names, f"did you mean {close[0]!r}?" if close else ""))

        joined_at: dict[str, int] = {}
        for f, fault in enumerate(self.faults):
            for path, name in _faults.uav_names(fault):
                check_name(("faults", f, *path), name)
            if isinstance(fault, JoinFault) and fault.uav in names:
                uav = self._uav_by_name(fault.uav)
                if fault.uav in joined_at:
                    problems.append(_Problem(("faults", f, "uav"), fault.uav,
                                             f"a UAV not already joined by faults[{joined_at[fault.uav]}]"))
                # join_s equal to at_s is the folded form this validator itself produces, so a
                # dumped scenario loads again.
                elif uav.join_s is not None and uav.join_s != fault.at_s:
                    problems.append(_Problem(("faults", f, "uav"), fault.uav,
                                             "a UAV without its own join_s (give the join time in one place)",
                                             found=f"{fault.uav!r} (string), which already has join_s = {_fmt(uav.join_s)}"))
                joined_at.setdefault(fault.uav, f)

        weights = self.planner.dacmp.level_weights
        if weights is not None and len(weights) != self.map.levels:
            problems.append(_Problem(("planner", "dacmp", "level_weights"), weights,
                                     f"an array of {self.map.levels} numbers "
                                     f"(one per pyramid layer 1..L, map.levels = {self.map.levels})"))
        if self.metrics.sample_s < self.dt_s:
            problems.append(_Problem(("metrics", "sample_s"), self.metrics.sample_s, f"a number >= dt_s ({_fmt(self.dt_s)})"))
        problems += self._runnable_problems(join_end)
        return problems

    def _runnable_problems(self, join_end: float | None) -> list[_Problem]:
        """Values that validate one by one but cannot run: a run that would never finish, a
        memory factor float32 cannot hold, a UAV that would join at or after ``join_end`` (the
        scenario's end; None: not judged)."""
        problems: list[_Problem] = []
        ticks = self.duration_s / self.dt_s
        if ticks > MAX_TICKS:
            problems.append(_Problem(("dt_s",), self.dt_s, f"a number >= duration_s / {MAX_TICKS:,} "
                                     f"({_fmt(self.duration_s / MAX_TICKS)}: a run has at most {MAX_TICKS:,} ticks)"))
        # Map times and q are float32: tau must be a normal float32 and tau * duration finite.
        if self.uavs and all(u.type in self.uav_types for u in self.uavs):
            tau = self.effective_tau
            key: tuple[str, ...] = ("map", "tau") if self.map.tau is not None else ("map", "prior_target_speed")
            value = self.map.tau if self.map.tau is not None else self.map.prior_target_speed
            if not (_FLOAT32_TINY <= tau and tau * max(self.duration_s, 1.0) <= _FLOAT32_MAX):
                problems.append(_Problem(key, value, f"a value giving a map memory factor tau in [{_FLOAT32_TINY:.3g}, "
                                         f"{_FLOAT32_MAX / max(self.duration_s, 1.0):.3g}] 1/s (float32 map times; "
                                         f"this gives {tau:.3g})"))
        for i, uav in enumerate(self.uavs):
            if join_end is not None and uav.join_s is not None and uav.join_s >= join_end:
                problems.append(_Problem(("uavs", i, "join_s"), uav.join_s,
                                         f"a number < duration_s ({_fmt(join_end)}: it would join after the end)"))
        for f, fault in enumerate(self.faults):
            if join_end is not None and isinstance(fault, JoinFault) and fault.at_s >= join_end:
                problems.append(_Problem(("faults", f, "at_s"), fault.at_s,
                                         f"a number < duration_s ({_fmt(join_end)}: the UAV would join after the end)"))
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
        """A new validated scenario with top-level fields (or dotted keys) replaced."""
        from swarm.scenario.loading import apply_overrides  # loading builds on this module

        return apply_overrides(self, changes)

    def _document(self) -> dict[str, Any]:
        """This scenario as an input document that validates to itself (used for overrides):
        joins are unfolded again so the join fault stays the one place that says when."""
        doc = self.model_dump(mode="python")
        joins = {f["uav"] for f in doc["faults"] if f["kind"] == "join"}
        for uav in doc["uavs"]:
            if uav["name"] in joins:
                uav["join_s"] = None
        return doc


def _finite_or_none(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(v) for v in value]
    return value
