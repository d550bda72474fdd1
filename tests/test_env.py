"""``swarm.env``: the PettingZoo parallel environment ``swarm_search_v1`` (docs/env.md).

Checked against PettingZoo's own API and seed tests, and against the simulator: agents leave on
a crash and enter when they join, a restarted UAV stays an agent under the policy, an action is
the waypoint the UAV flies from the first tick of its step, rewards are the step's ground truth
(their sum over agents is the run's coverage and targets found), the same seed gives the same
episode. Skipped without the ``rl`` extra.
"""

from __future__ import annotations

import contextlib
import io
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pettingzoo")
pytest.importorskip("gymnasium")

from pettingzoo.test import parallel_api_test, parallel_seed_test

from agents.planners.dacmp.planner import DacmpPlanner
from swarm.env import ENV_NAME, ExternalPlanner, RewardWeights, parallel_env, swarm_search_v1
from swarm.errors import APIMisuseError, UsageError
from swarm.scenario import apply_overrides, load_scenario


def case1(duration_s: float = 120.0, faults=(), joiners=()):
    """paper-case1, short, with optional faults and extra UAVs (dicts of a [[uavs]] table)."""
    sc = load_scenario("paper-case1")
    overrides: dict = {"duration_s": duration_s}
    if faults:
        overrides["faults"] = list(faults)
    if joiners:
        overrides["uavs"] = [u.model_dump(exclude_none=True) for u in sc.uavs] + list(joiners)
    return apply_overrides(sc, overrides)


def joiner(name: str, join_s: float) -> dict:
    return {"name": name, "type": "B", "x_m": 45_000.0, "y_m": 25_000.0, "heading_deg": 180.0, "join_s": join_s}


def run_random(env, seed: int, action_seed: int = 0):
    """One episode under a seeded random policy: every step's (obs, rewards, term, trunc, infos)."""
    rng = np.random.default_rng(action_seed)
    obs, infos = env.reset(seed=seed)
    steps = [(obs, {}, {}, {}, infos)]
    while env.agents:
        actions = {a: rng.uniform(-1.0, 1.0, 2).astype(np.float32) for a in env.agents}
        steps.append(env.step(actions))
    return steps


def test_docs_example_runs():
    doc = (Path(__file__).resolve().parent.parent / "docs" / "env.md").read_text()
    blocks = [b for b in re.findall(r"```python\n(.*?)```", doc, flags=re.S) if "parallel_env" in b]
    assert blocks, "docs/env.md lost its usage example"
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(blocks[0], "docs/env.md", "exec"), {"__name__": "__main__"})
    assert "'B1':" in out.getvalue() and "'A1'" not in out.getvalue()


@pytest.mark.slow  # whole runs or a subprocess: the full run has it, the quick loop need not
def test_import_swarm_needs_no_pettingzoo():
    code = (
        "import sys\n"
        "import swarm, swarm.kernel.simulation\n"
        "assert 'pettingzoo' not in sys.modules and 'gymnasium' not in sys.modules\n"
        "sys.modules['pettingzoo'] = None  # as if the rl extra were not installed\n"
        "try:\n"
        "    import swarm.env\n"
        "except ImportError as exc:\n"
        "    assert 'uav-swarm-sim[rl]' in str(exc), exc\n"
        "else:\n"
        "    raise AssertionError('swarm.env imported without pettingzoo')\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def test_names_and_version():
    env = parallel_env(scenario=case1())
    assert env.metadata["name"] == ENV_NAME == "swarm_search_v1"
    assert swarm_search_v1.parallel_env is parallel_env
    assert env.possible_agents == ["B1", "B2", "A1"]
    # v1 changed what a restart does (it stays under the policy): the old name no longer imports.
    with pytest.raises(ImportError):
        import swarm.env.swarm_search_v0  # noqa: F401


def test_pettingzoo_parallel_api():
    parallel_api_test(parallel_env(scenario=case1()), num_cycles=20)


def test_pettingzoo_parallel_api_with_crash_and_joiner():
    sc = case1(faults=[{"kind": "crash", "uav": "B1", "at_s": 30.0}], joiners=[joiner("B3", 60.0)])
    parallel_api_test(parallel_env(scenario=sc, controlled=["B"]), num_cycles=20)


def test_pettingzoo_parallel_api_with_restart():
    sc = case1(faults=[{"kind": "restart", "uav": "B1", "at_s": 30.0, "downtime_s": 15.0},
                       {"kind": "crash", "uav": "B2", "at_s": 50.0}])
    parallel_api_test(parallel_env(scenario=sc), num_cycles=20)


def test_a_restarted_uav_stays_an_agent_under_the_policy():
    """Issue 23: a restart gave the UAV the scenario's planner back. It stays in ``agents``
    through its downtime (state "restarting", never terminated) and flies the policy's
    waypoints again from the tick it is back."""
    sc = case1(faults=[{"kind": "restart", "uav": "B1", "at_s": 30.0, "downtime_s": 15.0}])
    env = parallel_env(scenario=sc)
    env.reset(seed=1)
    sim = env.sim
    uid = sim._names["B1"]
    first_actor = sim.actors[uid]
    states = []
    for _ in range(8):  # to 80 s
        assert "B1" in env.agents
        _obs, rewards, term, trunc, infos = env.step({a: np.array([0.3, 0.6], np.float32) for a in env.agents})
        assert not term["B1"] and not trunc["B1"]
        states.append((infos["B1"]["t"], infos["B1"]["state"], rewards["B1"]))
    assert [s[:2] for s in states[2:6]] == [(30.0, "alive"), (40.0, "restarting"), (50.0, "alive"), (60.0, "alive")]
    assert states[3][2] == 0.0  # down for the whole step [30 s, 40 s): nothing scanned, no reward
    actor = sim.actors[uid]
    assert actor is not first_actor  # a fresh actor (empty map) ...
    assert actor.planner is env._planners["B1"]  # ... with the policy's planner, not DACMP's
    # It flies the last action's waypoint: its current plan is the waypoint of the last step.
    assert (actor.plan.wx, actor.plan.wy) == pytest.approx(infos["B1"]["waypoint"])
    # A UAV left to the scenario's planner gets that planner back, as in any run.
    env = parallel_env(scenario=sc, controlled=["A"])
    env.reset(seed=1)
    while env.agents:
        env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert isinstance(env.sim.actors[env.sim._names["B1"]].planner, DacmpPlanner)
    env.close()


def test_pettingzoo_seed_test():
    parallel_seed_test(lambda: parallel_env(scenario="paper-case1"))


def test_random_episode_crash_truncation_and_spaces():
    sc = case1(faults=[{"kind": "crash", "uav": "B1", "at_s": 30.0}])
    env = parallel_env(scenario=sc)
    steps = run_random(env, seed=1)
    assert len(steps) == 1 + 12  # 120 s in steps of replan_s = 10 s
    finished: set[str] = set()
    for i, (obs, rewards, term, trunc, infos) in enumerate(steps):
        assert not finished & set(obs), "an agent came back"
        for a, o in obs.items():
            space = env.observation_space(a)
            assert space.contains(o), (a, o)
            assert all(v.dtype == np.float32 for v in o.values())
            assert infos[a]["t"] == pytest.approx(10.0 * i)
        for a, r in rewards.items():
            assert isinstance(r, float) and math.isfinite(r)
            assert isinstance(term[a], bool) and isinstance(trunc[a], bool)
        finished |= {a for a in term if term[a] or trunc[a]}
    # The crash at 30 s happens at the start of the step [30, 40): B1 leaves after it.
    obs, rewards, term, trunc, infos = steps[4]
    assert term["B1"] and not trunc["B1"] and infos["B1"]["state"] == "crashed"
    assert not any(term[a] for a in ("B2", "A1"))
    assert all("B1" not in s[0] for s in steps[5:])
    # The others are truncated at the scenario's duration.
    obs, rewards, term, trunc, infos = steps[-1]
    assert set(obs) == {"B2", "A1"} and all(trunc.values()) and not any(term.values())
    assert env.agents == [] and env.sim is not None and env.sim.done
    env.close()


def test_late_joiners_enter():
    sc = case1(joiners=[joiner("B3", 60.0), joiner("B4", 35.0)])
    env = parallel_env(scenario=sc)
    steps = run_random(env, seed=0)
    assert env.possible_agents == ["B1", "B2", "A1", "B3", "B4"]
    assert set(steps[0][0]) == {"B1", "B2", "A1"}
    # B4 joins at 35 s (inside the step [30, 40)) and enters when that step ends; B3 joins at
    # 60 s, a step boundary: it enters at 60 s and flies from the tick at 60 s.
    first = {a: next(i for i, s in enumerate(steps) if a in s[0]) for a in ("B3", "B4")}
    assert first == {"B4": 4, "B3": 6}
    obs, rewards, term, trunc, infos = steps[6]
    assert rewards["B3"] == 0.0 and not term["B3"] and not trunc["B3"]
    assert infos["B3"]["state"] == "pending" and infos["B3"]["t"] == 60.0
    assert steps[4][4]["B4"]["state"] == "alive"
    assert steps[7][4]["B3"]["state"] == "alive" and steps[7][4]["B3"]["new_cells"] > 0
    env.close()


def test_waiting_for_a_joiner_when_no_agent_flies():
    """The only flying agent crashes; the episode goes on (the others fly) until the next
    controlled UAV joins, and that step returns it."""
    sc = case1(faults=[{"kind": "crash", "uav": "B1", "at_s": 30.0}], joiners=[joiner("B3", 100.0)])
    env = parallel_env(scenario=sc, controlled=["B1", "B3"])
    env.reset()
    for _ in range(3):
        env.step({"B1": np.array([1.0, 0.0], np.float32)})
    obs, rewards, term, trunc, infos = env.step({"B1": np.array([1.0, 0.0], np.float32)})
    assert term == {"B1": True, "B3": False}
    assert env.agents == ["B3"] and env.sim.now == 100.0 and infos["B3"]["t"] == 100.0
    env.close()


def test_action_is_the_waypoint_flown_from_the_first_tick():
    env = parallel_env(scenario=case1())
    env.reset()
    sim = env.sim
    b1 = sim._world.uavs[sim._names["B1"]]
    planner = env._planners["B1"]
    calls = []  # (t, plan) of every plan request B1 makes
    answer = planner.plan

    def recorded(view):
        calls.append((view.t, answer(view)))
        return calls[-1][1]

    planner.plan = recorded
    reach = 90.0 * 10.0  # speed_max of type B times the period

    def act(forward, left):
        x, y, th = b1.x, b1.y, b1.theta
        _, _, _, _, infos = env.step({"B1": np.array([forward, left], np.float32)})
        wx = x + forward * reach * math.cos(th) - left * reach * math.sin(th)
        wy = y + forward * reach * math.sin(th) + left * reach * math.cos(th)
        assert infos["B1"]["waypoint"] == pytest.approx((wx, wy))
        return wx, wy

    act(0.5, 0.25)  # half the reach ahead, a quarter to the left
    # 10% of the reach: reached in the first ticks, so B1 replans inside the step (the same
    # waypoint again); the next step's action must still take effect at that step's first tick.
    near = act(0.1, 0.0)
    inside = [(t, (p.wx, p.wy)) for t, p in calls if 10.0 < t < 20.0]
    assert inside and all(w == pytest.approx(near) for _, w in inside)
    far = act(-1.0, 1.0)
    t, first = next((t, p) for t, p in calls if t >= 20.0)
    assert t == 20.0 and (first.wx, first.wy) == pytest.approx(far)
    assert sim.actors[sim._names["B1"]].plan.wx == pytest.approx(far[0])
    env.close()


def test_controlled_by_type_keeps_the_scenario_planner_for_the_rest():
    env = parallel_env(scenario=case1(), controlled=["A"])
    assert env.possible_agents == ["A1"]
    env.reset()
    planners = {b.name: type(env.sim.actors[uid].planner) for uid, b in env.sim._world.uavs.items()}
    assert planners == {"B1": DacmpPlanner, "B2": DacmpPlanner, "A1": ExternalPlanner}
    run_random(env, seed=0)
    env.close()
    with pytest.raises(UsageError, match="neither a UAV name"):
        parallel_env(scenario=case1(), controlled=["C7"])


def test_rewards_are_the_ground_truth_of_the_step():
    weights = {"area": 2.0, "found": 7.0, "violation": -3.0}
    env = parallel_env(scenario=case1(), rewards=weights)
    steps = run_random(env, seed=2)
    cells = found = 0
    for _obs, rewards, _term, _trunc, infos in steps[1:]:
        for a, r in rewards.items():
            i = infos[a]
            assert r == pytest.approx(2.0 * i["new_area_km2"] + 7.0 * i["found"] - 3.0 * i["violations"])
            assert i["new_area_km2"] == pytest.approx(i["new_cells"] * 0.01)  # 100 m cells
            cells += i["new_cells"]
            found += i["found"]
    # Every UAV is an agent: their new cells are the run's covered cells, their finds its finds.
    assert cells == env.sim._metrics.covered_cells > 0
    assert found == len(env.sim._metrics.found_t)
    assert RewardWeights.of(weights) == RewardWeights(2.0, 7.0, -3.0)
    with pytest.raises(UsageError, match="unknown reward weight"):
        parallel_env(scenario=case1(), rewards={"coverage": 1.0})
    env.close()


def test_same_seed_same_episode():
    sc = case1(duration_s=60.0)
    env = parallel_env(scenario=sc, controlled=["B"])  # A1 flies DACMP from its own stream
    a = run_random(env, seed=5, action_seed=1)
    assert env.sim.seed == 5
    b = run_random(env, seed=5, action_seed=1)  # reset again: the same episode
    c = run_random(parallel_env(scenario=sc, controlled=["B"]), seed=5, action_seed=1)
    for x, y in ((a, b), (a, c)):
        assert len(x) == len(y)
        for sx, sy in zip(x, y):
            for dx, dy in zip(sx[1:4], sy[1:4]):
                assert dx == dy
            assert sx[0].keys() == sy[0].keys()
            for agent in sx[0]:
                for key in sx[0][agent]:
                    np.testing.assert_array_equal(sx[0][agent][key], sy[0][agent][key])
    env.reset(seed=None)  # the scenario's seed
    assert env.sim.seed == sc.seed
    env.close()


def test_options_and_misuse():
    env = parallel_env(scenario=case1(duration_s=30.0), flatten=True, map_size=5, n_tracks=2)
    obs, _ = env.reset()
    space = env.observation_space("B1")
    assert obs["B1"].shape == space.shape == (5 * 5 + 8 + 2 * 6,)
    assert obs["B1"].dtype == np.float32 and space.contains(obs["B1"])
    with pytest.raises(UsageError, match="shape"):
        env.step({"B1": np.zeros(3, np.float32)})
    with pytest.raises(UsageError, match="unknown agent"):
        env.step({"Z9": np.zeros(2, np.float32)})
    env.close()
    with pytest.raises(APIMisuseError, match="reset"):
        parallel_env(scenario=case1()).step({})
    with pytest.raises(UsageError, match="odd"):
        parallel_env(scenario=case1(), map_size=4)


def geo_coast(duration_s: float = 2400.0):
    """geo-coast, shorter than its 3600 s, long enough that A2 (its battery fault at 1200 s)
    goes home, lands and relaunches."""
    return apply_overrides(load_scenario("geo-coast"), {"duration_s": duration_s})


@pytest.mark.slow  # a 2400 s episode of 6 UAVs (about 5 s)
def test_pettingzoo_parallel_api_whole_mission_with_endurance():
    """Issue 33: with [endurance] a controlled UAV turning for home crashed the env
    (``'NoneType' object has no attribute 'wx'``: each step cleared the plan that takes it
    home). Whole episodes now pass, through going home, landing and relaunching."""
    parallel_api_test(parallel_env(scenario=geo_coast()), num_cycles=200)


@pytest.mark.slow  # a 2400 s episode of 6 UAVs (about 5 s)
def test_going_home_landing_and_relaunching_as_an_agent():
    """docs/env.md, "Agents": a UAV going home flies its way home whatever the action (state
    "homebound"); landed, it stays in ``agents`` (not terminated), observes speed 0 at the base
    and earns 0; relaunched, it flies the policy's waypoints again."""
    env = parallel_env(scenario=geo_coast())
    env.reset(seed=0)
    sim = env.sim
    uid = next(u.uid for u in sim.snapshot().uavs if u.name == "A2")
    seen: list[str] = []
    while env.agents:
        # Always "turn hard left": never the way home.
        obs, rewards, term, trunc, infos = env.step({a: np.array([0.0, 1.0], np.float32) for a in env.agents})
        if "A2" not in infos:
            continue
        state = infos["A2"]["state"]
        if not seen or seen[-1] != state:
            seen.append(state)
        assert not term["A2"]
        b = next(u for u in sim.snapshot().uavs if u.uid == uid)
        e = sim.scenario.endurance
        if state == "homebound":
            plan = sim.actors[uid].plan
            # its way home (to its pad, round the no-fly zone), not the action's waypoint
            assert (plan.wx, plan.wy) != pytest.approx(infos["A2"]["waypoint"])
        if state == "landed":
            assert "A2" in env.agents or trunc["A2"]
            assert rewards["A2"] == 0.0 and obs["A2"]["state"][2] == 0.0
            # on its pad: pads lie pad_spacing_m apart in a row centred on the base
            spread = 0.5 * len(sim.snapshot().uavs) * e.pad_spacing_m
            assert math.hypot(b.x - e.x_m, b.y - e.y_m) <= e.land_radius_m + spread
        if state == "alive" and seen[-4:-1] == ["alive", "homebound", "landed"]:
            assert sim.actors[uid].plan is None or (sim.actors[uid].plan.wx, sim.actors[uid].plan.wy) == pytest.approx(
                infos["A2"]["waypoint"])  # under the policy again
    assert seen == ["pending", "alive", "homebound", "landed", "alive"]  # (A2 takes off in the second wave)
    env.close()


@pytest.mark.slow  # whole episodes of a few generated missions
def test_pettingzoo_parallel_api_on_generated_endurance_missions():
    """Issue 33: whole episodes with random actions pass the API test on generated missions
    with batteries and a base (and lon/lat polygon areas, polygon no-fly zones, wind), where
    UAVs go home, land and relaunch within the episode."""
    from budget import examples
    from hypothesis import HealthCheck, assume, given, settings

    from swarm.testing.strategies import scenarios

    homecomings = []

    @settings(max_examples=examples(8), deadline=None, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
    @given(scenarios(geo=True, max_no_fly=2, wind=True, endurance=True, faults=False, min_uavs=2, max_uavs=3,
                     min_duration_s=60, max_duration_s=150, planners=("greedy",)))
    def episode(scenario):
        assume(scenario.endurance is not None)
        env = parallel_env(scenario=scenario)
        parallel_api_test(env, num_cycles=1000)
        sim = env.sim  # the API test's last episode
        endurance = sim.result().metrics["endurance"]
        homecomings.append((endurance["sorties"] - len(scenario.uavs),
                            sum(1 for p in endurance["per_uav"].values() if p["state"] != "flying")))

    episode()
    # Some UAV went home (and relaunched) in the examples: the API test met those states.
    assert any(relaunches or home for relaunches, home in homecomings), homecomings

