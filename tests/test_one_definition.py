"""Each fact has one definition: these fail when one is (re)defined somewhere else.

* fault kinds, their fields, defaults and bounds: :mod:`faults.schedule`; the scenario's
  ``[[faults]]`` tables are generated from it;
* APF settings: :class:`agents.apf.ApfSettings`; DACMP settings:
  :class:`agents.planners.dacmp.settings.DacmpSettings`; ``[planner.apf]`` and
  ``[planner.dacmp]`` are generated from them;
* radio settings: :class:`comms.settings.RadioSettings`; ``[radio]`` is generated from it, the
  actors' settings hold one, the radio's link model is made from it and takes its defaults;
  the frame size cap (65536) is written once; the loss rules are written once for the scalar
  and the vectorised path (:class:`comms.settings.LinkModel`);
* the partition rule (:meth:`faults.schedule.Partition.separates`), mode names
  (:data:`comms.messages.MODE_NAMES`), UAV colours (:func:`swarm.viz.style.uav_colours`),
  atomic writes (:func:`swarm.outputs.atomic_write`).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import re
from pathlib import Path

import numpy as np
import pytest

from agents.apf import ApfSettings as AgentApf
from agents.inputs import ActorSettings
from agents.planners.dacmp import DacmpPlanner, DacmpSettings
from comms.messages import MODE_NAMES, MODE_SEARCH, MODE_SURVEIL
from comms.settings import LinkModel, LogDistance
from comms.settings import RadioSettings as CommsRadio
from faults import schedule
from faults.injector import FaultInjector
from faults.schedule import FaultSchedule, Partition, fault_from_dict, fault_to_dict
from swarm.scenario import generated
from swarm.scenario.tables import PlannerSettings, SafetySettings

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("swarm", "agents", "comms", "faults")
BOUNDS = ("gt", "ge", "lt", "le")
# [planner.apf] leaves these to others (documented in agents.apf.ApfSettings and the model).
APF_NOT_IN_TABLE = {"min_separation_m", "threat_margin_m"}


def _sources() -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


def _default(f: dataclasses.Field):
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return dataclasses.MISSING


def _as_scenario(value):
    """A dataclass default as the scenario writes it: inf is absent (None), tuples are arrays."""
    if isinstance(value, float) and math.isinf(value):
        return None
    if isinstance(value, tuple):
        return [_as_scenario(v) for v in value]
    return value


def _bounds(info) -> dict:
    return {k: getattr(m, k) for m in info.metadata for k in BOUNDS if getattr(m, k, None) is not None}


def _same_fields(source: type, table, exclude: frozenset[str] = frozenset(), extra: frozenset[str] = frozenset()):
    """Every field of the dataclass is in the table with its default (or required) and bounds."""
    fields = {f.name: f for f in dataclasses.fields(source) if f.name not in exclude}
    assert set(table.model_fields) == set(fields) | extra, f"{table.__name__} vs {source.__name__}"
    for name, f in fields.items():
        info = table.model_fields[name]
        default = _default(f)
        if default is dataclasses.MISSING:
            assert info.is_required(), f"{table.__name__}.{name} should be required (no default in {source.__name__})"
        else:
            assert not info.is_required(), f"{table.__name__}.{name} is required but {source.__name__} has a default"
            assert info.get_default(call_default_factory=True) == _as_scenario(default), f"{table.__name__}.{name}"
        assert _bounds(info) == {k: f.metadata[k] for k in BOUNDS if k in f.metadata}, f"{table.__name__}.{name}"


# --- faults --------------------------------------------------------------------------------------


def test_fault_kinds_are_those_of_faults_schedule_in_its_order():
    assert generated.FAULT_KINDS == tuple(schedule.FAULT_KINDS)
    assert {cls.kind for cls in schedule.FAULT_KINDS.values()} == set(schedule.FAULT_KINDS)


@pytest.mark.parametrize("kind", list(schedule.FAULT_KINDS))
def test_each_fault_table_has_the_dataclass_fields_defaults_and_bounds(kind):
    cls, table = schedule.FAULT_KINDS[kind], generated.FAULT_TABLES[kind]
    _same_fields(cls, table, extra=frozenset({"kind"}))
    assert table.model_fields["kind"].default == kind
    assert table.__name__ == f"{cls.__name__}Fault" and getattr(generated, table.__name__) is table


def _required_values(cls: type) -> dict:
    """Values for the required fields of a fault kind that a scenario accepts."""
    sample = {"rate": 0.25, "p_enter_bad": 0.1, "p_exit_bad": 0.3, "extra_s": 2.0,
              "groups": (("B1",), ("A1",)), "uav": "B1", "at_s": 5.0, "end_s": 50.0, "downtime_s": 10.0,
              "x_m": 1000.0, "y_m": 2000.0, "radius_m": 500.0, "range_m": 3000.0, "bridge": "A2", "count": 2}
    return {f.name: sample[f.name] for f in dataclasses.fields(cls) if _default(f) is dataclasses.MISSING}


@pytest.mark.parametrize("kind", list(schedule.FAULT_KINDS))
def test_a_fault_goes_through_the_scenario_unchanged(kind):
    """Python API -> scenario table -> Python API gives the same fault (what a run records)."""
    cls = schedule.FAULT_KINDS[kind]
    fault = cls(**_required_values(cls))
    table = generated.FAULT_TABLES[kind].model_validate(fault_to_dict(fault))
    again = fault_from_dict(table.model_dump(mode="python"))
    assert again == fault
    assert fault_to_dict(again) == fault_to_dict(fault)


def test_a_fault_without_its_required_fields_is_refused_in_python_too():
    for kind, cls in schedule.FAULT_KINDS.items():
        required = _required_values(cls)
        for name in required:
            with pytest.raises(TypeError):
                cls(**{k: v for k, v in required.items() if k != name})
        assert set(required) == {n for n, f in generated.FAULT_TABLES[kind].model_fields.items() if f.is_required()}


# --- APF and DACMP settings ----------------------------------------------------------------------


def test_apf_table_is_the_agents_settings_less_what_comes_from_elsewhere():
    _same_fields(AgentApf, generated.ApfSettings, exclude=frozenset(APF_NOT_IN_TABLE))
    # min_separation_m comes from [safety]: one default for both.
    names = {f.name: f for f in dataclasses.fields(AgentApf)}
    assert SafetySettings().min_separation_m == names["min_separation_m"].default
    # What the table gives, with [safety]'s separation, builds the agents' settings.
    table = generated.ApfSettings()
    built = AgentApf(**table.model_dump(), min_separation_m=SafetySettings().min_separation_m)
    assert built == AgentApf()


def test_dacmp_table_is_the_planner_settings():
    _same_fields(DacmpSettings, generated.DacmpSettings)
    names = {f.name for f in dataclasses.fields(DacmpSettings)}
    assert names <= {f.name for f in dataclasses.fields(DacmpPlanner)}, "the planner is built on DacmpSettings"
    assert issubclass(DacmpPlanner, DacmpSettings)


def test_dacmp_planner_takes_every_setting_of_the_table():
    values = {"particles": 7, "iterations": 3, "w_start": 0.8, "w_end": 0.3, "c1_start": 2.0, "c1_end": 0.4,
              "c2_start": 0.6, "c2_end": 2.2, "ring_mean_factor": 1.2, "ring_sd_factor": 0.4, "ring_max_factor": 2.0,
              "heading_sd_rad": 1.0, "eta": 0.7, "field_unit_m": 500.0, "threat_margin_m": 250.0,
              "track_max_age_s": 99.0, "level_weights": [1.0, 2.0, 3.0], "member_map": "base", "map_refresh_s": 20.0}
    assert set(values) == set(generated.DacmpSettings.model_fields), "update the test values with the new field"
    planner = DacmpPlanner.from_settings(PlannerSettings(dacmp=values), levels=3)
    for name, value in values.items():
        got = getattr(planner, name)
        assert (list(got) if isinstance(got, tuple) else got) == value, name
    assert DacmpPlanner.from_settings(PlannerSettings()) == DacmpPlanner()


# --- the radio -----------------------------------------------------------------------------------


def test_radio_table_is_the_radio_settings_dataclass():
    _same_fields(CommsRadio, generated.RadioSettings, exclude=frozenset({"log_distance"}), extra=frozenset({"log_distance"}))
    _same_fields(LogDistance, generated.LogDistanceSettings)
    table = generated.RadioSettings()
    assert table.settings() == CommsRadio() and table.log_distance.model_dump() == dataclasses.asdict(LogDistance())
    # What the table implies is what the dataclass implies.
    for values in ({}, {"range_m": 2500.0, "loss_base": 0.1, "loss_at_range": 0.4, "sync_horizon_m": 8000.0},
                   {"model": "log_distance", "range_m": 9000.0}):
        table = generated.RadioSettings(**values)
        radio = table.settings()
        assert radio == CommsRadio(**values)
        assert (table.horizon_m, table.range_limit_m, table.effective_loss_at_range, table.log_distance_model(),
                table.link_model()) == (radio.horizon_m, radio.range_limit_m, radio.effective_loss_at_range,
                                        radio.link_model().log_distance, radio.link_model())


def test_the_actors_and_the_radio_take_their_radio_settings_from_the_scenario():
    from swarm.kernel import build
    from swarm.scenario import parse_scenario

    assert ActorSettings().radio == CommsRadio() and LinkModel() == CommsRadio().link_model()
    sc = parse_scenario({"uavs": [{"type": "B", "x_m": 100.0, "y_m": 100.0}],
                         "radio": {"beacon_every_s": 2.0, "sync_horizon_m": 5000.0, "frame_max_bytes": 4096,
                                   "range_m": 3000.0, "loss_base": 0.1}})
    assert build.actor_settings(sc).radio == sc.radio.settings()
    assert build.actor_settings(sc).radio.horizon_m == 5000.0
    assert build.radio(sc, lambda s, d: np.random.default_rng(0), None).model == LinkModel(range_m=3000.0, loss_base=0.1)


def test_the_frame_size_cap_is_written_once():
    users = [p.relative_to(ROOT).as_posix() for p in _sources() if re.search(r"\b65_?536\b", p.read_text(encoding="utf-8"))]
    assert users == ["comms/codec.py"]


def test_the_disk_loss_rule_is_written_once():
    # loss_base + (loss_at_range - loss_base) * f * f, f = distance / range: LinkModel._disk, which
    # LinkModel.loss (one link) and LinkModel.losses (the radio's array of links) both call.
    users = [p.relative_to(ROOT).as_posix() for p in _sources() if re.search(r"\*\s*f\s*\*\s*f\b", p.read_text(encoding="utf-8"))]
    assert users == ["comms/settings.py"]
    m = LinkModel(range_m=1000.0, loss_base=0.1, loss_at_range=0.5)
    d = np.array([0.0, 1.0, 333.3, 999.9, 1000.0, 5000.0])
    assert m.losses(d).tolist() == [m.loss(x) for x in d.tolist()]


# --- rules and names written once ----------------------------------------------------------------


def test_the_partition_rule_is_the_same_in_the_injector_and_the_invariants():
    from swarm.scenario import parse_scenario
    from swarm.testing.invariants import RunContext

    names = ["a", "b", "c", "d"]
    ids = {n: i for i, n in enumerate(names)}
    scenario = parse_scenario({"uavs": [{"name": n, "type": "B", "x_m": 100.0 * (i + 1), "y_m": 100.0}
                                        for i, n in enumerate(names)]})
    for one_way in (False, True):
        cut = Partition(groups=(("a",), ("b", "c")), one_way=one_way)
        injector = FaultInjector(FaultSchedule([cut]), ids)
        injector.begin_tick(0.0)
        ctx = RunContext(scenario, faults=[cut])
        for src, dst in itertools.product(range(len(names)), repeat=2):
            assert injector.blocked(src, dst) == ctx.blocked(src, dst, 0.0), (one_way, src, dst)
        assert injector.blocked(0, 1) and injector.blocked(1, 0) is (not one_way)
        assert not injector.blocked(1, 2) and not injector.blocked(0, 3)


def test_mode_names_are_defined_next_to_the_constants():
    assert MODE_NAMES == {MODE_SEARCH: "search", MODE_SURVEIL: "surveil"}
    pattern = re.compile(r"^\s*(MODE_SEARCH|MODE_SURVEIL|MODE_NAMES)\s*[:=]", re.M)
    defining = [p.relative_to(ROOT).as_posix() for p in _sources() if pattern.search(p.read_text(encoding="utf-8"))]
    assert defining == ["comms/messages.py"]


def test_uav_colours_come_from_style():
    # tab20 is the palette of 11-20 UAVs (tab10 also colours planners in sweep reports).
    users = [p.relative_to(ROOT).as_posix() for p in _sources() if "tab20" in p.read_text(encoding="utf-8")]
    assert users == ["swarm/viz/style.py"]
    for name in ("swarm/viz/plots.py", "swarm/viz/animate.py", "swarm/viz/report/run_figures.py",
                 "swarm/experiments/paper/figures.py"):
        assert "uav_colours(" in (ROOT / name).read_text(encoding="utf-8"), name


def test_files_are_replaced_atomically_in_one_place():
    users = [p.relative_to(ROOT).as_posix() for p in _sources() if "os.replace(" in p.read_text(encoding="utf-8")]
    assert users == ["swarm/outputs.py"]


def test_the_type_checkers_view_of_the_generated_fault_tables_matches_what_runs():
    # swarm/scenario/generated.py declares for mypy, under TYPE_CHECKING, only the fault table the
    # scenario model reads field by field (JoinFault: a UAV's join_s); any other [[faults]] item is
    # a FaultTable (its kind tag; no kind is named there). What it declares must be what runs.
    import ast

    tree = ast.parse(Path(generated.__file__).read_text())
    static: dict[str, tuple[str, str]] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            for item in node.body:
                if isinstance(item, ast.ClassDef) and item.name.endswith("Fault") and len(item.bases) == 2:
                    bases = [b.id if isinstance(b, ast.Name) else ast.unparse(b) for b in item.bases]
                    static[item.name] = (bases[0], bases[1])
    runtime = {cls.__name__: cls for cls in generated.FAULT_TABLES.values()}
    assert set(static) == {"JoinFault"} and set(static) <= set(runtime)
    for name, (validator_base, dataclass_ref) in static.items():
        cls = runtime[name]
        assert cls.__bases__[0].__name__ == validator_base, name
        kind = next(k for k, c in generated.FAULT_TABLES.items() if c is cls)
        assert dataclass_ref == f"_faults.{schedule.FAULT_KINDS[kind].__name__}", name
