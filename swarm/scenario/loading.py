"""Loading scenarios: built-in names and TOML files, ``--set`` overrides, and the translation
of pydantic's validation errors into one :class:`~swarm.errors.ScenarioError` that names the
file, the key path, what was found and what was expected.

No other exception escapes the loader: the CLI prints ``str(err)`` and nothing else, so the
message must stand on its own.
"""

from __future__ import annotations

import difflib
import os
import re
import tomllib
import types
from collections.abc import Iterable, Mapping
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, NamedTuple, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from swarm.errors import ScenarioError
from swarm.scenario.model import _FAULT_CLASSES, DEFAULT_UAV_TYPES, FAULT_KINDS, PlannerSettings, Scenario, _Invalid
from swarm.scenario.positions import document_position, found_words, key_path, value_at
from swarm.scenario.trust import allowed, permits, refusal

# --- loading -------------------------------------------------------------------------------
_BUILTIN_PACKAGE = "swarm.scenario.builtin"


def builtin_scenarios() -> list[str]:
    """Names of the scenarios shipped with the package, sorted."""
    folder = resources.files(_BUILTIN_PACKAGE)
    return sorted(p.name[: -len(".toml")] for p in folder.iterdir() if p.name.endswith(".toml"))


def load_scenario(ref: str | os.PathLike[str], *, planner: str | None = None,
                  allow_planner_imports: bool | Iterable[str] = False,
                  overrides: Mapping[str, Any] | None = None, run_duration_s: float | None = None) -> Scenario:
    """Load a built-in scenario by name or a TOML file by path.

    ``planner``: run this planner instead of the one the file names (as ``--planner``: the
    file's ``[planner.options]`` move to ``[planner.options_for.<its planner>]``, see
    :func:`switch_planner`); the file's own planner is then never imported.
    ``allow_planner_imports``: a ``module:Class`` named in the file is imported (to check it)
    only if allowed here: ``True``, or its name among these (``planner`` always is); see
    :mod:`swarm.scenario.trust`. ``overrides``: dotted keys set in the document before it is
    validated (``--set``), as :func:`apply_overrides` does after, so that the document is judged
    once, as the user wrote it with those changes (``--planner X --set planner.surveillance=false``
    for a planner that only searches). ``run_duration_s`` (``--duration``): the document is
    judged as run for that long, with the overrides (``--set dt_s=1e-5 --duration 1`` is judged
    on the 1 s run; late joiners against the scenario's own end); the scenario returned keeps
    its own ``duration_s`` (``Simulation(..., duration_s=)`` then runs it for the shorter time)."""
    if not isinstance(ref, (str, os.PathLike)):
        raise ScenarioError("", "", found_words(ref), _file_expected())
    source = os.fspath(ref)
    if not isinstance(source, str):  # a bytes path
        raise ScenarioError(repr(source), "", found_words(source), _file_expected())
    path = Path(source)
    try:
        is_file = path.is_file()
    except (OSError, ValueError):  # e.g. a name too long, an embedded NUL
        is_file = False
    if is_file:
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ScenarioError(source, "", "a file that is not UTF-8 text", "a TOML document") from None
        except OSError as exc:
            raise ScenarioError(source, "", f"a file that cannot be read ({exc.strerror or exc})", _file_expected()) from None
        return scenario_from_toml(text, source, planner=planner, allow_planner_imports=allow_planner_imports,
                                  overrides=overrides, run_duration_s=run_duration_s)
    if isinstance(ref, str) and ref in builtin_scenarios():
        text = resources.files(_BUILTIN_PACKAGE).joinpath(f"{ref}.toml").read_text(encoding="utf-8")
        return scenario_from_toml(text, ref, planner=planner, allow_planner_imports=allow_planner_imports,
                                  overrides=overrides, run_duration_s=run_duration_s)
    found = "no such file" if not path.exists() else "something that is not a file"
    raise ScenarioError(source, "", found, _file_expected())


def _file_expected() -> str:
    return f"a path to an existing .toml file or a built-in name ({', '.join(builtin_scenarios())})"


def scenario_from_toml(text: str, source: str, *, planner: str | None = None,
                       allow_planner_imports: bool | Iterable[str] = False,
                       overrides: Mapping[str, Any] | None = None, run_duration_s: float | None = None) -> Scenario:
    """A scenario from TOML text (``planner``, ``allow_planner_imports``, ``overrides``,
    ``run_duration_s``: see :func:`load_scenario`)."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(source, "", f"invalid TOML ({exc})", "a TOML document") from None
    if planner is not None:
        switch_planner(doc, planner)
    _override(doc, overrides or {}, source)
    allow = allowed(allow_planner_imports, planner)
    if run_duration_s is None:
        return parse_scenario(doc, source, allow_planner_imports=allow)
    own = doc.get("duration_s", Scenario.model_fields["duration_s"].default)
    if isinstance(own, bool) or not isinstance(own, (int, float)) or not own > 0:
        return parse_scenario(doc, source, allow_planner_imports=allow)  # (says what is wrong with it)
    run = parse_scenario({**doc, "duration_s": run_duration_s}, source, truncated=True, scenario_duration_s=float(own),
                         allow_planner_imports=allow)
    return run.model_copy(update={"duration_s": float(own)})  # valid as run; kept with its own end


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
        raise ScenarioError(source, _PLANNER_NAME, *refusal(name))
    context = {"truncated": truncated, "scenario_duration_s": scenario_duration_s, "allow_planners": allow}
    try:
        return Scenario.model_validate(data, context=context)
    except ValidationError as exc:
        # from None: our message says everything; pydantic's would only repeat it less clearly.
        raise _first_error(exc, doc, source) from None


def _default_name(source: str) -> str:
    if not source or source.startswith("<"):
        return "scenario"
    return Path(source).stem or "scenario"


# --- overrides -----------------------------------------------------------------------------
def apply_overrides(scenario: Scenario, overrides: Mapping[str, Any], *, truncated: bool = False,
                    scenario_duration_s: float | None = None,
                    allow_planner_imports: bool | Iterable[str] = False) -> Scenario:
    """A new scenario with dotted keys replaced, e.g. ``{"radio.loss_base": 0.3}`` or
    ``{"uavs[0].x_m": 100}``; the result is validated as a whole. ``truncated``: the
    ``duration_s`` override shortens the run (``--duration``): everything is judged against
    it, except late joiners, which must join before ``scenario_duration_s``, the scenario's
    own end, if given (not judged otherwise); see :func:`parse_scenario`.

    ``planner.name`` is applied first and replaces the planner as :func:`switch_planner` does
    (its options follow it), so ``planner.options.KEY`` overrides are the new planner's.
    ``allow_planner_imports``: as :func:`parse_scenario`; the scenario's own planner stays
    allowed (it was when ``scenario`` was validated), a new ``module:Class`` needs allowing."""
    source = f"{scenario.name} (with overrides)"
    doc = scenario._document()
    _override(doc, overrides, source)
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


_PLANNER_NAME = "planner.name"


def _override(doc: dict[str, Any], overrides: Mapping[str, Any], source: str) -> None:
    """Set dotted keys in a scenario document (in place), ``planner.name`` first (it replaces
    the planner, and its options follow it: :func:`switch_planner`). The document is edited as
    merged with the built-in types (docs/scenarios.md): one field of A or B changes that field
    of Table 1's type, it does not make a table of one field."""
    for dotted, value in sorted(overrides.items(), key=lambda item: item[0] != _PLANNER_NAME):
        if dotted == _PLANNER_NAME:
            switch_planner(doc, value)
            continue
        parts = _split_key(dotted, source)
        if len(parts) > 2 and parts[0] == "uav_types" and parts[1] in DEFAULT_UAV_TYPES:
            types = doc.setdefault("uav_types", {})
            if isinstance(types, dict) and parts[1] not in types:
                types[parts[1]] = DEFAULT_UAV_TYPES[parts[1]].model_dump()
        _set_path(doc, dotted, value, source)


def switch_planner(doc: dict[str, Any], name: Any) -> None:
    """Make ``name`` the planner of a scenario document (in place). Options follow their
    planner: when the planner changes, ``[planner.options]`` (written for the old one) move to
    ``[planner.options_for.<old name>]``, where a later switch back finds them; the new planner
    is built with its own ``options_for`` entry, if any (``PlannerSettings.options_of``)."""
    table = doc.get("planner")
    if table is None:
        table = doc["planner"] = {}
    if not isinstance(table, dict):
        return  # not a table: validation says so
    old = table.get("name", _DEFAULT_PLANNER)
    table["name"] = name
    if name == old or not isinstance(old, str):
        return
    options = table.pop("options", None)
    if isinstance(options, dict) and options:
        others = table.get("options_for")
        if others is None:
            others = table["options_for"] = {}
        if isinstance(others, dict):
            theirs = others.get(old)
            others[old] = {**options, **theirs} if isinstance(theirs, dict) else options


_DEFAULT_PLANNER = str(PlannerSettings.model_fields["name"].default)

# One segment of a dotted key: a bare name or a "quoted" one (for names with dots, such as
# planner.options_for."pkg.mod:Class".key), then any [n] indices.
_SEGMENT = re.compile(r'(?:"([^"]*)"|([^."\[\]]+))((?:\[\d+\])*)(?:\.|$)')


def _split_key(dotted: str, source: str) -> list[str | int]:
    """'uavs[0].x_m' -> ['uavs', 0, 'x_m']; 'a."b.c".d' -> ['a', 'b.c', 'd']."""
    parts: list[str | int] = []
    pos = 0
    while pos < len(dotted) or not parts:
        match = _SEGMENT.match(dotted, pos)
        if match is None or match.end() == pos or (match.end() == len(dotted) and dotted.endswith(".")):
            raise ScenarioError(source, dotted, f"the key {dotted!r}",
                                'a dotted key like radio.loss_base, uavs[0].x_m or planner.options_for."pkg.mod:Class".key')
        parts.append(match.group(1) if match.group(1) is not None else match.group(2))
        parts.extend(int(i) for i in re.findall(r"\d+", match.group(3)))
        pos = match.end()
    return parts


def _set_path(doc: dict[str, Any], dotted: str, value: Any, source: str) -> None:
    parts = _split_key(dotted, source)
    node: Any = doc
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        here = key_path(tuple(parts[: depth + 1]))
        if isinstance(part, int):
            if not isinstance(node, list):
                raise ScenarioError(source, key_path(tuple(parts[:depth])), found_words(node),
                                    "an array (it is indexed with [n])")
            if not part < len(node):
                raise ScenarioError(source, here, f"index {part}", f"an index from 0 to {len(node) - 1}")
        elif not isinstance(node, dict):
            raise ScenarioError(source, key_path(tuple(parts[:depth])), found_words(node), "a table (it has keys below it)")
        elif part not in node and not last:
            # An unknown table: create it so that validation reports the unknown key with a hint.
            node[part] = {}
        if last:
            node[part] = value
        else:
            if node[part] is None:
                node[part] = {}
            node = node[part]


def parse_assignment(text: str) -> tuple[str, Any]:
    """Parse ``key=value`` from the command line; the value is read as a TOML value
    (``0.3``, ``true``, ``[1, 2]``, ``"x"``) and otherwise taken as a bare string."""
    key, eq, raw = text.partition("=")
    key = key.strip()
    if not eq or not key:
        raise ScenarioError("--set", key, repr(text), "key=value, e.g. radio.loss_base=0.3")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key, value


# --- error translation ---------------------------------------------------------------------
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


def _resolve(loc: tuple[Any, ...]) -> _Where:
    """Follow a pydantic location through the model classes: the document path (without the
    fault-kind tag pydantic inserts), and the field and table it points at."""
    tp: Any = Scenario
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
        elif origin in (Union, types.UnionType) and isinstance(part, str) and part in _FAULT_CLASSES:
            tp = _FAULT_CLASSES[part]  # the tag is pydantic's, not a key of the document
            continue
        else:
            tp = None
        path.append(part)
    return _Where(tuple(path), description, table)


def _issues(err: Any, doc: Any) -> list[_Issue]:
    """Turn one pydantic error into our words (our own checks may carry several problems)."""
    kind, loc, ctx, value = err["type"], tuple(err["loc"]), err.get("ctx") or {}, err.get("input")
    if kind == "value_error" and isinstance(ctx.get("error"), _Invalid):
        out = []
        for problem in ctx["error"].problems:
            where = _resolve(loc + problem.path)
            found = problem.found or found_words(value_at(doc, where.path, problem.value))
            out.append(_Issue(where.path, found, problem.expected, problem.hint))
        return out

    # "[key]": pydantic's marker for a dict key that failed validation.
    if len(loc) >= 2 and loc[-1] == "[key]" and kind != "extra_forbidden":
        where = _resolve(loc[:-1])
        return [_Issue(where.path, f"the key {loc[-2]!r}", "a name (keys are strings)")]
    where = _resolve(loc)
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
        return [_Issue((*where.path, "kind"), found, f"one of: {', '.join(FAULT_KINDS)}")]
    return [_Issue(where.path, found_words(value), expected)]






def _first_error(exc: ValidationError, doc: dict[str, Any], source: str) -> ScenarioError:
    """The problem a reader meets first in the document; every problem found is in its ``.all``."""
    issues = [issue for err in exc.errors(include_url=False) for issue in _issues(err, doc)]
    # Stable: among issues at one position, pydantic's (field) order decides.
    ordered = [issue for _i, issue in sorted(enumerate(issues), key=lambda pair: (document_position(doc, pair[1].path), pair[0]))]
    errors = [ScenarioError(source, key_path(i.path), i.found, i.expected, i.hint) for i in ordered]
    first = errors[0]
    first.all = errors
    return first
