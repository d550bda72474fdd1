"""Ground-truth metrics: block-wise certainty equals the whole-map formula; handovers."""

from __future__ import annotations

import numpy as np
import pytest

from agents.maps.grid import Grid
from swarm.metrics import Metrics


@pytest.mark.parametrize("grid", [Grid(50_000.0, 50_000.0, 100.0), Grid(130_000.0, 110_000.0, 100.0)])
def test_certainty_and_coverage_equal_the_whole_map_formulas(grid):
    m = Metrics(grid, 0.005)
    rng = np.random.default_rng(1)
    assert m.certainty(0.0) == 0.0 and m.coverage() == 0.0
    for k in range(400):  # disks in, near and off the area, of several radii and times
        x = rng.uniform(-3000.0, grid.width_m + 3000.0)
        y = rng.uniform(-3000.0, grid.height_m + 3000.0)
        m.scan(x, y, float(rng.choice([500.0, 1500.0, 2000.0, 3100.0])), float(k % 97))
        if k % 50 == 0:
            for t in (100.0, 777.5):
                whole = 1.0 - float(np.mean(m.union.uncertainty(t), dtype=np.float64))
                assert m.certainty(t) == whole
            seen = np.isfinite(m.union.to_dense())
            assert m.coverage() == np.count_nonzero(seen) / seen.size


# --- handovers: a new UAV taking a target over from the one that held it --------------------------

SURVEIL, SEARCH = (1, 0), (0, -1)  # (mode, target 0)
FAST, SLOW = 0, 1


def _handovers(script, t_end=120):
    """``script(t)`` -> {uid: ((mode, target), sees target 0)}; returns (handovers, events)."""
    m = Metrics(Grid(10_000.0, 10_000.0, 100.0), 0.005)
    events = []
    for t in range(t_end):
        plans, sensed = {}, {}
        for uid, (plan, sees) in script(float(t)).items():
            plans[uid] = plan
            sensed[uid] = [0] if sees else []
        events += m.observe(float(t), 1.0, plans, sensed, {FAST: "B", SLOW: "A"}, {})
    return m.handovers, events


def test_handover_counts_when_the_slow_uav_arrives_after_the_fast_one_left():
    # The slow UAV declares the target at 10 s from afar, the fast one lets go at 40 s, the slow
    # one arrives (sees it) at 50 s: a handover at 50 s, released 10 s before the arrival.
    (h,), _ = _handovers(lambda t: {FAST: (SURVEIL if t < 40 else SEARCH, t < 40),
                                    SLOW: (SURVEIL if t >= 10 else SEARCH, t >= 50)})
    assert (h.t, h.from_uav, h.to_uav, h.from_type, h.to_type, h.latency_s) == (50.0, FAST, SLOW, "B", "A", -10.0)


def test_handover_counts_at_the_release_when_both_hold_the_target():
    (h,), _ = _handovers(lambda t: {FAST: (SURVEIL if t < 45 else SEARCH, True),
                                    SLOW: (SURVEIL if t >= 10 else SEARCH, t >= 30)})
    assert (h.t, h.latency_s) == (45.0, 15.0)


def test_no_handover_without_arrival_or_when_the_target_was_dropped_first():
    never_arrives, _ = _handovers(lambda t: {FAST: (SURVEIL if t < 40 else SEARCH, t < 40),
                                             SLOW: (SURVEIL if t >= 10 else SEARCH, False)})
    assert never_arrives == []
    # The fast one drops the target at 20 s; the slow one only turns to it at 25 s: a new watch.
    dropped, events = _handovers(lambda t: {FAST: (SURVEIL if t < 20 else SEARCH, t < 20),
                                            SLOW: (SURVEIL if t >= 25 else SEARCH, t >= 40)})
    assert dropped == [] and ("release", 20.0, 0, FAST) in events
