"""Importing the simulator never needs Hypothesis (only swarm.testing's strategies and state
machine do, and say so; its checkers do not), the import graph points one way (agents, comms
and faults never import swarm), and it has no circles (checked package by package where there
are none: swarm.scenario, agents, comms, faults; the last three also counting the imports only
the type checker reads)."""

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


# --- import circles --------------------------------------------------------------------------------


def _our_sources() -> dict[str, str]:
    """Module name -> source of every module of ours (a package is its ``__init__``)."""
    sources = {}
    for package in ("swarm", "agents", "comms", "faults"):
        for path in (ROOT / package).rglob("*.py"):
            parts = path.relative_to(ROOT).with_suffix("").parts
            sources[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path.read_text(encoding="utf-8")
    return sources


def _runtime_imports(tree: ast.AST, type_checking: bool = False) -> list[str]:
    """Every module named by an import that runs (at the top or inside a function), and with
    ``type_checking`` also those under ``if TYPE_CHECKING:`` (which only the type checker reads)."""
    found: list[str] = []

    def visit(node: ast.AST) -> None:
        if (isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"
                and not type_checking):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            found.extend(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append(node.module)
            found.extend(f"{node.module}.{a.name}" for a in node.names)  # (a submodule imported by name)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return found


def import_circles(prefix: str, sources: dict[str, str] | None = None, type_checking: bool = False) -> list[list[str]]:
    """The import circles among the modules whose names start with ``prefix`` (strongly connected
    components of more than one module), from ``sources`` (default: ours); with ``type_checking``
    the imports only the type checker reads count too."""
    sources = _our_sources() if sources is None else sources

    def owner(name: str) -> str | None:
        while name and name not in sources:
            name = name.rpartition(".")[0]
        return name or None

    inside = sorted(m for m in sources if m == prefix or m.startswith(prefix + "."))
    graph: dict[str, set[str]] = {m: set() for m in inside}
    for m in inside:
        for name in _runtime_imports(ast.parse(sources[m]), type_checking):
            target = owner(name)
            if target in graph and target != m:
                graph[m].add(target)
    # Tarjan's strongly connected components.
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    for v in inside:
        if v not in index:
            connect(v)
    return circles


@pytest.mark.parametrize("prefix", ["swarm", "swarm.scenario", "agents", "comms", "faults"])
def test_no_import_circle(prefix):
    """No circle at run time, the ``swarm`` package's own ``__init__`` included (the kernel
    imports the event schema as ``swarm.events``, not through the package's faces)."""
    assert import_circles(prefix) == []


def test_the_kernels_only_type_checker_circle_is_the_host_mixin():
    """What is left for the type checker in ``swarm``: the host API (a mixin of Simulation), the
    host-change replay and the snapshot annotate their ``sim`` as a Simulation, which imports
    them. A new circle fails here."""
    assert import_circles("swarm", type_checking=True) == [
        ["swarm.kernel.host", "swarm.kernel.hostlog", "swarm.kernel.simulation", "swarm.kernel.snapshot"]]


@pytest.mark.parametrize("prefix", ["agents", "comms", "faults"])
def test_no_import_circle_even_for_the_type_checker(prefix):
    """Each name lives in the module it belongs to (issue 35: PlannerContext in the planner API,
    LinkBehaviour beside the other hooks of a fault kind, TickFault beside the engine that runs
    it), so not even an annotation needs an import back."""
    assert import_circles(prefix, type_checking=True) == []


def test_import_circles_are_found_at_any_depth_but_not_through_type_checking():
    sources = {
        "p": "",
        "p.a": "from p.b import x\n",
        "p.b": "def f():\n    from p.c import y\n",  # an import inside a function still runs
        "p.c": "import p.a\n",
        "p.d": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from p.e import z\n",
        "p.e": "from p.d import w\n",
    }
    assert import_circles("p", sources) == [["p.a", "p.b", "p.c"]]
    assert import_circles("p", sources, type_checking=True) == [["p.a", "p.b", "p.c"], ["p.d", "p.e"]]


# --- privates stay inside their class ----------------------------------------------------------

# Reads of another object's private attribute in agents, comms and faults that are allowed: an
# instance of the same class (a map merging or copying another map, a pyramid batching the work of
# several or copying its group base's, the shared surveillance logic preparing the plans of several of its instances).
# Another class's internals are read through a public name (issue 24: the radio's
# RadioGraph.edge_data, DecodeCache.derive, Disk.values_memo / stamps_memo, MapGroup.base_cells
# and the extra scans a MapGroup keeps for its members, DacmpPlanner.keep / search_weights / scratch).
SAME_CLASS = {
    "agents/maps/umap.py": {"new._tiles", "new._changes", "new._nty", "new._ntx", "other._materialize", "other._tiles",
                            "new._own", "new._share"},  # (issue 36, T8: a copy's owned tiles, its grid's sharing)
    "agents/maps/mapgroup.py": {"super()._cells"},
    "agents/planners/dacmp/maintained.py": {"plane._tiles", "MaintainedPyramid._recompute", "w.pyr._sum_chunks",
                                            "p._changed", "w.pyr._e_keys",
                                            # a group member's pyramid made from the base's (issue 36, T9)
                                            "MaintainedPyramid._follow_bases", "p._from_base", "base._chunk_sums",
                                            "base._block_sums",
                                            # ... copying only what is stale: what each update rewrote
                                            "base._history", "w.pyr._record", "w.pyr._written"},
    "agents/planners/surveillance.py": {"planner._prepared"},
}


def test_no_private_read_of_another_class():
    found: dict[str, set[str]] = {}
    for package in ("agents", "comms", "faults"):
        for path in sorted((ROOT / package).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if (isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")
                        and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))):
                    found.setdefault(path.relative_to(ROOT).as_posix(), set()).add(ast.unparse(node))
    assert found == SAME_CLASS


@pytest.mark.slow  # a subprocess running a short simulation
def test_a_plain_run_imports_neither_scipy_nor_plotting():
    # issue 36, startup: a run pays for what it uses. paper-case1 (3 UAVs, unlimited radio
    # range, disk model, no figures without --out): scipy is for k-d trees from 32 UAVs on, a
    # finite radio range, the log-distance model and two UAVs within the separation minimum.
    code = ("import sys\nfrom swarm.cli import main\nassert main(['run', 'paper-case1', '--duration', '20', '--quiet']) == 0\n"
            "heavy = sorted(m for m in sys.modules if m.split('.')[0] in ('scipy', 'matplotlib', 'pyarrow', 'dask', "
            "'pettingzoo', 'pandas', 'shapely', 'pyproj'))\nprint(heavy)\nassert not heavy, heavy\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
