"""The building blocks of every scenario table, and the generator of tables from dataclasses.

* strict value types (:data:`Num`, :data:`Int`, :data:`Bool`, :data:`Str`, :data:`NumOrInf`)
  and fields whose ``description`` is the 'expected' words of an error (:func:`num_field`,
  :func:`int_field`, :func:`table_field`);
* :class:`Problem` and :class:`Invalid`: what a check that needs more than one field raises
  (:func:`raise_if`), so the loader reports the first problem in document order
  (:mod:`swarm.scenario.translation`);
* :class:`Table`, the base of every table (frozen, strict, no unknown keys);
* :func:`table_of`: a table generated from one of the simulator's dataclasses, with its fields,
  defaults and the bounds of its field metadata (:mod:`swarm.scenario.generated` uses it).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import types
import typing
from collections.abc import Callable
from typing import Annotated, Any, Literal, NamedTuple, Union, get_args, get_origin

from pydantic import AllowInfNan, BaseModel, ConfigDict, Field, Strict, create_model

from swarm.scenario.positions import found_words, key_path

__all__ = ["Bool", "Int", "Invalid", "Num", "NumOrInf", "Problem", "Str", "Table", "fmt", "int_field", "num_field",
           "raise_if", "table_field", "table_of"]

# --- value types -------------------------------------------------------------------------
# Strict scalars: a TOML integer is fine where a float is wanted (pydantic's strict float takes
# ints), but a string ("fast") or a boolean (true) never silently becomes a number, and a float
# never becomes an integer. Infinity and NaN are refused everywhere (model config) except where
# a field says otherwise (NumOrInf).
Num = Annotated[float, Strict()]
Int = Annotated[int, Strict()]
Bool = Annotated[bool, Strict()]
Str = Annotated[str, Strict()]
# A float that may be infinite (TOML can write `inf`): the radio's range_m and sync_horizon_m.
NumOrInf = Annotated[float, Strict(), AllowInfNan(True)]


def fmt(x: float) -> str:
    """A bound or value as a person would write it: 50000 rather than 50000.0."""
    if isinstance(x, float) and x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def _range_words(noun: str, gt: float | None, ge: float | None, lt: float | None, le: float | None) -> str:
    low = (f"({fmt(gt)}", f"> {fmt(gt)}") if gt is not None else (f"[{fmt(ge)}", f">= {fmt(ge)}") if ge is not None else None
    high = (f"{fmt(lt)})", f"< {fmt(lt)}") if lt is not None else (f"{fmt(le)}]", f"<= {fmt(le)}") if le is not None else None
    if low and high:
        return f"{noun} in {low[0]}, {high[0]}"
    if low or high:
        return f"{noun} {(low or high)[1]}"  # type: ignore[index]
    return noun


def field_bounds(source: type, name: str, noun: str) -> tuple[str, Callable[[Any], bool]]:
    """The bounds of the dataclass field ``name`` of ``source`` (its metadata ``gt``, ``ge``,
    ``lt``, ``le``, as a scenario table checks them): the words of an error (``noun`` in [lo,
    hi]) and the test of a number against them."""
    meta = next(f.metadata for f in dataclasses.fields(source) if f.name == name)
    gt, ge, lt, le = (meta.get(k) for k in ("gt", "ge", "lt", "le"))

    def within(v: Any) -> bool:
        return (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                and (gt is None or v > gt) and (ge is None or v >= ge) and (lt is None or v < lt)
                and (le is None or v <= le))

    return _range_words(noun, gt, ge, lt, le), within


def num_field(default: Any = ..., *, gt: float | None = None, ge: float | None = None, lt: float | None = None,
              le: float | None = None, note: str = "", optional: bool = False) -> Any:
    """A float field whose ``description`` is the human 'expected' text used in errors."""
    words = _range_words("a number", gt, ge, lt, le)
    if note:
        words += f" ({note})"
    if optional:
        words += ", or leave it out"
    return Field(default, gt=gt, ge=ge, lt=lt, le=le, description=words)


def int_field(default: Any = ..., *, ge: int | None = None, le: int | None = None, note: str = "") -> Any:
    """An integer field, described as :func:`num_field` describes a float."""
    words = _range_words("a whole number", None, ge, None, le)
    if note:
        words += f" ({note})"
    return Field(default, ge=ge, le=le, description=words)


def table_field(factory: Any, name: str) -> Any:
    """A sub-table field ``[name]`` whose default is the table with its own defaults."""
    return Field(default_factory=factory, description=f"a table [{name}]")


# --- problems found by our own checks ----------------------------------------------------
class Problem(NamedTuple):
    """One thing wrong, found by a cross-field check. ``path`` is relative to the model that
    found it; pydantic prefixes the model's own location when it reports the error. ``value`` is
    the validated value; the error shows the document's own value where there is one (``60000``
    as written, not ``60000.0``), or ``found`` verbatim if given."""

    path: tuple[str | int, ...]
    value: Any
    expected: str
    hint: str = ""
    found: str | None = None


class Invalid(ValueError):
    """Raised inside validators with every problem found, so the loader can report the first one
    in document order (pydantic itself only knows field order). A ValueError so that pydantic
    wraps it into its ValidationError like any other validator failure."""

    def __init__(self, problems: list[Problem]):
        self.problems = problems
        super().__init__("; ".join(f"{key_path(p.path)}: found {p.found or found_words(p.value)}; expected {p.expected}"
                                   for p in problems))


def raise_if(problems: list[Problem]) -> None:
    if problems:
        raise Invalid(problems)


class Table(BaseModel):
    """The base of every scenario table: frozen, strict, no unknown keys, no infinity or NaN."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


# --- tables generated from the simulator's dataclasses ---------------------------------------
# Metadata a dataclass field may carry: bounds (gt, ge, lt, le), a note for the error words, the
# bounds of each item of an array (each), inf (a number that may be infinite: TOML can write
# `inf`), the least length of a string (min_length), and the whole 'expected' text of a field
# that is not a number (a Literal's is "one of: ..." unless given). Anything else is a typo in
# the dataclass and fails at import.
_METADATA_KEYS = frozenset({"gt", "ge", "lt", "le", "note", "each", "inf", "min_length", "expected"})


def _strict_type(tp: Any, each: dict[str, Any] | None = None, inf: bool = False) -> Any:
    """The strict scenario type of a dataclass annotation; tuples are TOML arrays, a Literal is
    itself.

    The types are built at run time, so ``list[x]`` and ``tuple[x, y]`` are spelled as the
    ``types.GenericAlias`` they evaluate to (which mypy reads as a value, not a type)."""
    if tp is float and inf:
        return NumOrInf
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


def _field_from(f: dataclasses.Field[Any], tp: Any) -> tuple[Any, Any]:
    """``(type, FieldInfo)`` of the scenario field for dataclass field ``f`` (annotation ``tp``).

    No default: required. ``math.inf``: absent from the scenario (``None``, "leave it out"), as a
    fault's ``end_s``. Numbers get their ``description`` (the 'expected' words of an error) from
    :func:`num_field` / :func:`int_field`, booleans "true or false", a Literal "one of: ...", other
    fields from ``expected``."""
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
        return annotation, num_field(default, **bounds, note=note, optional=default is None)
    if value_type is int:
        if set(bounds) - {"ge", "le"}:
            raise TypeError(f"{f.name}: a whole number takes only ge / le bounds")
        return annotation, int_field(default, **bounds, note=note)
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


def table_of(source: type, name: str, module: str, *, base: type[Table] = Table, exclude: tuple[str, ...] = (),
             order: list[str] | None = None, extra: dict[str, Any] | None = None) -> type[Table]:
    """A frozen, strict pydantic model named ``name`` with the fields of dataclass ``source``
    (less ``exclude``), in ``order`` (default: the dataclass's), plus ``extra`` definitions
    (``name: (type, default)``, placed by ``order``). ``base`` adds validators. ``module``: the
    module that binds the table to ``name`` (so that pickle finds it: sweeps ship scenarios to
    their workers)."""
    hints = typing.get_type_hints(source)
    defs: dict[str, Any] = {f.name: _field_from(f, hints[f.name])
                            for f in dataclasses.fields(source) if f.name not in exclude}
    defs.update(extra or {})
    order = order if order is not None else list(defs)
    if sorted(order) != sorted(defs):
        raise TypeError(f"{name}: the order {order} does not list exactly the fields {sorted(defs)}")
    return create_model(name, __base__=base, __module__=module, __doc__=source.__doc__,
                        **{k: defs[k] for k in order})
