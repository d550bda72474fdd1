"""The kernel's shape (issue 24): Simulation holds building, the tick's phases, driving and the
public API (at most 400 lines); the package's modules import one another without circles; the
fault kinds are listed once, and a kind defined outside the package runs end to end."""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx

from faults.registry import FAULT_KINDS

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("swarm", "agents", "comms", "faults")


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _runtime_imports(tree: ast.Module) -> list[str]:
    """The modules a module imports when it runs: every import except those under
    ``if TYPE_CHECKING:`` (annotations only, never executed)."""
    out: list[str] = []

    def visit(nodes: list[ast.stmt]) -> None:
        for node in nodes:
            if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
                visit(node.orelse)
                continue
            for sub in ast.walk(node):
                if isinstance(sub, ast.ImportFrom) and sub.module and sub.level == 0:
                    out.append(sub.module)
                    out.extend(f"{sub.module}.{a.name}" for a in sub.names)
                elif isinstance(sub, ast.Import):
                    out.extend(a.name for a in sub.names)

    visit(tree.body)
    return out


def _import_graph() -> nx.DiGraph:
    modules = {_module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}
    g = nx.DiGraph()
    for name, path in modules.items():
        g.add_node(name)
        for target in _runtime_imports(ast.parse(path.read_text())):
            if target in modules and target != name:
                g.add_edge(name, target)
    return g


def test_simulation_is_at_most_400_lines():
    n = len((ROOT / "swarm" / "simulation.py").read_text().splitlines())
    assert n <= 400, f"swarm/simulation.py has {n} lines"


def test_no_import_circle_among_the_packages_modules():
    g = _import_graph()
    # A package's __init__ importing its own submodules is how a package gathers its names, not
    # a circle of concerns; a circle through a package's __init__ from outside would still count.
    for node in list(g):
        for target in list(g.successors(node)):
            if target.startswith(node + ".") and (ROOT / node.replace(".", "/") / "__init__.py").exists():
                g.remove_edge(node, target)
    cycles = [c for c in nx.simple_cycles(g) if len(c) > 1]
    assert not cycles, "import circles: " + "; ".join(" -> ".join(c + [c[0]]) for c in cycles[:5])


def test_the_fault_kinds_are_listed_once():
    """No module holds a literal list (tuple, set) of half the kind names or more: the list is
    the registry's, filled by each kind registering. (A dict from each kind to its own thing,
    such as the testing strategies' kind -> strategy, is per kind, not a list of kinds; a
    family or axis of a few kinds is not the list either.)"""
    kinds = set(FAULT_KINDS)
    offenders = []
    for pkg in PACKAGES:
        for path in (ROOT / pkg).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
                    names = [e.value for e in node.elts if isinstance(e, ast.Constant) and e.value in kinds]
                    if len(names) >= len(kinds) / 2:
                        offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}: {names}")
    assert not offenders, "fault kinds listed outside faults.registry:\n" + "\n".join(offenders)


def test_the_kernel_names_no_fault_kind():
    source = (ROOT / "swarm" / "simulation.py").read_text()
    for kind in FAULT_KINDS:
        assert f'"{kind}"' not in source and f"'{kind}'" not in source, kind
