"""The event schema (swarm/events.py): every kind defined once, every written event as it
defines, every reader through it, subscribers given named records, and the order of a tick's
events as docs/outputs.md states it."""

from __future__ import annotations

import re
import tomllib
from collections import Counter
from pathlib import Path

import msgpack
import pytest

from faults.schedule import ClockSkew, Pause, Restart
from swarm import Simulation
from swarm import events as ev
from swarm.errors import UsageError
from swarm.events import KINDS, Decoder, EventLogError, check_wire, read_columns, read_events, to_wire
from swarm.kernel.recorder import EventLog
from swarm.scenario import parse_scenario
from tests.conftest import DATA

ROOT = Path(__file__).resolve().parent.parent


def _doc(duration_s: float = 300.0, level: str = "frames") -> dict:
    """faults-small (a partition, a crash, a late joiner, corruption, drops; targets found) with a
    UAV that flies into a threat at once (a violation event)."""
    with open(DATA / "faults-small.toml", "rb") as fh:
        doc = tomllib.load(fh)
    doc["duration_s"] = duration_s
    doc["uavs"][3]["join_s"] = min(100.0, duration_s / 2)  # A2 joins late
    # just ahead of B1's start (heading east at 90 m/s, a turn radius of over 2 km): it flies in.
    # (A UAV may no longer start inside a no-fly zone: issue 33.)
    doc["threats"].append({"x_m": 1650.0, "y_m": 2000.0, "radius_m": 500.0})
    doc["recording"] = {"level": level}
    return doc


NODE_FAULTS = [Pause(uav="B1", start_s=20.0, end_s=40.0), Restart(uav="A1", at_s=60.0, downtime_s=5.0),
               ClockSkew(uav="B2", start_s=10.0, end_s=30.0, offset_s=2.0)]


def _run(doc: dict, subscribe_at: float | None = None):
    """A run with the node faults, every event checked against the schema as it is written;
    with ``subscribe_at``, also the records a subscriber got from then on."""
    got: list[ev.Event] = []
    with Simulation(parse_scenario(doc)) as sim:
        for f in NODE_FAULTS:
            sim.add_fault(f)
        if subscribe_at is not None:
            if subscribe_at > 0:
                sim.step(int(subscribe_at / sim.dt))
            sim.subscribe(got.append)
        result = sim.run()
    return result, got


@pytest.fixture(scope="module")
def runs():
    """A frames log (a subscriber from before the first tick) and a summary log."""
    saved = EventLog.check_schema
    EventLog.check_schema = True
    try:
        frames, live = _run(_doc(), subscribe_at=0.0)
        summary, _ = _run(_doc(120.0, "summary"))
    finally:
        EventLog.check_schema = saved
    return frames, live, summary


def _wire(data: bytes) -> list[list]:
    unpacker = msgpack.Unpacker(raw=False, strict_map_key=False)
    unpacker.feed(data)
    return list(unpacker)


# --- one schema, and what is written is what it says --------------------------------------------


def _checked_run(doc: dict):
    """A run of ``doc`` with every event checked against the schema as it is written."""
    saved = EventLog.check_schema
    EventLog.check_schema = True
    try:
        with Simulation(parse_scenario(doc)) as sim:
            return sim.run()
    finally:
        EventLog.check_schema = saved


def _mission_run():
    """(issues 26, 33) Wind, and endurance with a watcher that asks for relief and goes home
    unrelieved, a landing, a relaunch and a battery fault that empties one UAV: the mission
    kinds, checked as they are written."""
    doc = {"duration_s": 200.0, "area": {"width_m": 20000.0, "height_m": 20000.0},
           "uavs": [{"type": "A", "x_m": 2800.0, "y_m": 3000.0}, {"type": "A", "x_m": 3200.0, "y_m": 3000.0}],
           "targets": {"placed": [{"x_m": 3800.0, "y_m": 3400.0}]},  # (A1 watches it, asks for relief, leaves unrelieved)
           "wind": {"speed_mps": 3.0, "gust_sigma_mps": 1.0},
           "endurance": {"x_m": 2500.0, "y_m": 2500.0, "turnaround_s": 20.0, "types": {"A": {"capacity_wh": 60.0}}},
           "faults": [{"kind": "battery", "uav": "A2", "start_s": 5.0, "loss_frac": 1.0}]}
    return _checked_run(doc)


def _release_run():
    """A ``release``: a fast UAV watching a target crashes with nobody else near it. (faults-small
    wrote one until issue 33, a fast UAV letting go before its slow relief had the target in
    sight; rule 3 now has it wait, and the handover there has no gap.)"""
    doc = {"duration_s": 80.0, "area": {"width_m": 10000.0, "height_m": 10000.0},
           "targets": {"count": 0, "placed": [{"x_m": 6000.0, "y_m": 5000.0}]},
           "uavs": [{"type": "B", "x_m": 5000.0, "y_m": 5000.0}],
           "faults": [{"kind": "crash", "uav": "B1", "at_s": 60.0}]}
    return _checked_run(doc)


def _handover_run():
    """A ``handover``: a fast UAV watches a target it found at once, a slow one comes and takes it
    over (rule 2). (faults-small's run wrote one until issue 33 moved its threat and made a fast
    watcher wait for its relief to have the target in sight.)"""
    doc = {"duration_s": 120.0, "area": {"width_m": 10000.0, "height_m": 10000.0},
           "targets": {"count": 0, "placed": [{"x_m": 6000.0, "y_m": 5000.0}]},
           "uavs": [{"type": "B", "x_m": 5000.0, "y_m": 5000.0}, {"type": "A", "x_m": 2500.0, "y_m": 5000.0}]}
    return _checked_run(doc)


def test_every_kind_is_written_and_every_event_is_as_the_schema_says(runs):
    frames, _, summary = runs
    mission = _mission_run()
    released = _release_run()
    handed = _handover_run()
    assert "release" in {e.kind for e in read_events(released.events)}
    seen = Counter(e.kind for r in (frames, summary, mission, released, handed) for e in read_events(r.events))
    assert set(seen) == set(KINDS), f"kinds never written by these runs: {set(KINDS) - set(seen)}"
    for r in (frames, summary, mission, released, handed):
        for wire in _wire(r.events):
            check_wire(wire)


def test_a_record_is_its_array_in_the_same_order_then_the_names(runs):
    frames, _, summary = runs
    for r in (frames, summary):
        wires = _wire(r.events)
        records = list(read_events(r.events))
        assert len(records) == len(wires)
        for wire, record in zip(wires, records):
            assert list(to_wire(record)) == wire
            spec = KINDS[record.kind]
            assert [f.name for f in spec.fields[:len(spec.wire)]] == [f.name for f in spec.wire]
            assert len(wire) == spec.arity


def test_records_carry_names_and_mode_names(runs):
    frames, _, _ = runs
    names = {0: "B1", 1: "B2", 2: "A1", 3: "A2"}
    records = list(read_events(frames.events))
    poses = [e for e in records if isinstance(e, ev.Pose)]
    assert {e.mode for e in poses} == {"search", "surveil"}
    assert all(e.uav_name == names[e.uav] for e in poses)
    assert all(e.dst_name == names[e.dst] for e in records if isinstance(e, (ev.Rx, ev.Lost)))
    handover = next(e for e in read_events(_handover_run().events) if isinstance(e, ev.Handover))
    assert (handover.from_name, handover.to_name) == ("B1", "A1")
    threat = next(e for e in records if isinstance(e, ev.Violation))
    assert threat.invariant == "threat" and threat.uav_name == "B1" and threat.other_name is None
    assert isinstance(records[0], ev.Start) and records[0].uavs == names


def test_a_separation_names_both_uavs_and_names_false_leaves_ids_only():
    header = {"uavs": [[0, "B1", "B"], [1, "B2", "B"]]}
    log = [["start", 0.0, header], ["violation", 1.0, "separation", 0, 1], ["violation", 1.0, "threat", 1, 0]]
    data = b"".join(msgpack.packb(e) for e in log)
    _, sep, threat = read_events(data)
    assert isinstance(sep, ev.Violation) and (sep.uav_name, sep.other_name) == ("B1", "B2")
    assert isinstance(threat, ev.Violation) and (threat.uav_name, threat.other_name) == ("B2", None)
    assert all(getattr(e, "uav_name", None) is None for e in read_events(data, names=False))
    cols = read_columns(data, {"violation"})["violation"]
    assert cols["other_name"] == ["B2", None] and cols["invariant"] == ["separation", "threat"]


def test_read_events_reads_twice_and_filters_kinds(runs):
    frames, _, _ = runs
    records = read_events(frames.events)
    assert list(records) == list(records) and len(list(records)) > 1000
    found = list(read_events(frames.events, {"found"}))
    assert found and all(isinstance(e, ev.Found) and e.uav_name for e in found)
    with pytest.raises(UsageError, match="unknown event kind"):
        read_events(frames.events, {"founds"})


def test_columns_hold_the_records_fields(runs):
    frames, _, _ = runs
    cols = read_columns(frames.events)
    assert list(cols) == list(KINDS)
    records = list(read_events(frames.events))
    for kind, spec in KINDS.items():
        assert list(cols[kind]) == [f.name for f in spec.fields]
        assert ev.records(kind, cols[kind]) == [e for e in records if e.kind == kind]


def test_what_is_not_an_event_log_is_refused():
    with pytest.raises(EventLogError, match="not an event kind"):
        list(read_events(msgpack.packb(["posed", 0.0])))
    with pytest.raises(EventLogError, match="has 9 items"):
        list(read_events(msgpack.packb(["pose", 0.0, 1, 2.0])))
    with pytest.raises(EventLogError, match="x should be float"):
        check_wire(("pose", 0.0, 1, "2", 3.0, 4.0, 5.0, 0, -1))
    with pytest.raises(EventLogError, match="mode"):
        Decoder()(("mode", 0.0, 1, 7, -1))


# --- subscribers ----------------------------------------------------------------------------------


def test_a_subscriber_from_the_start_gets_the_log_as_records(runs):
    frames, live, _ = runs
    assert isinstance(live[0], ev.Start)
    assert live == list(read_events(frames.events))


def test_a_subscriber_added_later_knows_the_names_logged_before():
    """A2 joined at 100 s, A1 restarted at 65 s: their names reach a subscriber from 150 s."""
    result, got = _run(_doc(200.0), subscribe_at=150.0)
    assert got and got[0].t == 150.0 and not any(isinstance(e, ev.Start) for e in got)
    late = [e for e in read_events(result.events) if e.t >= 150.0]
    assert got == late
    assert {e.uav_name for e in got if isinstance(e, ev.Pose)} >= {"A1", "A2"}


def test_a_subscriber_cannot_change_what_is_written():
    def vandal(e: ev.Event) -> None:
        if isinstance(e, ev.Start):
            e.header["uavs"].clear()
            e.header["seed"] = -1

    with Simulation(parse_scenario(_doc(20.0))) as a, Simulation(parse_scenario(_doc(20.0))) as b:
        a.subscribe(vandal, {"start"})
        assert a.run().events == b.run().events


def test_subscribe_refuses_an_unknown_kind():
    with Simulation(parse_scenario(_doc(5.0))) as sim, pytest.raises(UsageError, match="'poses'.*the kinds are start"):
        sim.subscribe(print, {"poses"})


def test_without_subscribers_nothing_is_converted(monkeypatch):
    def refuse(self, wire):
        raise AssertionError("converted an event nobody asked for")

    monkeypatch.setattr(Decoder, "__call__", refuse)
    with Simulation(parse_scenario(_doc(30.0))) as sim:
        sim.run()
        assert sim._log._decoder is None


# --- no reader indexes events by position -----------------------------------------------------------

# Indexing an event (a record, or the log's array) by position, under the names the code base
# gives events; unpacking the log's bytes by hand; tuple-unpacking what read_events yields.
_POSITIONAL = re.compile(r"\b(e|ev|evt|event|wire|record|rec)\[\s*(-?\d|:)")
_RAW_LOG = re.compile(r"msgpack\.(Unpacker|unpackb?)\(")
_UNPACKED = re.compile(r"for\s+\w+\s*,[^:]*\bin\s+(read_events|read_columns)\(")


def test_no_event_is_read_by_position_outside_the_schema():
    offences = []
    for package in ("swarm", "agents", "comms", "faults"):
        for path in sorted((ROOT / package).rglob("*.py")):
            if path == ROOT / "swarm" / "events.py":
                continue
            for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
                code = line.split("#", 1)[0]
                raw = package == "swarm" and _RAW_LOG.search(code)  # (comms decodes radio frames, not the log)
                if _POSITIONAL.search(code) or raw or _UNPACKED.search(code):
                    offences.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not offences, "read events by name through swarm.events:\n" + "\n".join(offences)


# --- the docs ----------------------------------------------------------------------------------------


def test_the_docs_table_of_kinds_is_the_schema():
    text = (ROOT / "docs" / "outputs.md").read_text(encoding="utf-8")
    assert ev.markdown_table() in text, "docs/outputs.md: paste swarm.events.markdown_table() into 'Event kinds'"


# --- the order of events within a tick (docs/outputs.md, "Order within a tick") -----------------------

# The phases of one instant t, in log order, and the kinds each may write. A kind in several
# phases (a lost copy: a crash's drained mailbox, a frame arriving, a broadcast) may be in any.
PHASES: list[tuple[str, set[str]]] = [
    ("tick boundary: host changes", {"host"}),
    ("clock: faults and joins", {"join", "crash", "restart", "resume", "fault_off", "lost"}),
    ("clock: frames arriving", {"lost"}),
    ("sense: node faults acting", {"fault_on", "pause"}),
    ("observe: per UAV in id order", {"mode", "pose", "rx"}),
    ("ground truth: first sightings", {"found"}),
    ("ground truth: per target", {"release", "handover"}),
    ("targets", {"target"}),
    ("safety", {"violation"}),
    ("transmit", {"lost"}),
    ("end of tick", {"radio"}),
    ("after the tick: zero-latency arrivals", {"lost"}),
]


def _phases_in_order(kinds: list[str]) -> bool:
    """Whether each event can be given a phase containing its kind, phases never going back
    (earliest fitting phase first: greedy is exact for this)."""
    at = 0
    for kind in kinds:
        while at < len(PHASES) and kind not in PHASES[at][1]:
            at += 1
        if at == len(PHASES):
            return False
    return True


def test_events_of_an_instant_come_in_the_documented_order(runs):
    frames, _, summary = runs
    for r in (frames, summary):
        records = list(read_events(r.events))
        assert isinstance(records[0], ev.Start)
        by_t: dict[float, list[ev.Event]] = {}
        for e in records[1:]:
            by_t.setdefault(e.t, []).append(e)
        for t, group in by_t.items():
            kinds = [e.kind for e in group]
            assert _phases_in_order(kinds), f"t={t}: {kinds}"
            # Per UAV in id order: its mode change, its pose, the frames it read.
            observed = [(e.dst if isinstance(e, ev.Rx) else e.uav, e.kind) for e in group if e.kind in ("mode", "pose", "rx")]
            assert observed == sorted(observed, key=lambda p: (p[0], ["mode", "pose", "rx"].index(p[1]))), t
            targets = [e.target for e in group if isinstance(e, ev.Target)]
            assert targets == sorted(targets)
            per_target = [e.target for e in group if isinstance(e, (ev.Release, ev.Handover))]
            assert per_target == sorted(per_target)
