"""The list of fault kinds (filled by :func:`register`, once per kind) and what works on any
fault: its UAV names, its dict form, a schedule of faults.

``FAULT_KINDS`` is the one list: the scenario's ``[[faults]]`` tables, ``fault_from_dict``, the
error messages ("kind = one of: ...") and the checkers all read it. The built-in kinds register
when :mod:`faults` is imported, family by family (link, cuts, node, sensing, adversary); a kind
defined elsewhere (a user's, a test's) registers the same way.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any, TypeVar

from faults.base import FaultKind

# In registration order (the order error messages list them).
FAULT_KINDS: dict[str, type[FaultKind]] = {}

K = TypeVar("K", bound=type[FaultKind])


def register(cls: K) -> K:
    """Class decorator: add the fault kind ``cls`` (a frozen, keyword-only dataclass subclassing
    :class:`faults.base.FaultKind` with a ``kind`` tag) to :data:`FAULT_KINDS`."""
    kind = getattr(cls, "kind", None)
    if not isinstance(kind, str) or not kind.isidentifier():
        raise TypeError(f"{cls.__name__}: a fault kind needs a `kind` tag (a class variable, an identifier)")
    if not (dataclasses.is_dataclass(cls) and issubclass(cls, FaultKind)):
        raise TypeError(f"{cls.__name__}: a fault kind is a dataclass subclassing faults.base.FaultKind")
    old = FAULT_KINDS.get(kind)
    if old is not None and (old.__module__, old.__qualname__) != (cls.__module__, cls.__qualname__):
        raise ValueError(f"fault kind {kind!r} is already registered by {old.__module__}.{old.__qualname__}")
    FAULT_KINDS[kind] = cls
    return cls


def unregister(kind: str) -> None:
    """Remove a kind registered by :func:`register` (a test's own kind, when it is done)."""
    FAULT_KINDS.pop(kind, None)


def uav_names(f: Any) -> list[tuple[tuple[str | int, ...], str]]:
    """Every UAV name a fault refers to, with its path inside the fault (``("groups", 0, 1)``):
    what a scenario's validation and ``Simulation.add_fault`` check against the UAVs. By field
    name (``uav``, ``bridge``, ``as_uav``, ``uavs``, ``links``, ``groups``), so that a scenario's
    ``[[faults]]`` table, not an instance of the dataclass, is read the same way."""
    names: list[tuple[tuple[str | int, ...], str]] = []
    for key in ("uav", "bridge"):
        if hasattr(f, key):
            names.append(((key,), getattr(f, key)))
    as_uav = getattr(f, "as_uav", "")  # "" = a random member per frame
    if as_uav:
        names.append((("as_uav",), as_uav))
    for k, name in enumerate(getattr(f, "uavs", ())):
        names.append((("uavs", k), name))
    for k, pair in enumerate(getattr(f, "links", ())):
        for end, name in enumerate(pair):
            names.append((("links", k, end), name))
    for g, group in enumerate(getattr(f, "groups", ())):
        for k, name in enumerate(group):
            names.append((("groups", g, k), name))
    return names


def fault_to_dict(f: FaultKind) -> dict[str, Any]:
    d = asdict(f)  # type: ignore[call-overload]  # (every registered kind is a dataclass)
    for k, v in list(d.items()):
        if isinstance(v, float) and math.isinf(v):
            d[k] = None
    return {"kind": f.kind, **d}


def _tuples(v: Any) -> Any:
    """Arrays (lists) of a dict form as the tuples a frozen dataclass holds, nested."""
    return tuple(_tuples(x) for x in v) if isinstance(v, (list, tuple)) else v


def fault_from_dict(d: Mapping[str, Any]) -> FaultKind:
    """Inverse of :func:`fault_to_dict` (validated input, e.g. a scenario's ``[[faults]]``)."""
    d = dict(d)
    cls = FAULT_KINDS[d.pop("kind")]
    if d.get("end_s", 0.0) is None:
        d["end_s"] = math.inf
    return cls(**{k: _tuples(v) for k, v in d.items() if v is not None or k == "end_s"})


@dataclass
class FaultSchedule:
    """An ordered list of faults; what a run applied is recorded with it."""

    faults: list[FaultKind] = field(default_factory=list)

    def add(self, fault: FaultKind) -> None:
        self.faults.append(fault)

    def __iter__(self) -> Iterator[FaultKind]:
        return iter(self.faults)

    def __len__(self) -> int:
        return len(self.faults)

    def kinds(self) -> list[str]:
        return sorted({f.kind for f in self.faults})

    def to_list(self) -> list[dict[str, Any]]:
        return [fault_to_dict(f) for f in self.faults]
