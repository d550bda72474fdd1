"""Many targets (issue 25, item 3): building is linear, and the per-target work of a tick is done
per array, with the numbers of the per-target code it stands in for.

* :func:`swarm.kernel.rng.stream_states`, :func:`~swarm.kernel.rng.first_randoms` and
  :func:`~swarm.kernel.rng.generator_from_state` give the streams of :meth:`RngTree.generator` bit for
  bit (seed words, first draws, and the generator itself);
* a simulation's random targets start where their own generators put them (four uniforms each)
  and move with those generators' later draws, made only when first used;
* :meth:`Targets._step_all` (numpy, every target at once) moves targets exactly as
  :meth:`Targets._step_each` (one by one), reflections and limits included, over several draw
  blocks and with targets added on the way;
* :func:`swarm.kernel.observer.pack_target_events` writes the bytes of packing each event on its own,
  :meth:`EventLog.extend_packed` logs them as ``extend`` would (subscribers get the tuples);
* the observer's target paths are the per-target rows it kept before;
* the memory guard refuses a million targets over paper-case1's 600 s with one error naming
  ``targets.count``, and not over a few seconds.
"""

from __future__ import annotations

import math

import msgpack
import numpy as np
import pytest

from agents.maps.grid import Grid
from swarm import Simulation
from swarm.kernel.memory import MemoryLimitError, estimate_memory
from swarm.kernel.observer import pack_target_events
from swarm.kernel.recorder import EventLog
from swarm.kernel.rng import RngTree, first_randoms, generator_from_state, stream_states
from swarm.kernel.world import _DRAW_BLOCK, TargetMotion, Targets
from swarm.scenario import load_scenario


@pytest.mark.parametrize("seed", [0, 1, 7, 2**32 - 1, 2**32, 2**40 + 5, 12345678901234567890])
def test_stream_states_and_first_draws_are_the_generators(seed):
    tree = RngTree(seed)
    ids = range(0, 300)
    states = stream_states(seed, ("target",), ids)
    u = first_randoms(states, 5)
    for i in (0, 1, 17, 128, 299):
        g = tree.generator("target", i)
        assert u[i - ids.start].tolist() == g.random(5).tolist()
        assert generator_from_state(states[i]).standard_normal(40).tolist() == \
            tree.generator("target", i).standard_normal(40).tolist()
    other = stream_states(seed, ("link", "A1"), range(1000, 1010))
    assert first_randoms(other, 3).tolist() == [tree.generator("link", "A1", i).random(3).tolist()
                                                 for i in range(1000, 1010)]


def _old_targets(sim_seed: int, n: int, width: float, height: float, speed_max: float, value: float) -> Targets:
    """The targets as the simulation placed them before issue 25: one generator each, four
    uniforms drawn from it, kept for the target's motion."""
    tree = RngTree(sim_seed)
    tg = Targets(TargetMotion(speed_max=speed_max))
    for i in range(n):
        g = tree.generator("target", i)
        tg.add(float(g.uniform(0, width)), float(g.uniform(0, height)), float(g.uniform(-math.pi, math.pi)),
               float(g.uniform(0, speed_max)), value, g)
    return tg


def _state(tg: Targets) -> list[list[float]]:
    return [a.tolist() for a in (tg.x, tg.y, tg.v, tg.theta, tg.a, tg.omega, tg.value)]


@pytest.mark.parametrize("n", [3, 40, 300])
def test_a_simulations_random_targets_are_those_of_their_own_generators(n):
    sc = load_scenario("paper-case1", overrides={"targets.count": n, "targets.placed": []})
    with Simulation(sc, seed=5) as sim:
        grid = sim._grid
        old = _old_targets(5, n, grid.width_m, grid.height_m, sim._targets.motion.speed_max, sc.targets.value)
        old.motion = sim._targets.motion
        assert _state(sim._targets) == _state(old)
        assert not any(g is not None for g in sim._targets._gens)  # no stream made yet
        for _ in range(_DRAW_BLOCK // 2 + 3):  # past a block of draws
            sim._targets.step(sim.dt, grid)
            old._step_each(sim.dt, grid)
        assert _state(sim._targets) == _state(old)


def _random_targets(tg: Targets, rng: np.random.Generator, n: int, w: float, h: float, first_seed: int) -> None:
    for k in range(n):
        # some on the border, some at rest or at full speed, some turning hard: every branch
        x = float(rng.choice([0.0, w, rng.uniform(0, w), 1e-9]))
        y = float(rng.choice([0.0, h, rng.uniform(0, h), h - 1e-9]))
        v = float(rng.choice([0.0, tg.motion.speed_max, rng.uniform(0, tg.motion.speed_max)]))
        tg.add(x, y, float(rng.uniform(-4, 4)), v, 1.0, np.random.default_rng(first_seed + k))
    tg._s[4, :len(tg)] = rng.uniform(-1, 1, len(tg))  # accelerations and turn rates beyond the limits
    tg._s[5, :len(tg)] = rng.uniform(-0.3, 0.3, len(tg))


@pytest.mark.parametrize("seed", range(4))
def test_all_targets_at_once_move_as_one_by_one(seed):
    rng = np.random.default_rng(seed)
    motion = TargetMotion(speed_max=20.0, accel_max=2.0, accel_sigma=3.0, turn_sigma=0.2, turn_rate_max=0.2)
    grid = Grid(3000.0, 2000.0, 100.0)
    one, all_ = Targets(motion), Targets(motion)
    for tg in (one, all_):
        _random_targets(tg, np.random.default_rng(seed), 50, grid.width_m, grid.height_m, 100 * seed)
    dt = float(rng.choice([0.5, 1.0, 2.0]))
    for step in range(150):
        if step in (20, 90):  # targets added on the way start their own draws
            for tg in (one, all_):
                _random_targets(tg, np.random.default_rng(seed + step), 7, grid.width_m, grid.height_m, 1000 + step)
        one._step_each(dt, grid)
        all_._step_all(dt, grid)
        assert _state(one) == _state(all_), step
    assert one.xy.tolist() == all_.xy.tolist()


def test_targets_sharing_a_generator_share_its_draws_in_order():
    shared, own = np.random.default_rng(1), np.random.default_rng(2)
    tg = Targets(TargetMotion())
    for rng in (shared, own, shared):
        tg.add(10.0, 10.0, 0.0, 1.0, 1.0, rng)
    assert tg._slot[0] == tg._slot[2] != tg._slot[1] and tg._shared
    for _ in range(_DRAW_BLOCK):  # step() goes one by one: target 0 draws before target 2
        tg.step(1.0, Grid(1000.0, 1000.0, 100.0))
    expected = np.random.default_rng(1).standard_normal(4 * _DRAW_BLOCK)
    assert tg._buf[tg._slot[0]].tolist() == expected[3 * _DRAW_BLOCK:].tolist()  # (4 draws a step)


@pytest.mark.parametrize("n", [0, 1, 127, 128, 255, 256, 257, 65535, 65536, 65600])
def test_packed_target_events_are_the_events_packed(n):
    xy = np.random.default_rng(n).normal(size=(n, 2)) * 1e4
    if n:
        xy[0] = (-0.0, math.inf)
    packer = msgpack.Packer(use_bin_type=True)
    expected = b"".join(packer.pack(("target", 12.5, i, x, y)) for i, (x, y) in enumerate(xy.tolist()))
    assert pack_target_events(12.5, xy) == expected


def test_extend_packed_logs_what_extend_would():
    events = [("target", 1.0, i, float(i), 2.0 * i) for i in range(300)]
    data = pack_target_events(1.0, np.array([[e[3], e[4]] for e in events]))
    a, b, c = EventLog(), EventLog(), EventLog()
    got: list[tuple] = []
    c.subscribe(got.append, ["target"])
    for log in (a, b, c):
        log.emit("pose", 1.0, 0)
    a.extend(events)
    b.extend_packed(data, len(events), lambda: events)
    c.extend_packed(data, len(events), lambda: events)
    for log in (a, b, c):
        log.emit("violation", 1.0, "x", 0, 1)
    assert a.to_bytes() == b.to_bytes() == c.to_bytes() and a.total == b.total == c.total
    assert [(g.kind, g.t, g.target, g.x, g.y) for g in got] == events  # (subscribers get records)


def test_target_paths_are_the_rows_each_target_was_observed_at():
    sc = load_scenario("paper-case1", overrides={"targets.count": 300})
    with Simulation(sc, duration_s=30.0) as sim:
        rows: dict[int, list[tuple[float, float, float]]] = {}
        sim.subscribe(lambda e: rows.setdefault(e.target, []).append((e.t, e.x, e.y)), ["target"])
        sim.step(10)
        sim.add_target(100.0, 200.0)
        sim.step(5)
        paths = sim.result().target_paths
    assert sorted(paths) == sorted(rows) == list(range(len(sim._targets)))
    for i, p in paths.items():
        assert p.shape == (len(rows[i]), 3) and p.tolist() == [list(r) for r in rows[i]]
    assert len(paths[0]) == 15 and len(paths[len(sim._targets) - 1]) == 5


def test_a_million_targets_are_refused_over_600_s_not_over_a_few():
    sc = load_scenario("paper-case1", overrides={"targets.count": 1_000_000})
    with pytest.raises(MemoryLimitError) as err:
        Simulation(sc, memory_limit_gb=8.0)
    message = str(err.value)
    assert "\n" not in message and "targets.count" in message and "target events" in message
    est = estimate_memory(load_scenario("paper-case1", overrides={"targets.count": 1_000_000, "duration_s": 2.0}))
    assert est.total < 2 * 1024**3
