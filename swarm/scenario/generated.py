"""The scenario tables generated from the simulator's own dataclasses, each the one definition
of its settings (fields, defaults, bounds and the words of an error, in field metadata):

* ``[radio]`` and ``[radio.log_distance]``: :class:`comms.settings.RadioSettings`,
  :class:`comms.settings.LogDistance`;
* ``[[faults]]``: one table per registered fault kind (:data:`faults.registry.FAULT_KINDS`),
  made from its class when it registers: :data:`FAULT_TABLES` (in registration order),
  :func:`fault_table`, the discriminated union :func:`fault_union`; a kind is named nowhere here
  (``JoinFault`` aside: the scenario model reads a join's UAV and time, its ``join_s``);
* ``[planner.dacmp]`` and ``[planner.apf]``: :class:`agents.planners.dacmp.settings.DacmpSettings`,
  :class:`agents.apf.ApfSettings`.

:func:`swarm.scenario.fields.table_of` builds each one; this module adds what needs more than
one field (fault windows, partition groups, the loss at the range limit, the level weights' sum)
and, for mypy, the static view of each generated table.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import TYPE_CHECKING, Annotated, Any, Literal, Protocol, Union

from pydantic import Field, model_validator

from agents import apf as _apf
from agents.planners.dacmp import settings as _dacmp
from comms import settings as _radio
from faults import schedule as _faults
from swarm.scenario.fields import Problem, Table, fmt, raise_if, table_field, table_of

__all__ = [
    "ApfSettings",
    "DacmpSettings",
    "FAULT_KINDS",
    "FAULT_TABLES",
    "Fault",
    "JoinFault",
    "LogDistanceSettings",
    "RadioSettings",
    "fault_table",
    "fault_union",
    "sync_fault_tables",
]


# --- radio ---------------------------------------------------------------------------------
class _RadioChecks(Table):
    """Checks of ``[radio]`` beyond each field's bounds, and what the table implies (each from
    :class:`comms.settings.RadioSettings`, the dataclass the table is generated from)."""

    @model_validator(mode="after")
    def _loss_never_falls(self: _LossAtRange) -> _LossAtRange:
        at = self.loss_at_range
        if at is not None and self.model == "log_distance":
            raise_if([Problem(("loss_at_range",), at, 'to be left out with model = "log_distance" '
                                                      "(the link budget gives the loss; loss_base is a floor)")])
        if _radio.loss_falls(self.loss_base, at):
            raise_if([Problem(("loss_at_range",), at,
                              f"a number in [{fmt(self.loss_base)}, 1] (>= loss_base: loss never falls with distance), "
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

    @property
    def loses_nothing(self) -> bool:
        """:attr:`comms.settings.RadioSettings.loses_nothing`."""
        return self.settings().loses_nothing

    def link_model(self) -> _radio.LinkModel:
        """The link model the radio runs with these settings (:meth:`comms.settings.RadioSettings.link_model`)."""
        return self.settings().link_model()

    def log_distance_model(self) -> _radio.LogDistance | None:
        """``[radio.log_distance]`` as the radio's :class:`~comms.settings.LogDistance` when
        ``model = "log_distance"``; None for the disk model."""
        return self.link_model().log_distance

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


if TYPE_CHECKING:  # the static view of generated tables: see FaultTable
    class LogDistanceSettings(Table, _radio.LogDistance, frozen=True): ...  # type: ignore[misc]
    class RadioSettings(_RadioChecks, _radio.RadioSettings, frozen=True): ...  # type: ignore[misc]
else:
    # [radio.log_distance] and [radio]: generated from comms.settings.LogDistance and
    # comms.settings.RadioSettings (their fields, defaults, bounds).
    LogDistanceSettings = table_of(_radio.LogDistance, "LogDistanceSettings", __name__)
    RadioSettings = table_of(
        _radio.RadioSettings, "RadioSettings", __name__, base=_RadioChecks, exclude=("log_distance",),
        extra={"log_distance": (LogDistanceSettings, table_field(LogDistanceSettings, "radio.log_distance"))})


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


class _WindowedFault(Table):
    """Checks of a fault with a window (the fields come from :mod:`faults.schedule`)."""

    @model_validator(mode="after")
    def _window(self: _Window) -> _Window:
        if self.end_s is not None and self.end_s <= self.start_s:
            raise_if([Problem(("end_s",), self.end_s, f"a number > start_s ({fmt(self.start_s)})")])
        return self


class _LinkFault(_WindowedFault):
    """A fault on frame copies (:class:`faults.schedule.LinkFault`)."""


class _PartitionChecks(_WindowedFault):
    """Checks of a partition's groups: at least two, none empty, a UAV in at most one."""

    @model_validator(mode="after")
    def _groups(self: _Groups) -> _Groups:
        problems: list[Problem] = []
        if len(self.groups) < 2:
            problems.append(Problem(("groups",), self.groups, "at least 2 groups of UAV names"))
        seen: dict[str, int] = {}
        for g, group in enumerate(self.groups):
            if not group:
                problems.append(Problem(("groups", g), group, "a non-empty array of UAV names"))
            for k, name in enumerate(group):
                if name in seen:
                    problems.append(Problem(("groups", g, k), name,
                                             f"a UAV name not already in groups[{seen[name]}] (a UAV is in at most one group)"))
                seen.setdefault(name, g)
        raise_if(problems)
        return self


# Keys in the order a [[faults]] table shows them (scenario.json, the 'valid keys' of an error):
# the window and scope first, then kind, then the kind's own keys (a node fault's at_s first).
_COMMON_FAULT_KEYS = ("start_s", "end_s", "uavs", "links")


def _fault_table(cls: type[_faults.Fault]) -> type[Table]:
    """The ``[[faults]]`` table of the fault kind ``cls`` (a registered dataclass)."""
    names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]  # (a registered kind is a dataclass)
    common = [n for n in _COMMON_FAULT_KEYS if n in names]
    own = sorted((n for n in names if n not in common), key=lambda n: n != "at_s")
    base = (_PartitionChecks if "groups" in names else _LinkFault if issubclass(cls, _faults.LinkFault)
            else _WindowedFault if "end_s" in names else Table)
    return table_of(cls, f"{cls.__name__}Fault", __name__, base=base, order=[*common, "kind", *own],
                     extra={"kind": (Literal[cls.kind], cls.kind)})


# One table per registered fault kind (faults.registry), in its order (the order error messages
# list them). A kind registered after this module is imported (a user's, a test's) gets its
# table from sync_fault_tables(), which the scenario calls before it validates a document.
FAULT_TABLES: dict[str, type[Table]] = {kind: _fault_table(cls) for kind, cls in _faults.FAULT_KINDS.items()}
FAULT_KINDS: tuple[str, ...] = tuple(FAULT_TABLES)  # (the built-in kinds, as this module was imported)
_TABLE_OF: dict[str, type] = dict(_faults.FAULT_KINDS)  # kind -> the class its table was made from


def sync_fault_tables() -> bool:
    """Make :data:`FAULT_TABLES` follow the registry (tables for kinds registered since, none
    for kinds unregistered); True if it changed (in place: every reference stays good)."""
    registry = _faults.FAULT_KINDS
    if _TABLE_OF == registry:
        return False
    tables = {kind: FAULT_TABLES[kind] if _TABLE_OF.get(kind) is cls else _fault_table(cls)
              for kind, cls in registry.items()}
    FAULT_TABLES.clear()
    FAULT_TABLES.update(tables)
    _TABLE_OF.clear()
    _TABLE_OF.update(registry)
    return True


def fault_union() -> Any:
    """The ``[[faults]]`` item type: the union of :data:`FAULT_TABLES`, told apart by ``kind``."""
    return Annotated[Union[tuple(FAULT_TABLES.values())], Field(discriminator="kind")]  # noqa: UP007

def fault_table(kind: str) -> type[Table]:
    """The ``[[faults]]`` table of the registered fault kind ``kind`` (``KeyError`` if none)."""
    sync_fault_tables()
    return FAULT_TABLES[kind]


def __getattr__(name: str) -> type[Table]:
    """A kind's table by its class name and ``Fault`` (``DropFault``, ``BurstFault``...: the
    names this module has always had, for any registered kind, without listing them)."""
    sync_fault_tables()
    for table in FAULT_TABLES.values():
        if table.__name__ == name:
            return table
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


if TYPE_CHECKING:
    # What mypy sees of the generated tables (here and for [planner.dacmp], [planner.apf]). It
    # cannot see the fields of a class made by create_model, so a table is declared, for type
    # checking only, as what it is: a model with the checks it is built on (its first base, as
    # _fault_table picks it: the pydantic API, model_dump, model_copy, ...) and the fields of the
    # dataclass it is generated from (its second base). Still one definition: the fields are the
    # dataclass's, not repeated here. Where the two differ the static view is the dataclass's:
    # arrays are lists at run time (typed as the dataclass's tuples); a field whose default is
    # math.inf (end_s) is None when left out; the dataclass's methods (active, separates) and
    # ApfSettings' excluded fields are not on the table. The ignores: mypy reads the dataclasses
    # as frozen and the models as not (pydantic's frozen is in model_config, where mypy does not
    # look). A [[faults]] item is any kind's table (FaultTable: its kind tag, and its other fields
    # by kind, so typed loosely); JoinFault is declared because the scenario model reads a join's
    # fields (the UAV's join_s).
    class FaultTable(Table):
        kind: str

        def __getattr__(self, name: str) -> Any: ...

    class JoinFault(Table, _faults.Join, frozen=True): ...  # type: ignore[misc]

    Fault = FaultTable
else:
    FaultTable = Table
    JoinFault = FAULT_TABLES["join"]
    Fault = fault_union()


# --- planner -------------------------------------------------------------------------------
class _LevelWeights(Protocol):
    @property
    def level_weights(self) -> Sequence[float] | None: ...


class _DacmpChecks(Table):
    """Checks of [planner.dacmp] beyond each field's bounds."""

    @model_validator(mode="after")
    def _positive_sum(self: _LevelWeights) -> _LevelWeights:
        # The length is checked against map.levels by Scenario.
        if self.level_weights is not None and not sum(self.level_weights) > 0:
            raise_if([Problem(("level_weights",), self.level_weights, "weights with a positive sum")])
        return self


if TYPE_CHECKING:  # the static view of generated tables: see FaultTable
    class DacmpSettings(_DacmpChecks, _dacmp.DacmpSettings, frozen=True): ...  # type: ignore[misc]
    class ApfSettings(Table, _apf.ApfSettings, frozen=True): ...  # type: ignore[misc]
else:
    DacmpSettings = table_of(_dacmp.DacmpSettings, "DacmpSettings", __name__, base=_DacmpChecks)
    # Not in [planner.apf]: min_separation_m is [safety]'s (the simulation passes it; the invariant
    # checkers read it too), and threat_margin_m is not a scenario setting (its default holds).
    ApfSettings = table_of(_apf.ApfSettings, "ApfSettings", __name__, exclude=("min_separation_m", "threat_margin_m"))
