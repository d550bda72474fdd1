"""Dotted keys (``--set key=value``): how an override changes a scenario document, before the
document is validated as a whole (:func:`swarm.scenario.parse_scenario`).

``uavs[0].x_m``, ``radio.loss_base``, ``planner.options_for."pkg.mod:Class".key``: a key is a
path of names and ``[n]`` indices (:func:`set_keys`); ``planner.name`` replaces the planner, and
its options follow it (:func:`switch_planner`); a value from the command line is read as a TOML
value (:func:`parse_assignment`).
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping
from typing import Any

from swarm.errors import ScenarioError
from swarm.scenario.positions import found_words, key_path
from swarm.scenario.tables import DEFAULT_UAV_TYPES, PlannerSettings

__all__ = ["PLANNER_NAME_KEY", "parse_assignment", "set_keys", "switch_planner"]

# The key that replaces the planner (its options follow it): applied before any other.
PLANNER_NAME_KEY = "planner.name"


def set_keys(doc: dict[str, Any], overrides: Mapping[str, Any], source: str) -> None:
    """Set dotted keys in a scenario document (in place), ``planner.name`` first (it replaces
    the planner, and its options follow it: :func:`switch_planner`). The document is edited as
    merged with the built-in types (docs/scenarios.md): one field of A or B changes that field
    of Table 1's type, it does not make a table of one field."""
    for dotted, value in sorted(overrides.items(), key=lambda item: item[0] != PLANNER_NAME_KEY):
        if dotted == PLANNER_NAME_KEY:
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
