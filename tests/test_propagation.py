"""Radio propagation (``[radio] model``): the disk model, whose loss never falls with distance,
and the log-distance model (link budget, log-normal shadowing, logistic loss in the margin).

Checked against: frame counts over many broadcasts on a two-node :class:`~comms.radio.Radio`
(statistical, with bounds of several standard errors and fixed seeds), the closed forms of the
models, a graph rebuilt from scratch, the scenario's error messages, and whole runs replayed.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from test_one_definition import _same_fields

from comms.radio import Delivery, Radio
from comms.settings import LinkModel, LogDistance
from swarm import Simulation
from swarm.errors import ScenarioError
from swarm.scenario import apply_overrides, load_scenario, parse_scenario
from swarm.scenario import generated as scenario_model


def link_rng(seed: int):
    return lambda src, dst: np.random.default_rng([seed, src, dst])


def measured_loss(model: LinkModel, d: float, n: int, seed: int = 0, dt: float = 1.0) -> float:
    """The share of ``n`` frames (one every ``dt`` s) lost on a link ``d`` metres long."""
    radio = Radio(model, link_rng(seed))
    radio.update_topology([0, 1], np.array([[0.0, 0.0], [d, 0.0]]), dt)
    if not radio.neighbours(0):
        return 1.0
    out: list[Delivery] = []
    for k in range(n):
        radio.broadcast(k * dt, 0, b"frame", out)
    return 1.0 - len(out) / n


# --- the disk model --------------------------------------------------------------------------------


def test_disk_loss_at_range_defaults_to_loss_base():
    m = LinkModel(range_m=15_000.0, loss_base=0.2)
    assert m.loss_at_range == 0.2 and m == LinkModel(range_m=15_000.0, loss_base=0.2, loss_at_range=0.2)
    assert all(m.loss(d) == 0.2 for d in (0.0, 1.0, 5000.0, 14_999.0, 15_000.0, 1e9))


@pytest.mark.parametrize("at_range", [None, 0.2, 0.5])
def test_disk_measured_loss_is_at_least_loss_base_at_every_distance(at_range):
    """The trap this replaces: loss_base = 0.2 with a 15 km range used to lose ~10% of frames
    (0.2 at 0 m falling to 0 at the limit), fewer the farther apart the UAVs."""
    model = LinkModel(range_m=15_000.0, loss_base=0.2, loss_at_range=at_range)
    n = 20_000
    se = math.sqrt(0.2 * 0.8 / n)
    losses = []
    for i, d in enumerate((0.0, 1000.0, 5000.0, 10_000.0, 14_000.0, 15_000.0)):
        assert model.loss(d) >= 0.2
        got = measured_loss(model, d, n, seed=100 + i)
        assert got >= 0.2 - 4 * se, (d, got)  # at least 0.2 (4 standard errors of slack)
        assert abs(got - model.loss(d)) < 4 * math.sqrt(model.loss(d) * (1 - model.loss(d)) / n) + 1e-9
        losses.append(got)
    if at_range == 0.5:
        assert losses[-1] > losses[0] + 0.2  # rises towards the limit


def test_disk_loss_may_not_fall_with_distance():
    with pytest.raises(ValueError, match="must not fall"):
        LinkModel(range_m=15_000.0, loss_base=0.2, loss_at_range=0.0)


def test_disk_interpolation_is_quadratic_in_distance():
    m = LinkModel(range_m=1000.0, loss_base=0.1, loss_at_range=0.5)
    assert m.loss(0.0) == 0.1 and m.loss(500.0) == pytest.approx(0.1 + 0.4 * 0.25) and m.loss(2000.0) == 0.5


# --- the scenario's disk settings --------------------------------------------------------------------

DOC = {"name": "prop", "seed": 2, "duration_s": 40.0, "area": {"width_m": 8000.0, "height_m": 8000.0},
       "uavs": [{"type": "B", "x_m": 1000.0, "y_m": 1000.0}, {"type": "A", "x_m": 2500.0, "y_m": 2500.0},
                {"type": "B", "x_m": 4000.0, "y_m": 1000.0}, {"type": "A", "x_m": 1000.0, "y_m": 5000.0}],
       "targets": {"count": 2}, "planner": {"name": "greedy"}}


def scenario(**radio):
    return parse_scenario({**DOC, "radio": radio})


def test_scenario_loss_at_range_follows_loss_base_when_absent():
    s = scenario(range_m=15_000.0, loss_base=0.2)
    assert s.radio.loss_at_range is None and s.radio.effective_loss_at_range == 0.2
    with Simulation(s) as sim:
        assert sim._radio.model.loss(14_000.0) == 0.2
    # --set radio.loss_base on a scenario that never gave loss_at_range: the whole curve moves
    s2 = apply_overrides(s, {"radio.loss_base": 0.4})
    assert s2.radio.effective_loss_at_range == 0.4
    assert load_scenario("paper-fig11").radio.loss_at_range is None


@pytest.mark.parametrize("radio, expected", [
    ({"loss_base": 0.3, "loss_at_range": 0.1}, "a number in [0.3, 1] (>= loss_base"),
    ({"model": "log_distance", "loss_at_range": 0.5}, 'to be left out with model = "log_distance"'),
    ({"model": "cone"}, "one of: disk, log_distance"),
])
def test_radio_model_mistakes_name_their_key(radio, expected):
    with pytest.raises(ScenarioError) as info:
        scenario(**radio)
    key = "radio.model" if "model" in radio and radio["model"] == "cone" else "radio.loss_at_range"
    assert info.value.key == key and info.value.expected.startswith(expected)


@pytest.mark.parametrize("field, value, expected", [
    ("exponent", 0.0, "a number in (0, 10]"),
    ("sigma_db", -1.0, "a number in [0, 30]"),
    ("corr_s", 0.0, "a number > 0"),
    ("width_db", 0.0, "a number > 0"),
    ("edge_sigmas", 11.0, "a number in [0, 10]"),
    ("ref_loss_db", -3.0, "a number >= 0"),
    ("tx_power_dbm", "loud", "a number"),
])
def test_log_distance_settings_are_validated_with_their_key_path(field, value, expected):
    with pytest.raises(ScenarioError) as info:
        scenario(model="log_distance", log_distance={field: value})
    assert info.value.key == f"radio.log_distance.{field}" and info.value.expected.startswith(expected)


def test_the_log_distance_table_is_generated_from_the_radio_dataclass():
    _same_fields(LogDistance, scenario_model.LogDistanceSettings)
    s = scenario(model="log_distance", log_distance={"sigma_db": 2.0}, range_m=2500.0)
    assert s.radio.log_distance_model() == LogDistance(sigma_db=2.0)
    assert scenario().radio.log_distance_model() is None
    with Simulation(s) as sim:
        assert sim._radio.model.log_distance == LogDistance(sigma_db=2.0)
        assert sim._radio.model.radius_m == s.radio.range_limit_m == 2500.0  # range_m caps the budget's range
    assert scenario(model="log_distance").radio.range_limit_m == LogDistance().range_m


# --- the log-distance model --------------------------------------------------------------------------


def test_log_distance_defaults_and_their_link_budget():
    ld = LogDistance()
    assert (ld.tx_power_dbm, ld.sensitivity_dbm, ld.exponent, ld.antenna_gain_db) == (20.0, -90.0, 2.0, 0.0)
    # free space at 1 m and 2.4 GHz: 20 log10(4 pi f / c)
    assert ld.ref_loss_db == pytest.approx(20 * math.log10(4 * math.pi * 2.4e9 / 299_792_458.0), abs=0.01)
    assert ld.margin_db(ld.median_range_m) == pytest.approx(0.0, abs=1e-9)
    assert ld.frame_loss(0.0) == 0.5 and ld.frame_loss(2.2) < 0.1 and ld.frame_loss(-2.2) > 0.9
    assert ld.median_range_m == pytest.approx(3144.0, rel=1e-3)
    cut = -(ld.edge_sigmas * ld.sigma_db + 4 * ld.width_db)
    assert ld.margin_db(ld.range_m) == pytest.approx(cut, abs=1e-9)
    assert ld.frame_loss(cut + ld.edge_sigmas * ld.sigma_db) > 0.98  # an excluded link: lost even when lucky
    assert ld.frame_loss(1e6) == 0.0 and ld.frame_loss(-1e6) == 1.0  # no overflow


def test_log_distance_loss_rises_with_distance():
    model = LinkModel(log_distance=LogDistance())
    ds = [10.0, 1000.0, 2000.0, 2500.0, 3000.0, 3500.0, 4000.0, 5000.0, 7000.0, 10_000.0]
    mean = [model.loss(d) for d in ds]
    assert all(a <= b for a, b in zip(mean, mean[1:])) and all(a < b for a, b in zip(mean[1:8], mean[2:8]))
    assert mean[0] < 1e-12 and mean[-1] > 0.999
    n = 6000
    got = [measured_loss(model, d, n, seed=7 + i) for i, d in enumerate(ds)]
    for a, b in zip(got, got[1:]):
        assert b >= a - 0.02, got  # never falls by more than noise...
    assert got[0] == 0.0 and got[-1] > 0.99 and got[2] < 0.3 < 0.7 < got[6], got  # ...and rises through the budget
    # with a loss floor: at least the floor everywhere, and still rising
    floor = LinkModel(loss_base=0.2, log_distance=LogDistance())
    near, far = measured_loss(floor, 100.0, n, seed=1), measured_loss(floor, 4000.0, n, seed=2)
    assert near >= 0.2 - 4 * math.sqrt(0.16 / n) and far > near + 0.3


def test_shadowing_is_a_slowly_varying_gauss_markov_process():
    ld = LogDistance(sigma_db=4.0, corr_s=5.0)
    radio = Radio(LinkModel(log_distance=ld), link_rng(3))
    radio.update_topology([0, 1], np.array([[0.0, 0.0], [1000.0, 0.0]]), 1.0)
    xs = []
    out: list[Delivery] = []
    for k in range(40_000):
        radio.broadcast(float(k), 0, b"f", out)
        xs.append(radio._shadow[(0, 1)][1])
    x = np.array(xs)
    assert abs(x.std() - 4.0) < 0.25 and abs(x.mean()) < 0.4
    lag = 5  # one correlation time
    r = np.corrcoef(x[:-lag], x[lag:])[0, 1]
    assert abs(r - math.exp(-1.0)) < 0.05
    # two frames at the same time see the same shadowing; no draw is made for the second
    radio.broadcast(40_000.0, 0, b"f", out)
    state = radio._shadow[(0, 1)]
    radio.broadcast(40_000.0, 0, b"f", out)
    assert radio._shadow[(0, 1)] == state


def test_without_shadowing_the_link_draws_only_its_loss():
    ld = LogDistance(sigma_db=0.0)
    model = LinkModel(log_distance=ld)
    d = ld.median_range_m
    assert measured_loss(model, d, 8000, seed=4) == pytest.approx(0.5, abs=4 * math.sqrt(0.25 / 8000))


def test_log_distance_edges_are_the_pairs_within_the_budgets_range():
    ld = LogDistance()
    r = ld.range_m
    radio = Radio(LinkModel(log_distance=ld), link_rng(0))
    xy = np.array([[0.0, 0.0], [r - 1.0, 0.0], [0.0, r + 1.0], [3000.0, 0.0]])
    radio.update_topology([0, 1, 2, 3], xy, 1.0)
    assert sorted(radio.graph.edges) == [(0, 1), (0, 3), (1, 3)]  # 2 is just beyond everyone's reach
    e = radio.graph.edges[0, 3]
    assert e["margin_db"] == pytest.approx(ld.margin_db(3000.0))
    assert e["loss"] == pytest.approx(LinkModel(log_distance=ld).loss(3000.0))


@settings(deadline=None, max_examples=examples(60))
@given(st.lists(st.dictionaries(st.integers(0, 9), st.tuples(st.integers(0, 40), st.integers(0, 40)), max_size=10),
                min_size=1, max_size=6),
       st.sampled_from([None, 6000.0]))
def test_log_distance_incremental_topology_equals_rebuilt_graph(ticks, range_m):
    model = LinkModel(range_m=range_m, log_distance=LogDistance(sigma_db=2.0))
    radio = Radio(model, link_rng(0))
    for nodes in ticks:
        ids = sorted(nodes)
        xy = np.array([(nodes[u][0] * 250.0, nodes[u][1] * 250.0) for u in ids], dtype=float).reshape(-1, 2)
        radio.update_topology(ids, xy, 1.0)
        fresh = Radio(model, link_rng(0))
        fresh.update_topology(ids, xy, 1.0)
        assert nx.utils.graphs_equal(radio.graph, fresh.graph)
        for *_, attrs in radio.graph.edges(data=True):
            assert attrs["distance"] <= model.radius_m
            assert set(attrs) == {"distance", "loss", "margin_db"}
            assert attrs["loss"] == pytest.approx(model.loss(attrs["distance"]), rel=1e-9, abs=1e-15)


def _deliveries(model: LinkModel, seed: int, third: bool) -> list[Delivery]:
    radio = Radio(model, link_rng(seed))
    ids = [0, 1, 2] if third else [0, 1]
    xy = np.array([[0.0, 0.0], [2800.0, 0.0], [0.0, 2500.0]])[: len(ids)]
    out: list[Delivery] = []
    for k in range(300):
        radio.update_topology(ids, xy, 1.0)
        if third:
            radio.broadcast(float(k), 2, b"noise", out)
        radio.broadcast(float(k), 0, bytes([k % 256]), out)
        radio.broadcast(float(k), 1, bytes([k % 256]), out)
    return [d for d in out if d.sender in (0, 1) and d.receiver in (0, 1)]


def test_log_distance_is_deterministic_and_each_link_draws_from_its_own_stream():
    model = LinkModel(latency_s=0.01, jitter_s=0.05, log_distance=LogDistance())
    a = _deliveries(model, 5, third=False)
    assert a == _deliveries(model, 5, third=False)
    assert a == _deliveries(model, 5, third=True)  # node 2's traffic leaves links 0<->1 alone
    assert a != _deliveries(model, 6, third=False)
    assert 50 < len(a) < 550  # some lost, some delivered


def test_log_distance_with_link_faults_draws_after_the_filter():
    from faults.injector import FaultInjector
    from faults.schedule import Drop, Duplicate, FaultSchedule

    def run():
        inj = FaultInjector(FaultSchedule([Drop(rate=0.2), Duplicate(rate=0.3)]), {"a": 0, "b": 1})
        radio = Radio(LinkModel(log_distance=LogDistance()), link_rng(2), inj)
        radio.update_topology([0, 1], np.array([[0.0, 0.0], [3000.0, 0.0]]), 1.0)
        out: list[Delivery] = []
        for k in range(400):
            inj.begin_tick(float(k))
            radio.broadcast(float(k), 0, b"f", out)
        return out, dict(radio.counters.dropped)

    (out1, dropped1), (out2, dropped2) = run(), run()
    assert out1 == out2 and dropped1 == dropped2 and dropped1["drop"] > 0 and dropped1["loss"] > 0


# --- whole runs ------------------------------------------------------------------------------------


def test_a_log_distance_run_is_deterministic_and_keeps_to_its_range(small_scenario_path):
    sc = apply_overrides(load_scenario(small_scenario_path), {"radio.model": "log_distance", "radio.range_m": None},
                         truncated=True)
    sc = sc.model_copy(update={"duration_s": 80.0})
    hashes = []
    for _ in range(2):
        with Simulation(sc) as sim:
            m = sim.run().metrics
            assert all(attrs["distance"] <= LogDistance().range_m for *_, attrs in sim._radio.graph.edges(data=True))
        hashes.append(m["event_log_sha256"])
    assert hashes[0] == hashes[1]
    assert m["radio"]["dropped_by_cause"].get("loss", 0) > 0


def test_a_short_log_distance_run_replays_identically():
    sc = scenario(model="log_distance", log_distance={"sigma_db": 4.0})
    runs = []
    for _ in range(2):
        with Simulation(sc) as sim:
            runs.append(sim.run().metrics)
    assert runs[0]["event_log_sha256"] == runs[1]["event_log_sha256"]
    assert runs[0]["radio"]["dropped_by_cause"].get("loss", 0) > 0
