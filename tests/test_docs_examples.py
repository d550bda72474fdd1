"""Every Python example in README.md and docs/*.md runs as written, so a renamed function breaks
the build, not the user.

A ```` ```python ```` block (indented ones inside list items included) is executed in a fresh
namespace, in a temporary working directory; then every top-level function it defines whose
name starts with ``test`` is called, and every ``unittest.TestCase`` class whose name starts
with ``Test`` (a Hypothesis state machine's ``TestCase``) is run. A block preceded by the
comment ``<!-- fragment: why -->`` (the last non-blank line before its opening fence) is a
fragment on purpose: it is not run, but if it parses, the names it imports must exist.

Blocks that run Hypothesis tests are marked ``slow`` (whole runs, many examples) and run with
``swarm.testing.settings.simulation_settings`` as shipped (no deadline, the same health checks)
except for the number of examples: the active profile's ``examples(20)`` (20 under ``ci``), not
50. The other blocks are in the quick loop.
"""

from __future__ import annotations

import ast
import importlib
import re
import textwrap
import unittest
from dataclasses import dataclass
from pathlib import Path

import pytest
from budget import examples
from hypothesis import settings

ROOT = Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

_FENCE = re.compile(r"^(?P<indent>[ \t]*)```python[ \t]*\n(?P<body>.*?)^(?P=indent)```[ \t]*$", re.M | re.S)
_FRAGMENT = re.compile(r"<!--\s*fragment\b.*?-->\s*$")


@dataclass(frozen=True)
class Block:
    doc: str  # path relative to the repository
    line: int  # line of the opening fence, 1-based
    code: str
    fragment: bool

    @property
    def id(self) -> str:
        return f"{self.doc}:{self.line}"

    @property
    def runs_hypothesis(self) -> bool:
        return "@given" in self.code or ".TestCase" in self.code


def blocks() -> list[Block]:
    out = []
    for path in DOCS:
        text = path.read_text(encoding="utf-8")
        for m in _FENCE.finditer(text):
            before = [line for line in text[: m.start()].splitlines() if line.strip()]
            out.append(Block(str(path.relative_to(ROOT)), text.count("\n", 0, m.start()) + 1,
                             textwrap.dedent(m.group("body")),
                             bool(before) and _FRAGMENT.search(before[-1]) is not None))
    return out


BLOCKS = blocks()


def _imported_names(tree: ast.AST) -> list[tuple[str, str | None]]:
    names: list[tuple[str, str | None]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names += [(node.module, a.name) for a in node.names if a.name != "*"]
        elif isinstance(node, ast.Import):
            names += [(a.name, None) for a in node.names]
    return names


def test_the_docs_have_python_examples_and_fragments_say_so():
    assert len(BLOCKS) >= 5, [b.id for b in BLOCKS]
    assert {b.doc for b in BLOCKS} >= {"README.md", "docs/resilience.md", "docs/env.md"}
    assert [b.id for b in BLOCKS if b.fragment] == [b.id for b in BLOCKS if b.doc == "docs/planners.md"
                                                    and "Client(" in b.code]  # the Dask upload needs a cluster


@pytest.mark.parametrize("block", BLOCKS, ids=[b.id for b in BLOCKS])
def test_imported_names_exist(block):
    """Cheap, for every block, fragments too: what it imports is there (a renamed function)."""
    try:
        tree = ast.parse(block.code, block.id)
    except SyntaxError:
        if block.fragment:
            pytest.skip("a fragment that is not a whole program")
        raise
    for module, name in _imported_names(tree):
        if module.split(".")[0] in {"pettingzoo", "gymnasium"}:
            pytest.importorskip(module.split(".")[0])
        mod = importlib.import_module(module)
        if name is not None and not hasattr(mod, name):
            importlib.import_module(f"{module}.{name}")  # a submodule; else ImportError names it


def _run(block: Block, monkeypatch, tmp_path) -> None:
    import swarm.testing.settings as shipped

    if "swarm.env" in block.code:
        pytest.importorskip("pettingzoo")
    # The shipped settings, with the profile's count of examples (and its derandomize).
    monkeypatch.setattr(shipped, "simulation_settings", settings(
        shipped.simulation_settings, max_examples=examples(20), derandomize=settings.default.derandomize))
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__main__"}
    exec(compile(block.code, block.id, "exec"), namespace)
    ran = 0
    for name, obj in list(namespace.items()):
        if name.startswith("test") and callable(obj) and not isinstance(obj, type):
            obj()
            ran += 1
        elif name.startswith("Test") and isinstance(obj, type) and issubclass(obj, unittest.TestCase):
            result = unittest.TestResult()
            unittest.defaultTestLoader.loadTestsFromTestCase(obj).run(result)
            assert result.wasSuccessful(), "\n".join(text for _, text in result.errors + result.failures)
            ran += 1
    if block.runs_hypothesis:
        assert ran, f"{block.id} defines Hypothesis tests but none was found to run"


@pytest.mark.parametrize("block", [
    pytest.param(b, id=b.id, marks=[pytest.mark.slow] if b.runs_hypothesis else [])  # Hypothesis: whole runs
    for b in BLOCKS if not b.fragment])
def test_example_runs(block, monkeypatch, tmp_path):
    _run(block, monkeypatch, tmp_path)
