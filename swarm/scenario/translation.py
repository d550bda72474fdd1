"""Pydantic's validation errors in our words: one :class:`~swarm.errors.ScenarioError` per
problem, naming the document's key path, what was found and what was expected, and the first of
them in document order (pydantic only knows field order), with every problem in its ``.all``.

Problems come from pydantic (a missing key, a wrong type, a bound) and from the tables' own
checks (:class:`~swarm.scenario.fields.Invalid`, which may carry several). A location is followed
through the model classes from the root table (:class:`~swarm.scenario.model.Scenario`) to find
the field's 'expected' words (its ``description``).
"""

from __future__ import annotations

import difflib
import types
from typing import Annotated, Any, NamedTuple, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from swarm.errors import ScenarioError
from swarm.scenario.fields import Invalid
from swarm.scenario.generated import FAULT_TABLES
from swarm.scenario.positions import document_position, found_words, key_path, value_at

__all__ = ["first_error"]


class _Issue(NamedTuple):
    path: tuple[Any, ...]  # document path: list indices as ints, no pydantic union tags
    found: str
    expected: str
    hint: str = ""


def _unwrap(tp: Any) -> Any:
    """Strip Annotated[...] and Optional[...] to reach the type that matters."""
    while True:
        origin = get_origin(tp)
        if origin is Annotated:
            tp = get_args(tp)[0]
        elif origin in (Union, types.UnionType) and type(None) in get_args(tp):
            rest = [a for a in get_args(tp) if a is not type(None)]
            tp = rest[0] if len(rest) == 1 else Union[tuple(rest)]  # noqa: UP007 (a union made at run time)
        else:
            return tp


class _Where(NamedTuple):
    path: tuple[Any, ...]
    field_description: str | None  # of the deepest field the location reached
    table: type[BaseModel] | None  # the deepest model reached (for unknown keys)


def _resolve(root: type[BaseModel], loc: tuple[Any, ...]) -> _Where:
    """Follow a pydantic location through the model classes from ``root``: the document path
    (without the fault-kind tag pydantic inserts), and the field and table it points at."""
    tp: Any = root
    path: list[Any] = []
    description: str | None = None
    table: type[BaseModel] | None = None
    for part in loc:
        tp = _unwrap(tp)
        if isinstance(tp, type) and issubclass(tp, BaseModel):
            table = tp
            field = tp.model_fields.get(part) if isinstance(part, str) else None
            if field is not None:
                description = field.description
                tp = field.annotation
            else:
                tp = None
            path.append(part)
            continue
        origin = get_origin(tp)
        if origin in (list, tuple):
            tp = get_args(tp)[0]
        elif origin is dict:
            tp = get_args(tp)[1]
        elif origin in (Union, types.UnionType) and isinstance(part, str) and part in FAULT_TABLES:
            tp = FAULT_TABLES[part]  # the tag is pydantic's, not a key of the document
            continue
        else:
            tp = None
        path.append(part)
    return _Where(tuple(path), description, table)


def _issues(root: type[BaseModel], err: Any, doc: Any) -> list[_Issue]:
    """Turn one pydantic error into our words (our own checks may carry several problems)."""
    kind, loc, ctx, value = err["type"], tuple(err["loc"]), err.get("ctx") or {}, err.get("input")
    if kind == "value_error" and isinstance(ctx.get("error"), Invalid):
        out = []
        for problem in ctx["error"].problems:
            where = _resolve(root, loc + problem.path)
            found = problem.found or found_words(value_at(doc, where.path, problem.value))
            out.append(_Issue(where.path, found, problem.expected, problem.hint))
        return out

    # "[key]": pydantic's marker for a dict key that failed validation.
    if len(loc) >= 2 and loc[-1] == "[key]" and kind != "extra_forbidden":
        where = _resolve(root, loc[:-1])
        return [_Issue(where.path, f"the key {loc[-2]!r}", "a name (keys are strings)")]
    where = _resolve(root, loc)
    expected = where.field_description or err["msg"]
    if kind == "missing" and where.path and isinstance(where.path[-1], int):
        # a tuple (a [sender, receiver] pair) with too few items: show the whole pair
        return [_Issue(where.path[:-1], found_words(value_at(doc, where.path[:-1], None)), expected)]
    if kind == "missing":
        return [_Issue(where.path, "nothing (the key is missing)", expected)]
    if kind == "invalid_key":
        return [_Issue(where.path, f"the key {where.path[-1]!r}", "keys that are strings")]
    if kind == "extra_forbidden":
        unknown = where.path[-1]
        valid = list(where.table.model_fields) if where.table else []
        prefix = key_path(where.path[:-1])
        close = difflib.get_close_matches(str(unknown), valid, n=1)
        hint = f"did you mean {close[0]!r}?" if close else f"valid keys: {', '.join(valid)}"
        table_words = f"[{prefix}]" if prefix else "the top level"
        return [_Issue(where.path, f"unknown key {unknown!r}", f"a key that {table_words} accepts", hint)]
    if kind in ("model_type", "model_attributes_type") and where.path and isinstance(where.path[-1], int):
        return [_Issue(where.path, found_words(value), "a table")]  # an entry of an array of tables
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        tag = value.get("kind") if isinstance(value, dict) else None
        found = found_words(tag) if kind == "union_tag_invalid" else "nothing (the key is missing)"
        close = difflib.get_close_matches(str(tag), list(FAULT_TABLES), n=1) if isinstance(tag, str) else []
        return [_Issue((*where.path, "kind"), found, f"one of: {', '.join(FAULT_TABLES)}",
                       f"did you mean {close[0]!r}?" if close else "")]
    return [_Issue(where.path, found_words(value), expected)]


def first_error(exc: ValidationError, doc: dict[str, Any], source: str, root: type[BaseModel]) -> ScenarioError:
    """The problem a reader meets first in document ``doc`` (from ``source``), which failed to
    validate as ``root`` with ``exc``; every problem found is in its ``.all``."""
    issues = [issue for err in exc.errors(include_url=False) for issue in _issues(root, err, doc)]
    # Stable: among issues at one position, pydantic's (field) order decides.
    ordered = [issue for _i, issue in sorted(enumerate(issues), key=lambda pair: (document_position(doc, pair[1].path), pair[0]))]
    errors = [ScenarioError(source, key_path(i.path), i.found, i.expected, i.hint) for i in ordered]
    first = errors[0]
    first.all = errors
    return first
