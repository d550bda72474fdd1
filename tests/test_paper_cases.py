"""The paper's Cases 1-3 (section 4.3, Fig. 12-18), from the event log and the metrics.

Case 1: the fast-to-slow handover. Case 2: every target found and watched by one UAV at the end,
slow UAVs taking targets over from fast ones, no threat or separation violation. Case 3: the
joining UAV raises coverage.

Case 1 (one 600 s run of 3 UAVs, under a second) is in the quick loop; Case 2 and 3 (2000 s runs
of 10-11 UAVs, over several seeds) are marked ``slow``. Case 2's criterion across seeds 0-19,
judged on 4000 s runs (DACMP-SPEC "Reproduction targets": at least 18 of 20), is
``test_case2_criterion.py``.

Each (scenario, seed) runs once per session and its digest is shared by every test that reads
it, on any xdist worker (:func:`case_runs`: the first test that needs a run makes it, holding a
lock on it; the others read it). No fixture is module-scoped, so the tests are spread over the
workers one by one, and so are the runs.
"""

from __future__ import annotations

import fcntl
import math
import os
import pickle
from collections.abc import Callable
from pathlib import Path

import pytest

from comms.messages import MODE_NAMES, MODE_SURVEIL
from swarm import Simulation, load_scenario
from swarm.events import Pose, Target, read_events

SURVEIL = MODE_NAMES[MODE_SURVEIL]  # poses carry mode names


CaseRuns = Callable[[str, "int | None"], dict]


@pytest.fixture(scope="session")
def case_runs(tmp_path_factory) -> CaseRuns:
    """``case_runs(scenario, seed)``: the digest of that run (:func:`_case_run`), made once in
    the session. Under xdist the workers share a folder (the session's base temporary folder,
    not a worker's), and a lock per run, so a run is made by one worker and read by the others."""
    folder = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        folder = folder.parent  # (the session's; each worker's own is below it)
    folder = folder / "paper-case-runs"
    folder.mkdir(exist_ok=True)
    memo: dict[Path, dict] = {}

    def run(scenario: str, seed: int | None = None) -> dict:
        path = folder / f"{scenario}-seed-{seed}.pickle"
        if path not in memo:
            with open(path.with_suffix(".lock"), "w") as lock:
                fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
                if path.exists():
                    memo[path] = pickle.loads(path.read_bytes())
                else:
                    memo[path] = _case_run(scenario, seed)
                    path.write_bytes(pickle.dumps(memo[path]))
        return memo[path]

    return run


@pytest.fixture
def case1(case_runs):
    return case_runs("paper-case1", None)


def _watch_intervals(events, names):
    """(uav name, target) -> seconds spent in surveillance mode of that target (pose events,
    one per UAV per 1 s tick)."""
    seconds: dict[tuple[str, int], float] = {}
    for e in events:
        if e.kind == "pose" and e.mode == SURVEIL:
            key = (names[e.uav], e.target)
            seconds[key] = seconds.get(key, 0.0) + 1.0
    return seconds


def test_case1_slow_uav_takes_target_1_over_and_the_fast_finder_returns_to_search(case1):
    m, events = case1["metrics"], case1["events"]
    found = {e.target: e.uav_name for e in events if e.kind == "found"}
    assert found[0] == "B1"  # target 1 (id 0) is found by fast UAV 1, as in Fig. 12a
    handovers = [h for h in m["handover_list"] if h["target"] == 0]
    assert handovers and handovers[0]["from"] == "B1" and handovers[0]["to"] == "A1"
    t_hand = handovers[0]["t"]
    last = {}
    for e in events:
        if e.kind == "pose":
            last[e.uav_name] = (e.mode, e.target)
    assert last["A1"] == (SURVEIL, 0)  # the slow UAV ends up watching target 1
    assert last["B1"][0] != SURVEIL  # ... and the fast one is searching again
    b1_after = [e for e in events if e.kind == "pose" and e.uav_name == "B1" and e.t > t_hand + 30]
    assert b1_after and all(e.mode != SURVEIL for e in b1_after)
    assert m["surveillance_ratio"]["0"] > 0.5
    assert m["violations"] == {"separation": 0, "threat": 0, "dynamics": 0}


def test_case1_a_fast_uav_does_not_capture_a_target_already_watched(case1):
    watched = _watch_intervals(case1["events"], case1["names"])
    # Target 2 (id 1) is watched by B2; B1 never joins it, and no two fast UAVs share a target.
    assert watched.get(("B2", 1), 0.0) > 300
    assert watched.get(("B1", 1), 0.0) == 0.0
    for target in (0, 1):
        fast = [u for (u, t), s in watched.items() if t == target and u.startswith("B") and s > 0]
        assert len(fast) == 1, (target, fast)


# --- Case 2 and Case 3 (section 4.3, Fig. 13-18) --------------------------------------------------
# One run per (scenario, seed), shared by the tests below (case_runs). A paper-case2 run takes
# 5-10 s on the 2-core machine, paper-case3 a little more.

CASE_SEEDS = (0, 1, 2, 3, 4)  # the statistical checks; 0 is the scenarios' default seed
_FROM_S = 600.0  # Case 3: coverage at or above Case 2's from here on (mean over CASE_SEEDS)


def _case_run(scenario: str, seed: int | None = None) -> dict:
    """What the tests read from one run (the event log itself is kept for Case 1 only: 600 s of 3 UAVs)."""
    with Simulation(scenario, seed=seed) as sim:
        result = sim.run()
        names = {uid: b.name for uid, b in sim._world.uavs.items()}
        radius = {b.name: b.kind.detect_radius for b in sim._world.uavs.values()}
        speed = {b.name: b.kind.speed_max for b in sim._world.uavs.values()}
    events = list(read_events(result.events))
    handover_ticks = {e.t for e in events if e.kind == "handover"}
    t_end = max(e.t for e in events if e.kind == "pose")
    poses: dict[float, dict[str, tuple]] = {}  # t -> name -> (x, y, mode, target), at handovers and the end
    targets: dict[float, dict[int, tuple]] = {}
    modes: dict[str, list[tuple]] = {}  # name -> [(t, mode, target)] every tick
    for e in events:
        if isinstance(e, Pose):
            modes.setdefault(names[e.uav], []).append((e.t, e.mode, e.target))
            if e.t in handover_ticks or e.t == t_end:
                poses.setdefault(e.t, {})[names[e.uav]] = (e.x, e.y, e.mode, e.target)
        elif isinstance(e, Target) and (e.t in handover_ticks or e.t == t_end):
            targets.setdefault(e.t, {})[e.target] = (e.x, e.y)
    return {"metrics": result.metrics, "timeseries": result.timeseries, "radius": radius, "speed": speed,
            "poses": poses, "targets": targets, "modes": modes, "t_end": t_end, "names": names,
            "events": events if scenario == "paper-case1" else None}


def _watchers_at_end(run: dict) -> dict[int, list[tuple[str, bool]]]:
    """Target -> (UAV, target inside its detection radius) for every UAV in surveillance mode
    assigned to it at the last tick."""
    t = run["t_end"]
    out: dict[int, list[tuple[str, bool]]] = {m: [] for m in run["targets"][t]}
    for name, (x, y, mode, target) in sorted(run["poses"][t].items()):
        if mode == SURVEIL and target >= 0:
            tx, ty = run["targets"][t][target]
            out[target].append((name, math.hypot(x - tx, y - ty) <= run["radius"][name]))
    return out


def _fast_to_slow(run: dict) -> list[dict]:
    speed = run["speed"]
    return [h for h in run["metrics"]["handover_list"] if speed[h["from"]] > speed[h["to"]]]


def _lets_go(run: dict, h: dict, for_s: float = 60.0) -> bool:
    """The old watcher of handover ``h`` does not watch that target from the handover on, for
    ``for_s`` seconds (it may find and watch another one)."""
    after = [(mode, target) for t, mode, target in run["modes"][h["from"]] if h["t"] <= t <= h["t"] + for_s]
    return bool(after) and (SURVEIL, h["target"]) not in after


@pytest.fixture
def case2(case_runs):
    return case_runs("paper-case2", load_scenario("paper-case2").seed)  # the scenario's own seed


# With the paper's layout (targets straight ahead of the UAVs that found them in the paper, not
# where our fast UAVs happen to drift) the default seed misses target 2: fast UAV B2 passes it at
# 2.4 km on its first pass and no UAV finds it in 2000 s. A search result, not a handover one:
# how often the conditions hold is test_case2_holds_on_at_least_18_of_20_seeds.
_SEED0_MISSES_TARGET_2 = pytest.mark.xfail(strict=False, reason="default seed: target 2 never found (first-pass "
                                           "search miss); see test_case2_holds_on_at_least_18_of_20_seeds")


@pytest.mark.slow  # the case2 fixture: a 2000 s run of 10 UAVs
@_SEED0_MISSES_TARGET_2
def test_case2_every_target_is_found(case2):
    m = case2["metrics"]
    assert m["targets_total"] == 6
    assert m["targets_found"] == 6


@pytest.mark.slow  # the case2 fixture: a 2000 s run of 10 UAVs
@_SEED0_MISSES_TARGET_2
def test_case2_each_target_ends_watched_by_exactly_one_uav_that_sees_it(case2):
    watchers = _watchers_at_end(case2)
    assert len(watchers) == 6
    for target, ws in sorted(watchers.items()):
        assert len(ws) == 1, (target, ws)
        assert ws[0][1], f"target {target} is assigned to {ws[0][0]} but outside its detection radius"
    # Five slow UAVs cannot watch six targets: at least one is kept by a fast one.
    assert any(case2["speed"][ws[0][0]] == max(case2["speed"].values()) for ws in watchers.values())


@pytest.mark.slow  # the case2 fixture: a 2000 s run of 10 UAVs
def test_case2_slow_uavs_take_at_least_four_targets_over_from_fast_ones(case2):
    handovers = _fast_to_slow(case2)
    assert case2["metrics"]["handovers_fast_to_slow"] == len(handovers)
    assert len(handovers) >= 4, handovers
    for h in handovers:
        # A handover is an arrival: the slow UAV watches the target and has it in its sensor.
        x, y, mode, target = case2["poses"][h["t"]][h["to"]]
        tx, ty = case2["targets"][h["t"]][h["target"]]
        assert (mode, target) == (SURVEIL, h["target"])
        assert math.hypot(x - tx, y - ty) <= case2["radius"][h["to"]]
        # ... and the fast one has let the target go (it is free to find and watch another).
        assert _lets_go(case2, h), h


@pytest.mark.slow  # the case2 fixture: a 2000 s run of 10 UAVs
def test_case2_no_threat_or_separation_violations(case2):
    assert case2["metrics"]["violations"] == {"separation": 0, "threat": 0, "dynamics": 0}


@pytest.mark.slow
@pytest.mark.parametrize("seed", CASE_SEEDS)
def test_case2_assignment_and_safety_hold_on_every_seed(seed, case_runs):
    """What must hold on any seed, whatever the search finds: no violations, never two UAVs
    on one target at the end but during a handover (a faster one that has the target in sight
    and a slower relief on its way, which the faster one waits for: rule 3 of docs/modelling.md's
    "Assignment rules"), and a fast UAV that hands a target over lets it go."""
    run = case_runs("paper-case2", seed)
    assert run["metrics"]["violations"] == {"separation": 0, "threat": 0, "dynamics": 0}
    speed = run["speed"]
    for target, ws in _watchers_at_end(run).items():
        handing_over = (len(ws) == 2 and [sees for _, sees in sorted(ws, key=lambda w: speed[w[0]])] == [False, True]
                        and speed[ws[0][0]] != speed[ws[1][0]])
        assert len(ws) <= 1 or handing_over, (seed, target, ws)
    for h in _fast_to_slow(run):
        assert _lets_go(run, h), (seed, h)


@pytest.mark.slow
def test_case2_over_seeds_finds_targets_and_hands_them_over(case_runs):
    """Means over CASE_SEEDS (the default seed alone is one draw of the search): targets found
    and fast-to-slow handovers."""
    runs = [case_runs("paper-case2", s) for s in CASE_SEEDS]
    found = [r["metrics"]["targets_found"] for r in runs]
    handovers = [r["metrics"]["handovers_fast_to_slow"] for r in runs]
    assert sum(found) / len(found) >= 5.5, found
    assert sum(handovers) / len(handovers) >= 3.5, handovers
    assert min(handovers) >= 2, handovers


@pytest.mark.slow
def test_case3_coverage_with_the_joiner_is_at_least_case2s_from_600_s(case_runs):
    """Fig. 18: the eleventh UAV (joining at 300 s) raises coverage; mean over CASE_SEEDS, at
    every sample from 600 s on."""
    def mean_coverage(scenario):
        series = []
        for s in CASE_SEEDS:
            rows = case_runs(scenario, s)["timeseries"]
            series.append({r["t"]: r["coverage"] for r in rows})
        times = sorted(set.intersection(*(set(c) for c in series)))
        return {t: sum(c[t] for c in series) / len(series) for t in times}
    case2, case3 = mean_coverage("paper-case2"), mean_coverage("paper-case3")
    times = [t for t in sorted(case2) if t >= _FROM_S and t in case3]
    assert times and times[-1] == 2000.0
    below = [(t, round(case3[t], 4), round(case2[t], 4)) for t in times if case3[t] < case2[t]]
    assert not below, below
