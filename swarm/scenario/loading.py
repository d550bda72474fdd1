"""Loading scenarios: the built-in ones by name and TOML files by path, with the command line's
``--planner``, ``--set`` and ``--duration`` applied to the document before it is validated
(:func:`swarm.scenario.model.parse_scenario`).

No other exception than :class:`~swarm.errors.ScenarioError` escapes the loader: the CLI prints
``str(err)`` and nothing else, so the message must stand on its own.
"""

from __future__ import annotations

import json
import os
import tomllib
from collections.abc import Iterable, Mapping
from importlib import resources
from pathlib import Path
from typing import Any

from swarm.errors import ScenarioError
from swarm.scenario.model import Scenario, parse_scenario
from swarm.scenario.overrides import set_keys, switch_planner
from swarm.scenario.positions import found_words
from swarm.scenario.trust import allowed

__all__ = ["builtin_folder", "builtin_scenarios", "load_scenario", "scenario_from_document", "scenario_from_toml"]

_BUILTIN_PACKAGE = "swarm.scenario.builtin"


def builtin_folder() -> str:
    """Where the built-in scenario files are, as a path (for a tool that reads them itself, such
    as the bench yardstick through ``SWARM_BUILTIN``)."""
    return str(resources.files(_BUILTIN_PACKAGE))


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
    :func:`~swarm.scenario.overrides.switch_planner`); the file's own planner is then never imported.
    ``allow_planner_imports``: a ``module:Class`` named in the file is imported (to check it)
    only if allowed here: ``True``, or its name among these (``planner`` always is); see
    :mod:`swarm.scenario.trust`. ``overrides``: dotted keys set in the document before it is
    validated (``--set``), as :func:`~swarm.scenario.model.apply_overrides` does after, so that the document is judged
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
        if path.suffix.lower() == ".json":  # a run folder's scenario.json (the scenario that ran, as a document)
            return scenario_from_document(_json_document(text, source), source, planner=planner,
                                          allow_planner_imports=allow_planner_imports, overrides=overrides,
                                          run_duration_s=run_duration_s, written=True)
        return scenario_from_toml(text, source, planner=planner, allow_planner_imports=allow_planner_imports,
                                  overrides=overrides, run_duration_s=run_duration_s)
    if path.is_dir() and (path / "scenario.json").is_file():
        raise ScenarioError(source, "", "a run folder",
                            "a scenario; re-run the folder with `swarm rerun " + source + "`, or run its scenario with "
                            "other settings with `swarm run " + str(path / "scenario.json") + " --seed N ...`")
    if isinstance(ref, str) and ref in builtin_scenarios():
        text = resources.files(_BUILTIN_PACKAGE).joinpath(f"{ref}.toml").read_text(encoding="utf-8")
        return scenario_from_toml(text, ref, planner=planner, allow_planner_imports=allow_planner_imports,
                                  overrides=overrides, run_duration_s=run_duration_s)
    found = "no such file" if not path.exists() else "something that is not a file"
    raise ScenarioError(source, "", found, _file_expected())


def _file_expected() -> str:
    return (f"a path to an existing .toml file (or a run folder's scenario.json) or a built-in name "
            f"({', '.join(builtin_scenarios())})")


def _json_document(text: str, source: str) -> dict[str, Any]:
    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise ScenarioError(source, "", f"invalid JSON ({exc})", "a scenario document (a run folder's scenario.json)") from None
    if not isinstance(doc, dict):
        raise ScenarioError(source, "", found_words(doc), "a table of scenario settings")
    return doc


def scenario_from_toml(text: str, source: str, *, planner: str | None = None,
                       allow_planner_imports: bool | Iterable[str] = False,
                       overrides: Mapping[str, Any] | None = None, run_duration_s: float | None = None) -> Scenario:
    """A scenario from TOML text (``planner``, ``allow_planner_imports``, ``overrides``,
    ``run_duration_s``: see :func:`load_scenario`)."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(source, "", f"invalid TOML ({exc})", "a TOML document") from None
    return scenario_from_document(doc, source, planner=planner, allow_planner_imports=allow_planner_imports,
                                  overrides=overrides, run_duration_s=run_duration_s)


def scenario_from_document(doc: dict[str, Any], source: str, *, planner: str | None = None,
                           allow_planner_imports: bool | Iterable[str] = False,
                           overrides: Mapping[str, Any] | None = None, run_duration_s: float | None = None,
                           written: bool = False) -> Scenario:
    """A scenario from a parsed document (a TOML file's, or a run folder's ``scenario.json``;
    the keyword arguments as :func:`load_scenario`). ``written``: the document is a scenario
    that ran (``scenario.json``), whose ``duration_s`` may be a run cut short (``--duration``):
    UAVs that join after it are not refused."""
    if planner is not None:
        switch_planner(doc, planner)
    set_keys(doc, overrides or {}, source)
    allow = allowed(allow_planner_imports, planner)
    if run_duration_s is None:
        return parse_scenario(doc, source, allow_planner_imports=allow, truncated=written)
    own = doc.get("duration_s", Scenario.model_fields["duration_s"].default)
    if isinstance(own, bool) or not isinstance(own, (int, float)) or not own > 0:
        return parse_scenario(doc, source, allow_planner_imports=allow)  # (says what is wrong with it)
    run = parse_scenario({**doc, "duration_s": run_duration_s}, source, truncated=True, scenario_duration_s=float(own),
                         allow_planner_imports=allow)
    return run.model_copy(update={"duration_s": float(own)})  # valid as run; kept with its own end

