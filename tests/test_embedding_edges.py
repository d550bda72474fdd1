"""Embedding without surprises: write_run writes what `swarm report` needs, step() past the end
is a clear error, and the event log reads back with UAV names."""

from __future__ import annotations

import pytest

from swarm import APIMisuseError, Simulation
from swarm.cli import main
from swarm.events import read_events
from swarm.outputs import write_run


def test_write_run_from_the_api_is_a_folder_swarm_report_accepts(tmp_path, capsys):
    with Simulation("paper-case1", duration_s=30.0) as sim:
        result = sim.run()
    out = write_run(result, tmp_path / "run")
    assert (out / "scenario.json").is_file()
    assert main(["report", str(out), "--quiet"]) == 0
    assert (out / "report.html").stat().st_size > 10_000


def test_step_past_the_end_is_an_api_misuse():
    with Simulation("paper-case1", duration_s=5.0) as sim:
        sim.step(5)
        assert sim.done
        with pytest.raises(APIMisuseError, match="past the end"):
            sim.step()
    with Simulation("paper-case1", duration_s=5.0) as sim:
        with pytest.raises(APIMisuseError, match="step at most 5 more"):
            sim.step(6)
        sim.step(5)  # the refused call changed nothing


def test_events_read_back_with_names():
    with Simulation("paper-case1", duration_s=10.0) as sim:
        result = sim.run()
    names = {"B1", "B2", "A1"}
    events = list(read_events(result.events))
    assert {e.uav_name for e in events if e.kind == "pose"} == names
    assert all(e.src_name in names and e.dst_name in names for e in events if e.kind == "rx")
    assert {e.uav for e in events if e.kind == "pose"} == {0, 1, 2}  # the ids stay
    assert {e.uav_name for e in read_events(result.events, names=False) if e.kind == "pose"} == {None}


def test_check_events_takes_what_run_result_events_holds_and_schedules_iterate():
    from faults.schedule import Drop, FaultSchedule
    from swarm.testing.invariants import check_events

    with Simulation("paper-case1", duration_s=30.0) as sim:
        result = sim.run()
        scenario = sim.scenario
    assert check_events(result.events, scenario) == []
    schedule = FaultSchedule([Drop(rate=0.5), Drop(rate=0.1, start_s=5.0)])
    assert [f.rate for f in schedule] == [0.5, 0.1] and len(schedule) == 2


def test_uav_map_is_what_embedding_md_says():
    """docs/embedding.md: a float32 (ny, nx) copy indexed [iy, ix], last-seen times in simulated
    seconds (never after now, never decreasing), -inf where never known scanned."""
    import math

    import numpy as np

    with Simulation("paper-case1", duration_s=30.0) as sim:
        sim.step(10)
        first = sim.uav_map("B1")
        sim.step(10)
        m = sim.uav_map("B1")
        area = sim.scenario.area
        assert m.dtype == np.float32 and m.shape == (math.ceil(area.height_m / area.cell_m),
                                                     math.ceil(area.width_m / area.cell_m))
        assert np.isneginf(m).any() and np.isfinite(m).any()
        assert float(m[np.isfinite(m)].max()) <= sim.now and (m >= first).all()
        b1 = next(u for u in sim.snapshot().uavs if u.name == "B1")
        assert np.isfinite(m[int(b1.y // area.cell_m), int(b1.x // area.cell_m)])  # [iy, ix]: under B1 is scanned
        m[:] = 0.0
        assert np.isneginf(sim.uav_map("B1")).any()  # a copy
