"""Choosing a planner: built-in names, ``package.module:Class``, and entry points.

A scenario's ``[planner] name`` (or ``--planner``, or ``Simulation(planner=...)``) is one of:

* a built-in name (:data:`BUILTIN`: ``dacmp``, ``greedy`` and the reference planners);
* ``package.module:Class``: any class importable in the process that runs the simulation (on
  ``PYTHONPATH``; for a Dask cluster, on every worker's);
* a name registered by an installed distribution under the entry-point group
  ``swarm.planners`` (``[project.entry-points."swarm.planners"] mine = "pkg.mod:Class"``).

Each UAV gets its own instance. A class with a ``from_context(context, **options)`` class
method is built by it (it sees the :class:`PlannerContext`: what a planner may know before the
run); otherwise by ``Class(**options)``. ``options`` is the scenario's ``[planner.options]``
table; :func:`option_problems` checks it against the signature before anything runs, so a
wrong option is reported with its key path like any other scenario mistake.

Importing a ``module:Class`` runs that module's code, so *whether* to import one is the
caller's decision (a scenario file may not make it: :mod:`swarm.scenario.trust`). What is
imported is checked before anything in it is called: it must be a class (found without running
its module's ``__getattr__`` or descriptors) with a ``plan`` method, its ``from_context`` if any
a class method, and the options must fit its signature.

Every planner either surveils or says it does not, with a class attribute ``surveils``
(:func:`surveils_of`):

* ``True`` (and a class without the attribute): it decides itself when its UAV watches a
  target (``PlanView.surveillance`` tells it whether it may); ``dacmp`` does;
* ``"shared"``: it only searches, and with ``planner.surveillance = true`` each UAV's instance
  is wrapped in the one shared surveillance and handover logic
  (:class:`agents.planners.surveillance.SharedSurveillance`, DACMP's decision): ``greedy`` and
  the reference planners do;
* ``False``: it only searches and cannot watch: a scenario with ``planner.surveillance = true``
  is refused when it is validated (:func:`surveillance_problem`).
"""

from __future__ import annotations

import difflib
import importlib
import inspect
from collections.abc import Callable
from importlib.metadata import entry_points
from typing import Any, cast

from agents.planners.base import Planner, PlannerContext, PlannerError

__all__ = [
    "BUILTIN",
    "ENTRY_POINT_GROUP",
    "PlannerContext",
    "available_planners",
    "build_planner",
    "is_module_ref",
    "option_problems",
    "resolve_planner",
    "surveillance_problem",
    "surveils_of",
]

ENTRY_POINT_GROUP = "swarm.planners"

# Built-in planners by name: where their classes live (imported only when used).
BUILTIN: dict[str, str] = {
    "dacmp": "agents.planners.dacmp.planner:DacmpPlanner",
    # Not in the paper: DACMP with a search-mode spacing term (agents/planners/dacmp/spread.py).
    "dacmp-spread": "agents.planners.dacmp.spread:DacmpSpreadPlanner",
    "greedy": "agents.planners.greedy:GreedyPlanner",
    "lawnmower": "agents.planners.lawnmower:LawnmowerPlanner",
    "formation": "agents.planners.formation:FormationPlanner",
    "levy": "agents.planners.levy:LevyPlanner",
}


def is_module_ref(name: str) -> bool:
    """Whether a planner name is ``package.module:Class`` (code to import), not a built-in or an
    entry-point name."""
    return isinstance(name, str) and ":" in name and name not in BUILTIN


def _import(ref: str) -> type:
    """The planner class ``module:Class`` names, checked to be one before anything in it is
    called: importing the module runs its top-level code (the caller decides whether that is
    allowed), but nothing the module defines is called here. Raises :class:`PlannerError` for a
    module that is not found, a name that is not a class, or a class that is not a planner."""
    module_name, _, attr = ref.partition(":")
    if not module_name or not attr or not all(part.isidentifier() for part in (*module_name.split("."), *attr.split("."))):
        raise PlannerError(f"planner {ref!r}: expected package.module:Class (dotted Python names)")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise PlannerError(f"planner {ref!r}: cannot import module {module_name!r} ({exc}); "
                           f"is it on PYTHONPATH?") from None
    obj: Any = module
    for part in attr.split("."):
        # Static lookup: no descriptor, property or module __getattr__ of the user's code runs.
        obj = inspect.getattr_static(obj, part, None)
        if obj is None:
            raise PlannerError(f"planner {ref!r}: module {module_name!r} has no {attr!r}")
    if not inspect.isclass(obj):
        what = "a function" if inspect.isroutine(obj) else f"a {type(obj).__name__}"
        raise PlannerError(f"planner {ref!r}: {attr!r} is {what}, not a class; expected a planner class "
                           f"(a class with a plan(view) method)")
    if not callable(inspect.getattr_static(obj, "plan", None)):
        raise PlannerError(f"planner {ref!r}: {obj.__name__} is not a planner (it has no plan(view) method)")
    maker = inspect.getattr_static(obj, "from_context", None)
    if maker is not None and not isinstance(maker, (classmethod, staticmethod)):
        raise PlannerError(f"planner {ref!r}: {obj.__name__}.from_context is not a class method")
    return obj


def _entry_points() -> dict[str, str]:
    return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_planners() -> dict[str, str]:
    """Every planner a name can choose: ``{name: "module:Class"}``, built-ins first."""
    found = dict(BUILTIN)
    for name, value in sorted(_entry_points().items()):
        found.setdefault(name, value)
    return found


def resolve_planner(name: str) -> type:
    """The planner class a name stands for (see the module docstring)."""
    if not isinstance(name, str) or not name:
        raise PlannerError(f"planner {name!r}: expected a built-in name, module:Class or an entry-point name")
    if name in BUILTIN:
        return _import(BUILTIN[name])
    if ":" in name:
        return _import(name)
    registered = _entry_points()
    if name in registered:
        return _import(registered[name])
    known = list(available_planners())
    close = difflib.get_close_matches(name, known, n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise PlannerError(f"unknown planner {name!r}; expected one of {', '.join(known)}, or module:Class{hint}")


def _maker(cls: type) -> tuple[Callable[..., object], bool]:
    """The callable that builds an instance, and whether it takes the context first."""
    maker: Callable[..., object] | None = getattr(cls, "from_context", None)
    return (maker, True) if maker is not None else (cls, False)


def option_problems(name: str, options: dict[str, Any]) -> list[tuple[str, str, str]]:
    """``(key, found, expected)`` for each option the planner's constructor does not take or
    lacks (checked against its signature; nothing is built)."""
    cls = resolve_planner(name)
    maker, with_context = _maker(cls)
    try:
        params = list(inspect.signature(maker).parameters.values())
    except (TypeError, ValueError):  # no signature to read (a class written in C): it takes no options we can check
        return [(key, f"option {key!r}", f"no options (the constructor of planner {name!r} has no signature to check "
                 f"them against)") for key in options]
    if with_context and params:
        params = params[1:]
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return []
    named = {p.name: p for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    problems = [(p.name, f"a positional-only parameter {p.name!r} without a default",
                 f"a constructor planner {name!r} can be built with by keyword (options are passed by name)")
                for p in params if p.kind is p.POSITIONAL_ONLY and p.default is p.empty]
    for key in options:
        if key not in named:
            close = difflib.get_close_matches(key, list(named), n=1)
            valid = f"did you mean {close[0]!r}?" if close else (f"it takes: {', '.join(named)}" if named else "it takes none")
            problems.append((key, f"unknown option {key!r}", f"an option of planner {name!r} ({valid})"))
    for key, p in named.items():
        if p.default is p.empty and key not in options and key != "name":
            problems.append((key, "nothing (the option is missing)", f"a value: planner {name!r} requires it"))
    return problems


def surveils_of(cls: type) -> bool | str:
    """What a planner class declares about surveillance: ``True``, ``False`` or ``"shared"``
    (module docstring); a class that declares nothing counts as ``True``."""
    value = getattr(cls, "surveils", True)
    if value is True or value is False or value == "shared":
        return value
    raise PlannerError(f"planner class {cls.__name__}: surveils = {value!r}; expected True (it watches targets "
                       f"itself), False (search only) or \"shared\" (the shared surveillance logic)")


def surveillance_problem(name: str) -> str | None:
    """Why planner ``name`` cannot run with ``planner.surveillance = true`` (None: it can)."""
    if surveils_of(resolve_planner(name)) is not False:
        return None
    return (f"planner {name!r} only searches (its class declares surveils = False): set "
            f"planner.surveillance = false (in the scenario, or --set planner.surveillance=false beside "
            f"--planner), choose a planner that "
            f"watches targets (dacmp, greedy, lawnmower, formation, levy), or declare surveils = \"shared\" "
            f"in the class to use the shared surveillance logic (docs/planners.md)")


def build_planner(name: str, options: dict[str, Any], context: PlannerContext) -> Planner:
    """One UAV's planner instance: with ``planner.surveillance = true`` (``context.settings``), a
    planner that declares ``surveils = "shared"`` comes wrapped in the shared surveillance logic."""
    cls = resolve_planner(name)
    problems = option_problems(name, options)
    if problems:  # checked before anything of the class is called
        key, found, expected = problems[0]
        raise PlannerError(f"planner {name!r}: option {key}: found {found}; expected {expected}")
    maker, with_context = _maker(cls)
    try:
        planner = maker(context, **options) if with_context else maker(**options)
    except PlannerError:
        raise
    except Exception as exc:
        raise PlannerError(f"planner {name!r} could not be built for UAV {context.name}: "
                           f"{type(exc).__name__}: {exc}") from exc
    if not callable(getattr(planner, "plan", None)):
        raise PlannerError(f"planner {name!r}: {cls.__name__} has no plan(view) method")
    built = cast(Planner, planner)  # (a user's class, duck-typed: its plan method checked just above)
    surveils = surveils_of(cls)
    if context.settings is not None and getattr(context.settings, "surveillance", False):
        if surveils is False:
            raise PlannerError(cast(str, surveillance_problem(name)))
        if surveils == "shared":
            from agents.planners.surveillance import SharedSurveillance

            return SharedSurveillance.of(built, context)
    return built
