"""Scenario model and loader: built-ins, defaults, and one readable ScenarioError per mistake."""

from __future__ import annotations

import copy
import math
import tomllib

import pytest
from budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from swarm.errors import ScenarioError
from swarm.scenario import (
    DEFAULT_UAV_TYPES,
    FAULT_KINDS,
    JoinFault,
    Scenario,
    apply_overrides,
    builtin_scenarios,
    load_scenario,
    parse_assignment,
    parse_scenario,
    scenario_from_toml,
)

MINIMAL = """
[[uavs]]
type = "B"
x_m = 1000
y_m = 2000
"""


def write(tmp_path, text: str, name: str = "bad.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def error_for(tmp_path, text: str) -> ScenarioError:
    path = write(tmp_path, text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.source == str(path)
    assert str(path) in str(info.value)
    return info.value


# --- built-ins -----------------------------------------------------------------------------
def test_builtins_are_listed_sorted():
    assert builtin_scenarios() == ["bench-100", "bench-1000", "bench-dense-300", "demo-all-faults", "geo-coast",
                                   "paper-case1", "paper-case2", "paper-case3", "paper-fig11"]


@pytest.mark.parametrize("name", ["paper-case1", "paper-case2", "paper-case3", "paper-fig11"])
def test_every_builtin_loads_and_round_trips(name):
    scenario = load_scenario(name)
    assert scenario.name == name
    assert scenario.area.cols == scenario.area.rows == 500
    # to_dict() is JSON-safe and loads back to the same scenario.
    assert parse_scenario(scenario.to_dict(), name) == scenario


def test_fig11_layout():
    s = load_scenario("paper-fig11")
    assert [u.type for u in s.uavs] == ["B"] * 6
    assert [(u.x_m, u.y_m) for u in s.uavs] == [(0.0, 1000.0 * y) for y in (20, 22, 24, 26, 28, 30)]
    assert all(u.heading_deg == 0.0 for u in s.uavs)
    assert s.uav_names == ["B1", "B2", "B3", "B4", "B5", "B6"]
    assert s.targets.count == 14 and s.threats == []
    assert s.duration_s == 2000.0
    assert s.planner.surveillance is False
    assert s.radio.range_limit_m == math.inf and s.radio.loss_base == 0.0


def test_case1_layout():
    s = load_scenario("paper-case1")
    assert {u.name: (u.type, u.x_m, u.y_m) for u in s.uavs} == {
        "B1": ("B", 20000.0, 22000.0), "B2": ("B", 36000.0, 22000.0), "A1": ("A", 10000.0, 22000.0)}
    assert [(t.x_m, t.y_m, t.heading_deg, t.speed) for t in s.targets.placed] == [
        (22500.0, 22500.0, 90.0, 3.0), (38500.0, 22500.0, 180.0, 3.0)]
    assert s.duration_s == 600.0 and s.threats == []


def test_case2_layout_and_target_clearance():
    s = load_scenario("paper-case2")
    b = [(u.x_m / 1000, u.y_m / 1000) for u in s.uavs if u.type == "B"]
    a = [(u.x_m / 1000, u.y_m / 1000) for u in s.uavs if u.type == "A"]
    assert b == [(10, 1), (29, 1), (30, 49), (15, 49), (39, 49)]
    assert a == [(20, 1), (35, 1), (5, 49), (23, 49), (45, 49)]
    assert all(u.heading_deg == (90.0 if u.y_m == 1000 else 270.0) for u in s.uavs)
    assert len(s.targets.placed) == 6 and len(s.threats) == 4
    for threat in s.threats:
        assert 2000 <= threat.radius_m <= 3000
        # away from the start lines (y = 1 km and y = 49 km)
        assert threat.y_m - threat.radius_m > 5000 and threat.y_m + threat.radius_m < 45000
        for target in s.targets.placed:
            edge = math.hypot(target.x_m - threat.x_m, target.y_m - threat.y_m) - threat.radius_m
            assert edge >= 5000, (target, threat)
    assert all(3 <= t.speed <= 8 for t in s.targets.placed)


def test_case3_is_case2_plus_a_joiner():
    case2, case3 = load_scenario("paper-case2"), load_scenario("paper-case3")
    assert case3.uavs[:-1] == case2.uavs
    assert case3.threats == case2.threats and case3.targets == case2.targets
    joiner = case3.uavs[-1]
    assert (joiner.name, joiner.type, joiner.x_m, joiner.y_m, joiner.heading_deg, joiner.join_s) == (
        "B6", "B", 50000.0, 25000.0, 180.0, 300.0)
    assert all(u.join_s is None for u in case3.uavs[:-1])


def test_defaults_match_table1_and_spec():
    s = parse_scenario(tomllib.loads(MINIMAL), "mini.toml")
    assert s.name == "mini"
    a, b = s.uav_type("A"), s.uav_type("B")
    assert (a.speed_min, a.speed_max, a.accel_max, a.bank_max_deg, a.detect_radius_m, a.w_t, a.w_r,
            a.influence_radius_m) == (30, 50, 0.4, 30, 1500, 5.0, 5.1, 10000)
    assert (b.speed_min, b.speed_max, b.accel_max, b.bank_max_deg, b.detect_radius_m, b.w_t, b.w_r,
            b.influence_radius_m) == (60, 90, 0.6, 20, 2000, 2.0, 2.1, 4000)
    assert (s.area.width_m, s.area.height_m, s.area.cell_m, s.map.levels) == (50000, 50000, 100, 7)
    assert s.planner.name == "dacmp" and s.planner.dacmp.particles == 40 and s.planner.dacmp.iterations == 25
    assert s.safety.min_separation_m == 200.0
    # tau = v_prior / largest detection radius among the types flown (only B here: 2 km).
    assert s.effective_tau == pytest.approx(10.0 / 2000.0)


def test_scenario_from_toml_names_from_source_and_keeps_explicit_name():
    assert scenario_from_toml(MINIMAL, "runs/my-run.toml").name == "my-run"
    assert scenario_from_toml('name = "x"\n' + MINIMAL, "runs/my-run.toml").name == "x"
    with pytest.raises(ScenarioError) as info:
        scenario_from_toml("seed = ", "inline")
    assert info.value.source == "inline" and info.value.found.startswith("invalid TOML")


def test_effective_tau_uses_only_flown_types_and_explicit_tau():
    doc = tomllib.loads(MINIMAL.replace('"B"', '"A"'))
    assert parse_scenario(doc).effective_tau == pytest.approx(10.0 / 1500.0)
    doc["map"] = {"tau": 0.02}
    assert parse_scenario(doc).effective_tau == 0.02


def test_uav_types_merge_over_table1_by_name():
    doc = tomllib.loads(MINIMAL + """
[uav_types.C]
speed_min = 10
speed_max = 20
accel_max = 1
bank_max_deg = 45
detect_radius_m = 500
w_t = 1
w_r = 1
influence_radius_m = 1000
""")
    s = parse_scenario(doc)
    assert set(s.uav_types) == {"A", "B", "C"}
    assert s.uav_types["A"] == DEFAULT_UAV_TYPES["A"]
    assert isinstance(s.uav_types["C"].speed_min, float)  # integers in TOML become floats


def test_default_names_count_within_type_and_join_fault_is_folded():
    doc = {
        "uavs": [{"type": "B", "x_m": 0, "y_m": 0}, {"type": "A", "x_m": 0, "y_m": 0},
                 {"type": "B", "x_m": 0, "y_m": 0}],
        "faults": [{"kind": "join", "at_s": 120, "uav": "B2"}],
    }
    s = parse_scenario(doc)
    assert s.uav_names == ["B1", "A1", "B2"]
    assert s.uavs[2].join_s == 120.0 and s.uavs[0].join_s is None
    assert isinstance(s.faults[0], JoinFault)  # the fault stays in the list


def test_threat_d_max_default_and_radio_inf():
    doc = tomllib.loads(MINIMAL + "[[threats]]\nx_m = 5000\ny_m = 5000\nradius_m = 2000\n[radio]\nrange_m = inf\n")
    s = parse_scenario(doc)
    assert s.threats[0].d_max == 5000.0
    assert s.radio.range_limit_m == math.inf
    assert s.to_dict()["radio"]["range_m"] is None


# --- errors --------------------------------------------------------------------------------
def test_unknown_key_in_nested_table_names_path_and_suggests(tmp_path):
    err = error_for(tmp_path, MINIMAL + "[uav_types.A]\nsped_max = 60\n")
    assert err.key == "uav_types.A.sped_max"
    assert err.found == "unknown key 'sped_max'"
    assert err.hint == "did you mean 'speed_max'?"


def test_unknown_key_without_close_match_lists_valid_keys(tmp_path):
    err = error_for(tmp_path, MINIMAL + "[safety]\nzzzz = 1\n")
    assert err.key == "safety.zzzz"
    assert "min_separation_m" in err.hint


def test_string_for_a_float(tmp_path):
    err = error_for(tmp_path, 'duration_s = "fast"\n' + MINIMAL)
    assert (err.key, err.found, err.expected) == ("duration_s", "'fast' (string)", "a number > 0")


def test_bool_for_a_float(tmp_path):
    err = error_for(tmp_path, MINIMAL + "[radio]\nlatency_s = true\n")
    assert err.key == "radio.latency_s"
    assert err.found == "True (boolean)"


def test_float_for_an_int(tmp_path):
    err = error_for(tmp_path, MINIMAL + "[map]\nlevels = 7.0\n")
    assert err.key == "map.levels" and err.found == "7.0 (float)"


def test_negative_speed(tmp_path):
    err = error_for(tmp_path, MINIMAL + "speed = -3.0\n")
    assert err.key == "uavs[0].speed"
    assert err.found == "-3.0 (float)"


def test_speed_outside_the_type_range(tmp_path):
    err = error_for(tmp_path, MINIMAL + "speed = 95\n")
    assert err.key == "uavs[0].speed"
    assert err.found == "95 (integer)"
    assert "[60, 90]" in err.expected


def test_loss_above_one(tmp_path):
    err = error_for(tmp_path, MINIMAL + "[radio]\nloss_base = 1.5\n")
    assert (err.key, err.found, err.expected) == ("radio.loss_base", "1.5 (float)", "a number in [0, 1]")


def test_missing_required_key(tmp_path):
    err = error_for(tmp_path, '[[uavs]]\ntype = "B"\nx_m = 0\n')
    assert err.key == "uavs[0].y_m"
    assert err.found == "nothing (the key is missing)"


def test_missing_uavs(tmp_path):
    err = error_for(tmp_path, "seed = 3\n")
    assert err.key == "uavs" and err.found == "nothing (the key is missing)"


def test_uav_of_undefined_type(tmp_path):
    err = error_for(tmp_path, MINIMAL.replace('"B"', '"C"'))
    assert err.key == "uavs[0].type"
    assert err.found == "'C' (string)"
    assert err.expected == "a UAV type defined in [uav_types]: A, B"


def test_fault_naming_an_unknown_uav(tmp_path):
    err = error_for(tmp_path, MINIMAL + '[[faults]]\nkind = "crash"\nat_s = 10\nuav = "B7"\n')
    assert err.key == "faults[0].uav"
    assert err.expected == "a UAV name defined in [[uavs]]: B1"


def test_fault_path_has_no_union_tag(tmp_path):
    err = error_for(tmp_path, MINIMAL + '[[faults]]\nkind = "drop"\nrate = 2\n')
    assert err.key == "faults[0].rate"
    assert err.expected == "a number in [0, 1]"


def test_unknown_fault_kind(tmp_path):
    err = error_for(tmp_path, MINIMAL + '[[faults]]\nkind = "explode"\n')
    assert err.key == "faults[0].kind"
    assert err.expected == "one of: " + ", ".join(FAULT_KINDS)
    # In registration order: family by family (faults/__init__.py), the link kinds first.
    assert err.expected.startswith("one of: drop, burst, delay, duplicate, corrupt, partition")


def test_fault_window_and_partition_rules(tmp_path):
    err = error_for(tmp_path, MINIMAL + '[[faults]]\nkind = "drop"\nrate = 0.1\nstart_s = 50\nend_s = 40\n')
    assert err.key == "faults[0].end_s" and "start_s" in err.expected
    err = error_for(tmp_path, MINIMAL + '[[faults]]\nkind = "partition"\ngroups = [["B1"]]\n')
    assert err.key == "faults[0].groups"


def test_join_fault_and_join_s_both(tmp_path):
    err = error_for(tmp_path, MINIMAL + 'join_s = 5\n[[faults]]\nkind = "join"\nat_s = 9\nuav = "B1"\n')
    assert err.key == "faults[0].uav"


def test_duplicate_uav_names(tmp_path):
    err = error_for(tmp_path, MINIMAL + '[[uavs]]\nname = "B1"\ntype = "A"\nx_m = 0\ny_m = 0\n')
    assert err.key == "uavs[1].name"
    assert err.found == "'B1' (string)"


def test_position_outside_the_area(tmp_path):
    err = error_for(tmp_path, MINIMAL.replace("x_m = 1000", "x_m = 60000"))
    assert err.key == "uavs[0].x_m"
    assert err.found == "60000 (integer)"  # as written in the file
    assert "[0, 50000]" in err.expected


def test_area_not_whole_cells(tmp_path):
    err = error_for(tmp_path, "[area]\nwidth_m = 50050\n" + MINIMAL)
    assert err.key == "area.width_m" and "cell_m" in err.expected


def test_level_weights_length(tmp_path):
    err = error_for(tmp_path, MINIMAL + "[planner.dacmp]\nlevel_weights = [1, 2]\n")
    assert err.key == "planner.dacmp.level_weights"


def test_first_error_in_document_order(tmp_path):
    # pydantic reports errors in model field order (uavs before radio, radio before metrics);
    # the user gets the first one as written in the file.
    err = error_for(tmp_path, "[metrics]\nsample_s = -1\n[radio]\nloss_base = 2\n" + MINIMAL)
    assert err.key == "metrics.sample_s"
    err = error_for(tmp_path, "[radio]\nloss_base = 2\n" + MINIMAL + "speed = -3\n")
    assert err.key == "radio.loss_base"
    err = error_for(tmp_path, MINIMAL + "speed = -3\n[radio]\nloss_base = 2\n")
    assert err.key == "uavs[0].speed"


def test_invalid_toml(tmp_path):
    err = error_for(tmp_path, "seed = [1,\n")
    assert err.key == ""
    assert err.found.startswith("invalid TOML (")
    assert err.expected == "a TOML document"


def test_missing_file(tmp_path):
    path = tmp_path / "nope.toml"
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    err = info.value
    assert err.source == str(path) and err.key == ""
    assert err.expected.startswith(
        "a path to an existing .toml file (or a run folder's scenario.json) or a built-in name (bench-100, ")
    assert "paper-case1, " in err.expected
    assert str(path) in str(err)


def test_error_is_a_value_error_with_one_line(tmp_path):
    err = error_for(tmp_path, MINIMAL + "[radio]\nloss_base = 1.5\n")
    assert isinstance(err, ValueError)
    assert "\n" not in str(err) and "radio.loss_base" in str(err)


def test_non_table_document_and_entries():
    with pytest.raises(ScenarioError) as info:
        parse_scenario([1, 2], "x")  # type: ignore[arg-type]
    assert info.value.key == ""
    with pytest.raises(ScenarioError) as info:
        parse_scenario({"uavs": [3]}, "x")
    assert info.value.key == "uavs[0]" and info.value.expected == "a table"


# --- overrides -----------------------------------------------------------------------------
def test_apply_overrides_valid_dotted_keys():
    base = load_scenario("paper-case3")
    s = apply_overrides(base, {"radio.loss_base": 0.3, "uavs[0].x_m": 500, "seed": 7})
    assert s.radio.loss_base == 0.3 and s.uavs[0].x_m == 500.0 and s.seed == 7
    assert base.radio.loss_base == 0.0  # the original is untouched
    assert s.uavs[-1].join_s == 300.0  # the folded join survives re-validation
    assert base.with_overrides(duration_s=400).duration_s == 400.0
    with pytest.raises(ScenarioError, match="join after the end"):  # the joiner comes at 300 s
        base.with_overrides(duration_s=100)
    assert apply_overrides(base, {"duration_s": 100}, truncated=True).duration_s == 100.0  # cut short on purpose
    # moving the join time through the fault re-folds it
    joined = apply_overrides(parse_scenario({**load_scenario("paper-fig11").to_dict(),
                                             "faults": [{"kind": "join", "at_s": 5, "uav": "B6"}]}),
                             {"faults[0].at_s": 60})
    assert joined.uavs[-1].join_s == 60.0


def test_apply_overrides_invalid_value_names_the_key():
    with pytest.raises(ScenarioError) as info:
        apply_overrides(load_scenario("paper-fig11"), {"radio.loss_base": 1.3})
    assert info.value.key == "radio.loss_base"
    with pytest.raises(ScenarioError) as info:
        load_scenario("paper-fig11").with_overrides(seed="x")
    assert info.value.key == "seed"


def test_apply_overrides_unknown_key_names_it_with_a_hint():
    with pytest.raises(ScenarioError) as info:
        apply_overrides(load_scenario("paper-fig11"), {"radio.loss_bse": 0.3})
    assert info.value.key == "radio.loss_bse"
    assert info.value.hint == "did you mean 'loss_base'?"
    with pytest.raises(ScenarioError) as info:
        apply_overrides(load_scenario("paper-fig11"), {"uavs[9].x_m": 1})
    assert info.value.key == "uavs[9]"


def test_override_breaking_another_key_says_which_override():
    with pytest.raises(ScenarioError) as info:
        apply_overrides(load_scenario("paper-case2"), {"area.width_m": 40000})
    assert info.value.key.endswith(".x_m")
    assert "area.width_m" in info.value.hint


def test_parse_assignment():
    assert parse_assignment("radio.loss_base=0.3") == ("radio.loss_base", 0.3)
    assert parse_assignment("planner.name=greedy") == ("planner.name", "greedy")
    assert parse_assignment("planner.surveillance=false") == ("planner.surveillance", False)
    with pytest.raises(ScenarioError):
        parse_assignment("no-equals-sign")


# --- never anything but ScenarioError ------------------------------------------------------
scalars = st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8)
json_like = st.recursive(
    scalars,
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4),
    max_leaves=20,
)
key_names = st.sampled_from(["uavs", "area", "radio", "faults", "type", "x_m", "y_m", "rate", "kind",
                             "uav_types", "A", "speed_max", "planner", "dacmp", "level_weights", "groups"])
structured = st.recursive(
    scalars,
    lambda children: st.lists(children, max_size=4) | st.dictionaries(key_names | st.text(max_size=5), children, max_size=4),
    max_leaves=25,
)


def parse_or_scenario_error(doc) -> None:
    try:
        result = parse_scenario(doc, "fuzz.toml")
    except ScenarioError as err:
        assert err.source == "fuzz.toml"
        str(err)
    else:
        assert isinstance(result, Scenario)


@settings(max_examples=examples(300), suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(key_names | st.text(max_size=8), json_like, max_size=6) | structured)
def test_arbitrary_documents_only_raise_scenario_error(doc):
    parse_or_scenario_error(doc)


RICH = tomllib.loads(MINIMAL + """
[[uavs]]
type = "A"
x_m = 100
y_m = 200
speed = 40
[[targets.placed]]
x_m = 10
y_m = 10
[[threats]]
x_m = 9000
y_m = 9000
radius_m = 1000
[[faults]]
kind = "partition"
groups = [["B1"], ["A1"]]
[[faults]]
kind = "drop"
rate = 0.1
links = [["B1", "A1"]]
[[faults]]
kind = "join"
at_s = 5
uav = "A1"
[planner.dacmp]
level_weights = [1, 1, 1, 1, 1, 1, 1]
""")


def leaf_paths(node, prefix=()):
    if isinstance(node, dict):
        for k, v in node.items():
            yield (*prefix, k)
            yield from leaf_paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield (*prefix, i)
            yield from leaf_paths(v, (*prefix, i))


RICH_PATHS = list(leaf_paths(RICH))


def test_rich_document_is_valid():
    assert parse_scenario(RICH).uavs[1].join_s == 5.0


@settings(max_examples=examples(300))
@given(st.sampled_from(RICH_PATHS), scalars | st.just([]) | st.just({}), st.booleans())
def test_mutated_valid_document_only_raises_scenario_error(path, value, delete):
    doc = copy.deepcopy(RICH)
    parent = doc
    for part in path[:-1]:
        parent = parent[part]
    if delete:
        del parent[path[-1]]
    else:
        parent[path[-1]] = value
    parse_or_scenario_error(doc)
