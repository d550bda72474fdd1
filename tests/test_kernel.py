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
    n = len((ROOT / "swarm" / "kernel" / "simulation.py").read_text().splitlines())
    assert n <= 400, f"swarm/kernel/simulation.py has {n} lines"


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
    source = (ROOT / "swarm" / "kernel" / "simulation.py").read_text()
    for kind in FAULT_KINDS:
        assert f'"{kind}"' not in source and f"'{kind}'" not in source, kind


# --- a fault kind defined here, with no edit to the kernel, the actor or the checkers -------------

import math  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from typing import ClassVar  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from faults.base import COPY_STAGES, END, START, UAV, Copy, Draws, FaultRng, LinkBehaviour, Windowed  # noqa: E402
from faults.registry import register, unregister  # noqa: E402


@dataclass(frozen=True, kw_only=True)
class Blackout(Windowed):
    """The UAV's radio is dead in its window: every copy to or from it is lost."""

    uav: str = field(metadata=UAV)
    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(default=math.inf, metadata=END)
    kind: ClassVar[str] = "blackout"
    disturbs_links: ClassVar[bool] = True  # its excuse: the maps need not agree meanwhile
    min_uavs: ClassVar[int] = 1  # (how tests draw it: one UAV's radio, over a window)

    def link_behaviour(self, ids, fault_rng: FaultRng, rank: int) -> LinkBehaviour:
        return _Dead(self, ids[self.uav])

    @classmethod
    def generate(cls, d: Draws) -> Blackout:
        start, end = d.draw(d.windows())
        return cls(uav=d.draw(d.names()), start_s=start, end_s=end)


@dataclass(frozen=True, kw_only=True)
class UnexcusedBlackout(Blackout):
    """The same, claiming no excuse: what the checkers make of it shows the excuse matters."""

    kind: ClassVar[str] = "unexcused_blackout"
    disturbs_links: ClassVar[bool] = False


class _Dead(LinkBehaviour):
    stage = COPY_STAGES + 10  # (after the built-in copy faults)

    def __init__(self, fault: Blackout, uid: int):
        super().__init__(fault)
        self.uid = uid

    def on_copy(self, c: Copy, src: int, dst: int, rng: np.random.Generator) -> bool:
        if self.uid in (src, dst):
            c.lost = True
            return True
        return False


@pytest.fixture
def blackouts():
    register(Blackout)
    register(UnexcusedBlackout)
    yield
    unregister("blackout")
    unregister("unexcused_blackout")


SCENARIO = """
name = "blackout"
seed = 2
duration_s = 150.0
[area]
width_m = 3000.0
height_m = 3000.0
cell_m = 100.0
[planner]
name = "greedy"
[[uavs]]
name = "B1"
type = "B"
x_m = 500.0
y_m = 500.0
[[uavs]]
name = "B2"
type = "B"
x_m = 1500.0
y_m = 1500.0
[[uavs]]
name = "B3"
type = "B"
x_m = 2500.0
y_m = 2500.0
[[faults]]
kind = "{kind}"
uav = "B2"
start_s = 10.0
end_s = 120.0
"""


def _run_checked(tmp_path, kind):
    from swarm.kernel.simulation import Simulation
    from swarm.scenario import load_scenario
    from swarm.testing.invariants import MapAgreementChecker, Monitor, RunContext

    path = tmp_path / f"{kind}.toml"
    path.write_text(SCENARIO.format(kind=kind))
    sim = Simulation(load_scenario(path))
    lost: list = []
    sim.subscribe(lambda e: lost.append(e) if e.cause == kind else None, kinds=["lost"])
    monitor = Monitor([MapAgreementChecker(quiet_s=20.0, every_s=5.0)]).attach(sim)
    while not sim.done:
        sim.step()
        monitor.flush()
    violations = monitor.finish()
    ctx = RunContext(sim.scenario, sim=sim)
    sim.close()
    return sim, lost, violations, ctx


def test_a_fault_kind_defined_in_a_test_runs_from_a_scenario_file_end_to_end(tmp_path, blackouts):
    sim, lost, violations, ctx = _run_checked(tmp_path, "blackout")
    # It fired (counted by kind) exactly on copies to or from B2, inside its window.
    assert sim.injector.fired["blackout"] == len(lost) > 0
    assert all(10.0 <= e.t < 120.0 + 1e-9 and "B2" in (e.src_name, e.dst_name) for e in lost)
    # The checkers grant its excuse: maps need not agree while it acts, and it explains B2.
    (f,) = sim.injector.schedule.faults
    assert ctx.link_faults_active(50.0) and not ctx.link_faults_active(130.0)
    assert ctx.explaining([1], 40.0, 60.0) == [f] and ctx.explaining([0], 40.0, 60.0) == []  # (B2 is uid 1)
    assert violations == []


def test_without_its_excuse_the_same_kind_breaks_map_agreement(tmp_path, blackouts):
    sim, lost, violations, _ctx = _run_checked(tmp_path, "unexcused_blackout")
    assert len(lost) > 0
    assert violations and {v.invariant for v in violations} == {"map_agreement"}


def test_a_kind_registered_in_a_test_is_in_the_tables_and_the_strategies(blackouts):
    """What a built-in kind costs is its class (and its tests): the scenario's [[faults]] table
    and the toolkit's strategies follow the registry, so a kind registered here, with nothing
    else edited, is in each of them (the coverage gate: the test below)."""
    from hypothesis import Phase, find, settings

    from swarm.scenario import fault_table, parse_scenario
    from swarm.scenario.generated import FAULT_TABLES
    from swarm.testing.fault_strategies import fault_kinds, fault_schedules, faults
    from swarm.testing.strategies import fault_schedule_of

    # The generated tables: one for the kind, by kind and by name, its fields and bounds from the class.
    doc = {"name": "t", "duration_s": 60.0, "area": {"width_m": 3000.0, "height_m": 3000.0, "cell_m": 100.0},
           "uavs": [{"name": "B1", "type": "B", "x_m": 500.0, "y_m": 500.0}],
           "faults": [{"kind": "blackout", "uav": "B1", "start_s": 5.0}]}
    sc = parse_scenario(doc)
    assert "blackout" in FAULT_TABLES and isinstance(sc.faults[0], fault_table("blackout"))
    from swarm import scenario as scenario_module
    assert scenario_module.BlackoutFault is fault_table("blackout")
    assert fault_schedule_of(sc).faults == [Blackout(uav="B1", start_s=5.0)]
    # The strategies: drawn alone and among the others (in registration order after the built-ins).
    assert fault_kinds()[-2:] == ("blackout", "unexcused_blackout")
    only = settings(phases=[Phase.generate], database=None, derandomize=True)
    f = find(faults(["B1", "B2"], 60.0, kinds=["blackout"]), lambda f: True, settings=only)
    assert isinstance(f, Blackout) and f.uav in ("B1", "B2")
    s = find(fault_schedules(["B1", "B2"], 60.0, min_faults=1), lambda s: any(f.kind == "blackout" for f in s.faults),
             settings=settings(only, max_examples=500))
    assert any(f.kind == "blackout" for f in s.faults)


@pytest.mark.slow  # the coverage gate's seeded simulations (as tests/test_fault_coverage.py, slow there too)
def test_a_kind_registered_in_a_test_is_judged_by_the_coverage_gate(blackouts):
    from test_fault_coverage import fires_in_seeded_examples

    runs, fired = fires_in_seeded_examples("blackout")
    assert fired > 0 and runs >= 1
    # A kind whose class does not say how tests draw it is named by the gate's first check.
    assert not Windowed.has_strategy() and Blackout.has_strategy()
