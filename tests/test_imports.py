"""Importing the simulator never needs Hypothesis (only swarm.testing's strategies and state
machine do, and say so; its checkers do not), and
the import graph points one way: agents, comms and faults never import swarm."""

from __future__ import annotations

import ast
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

BLOCK_HYPOTHESIS = "import sys; sys.modules['hypothesis'] = None\n"


def _modules(package: str) -> list[str]:
    pkg_path = ROOT / package.replace(".", "/")
    return [package] + [f"{package}.{m.name}" for m in pkgutil.walk_packages([str(pkg_path)])]


@pytest.mark.slow  # a subprocess importing every module (the swarm.testing one below is quick)
def test_every_module_outside_swarm_testing_imports_without_hypothesis():
    names = [m for p in ("swarm", "agents", "comms", "faults") for m in _modules(p)
             if not m.startswith(("swarm.testing.strategies", "swarm.testing.fault_strategies", "swarm.testing.stateful",
                                  "swarm.testing._hypothesis", "swarm.env")) and m != "swarm.__main__"]
    code = BLOCK_HYPOTHESIS + "import importlib\n" + "".join(f"importlib.import_module({n!r})\n" for n in names)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("code", ["import swarm.testing.strategies", "import swarm.testing.stateful",
                                  "from swarm.testing import scenarios"])
def test_swarm_testing_strategies_name_the_extra_they_need(code):
    r = subprocess.run([sys.executable, "-c", BLOCK_HYPOTHESIS + code], capture_output=True,
                       text=True, cwd=ROOT, timeout=60)
    assert r.returncode != 0 and "uav-swarm-sim[testing]" in r.stderr


def test_swarm_testing_checkers_need_no_hypothesis():
    code = BLOCK_HYPOTHESIS + "import swarm.testing.invariants, swarm.testing.liveness\nfrom swarm.testing import Monitor"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert r.returncode == 0, r.stderr


def test_lower_packages_never_import_swarm():
    for package in ("agents", "comms", "faults"):
        for path in (ROOT / package).rglob("*.py"):
            tree = ast.parse(path.read_text())
            for node in ast.walk(tree):
                if isinstance(node, ast.ImportFrom) and node.module:
                    assert not node.module.split(".")[0] == "swarm", f"{path}: imports {node.module}"
                elif isinstance(node, ast.Import):
                    assert all(a.name.split(".")[0] != "swarm" for a in node.names), f"{path}"
    for path in (ROOT / "comms").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                assert node.module.split(".")[0] not in ("agents", "faults"), f"{path}: imports {node.module}"
