"""Which software produced a run: the simulator's version (and git commit when it runs from a
checkout), Python's and numpy's.

A run records them in ``metrics.json`` (``versions``) and at the head of its event log file
(a provenance record before the events, :func:`swarm.events.with_provenance`). They are kept out
of the event-log hash on purpose: the hash says what the run *did*, so the same scenario and seed
give the same hash on another machine or after a release that changes nothing the run does, and
``swarm rerun`` says separately when the versions differ (:func:`differences`).
"""

from __future__ import annotations

import functools
import platform
import subprocess
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _package_version
from pathlib import Path

import numpy as np

__all__ = ["SIMULATOR_VERSION", "differences", "versions"]

_CHECKOUT = Path(__file__).resolve().parent.parent  # the folder holding swarm/, agents/, ...


def _simulator_version() -> str:
    try:
        # One version source: pyproject.toml's, as installed.
        return _package_version("uav-swarm-sim")
    except PackageNotFoundError:  # imported from a source tree that was never installed
        return "0+unknown"


SIMULATOR_VERSION = _simulator_version()  # (``swarm.__version__``)


@functools.lru_cache(maxsize=1)
def versions() -> dict[str, str]:
    """``{"simulator", "python", "numpy"}`` and, when the code runs from a git checkout,
    ``"git_commit"`` (with ``+dirty`` when tracked files differ from that commit)."""
    found = {"simulator": SIMULATOR_VERSION, "python": platform.python_version(), "numpy": np.__version__}
    commit = _git_commit(_CHECKOUT)
    if commit:
        found["git_commit"] = commit
    return found


def _git_commit(folder: Path) -> str | None:
    """The checkout's commit, or ``None`` (not a checkout, no git, or git failed)."""
    if not (folder / ".git").exists():
        return None
    try:
        head = subprocess.run(["git", "-C", str(folder), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(folder), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "") if head else None


def differences(then: dict[str, str] | None, now: dict[str, str]) -> list[str]:
    """What differs between two ``versions()`` tables, as ``"numpy 2.3.1 -> 2.4.6"`` lines
    (a table that was not recorded: one line saying so)."""
    if not then:
        return ["the original run recorded no versions (written before they were recorded)"]
    return [f"{key} {then.get(key, '(none)')} -> {now.get(key, '(none)')}"
            for key in sorted(set(then) | set(now)) if then.get(key) != now.get(key)]
