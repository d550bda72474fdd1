"""Every built-in scenario through every path that reads a run, as a user would take it.

Driven by :func:`swarm.scenario.builtin_scenarios`: a new built-in joins without an edit here
(give it a shorter run in ``SHORT`` if it is heavy). For each: ``swarm run`` (figures on) ->
``swarm rerun`` (the same hash) -> ``load_run_log`` + ``check_events`` (no violation that no fault
explains) -> ``swarm report`` -> ``swarm animate`` (GIF) -> ``swarm export --format parquet`` (the
event rows are the log's events) -> a one-run ``swarm sweep`` whose table row carries every
numeric metric of the run's ``metrics.json`` -> the PettingZoo environment for a whole episode.
The same for generated scenarios (geography, wind, endurance, faults) in
``test_generated_missions_through_every_path``.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings

from swarm.cli import main
from swarm.events import read_events
from swarm.scenario import builtin_scenarios, load_scenario
from swarm.testing import scenarios
from swarm.testing.invariants import check_events, load_run_log

# Simulated seconds per built-in (default DEFAULT_S): the big ones build thousands of links.
DEFAULT_S = 20.0
SHORT = {"bench-1000": 3.0, "bench-dense-300": 3.0, "bench-100": 10.0}


def _numeric_leaves(value, prefix: str = "") -> dict[str, float]:
    """The numeric leaves of a JSON value by dotted path (what a sweep table must carry)."""
    if isinstance(value, bool):
        return {}
    if isinstance(value, (int, float)):
        return {prefix: float(value)}
    if isinstance(value, dict):
        out: dict[str, float] = {}
        for key, item in value.items():
            out.update(_numeric_leaves(item, f"{prefix}.{key}" if prefix else str(key)))
        return out
    return {}


def _through_every_path(name: str, tmp_path: Path, duration: float, extra: list[str] = ()) -> None:
    run = tmp_path / "run"
    assert main(["run", name, "--duration", str(duration), "--seed", "3", "--out", str(run), "--quiet", *extra]) == 0
    metrics = json.loads((run / "metrics.json").read_text())
    assert (run / "trajectories.png").stat().st_size > 0

    # Re-run from the folder: the same event-log hash.
    assert main(["rerun", str(run), "--out", str(tmp_path / "again"), "--quiet", "--no-figures"]) == 0

    # The checkers read the folder back and find nothing that no fault explains.
    sc, events = load_run_log(run)
    assert sc.name == metrics["scenario"]
    unexplained = [v for v in check_events(events, sc) if not v.faults]
    assert not unexplained, "\n".join(map(str, unexplained[:5]))

    # Report and animation.
    assert main(["report", str(run), "--quiet"]) == 0
    assert (run / "report.html").stat().st_size > 0
    assert main(["animate", str(run), "--out", str(run / "animation.gif"), "--quiet", "--speed", "30"]) == 0
    assert (run / "animation.gif").stat().st_size > 0

    # Parquet: one row per event, kind by kind.
    pq = pytest.importorskip("pyarrow.parquet")
    assert main(["export", str(run), "--format", "parquet", "--out", str(tmp_path / "pq"), "--quiet"]) == 0
    counts: dict[str, int] = {}
    for ev in read_events((run / "events.msgpack").read_bytes()):
        counts[ev.kind] = counts.get(ev.kind, 0) + 1
    for kind, n in counts.items():
        assert pq.read_metadata(tmp_path / "pq" / f"{kind}.parquet").num_rows == n, kind
    assert sum(counts.values()) == len(events)

    # A sweep of this one run: its table row carries every numeric metric.
    sweep = tmp_path / "sweep"
    assert main(["sweep", name, "--seeds", "3-3", "--planner", sc.planner.name, "--duration", str(duration),
                 "--workers", "1", "--out", str(sweep), "--quiet", *extra]) in (0,)
    with open(sweep / "runs.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 1
    row = rows[0]
    swept = json.loads(next(sweep.glob("runs/*/*/seed-003/metrics.json")).read_text())
    assert swept["event_log_sha256"] == metrics["event_log_sha256"]
    leaves = {k: v for k, v in _numeric_leaves(swept).items() if k not in ("wall_seconds", "seed")}
    missing = sorted(set(leaves) - set(row))
    assert not missing, f"runs.csv lacks {len(missing)} numeric metrics, e.g. {missing[:8]}"
    for key, value in leaves.items():
        cell = row[key]
        if "share" in key and cell not in ("", None):
            assert 0.0 <= float(cell) <= 1.0, (key, cell)
        if cell not in ("", None) and math.isfinite(value):
            assert float(cell) == pytest.approx(value, rel=1e-9, abs=1e-12), key


@pytest.mark.slow
@pytest.mark.parametrize("name", builtin_scenarios())
def test_builtin_through_every_path(name, tmp_path):
    _through_every_path(name, tmp_path, SHORT.get(name, DEFAULT_S))


@pytest.mark.slow
@pytest.mark.parametrize("name", builtin_scenarios())
def test_builtin_env_flies_a_whole_episode(name):
    """The PettingZoo environment flies each built-in for a whole (short) episode with random
    actions, every UAV controlled."""
    pytest.importorskip("pettingzoo")
    from swarm.env import parallel_env

    sc = load_scenario(name)
    env = parallel_env(scenario=sc, duration_s=SHORT.get(name, DEFAULT_S))
    try:
        env.reset(seed=1)
        assert env.agents, f"{name}: no UAV to control"
        rng = np.random.default_rng(0)
        steps = 0
        while env.agents:
            actions = {a: rng.uniform(-1.0, 1.0, 2).astype(np.float32) for a in env.agents}
            _obs, rewards, terms, truncs, _infos = env.step(actions)
            assert all(math.isfinite(r) for r in rewards.values())
            steps += 1
        assert steps >= 1
    finally:
        env.close()


@pytest.mark.slow
@settings(max_examples=3, derandomize=True, database=None, deadline=None, phases=[Phase.generate],
          suppress_health_check=list(HealthCheck))
@given(sc=scenarios(geo=True, max_no_fly=2, wind=True, endurance=None, max_uavs=4, min_duration_s=30,
                    max_duration_s=40, max_faults=3))
def test_generated_missions_through_every_path(sc, tmp_path_factory):
    """Generated missions with a lon/lat area, polygon no-fly zones, wind, faults and batteries
    with a base (as the rule tests have them: ``strategies.ENDURANCE_IN_RULE_TESTS``), written as
    the toolkit's reproduction file, through every path; then a whole episode of the env."""
    from swarm.env import parallel_env
    from swarm.testing.strategies import reproduction

    tmp = tmp_path_factory.mktemp("mission")
    path, _command = reproduction(sc, tmp)
    _through_every_path(str(path), tmp, sc.duration_s, extra=["--allow-planner-imports"])
    env = parallel_env(scenario=str(path))
    try:
        env.reset(seed=1)
        rng = np.random.default_rng(0)
        while env.agents:
            env.step({a: rng.uniform(-1.0, 1.0, 2).astype(np.float32) for a in env.agents})
    finally:
        env.close()
