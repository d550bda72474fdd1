"""The recorded view (issue 26, item 6): a run recorded for the rerun viewer reads back, with
rerun's own reader, with the expected entities and as many rows as the event log says."""

from __future__ import annotations

import math

import pytest

from swarm import Simulation
from swarm.events import read_events
from swarm.scenario import apply_overrides, load_scenario

pytest.importorskip("rerun")


def test_recording_reads_back_with_the_event_logs_counts(tmp_path):
    from swarm.viz.rerun_view import EVENT_KINDS, entity_rows, record

    sc = apply_overrides(load_scenario("paper-case1"), {"faults": [{"kind": "crash", "uav": "B2", "at_s": 60.0}]})
    with Simulation(sc, duration_s=120.0) as sim:
        result = sim.run()
        scenario = sim.scenario.to_dict()
    path = record(result.events, scenario, tmp_path / "run.rrd", every_s=5.0, coverage_every_s=30.0)
    rows = entity_rows(path)
    ticks = round(120.0 / sim.dt)
    events = list(read_events(result.events))
    assert set(rows) >= {"/world/uavs", "/world/detection", "/world/paths", "/world/targets", "/world/radio",
                         "/world/coverage", "/world/zones", "/events", "/faults"}
    assert rows["/world/uavs"] == rows["/world/detection"] == ticks  # one row per tick
    assert rows["/world/paths"] == rows["/world/targets"] == rows["/world/radio"] == math.ceil(ticks / 5)
    assert rows["/world/coverage"] == ticks // 30 + 1
    assert rows["/events"] == sum(1 for e in events if e.kind in EVENT_KINDS) > 0
    assert rows["/faults"] == 1  # the crash (a time, no window)
    assert any(e.kind == "crash" for e in events)


@pytest.mark.slow
def test_swarm_run_rerun_and_view_without_a_display(tmp_path, monkeypatch):
    from swarm.cli import main

    out = tmp_path / "run"
    assert main(["run", "paper-case1", "--duration", "30", "--quiet", "--no-figures", "--out", str(out),
                 "--rerun", str(out / "run.rrd")]) == 0
    assert (out / "run.rrd").stat().st_size > 0
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", str(out)]) == 0
