from __future__ import annotations

import functools
import hashlib
import json
import os
import re
import types
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
from hypothesis import settings

from swarm.testing.fault_strategies import fault_kinds
from swarm.testing.settings import simulation_settings
from swarm.testing.strategies import set_swarm_testing

DATA = Path(__file__).parent / "data"

# --- Hypothesis profiles ----------------------------------------------------------------------
# All four are built on swarm.testing.settings.simulation_settings, the settings the toolkit ships
# for simulation-backed properties (no deadline, the too_slow health check suppressed).
# ci: the same examples on every run (derandomize), a fixed number of them, no per-example
#   deadline (a simulation run is not a microbenchmark). Tests scale their example counts with
#   the profile's max_examples (``examples(n)`` = n * max_examples // 100 in each test module),
#   so `deep` multiplies them by 10 and `quick` divides them by 10.
# deep: 10x the examples, random (new examples each run, failures kept in the database).
#   HYPOTHESIS_PROFILE=deep .venv/bin/python -m pytest tests/test_strategies.py tests/test_invariants.py
# quick: ci with a tenth of the examples (same derandomized draws, fewer of them); the profile
#   of the quick loop, ``pytest -m "not slow"``.
# swarm: swarm testing (FoundationDB's simulation, Groce et al. 2012): the ci count of examples,
#   random ones each run, and every generated scenario also draws its configuration (UAV types
#   flown, radio model disk / log_distance, map tau, replan period) and the subset of fault kinds
#   it may use (swarm.testing.strategies.set_swarm_testing, turned on in pytest_configure).
#   HYPOTHESIS_PROFILE=swarm .venv/bin/python -m pytest tests/test_strategies.py tests/test_invariants.py tests/test_stateful.py
# Which one: HYPOTHESIS_PROFILE if set; else `quick` when the marker expression deselects the
# slow tests (``-m "not slow"``); else `ci` (a plain ``python -m pytest``, what CI runs).
# Chosen in pytest_configure, before any test module is imported: the modules read
# settings.default.max_examples when their decorators run.
settings.register_profile("ci", simulation_settings, derandomize=True, max_examples=100, print_blob=True)
settings.register_profile("deep", simulation_settings, max_examples=1000, print_blob=True)
settings.register_profile("quick", parent=settings.get_profile("ci"), max_examples=10)
settings.register_profile("swarm", simulation_settings, max_examples=100, print_blob=True)


# --- running on every core (pytest-xdist) ----------------------------------------------------------
# pyproject.toml's addopts run the suite with `-n auto`: one worker process per core, each test
# sent to a free worker. Each worker is a whole pytest session of its own: it reads the options,
# so it loads the same Hypothesis profile (pytest_configure below), and it builds the fixtures
# its tests need. Tests share nothing across workers but the file system, and every test writes
# only below its own tmp_path (or pytest's tmp_path_factory, which gives each worker its own
# folders). Two things need care:
# * a module whose tests share state goes to one worker, whole and in file order (the scheduler
#   below): one with a module-scoped fixture (a run, a results folder filled test by test:
#   built once, not once per worker) and the modules in SHARED_STATE_MODULES, whose tests read
#   what earlier tests of the file left in the process;
# * the fault-kind tally (FaultStats, below) is kept per worker; each worker hands its tally to
#   the controller when it finishes (`workeroutput`), and the controller adds them up, so the
#   session-wide check sees every run, as in one process.
# (xdist's own `--dist loadgroup` with `xdist_group` marks would do the first, but it renames the
# tests' node ids to group them, which pytest 9 no longer lets a plugin do: its groups are lost.)

# Modules whose tests read process state that earlier tests of the file left (not a fixture):
# test_stateful's liveness tally is filled by TestSwarmMachine and judged by the test after it.
SHARED_STATE_MODULES = frozenset({"test_stateful.py"})
_MODULE_FIXTURE = re.compile(r"""@pytest\.fixture\([^)]*scope\s*=\s*["'](?:module|package)["']""")


@functools.cache
def one_worker_module(path: Path) -> bool:
    """True for a test module whose tests must run on one worker, in file order (see above)."""
    return path.name in SHARED_STATE_MODULES or bool(_MODULE_FIXTURE.search(path.read_text(encoding="utf-8")))


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """xdist's `load` distribution (what `-n` uses), except that each module of
    :func:`one_worker_module` is one unit of work: its tests go to one worker, in file order.
    Other `--dist` modes are xdist's own."""
    if config.getvalue("dist") != "load":
        return None
    from xdist.scheduler import LoadScopeScheduling

    root = config.rootpath

    class ModuleGroupScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            module = nodeid.split("::", 1)[0]
            return module if one_worker_module(root / module) else nodeid

    return ModuleGroupScheduling(config, log)


def _is_worker(config: pytest.Config) -> bool:
    return hasattr(config, "workerinput")


def deselects_slow(config: pytest.Config) -> bool:
    """True when ``-m`` leaves out the tests marked ``slow`` (the quick loop: ``-m "not slow"``)."""
    return re.search(r"\bnot\s+slow\b", config.getoption("markexpr", "") or "") is not None


PROFILE = "ci"  # the profile this session runs (set below)
QUICK_LOOP = False  # -m "not slow"


def pytest_configure(config: pytest.Config) -> None:
    global PROFILE, QUICK_LOOP
    QUICK_LOOP = deselects_slow(config)
    PROFILE = (config.getoption("hypothesis_profile", None) or os.environ.get("HYPOTHESIS_PROFILE")
               or ("quick" if QUICK_LOOP else "ci"))
    settings.load_profile(PROFILE)
    set_swarm_testing(PROFILE == "swarm")
    _fix_hypothesis_constants()
    if config.getoption("examples_digest", None):
        from hypothesis.internal.observability import add_observability_callback

        add_observability_callback(_DIGESTS.observe, all_threads=True)


# --- the same examples in any order ---------------------------------------------------------------
# Under `ci` and `quick` every test's examples are derandomized (seeded from the test's own source,
# no example database), so they cannot depend on which tests ran before it. Two options check it:
# `--order reverse` runs the modules, and the tests inside each, in the reverse of the collected
# order (a module of one_worker_module keeps its own order: its tests read what earlier ones
# left), and `--examples-digest PATH` writes, per test, a digest of every choice sequence
# Hypothesis drew (its examples) to PATH as JSON. Run twice, once each way, and compare:
#   HYPOTHESIS_EXPERIMENTAL_OBSERVABILITY_CHOICES=1 HYPOTHESIS_EXPERIMENTAL_OBSERVABILITY_NOCOVER=1 \
#     python -m pytest -n 0 FILES --examples-digest a.json   (and again with --order reverse)


# Hypothesis (6.131 and later) also draws, now and then, constants found in the source of the
# "local" modules imported so far in the process: which modules those are depends on the tests
# that ran before (a module imported lazily, a planner module a test writes and imports), so the
# same test drew other examples in another order (measured: 52 of 112 tests of the quick loop
# that draw examples, run in reverse). The pool is fixed here, once, to the constants of every
# module of the four packages, imported or not: a test's examples no longer depend on the order.
ROOT = Path(__file__).resolve().parent.parent


def _fix_hypothesis_constants() -> None:
    try:
        from hypothesis.internal.conjecture import providers
        from hypothesis.internal.constants_ast import Constants, constants_from_module
    except ImportError:  # a Hypothesis without the pool
        return
    if not hasattr(providers, "_get_local_constants"):
        return
    pool: list[Any] = []

    def fixed_pool() -> Any:
        # Made at the first draw (Hypothesis asks plugins not to read its storage while pytest starts).
        if not pool:
            # Sorted sets, as Hypothesis's own pool: a plain set of strings would be ordered by
            # the process's hash seed, and a constant is drawn by its index.
            sorted_set = type(providers.GLOBAL_CONSTANTS.integers)
            constants = Constants(integers=sorted_set(), floats=sorted_set(key=providers.float_to_int),
                                  bytes=sorted_set(), strings=sorted_set())
            for package in ("agents", "comms", "faults", "swarm"):
                for path in sorted((ROOT / package).rglob("*.py")):
                    module = types.ModuleType(path.stem)  # its file, not imported (Hypothesis reads the source)
                    module.__file__ = str(path)
                    constants |= constants_from_module(module)  # (cached by Hypothesis, by the source's hash)
            pool.append(constants)
        return pool[0]

    providers._get_local_constants = fixed_pool
    providers.CONSTANTS_CACHE.cache.clear()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("swarm", "uav-swarm-sim test options")
    group.addoption("--order", choices=("collected", "reverse"), default="collected",
                    help="run the tests in the collected order or its reverse (modules that share state keep theirs)")
    group.addoption("--examples-digest", metavar="PATH", default=None,
                    help="write per test a digest of the examples Hypothesis drew (needs "
                         "HYPOTHESIS_EXPERIMENTAL_OBSERVABILITY_CHOICES=1)")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.getoption("order") != "reverse":
        return
    modules: dict[Path, list[pytest.Item]] = {}
    for item in items:
        modules.setdefault(item.path, []).append(item)
    items[:] = [item for path in reversed(list(modules))
                for item in (modules[path] if one_worker_module(path) else reversed(modules[path]))]


class _ExampleDigests:
    """What ``--examples-digest`` records: each test's examples, as Hypothesis's choice sequences."""

    def __init__(self) -> None:
        self.current = ""
        self.digests: dict[str, Any] = {}
        self.cases: Counter[str] = Counter()

    def observe(self, observation: Any, thread_id: int = 0) -> None:
        nodes = getattr(getattr(observation, "metadata", None), "choice_nodes", None)
        if getattr(observation, "type", "") != "test_case" or nodes is None:
            return
        h = self.digests.setdefault(self.current, hashlib.sha256())
        h.update(repr([n.value for n in nodes]).encode())
        self.cases[self.current] += 1

    def write(self, path: str) -> None:
        Path(path).write_text(json.dumps({k: f"{self.cases[k]} examples, {h.hexdigest()}"
                                          for k, h in sorted(self.digests.items())}, indent=1))


_DIGESTS = _ExampleDigests()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item):
    _DIGESTS.current = item.nodeid
    return (yield)


@pytest.fixture
def small_scenario_path() -> Path:
    """4 UAVs, 300 s, with a partition, a crash, a late joiner, corruption and 30% drops."""
    return DATA / "faults-small.toml"


@pytest.fixture
def seed1_fails(monkeypatch) -> str:
    """Every ``Simulation.run`` of seed 1 raises ``RuntimeError`` with the returned message (the
    sweeps must record such a run and go on; threads only: the patch is in this process)."""
    from swarm.kernel import simulation

    message = "planted failure"
    real_run = simulation.Simulation.run

    def flaky(self, *a, **kw):
        if self.seed == 1:
            raise RuntimeError(message)
        return real_run(self, *a, **kw)

    monkeypatch.setattr(simulation.Simulation, "run", flaky)
    return message


# --- fault-kind coverage across the session -------------------------------------------------------
# Tests that run generated fault schedules record them here (the `fault_stats` fixture). At the
# end of the session a summary says how often each kind was scheduled and how often the injector
# reported it actually changed something. Only a report: what the session's property tests
# generate depends on which tests ran before them in each worker, so it cannot be a gate that
# passes or fails the same way in any order. The gate is tests/test_fault_coverage.py: a fixed,
# seeded set of examples per registered kind.


class FaultStats:
    def __init__(self) -> None:
        self.schedules = 0  # fault schedules generated (run or not)
        self.runs = 0  # simulations run with a generated schedule
        self.scheduled: Counter[str] = Counter()  # faults per kind in those schedules
        self.fired: Counter[str] = Counter()  # injector fired counts per kind, summed over runs
        self.runs_fired: Counter[str] = Counter()  # runs in which each kind fired at least once

    def schedule(self, faults) -> None:
        self.schedules += 1
        self.scheduled.update(getattr(f, "kind", None) or f["kind"] for f in faults)

    def run(self, faults_applied: dict[str, int]) -> None:
        self.runs += 1
        for kind, n in faults_applied.items():
            self.fired[kind] += n
            if n:
                self.runs_fired[kind] += 1

    def never_fired(self) -> list[str]:
        return [k for k in fault_kinds() if self.fired[k] == 0]

    def to_dict(self) -> dict:
        """What a worker sends the controller (plain data: it crosses a process boundary)."""
        return {"schedules": self.schedules, "runs": self.runs, "scheduled": dict(self.scheduled),
                "fired": dict(self.fired), "runs_fired": dict(self.runs_fired)}

    def add(self, d: dict) -> None:
        """Add a worker's tally (:meth:`to_dict`) to this one."""
        self.schedules += d["schedules"]
        self.runs += d["runs"]
        self.scheduled.update(d["scheduled"])
        self.fired.update(d["fired"])
        self.runs_fired.update(d["runs_fired"])


_STATS = FaultStats()


@pytest.fixture(scope="session")
def fault_stats() -> FaultStats:
    return _STATS


# --- the quick loop's budget ---------------------------------------------------------------------
# `pytest -m "not slow"` should answer in under a minute. At its end, tests that took longer
# than QUICK_TEST_BUDGET_S (setup, call and teardown) are listed: mark them `slow`, or make
# them cheaper, and keep a quick test of the same thing (see tests/README.md). Only a hint.

QUICK_TEST_BUDGET_S = 2.0
_DURATIONS: Counter[str] = Counter()


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if QUICK_LOOP:
        _DURATIONS[report.nodeid] += report.duration


def _quick_loop_summary(tr) -> None:
    over = [(d, nodeid) for nodeid, d in _DURATIONS.items() if d > QUICK_TEST_BUDGET_S]
    if not over:
        return
    tr.section(f"quick loop: tests over {QUICK_TEST_BUDGET_S:g} s not marked slow")
    for d, nodeid in sorted(over, reverse=True):
        tr.write_line(f"{d:6.2f} s  {nodeid}")
    tr.write_line("(a loaded machine inflates these; mark a test @pytest.mark.slow when it is slow on a quiet one)")


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    _quick_loop_summary(terminalreporter)
    _fault_kind_summary(terminalreporter)


def _fault_kind_summary(tr) -> None:
    s = _STATS
    if not s.schedules:
        return
    tr.section("fault-kind coverage (generated schedules)")
    tr.write_line(f"schedules generated: {s.schedules}; simulations run with one: {s.runs}")
    tr.write_line(f"{'kind':10s} {'scheduled':>10s} {'fired':>10s} {'runs fired':>11s}")
    for kind in fault_kinds():
        tr.write_line(f"{kind:10s} {s.scheduled[kind]:10d} {s.fired[kind]:10d} {s.runs_fired[kind]:11d}")
    if s.never_fired():
        tr.write_line(f"(never fired in these {s.runs} runs: {', '.join(s.never_fired())}; a report, not a gate: "
                      f"tests/test_fault_coverage.py is the gate)")


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error) -> None:
    """xdist, in the controller: a worker finished; add its fault-kind tally to the session's."""
    tally = getattr(node, "workeroutput", {}).get("fault_stats")
    if tally:
        _STATS.add(tally)


def pytest_sessionfinish(session, exitstatus):
    digest_path = session.config.getoption("examples_digest", None)
    if digest_path and not _is_worker(session.config):
        _DIGESTS.write(digest_path)
    s = _STATS
    if _is_worker(session.config):  # hand the tally to the controller, which reports the whole session
        session.config.workeroutput["fault_stats"] = s.to_dict()
