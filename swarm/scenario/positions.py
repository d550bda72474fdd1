"""Words and positions for scenario errors: how a found value is described ("-3.0 (float)"),
how a document path is written ("uavs[2].x_m"), and where a path sits in the document as written
(so the first problem reported is the first one a reader meets in the file)."""

from __future__ import annotations

import datetime as _dt
from typing import Any

_TOML_TYPES: tuple[tuple[type, str], ...] = (
    (bool, "boolean"),  # before int: bool is an int in Python
    (int, "integer"),
    (float, "float"),
    (str, "string"),
    (list, "array"),
    (tuple, "array"),
    (dict, "table"),
    (_dt.datetime, "datetime"),  # before date: a datetime is a date
    (_dt.date, "date"),
    (_dt.time, "time"),
    (type(None), "nothing"),
)


def found_words(value: Any) -> str:
    """The offending value and its TOML type, e.g. "-3.0 (float)"."""
    kind = next((name for cls, name in _TOML_TYPES if isinstance(value, cls)), type(value).__name__)
    try:
        text = repr(value)
    except Exception:  # a repr that fails must not hide the real error
        text = f"<{type(value).__name__}>"
    if len(text) > 80:
        text = text[:77] + "..."
    return f"{text} ({kind})"


def key_path(path: tuple[Any, ...]) -> str:
    """('uavs', 2, 'x_m') -> 'uavs[2].x_m'; a name with a dot is quoted, as ``--set`` reads it:
    ('planner', 'options_for', 'pkg.mod:C', 'k') -> 'planner.options_for."pkg.mod:C".k'."""
    out = ""
    for part in path:
        if isinstance(part, int) and not isinstance(part, bool):
            out += f"[{part}]"
        else:
            text = f'"{part}"' if "." in str(part) else str(part)
            out += f".{text}" if out else text
    return out


def value_at(doc: Any, path: tuple[Any, ...], default: Any) -> Any:
    """The value at a path of the document as written, or ``default`` if it is not there."""
    node = doc
    for part in path:
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            node = node[part]
        else:
            return default
    return node


def document_position(doc: Any, path: tuple[Any, ...]) -> tuple[int, ...]:
    """Where a path sits in the document, for ordering: the index of each key in its table
    (a missing key counts as after the table's last key) and each list index."""
    position: list[int] = []
    node = doc
    for part in path:
        if isinstance(node, dict):
            keys = list(node)
            if part in keys:
                position.append(keys.index(part))
                node = node[part]
                continue
            position.append(len(keys))
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            position.append(part)
            node = node[part]
            continue
        break
    return tuple(position)
