"""Which planner code a scenario may make us import.

A scenario is data: it travels with papers and bug reports, is written by the test toolkit
(``reproducible()``), read back from run folders and shipped to sweep workers. A planner named
``package.module:Class`` is code: importing it runs the module. So a ``module:Class`` name is
imported only when the user allowed it:

* typed by the user: ``--planner module:Class`` on the command line, ``planner=`` (a name or a
  class) in a Python call, the planners of a sweep (``--planner a,b`` / ``planners=``);
* an explicit opt-in for what files name: ``--allow-planner-imports`` (``swarm run``,
  ``validate``, ``sweep``), ``allow_planner_imports=True`` in Python, or the environment
  variable ``SWARM_ALLOW_PLANNER_IMPORTS=1``.

Built-in names and entry-point names (``swarm.planners``: installing a package is the act of
trust) are always allowed. A refused name is never imported: the scenario fails validation
with one error naming the key ``planner.name`` and how to allow it.

The decision is made where the user acts (the CLI, the Python call) and travels as a value:
validation reads it from pydantic's context (:func:`swarm.scenario.parse_scenario`'s
``allow_planner_imports``), and a sweep's :class:`~swarm.experiments.sweep.RunSpec` carries it to
its workers, so a Dask worker (whose environment may differ) honours the caller's decision.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from typing import Literal

from agents.planners.registry import is_module_ref

__all__ = ["ALLOW_ENV", "ALLOW_FLAG", "Allowed", "allowed", "env_allows", "permits", "refusal"]

ALLOW_ENV = "SWARM_ALLOW_PLANNER_IMPORTS"
ALLOW_FLAG = "--allow-planner-imports"

# True: any module:Class; a frozenset: these names only (built-ins and entry points always).
Allowed = Literal[True] | frozenset[str]


def env_allows() -> bool:
    """``SWARM_ALLOW_PLANNER_IMPORTS`` is set to 1 (or true, yes, on)."""
    return os.environ.get(ALLOW_ENV, "").strip().lower() in {"1", "true", "yes", "on"}


def allowed(*parts: bool | str | Iterable[str] | None) -> Allowed:
    """The union of several allowances: ``True`` (anything), ``False``/``None`` (nothing), a
    planner name or names. The environment variable counts as ``True``."""
    names: set[str] = set()
    for part in parts:
        if part is True:
            return True
        if part is None or part is False:
            continue
        if isinstance(part, str):
            names.add(part)
        else:
            names.update(p for p in part if isinstance(p, str))
    return True if env_allows() else frozenset(names)


def permits(allow: bool | str | Iterable[str] | None, name: object) -> bool:
    """Whether planner ``name`` may be imported under ``allow``."""
    if not isinstance(name, str) or not is_module_ref(name):
        return True
    a = allowed(allow)
    return a is True or name in a


def refusal(name: str) -> tuple[str, str, str]:
    """``(found, expected, hint)`` of the error for a ``module:Class`` nobody allowed."""
    return (f"{name!r} (a module:Class: code, which a scenario may not import on its own)",
            "a built-in or entry-point planner (swarm list --planners), or a module:Class you allowed",
            f"type it yourself: --planner {name}; or trust the planners this file names: {ALLOW_FLAG} or "
            f"{ALLOW_ENV}=1; in Python: planner=... or allow_planner_imports=True")
