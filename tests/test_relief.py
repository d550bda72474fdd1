"""``agents.relief.Relief``: rule 6 of docs/modelling.md's assignment rules (relief on station)
as one UAV decides it, against hand-made knowledge: the time on station it announces (a lower
bound: worst power, worst turn, distance from home growing), which of two askers keeps the
target, when a co-watcher counts as the relief, and which request a free UAV answers, when.
(The whole rule over generated missions: tests/test_assignment_rules.py.)"""

from __future__ import annotations

import math

from agents.inputs import EnergyReading, SensorReading
from agents.knowledge import Knowledge
from agents.planners.base import Plan
from agents.relief import Relief
from comms.messages import MODE_SEARCH, MODE_SURVEIL, NO_TARGET
from swarm.scenario import DEFAULT_UAV_TYPES

A = DEFAULT_UAV_TYPES["A"].uav_type("A")
B = DEFAULT_UAV_TYPES["B"].uav_type("B")
TYPES = {"A": A, "B": B}
REPLAN_S = 10.0


def _relief(uid: int = 0, kind=A) -> Relief:
    return Relief(uid, kind, Knowledge(), peer_timeout_s=5.0, replan_s=REPLAN_S, types=TYPES)


def _energy(spare_s: float, s_per_m: float = 0.0, must_go: bool = False, handover_s: float = 60.0) -> EnergyReading:
    return EnergyReading(0.0, 0.0, 0.0, 0.0, must_go, 35.0, spare_s, handover_s, 0.0, s_per_m)


def _reading(t: float, x: float, y: float, energy: EnergyReading | None, theta: float = 0.0) -> SensorReading:
    return SensorReading(t, x, y, 40.0, theta, [], [], energy=energy)


def _peer(r: Relief, uid: int, kind: str, x: float, y: float, t: float, mode: int, target: int, asks: bool = False):
    p = r.knowledge.peer(uid)
    p.type, p.x, p.y, p.v, p.theta, p.t_pose = kind, x, y, 40.0, 0.0, t
    p.mode, p.target, p.t_intent, p.asks = mode, target, t, asks
    return p


def test_time_on_station_allows_for_the_way_away_from_home_and_the_drift():
    r = _relief()
    r.knowledge.see_target(7, 1000.0, 0.0, 3.0, 4.0, 0.0, 1.0)  # a target 1 km off, drifting at 5 m/s
    reading = _reading(0.0, 0.0, 0.0, _energy(spare_s=600.0, s_per_m=0.01))
    # (600 - 0.01 (1000 + 1500)) / (1 + 0.01 * 5)
    assert r.station_s(reading, 7) == (600.0 - 0.01 * (1000.0 + A.detect_radius)) / 1.05
    assert r.station_s(_reading(0.0, 0.0, 0.0, _energy(spare_s=600.0)), 7) == 600.0  # nothing to lose a metre
    assert r.station_s(_reading(0.0, 0.0, 0.0, _energy(spare_s=10.0, s_per_m=0.01)), 7) == 0.0  # never negative


def test_a_watcher_asks_with_its_time_on_station_as_by_and_keeps_its_target():
    r = _relief()
    r.knowledge.see_target(7, 1000.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    plan = Plan(1000.0, 0.0, MODE_SURVEIL, 7)
    assert r.home(_reading(0.0, 0.0, 0.0, _energy(spare_s=500.0)), plan) is None
    assert r.asked is None and not r.releasing  # 500 s > handover_s, nobody to wait for
    assert r.home(_reading(1.0, 0.0, 0.0, _energy(spare_s=59.0)), plan) is None
    assert r.asked == (7, 60.0) and r.releasing and r.intent(plan) == (MODE_SEARCH, 7)
    home = r.home(_reading(2.0, 0.0, 0.0, _energy(spare_s=0.0, must_go=True)), plan)
    assert home is not None and r.homebound and not r.relieved and r.handed_target == 7


def test_of_two_watchers_asking_for_one_target_the_lower_id_keeps_it():
    plan = Plan(1000.0, 0.0, MODE_SURVEIL, 7)
    for me, other, goes in ((1, 0, True), (0, 1, False)):
        r = _relief(uid=me)
        r.knowledge.see_target(7, 1000.0, 0.0, 0.0, 0.0, 0.0, 1.0)
        assert r.home(_reading(1.0, 0.0, 0.0, _energy(spare_s=30.0)), plan) is None  # asks
        # the other is nearer the target: an order both know decides, not positions as heard
        _peer(r, other, "A", 900.0, 0.0, 1.0, MODE_SURVEIL, 7, asks=True)
        home = r.home(_reading(2.0, 0.0, 0.0, _energy(spare_s=29.0)), plan)
        assert (home is not None) is goes, (me, other)
        assert not goes or r.relieved


def test_a_co_watcher_is_the_relief_only_once_it_has_replanned_since_the_request():
    r = _relief(uid=1)
    r.knowledge.see_target(7, 1000.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    plan = Plan(1000.0, 0.0, MODE_SURVEIL, 7)
    assert r.home(_reading(5.0, 0.0, 0.0, _energy(spare_s=30.0)), plan) is None
    p = _peer(r, 0, "A", 1100.0, 0.0, 6.0, MODE_SURVEIL, 7)  # holds it, but may leave it to this one
    assert r.home(_reading(6.0, 0.0, 0.0, _energy(spare_s=29.0)), plan) is None
    p.t_intent = p.t_pose = 5.0 + REPLAN_S  # still holding it a replanning period after the request
    home = r.home(_reading(15.0, 0.0, 0.0, _energy(spare_s=20.0)), plan)
    assert home is not None and r.relieved


def test_a_free_uav_answers_the_request_it_reaches_first_and_waits_its_turn_behind_faster_ones():
    r = _relief(uid=5, kind=A)
    for m, x in ((3, 20_000.0), (4, 5_000.0)):
        r.knowledge.see_target(m, x, 0.0, 0.0, 0.0, 0.0, 1.0)
    _peer(r, 1, "A", 20_000.0, 1000.0, 0.0, MODE_SEARCH, 3, asks=True)
    _peer(r, 2, "A", 5_000.0, 1000.0, 0.0, MODE_SEARCH, 4, asks=True)
    _peer(r, 3, "B", 4_000.0, 0.0, 0.0, MODE_SEARCH, NO_TARGET)  # free, faster, nearer target 4
    e = _energy(spare_s=10_000.0)
    # from 25 km east: target 4 is B3's to take first; target 3 is this UAV's (B3 is farther)
    plan = r.answer(_reading(0.0, 25_000.0, 0.0, e, theta=math.pi), Plan(0.0, 0.0))
    assert plan is not None and (plan.mode, plan.target) == (MODE_SEARCH, 3) and r.relieving == 3
    # without target 3's request, it waits one replanning period for B3 (who may not afford it)
    r = _relief(uid=5, kind=A)
    r.knowledge.see_target(4, 5_000.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    _peer(r, 2, "A", 5_000.0, 1000.0, 0.0, MODE_SEARCH, 4, asks=True)
    b3 = _peer(r, 3, "B", 4_000.0, 0.0, 0.0, MODE_SEARCH, NO_TARGET)
    assert r.answer(_reading(0.0, 0.0, 0.0, e), Plan(0.0, 0.0)) is None
    for p in r.knowledge.peers.values():
        p.t_intent = p.t_pose = REPLAN_S
    plan = r.answer(_reading(REPLAN_S, 0.0, 0.0, e), Plan(0.0, 0.0))
    assert plan is not None and plan.target == 4
    # ... unless B3 is on its way (it beacons that it watches the target)
    r.relieving = NO_TARGET
    b3.mode, b3.target = MODE_SURVEIL, 4
    assert r.answer(_reading(REPLAN_S, 0.0, 0.0, e), Plan(0.0, 0.0)) is None


def test_a_free_uav_does_not_answer_what_its_energy_cannot_afford():
    r = _relief(uid=5, kind=A)
    r.knowledge.see_target(4, 5_000.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    _peer(r, 2, "A", 5_000.0, 1000.0, 0.0, MODE_SEARCH, 4, asks=True)
    way = 5_000.0 / (40.0 - 0.0)  # its flight there (heading at it, 40 m/s, no wind)
    need = way + 2 * 60.0
    assert r.answer(_reading(0.0, 0.0, 0.0, _energy(spare_s=need - 1.0)), Plan(0.0, 0.0)) is None
    assert r.answer(_reading(0.0, 0.0, 0.0, _energy(spare_s=need + 1.0)), Plan(0.0, 0.0)) is not None
    # the way there takes it 6.5 km farther from home: that much less spare at 0.01 s a metre
    r.relieving = NO_TARGET
    assert r.answer(_reading(0.0, 0.0, 0.0, _energy(spare_s=need + 1.0, s_per_m=0.01)), Plan(0.0, 0.0)) is None
    assert math.isclose(0.01 * (5_000.0 + A.detect_radius), 65.0)


def test_of_two_requests_it_answers_the_one_whose_target_it_reaches_first():
    r = _relief(uid=5, kind=A)
    for m, x in ((3, 20_000.0), (4, 5_000.0)):  # the lower id is the farther one
        r.knowledge.see_target(m, x, 0.0, 0.0, 0.0, 0.0, 1.0)
    _peer(r, 1, "A", 20_000.0, 1000.0, 0.0, MODE_SEARCH, 3, asks=True)
    _peer(r, 2, "A", 5_000.0, 1000.0, 0.0, MODE_SEARCH, 4, asks=True)
    plan = r.answer(_reading(0.0, 0.0, 0.0, _energy(spare_s=10_000.0)), Plan(0.0, 0.0))
    assert plan is not None and plan.target == 4 and (plan.wx, plan.wy) == (5_000.0, 0.0)
