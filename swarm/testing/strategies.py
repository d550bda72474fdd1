"""Hypothesis strategies for small valid scenarios: import them in your own property tests.

Every scenario is built as a document and validated by the project's own model
(:func:`swarm.scenario.parse_scenario`), so it is always one a user could have written::

    from hypothesis import given
    from swarm import Simulation
    from swarm.testing.strategies import scenarios

    @given(scenarios(max_uavs=3, max_duration_s=40))
    def test_no_dynamics_violation(scenario):
        with Simulation(scenario) as sim:
            assert sim.run().metrics["violations"]["dynamics"] == 0

The pieces compose: :func:`areas` (5-15 km squares by default), :func:`fleets` (mixed UAV
types, optionally a generated third type and late joiners), :func:`target_layouts`,
:func:`threat_layouts`, :func:`radio_tables` (from :func:`swarm.testing.fault_strategies.link_models`) and
fault schedules (:func:`swarm.testing.fault_strategies.fault_schedules`). Runs are short (20-60 s) so each
example is cheap. Shrinking goes towards one UAV, no targets, no threats, the ideal radio, no
faults, the greedy planner and the shortest run.

When an example fails, :func:`reproduction` writes it as a TOML file and returns the exact
``swarm run`` command that replays it (:func:`scenario_toml` is the writer).

Needs ``hypothesis`` (the ``test`` extra); nothing in the simulator imports this module.
"""

from __future__ import annotations

import swarm.testing._hypothesis  # noqa: F401  (first: a clear error without Hypothesis)

# isort: split

import contextlib
import hashlib
import math
import os
import re
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from hypothesis import assume, currently_in_test_context, note
from hypothesis import strategies as st
from hypothesis.control import current_build_context
from hypothesis.errors import InvalidArgument

from agents.assignment import rule_breaks
from agents.planners.registry import is_module_ref
from agents.types import UavType
from faults.schedule import Fault, FaultSchedule, Join, fault_from_dict, fault_to_dict
from swarm.scenario import DEFAULT_UAV_TYPES, Scenario, UavTypeSpec, parse_scenario
from swarm.testing.fault_strategies import fault_kinds as registered_fault_kinds
from swarm.testing.fault_strategies import fault_schedules, link_models

__all__ = [
    "areas",
    "configurations",
    "endurance_tables",
    "fault_schedule_of",
    "fleets",
    "geo_areas",
    "geo_frame",
    "no_fly_polygons",
    "radio_tables",
    "reproduction",
    "reproduce_command",
    "reproducible",
    "scenario_documents",
    "scenario_toml",
    "scenarios",
    "set_swarm_testing",
    "swarm_testing_enabled",
    "target_layouts",
    "threat_layouts",
    "uav_type_specs",
    "wind_tables",
]

GENERATED_SOURCE = "<generated>"


# --- the world -------------------------------------------------------------------------------


@st.composite
def areas(draw: st.DrawFn, min_km: int = 5, max_km: int = 15, cell_m: Sequence[float] = (100.0, 200.0, 250.0)) -> dict[str, Any]:
    """An ``[area]`` table: whole kilometres on each side (so any listed cell size tiles it)."""
    if not 1 <= min_km <= max_km:
        raise ValueError(f"need 1 <= min_km <= max_km, got {min_km}, {max_km}")
    w = draw(st.integers(min_km, max_km)) * 1000.0
    h = draw(st.integers(min_km, max_km)) * 1000.0
    return {"width_m": w, "height_m": h, "cell_m": float(draw(st.sampled_from(list(cell_m))))}


@st.composite
def uav_type_specs(draw: st.DrawFn, *, rule_abiding: bool = True,
                   others: Mapping[str, dict[str, Any]] | None = None) -> dict[str, Any]:
    """A ``[uav_types.NAME]`` table for a type that is not in Table 1 (types are data).

    With ``rule_abiding`` (the default) its weights meet the preconditions of the assignment
    rules (docs/modelling.md, "Assignment rules"; :mod:`agents.assignment`: eq. 25-27) on their
    own and beside ``others`` (``[uav_types]`` tables by name; default Table 1's A and B):
    ``w_t`` just below ``w_r``, and above ``w_r`` times its top speed over each faster type's.
    ``rule_abiding=False`` draws ``w_t`` and ``w_r`` independently: such a type may break the
    rules, the scenario validator warns about it, and the assignment checkers do not judge it."""
    speed_min = float(draw(st.integers(15, 60)))
    spec: dict[str, Any] = {
        "speed_min": speed_min,
        "speed_max": speed_min + float(draw(st.integers(0, 40))),
        "accel_max": draw(st.sampled_from([0.5, 0.2, 1.0, 2.0])),
        "bank_max_deg": float(draw(st.integers(10, 45))),
        "detect_radius_m": float(draw(st.integers(5, 25)) * 100),
        "influence_radius_m": float(draw(st.integers(1, 10)) * 1000),
    }
    if not rule_abiding:
        spec["w_t"] = draw(st.sampled_from([3.0, 0.0, 1.0, 6.0]))
        spec["w_r"] = draw(st.sampled_from([3.1, 0.0, 1.1, 6.1]))
        return spec
    others = {k: v.model_dump() for k, v in DEFAULT_UAV_TYPES.items()} if others is None else dict(others)
    w_r = draw(st.sampled_from([3.1, 1.1, 6.1]))
    # eq. 25 as the slower type: w_t / w_r above v / v_faster for every faster type.
    need = max([spec["speed_max"] / o["speed_max"] for o in others.values() if o["speed_max"] > spec["speed_max"]],
               default=0.0)
    ratio = draw(st.sampled_from([0.98, 0.95, 0.9, 0.99]))
    if ratio <= need:
        ratio = (need + 1.0) / 2.0
    spec["w_r"], spec["w_t"] = w_r, round(w_r * ratio, 6)
    kinds = [_uav_type(n, o) for n, o in others.items()]
    # The others as slower types beside this one (eq. 25 for them) depend on its speed alone.
    assume(not rule_breaks([*kinds, _uav_type("NEW", spec)]))
    return spec


def _uav_type(name: str, spec: Mapping[str, Any]) -> UavType:
    return UavTypeSpec(**spec).uav_type(name)


def _lattice(area: dict[str, Any], spacing_m: float, margin_m: float) -> list[tuple[float, float]]:
    w, h = area["width_m"], area["height_m"]
    xs = [margin_m + i * spacing_m for i in range(int((w - 2 * margin_m) // spacing_m) + 1)] or [w / 2]
    ys = [margin_m + j * spacing_m for j in range(int((h - 2 * margin_m) // spacing_m) + 1)] or [h / 2]
    return [(x, y) for y in ys for x in xs]


@st.composite
def fleets(draw: st.DrawFn, area: dict[str, Any], types: Sequence[str] = ("B", "A"), *, min_uavs: int = 1, max_uavs: int = 4,
           duration_s: float | None = None, late_joiners: bool = True, spacing_m: float = 2000.0,
           type_specs: dict[str, dict[str, Any]] | None = None,
           where: Callable[[float, float], bool] | None = None) -> list[dict[str, Any]]:
    """``[[uavs]]`` entries of mixed ``types``, named TYPE + number (``B1``, ``A1``, ...), starting
    on distinct points of a lattice ``spacing_m`` apart (never inside each other's separation
    distance), heading anywhere, at their type's top speed or a speed in range. With
    ``late_joiners`` (and a ``duration_s``) some may enter later (``join_s``). ``where``: only
    the lattice points it accepts (for a geographic area: inside its polygon, clear of zones)."""
    slots = _lattice(area, spacing_m, margin_m=500.0)
    if where is not None:  # (a geographic area, no-fly polygons: only the slots inside and clear)
        slots = [p for p in slots if where(*p)]
        if not slots:
            raise ValueError("no lattice slot lies inside the area polygon, clear of the no-fly zones")
    n = draw(st.integers(min_uavs, max(min_uavs, min(max_uavs, len(slots)))))
    if n > len(slots):
        raise ValueError(f"{n} UAVs do not fit {spacing_m} m apart in a {area['width_m']} x {area['height_m']} m area")
    picks = draw(st.lists(st.integers(0, len(slots) - 1), min_size=n, max_size=n, unique=True))
    specs = {**{k: v.model_dump() for k, v in DEFAULT_UAV_TYPES.items()}, **(type_specs or {})}
    per_type: dict[str, int] = {}
    out = []
    for i, slot in enumerate(picks):
        kind = draw(st.sampled_from(list(types)))
        per_type[kind] = per_type.get(kind, 0) + 1
        x, y = slots[slot]
        uav: dict[str, Any] = {"name": f"{kind}{per_type[kind]}", "type": kind, "x_m": x, "y_m": y,
                               "heading_deg": float(draw(st.integers(0, 23)) * 15)}
        spec = specs.get(kind)
        if spec is not None and draw(st.booleans()):
            uav["speed"] = float(draw(st.integers(math.ceil(spec["speed_min"]), math.floor(spec["speed_max"]))))
        # The first UAV always starts at 0 s, so the run has someone flying.
        if late_joiners and duration_s is not None and i > 0 and duration_s >= 2 and draw(st.booleans()):
            uav["join_s"] = float(draw(st.integers(1, int(duration_s) - 1)))
        out.append(uav)
    return out


@st.composite
def target_layouts(draw: st.DrawFn, area: dict[str, Any], *, max_targets: int = 3, speed_max: float = 20.0,
                   where: Callable[[float, float], bool] | None = None) -> dict[str, Any]:
    """A ``[targets]`` table: some placed targets and/or a random ``count``. ``where``: placed
    targets only where it accepts (inside an area polygon)."""
    w, h = area["width_m"], area["height_m"]
    placed = draw(st.lists(
        st.fixed_dictionaries({
            "x_m": st.integers(0, int(w) // 100).map(lambda k: k * 100.0),
            "y_m": st.integers(0, int(h) // 100).map(lambda k: k * 100.0),
            "heading_deg": st.integers(0, 23).map(lambda k: k * 15.0),
            "speed": st.integers(0, int(speed_max)).map(float),
        }),
        max_size=max_targets,
    ))
    if where is not None:
        placed = [p for p in placed if where(p["x_m"], p["y_m"])]
    count = draw(st.integers(0, max(0, max_targets - len(placed))))
    return {"count": count, "speed_max": speed_max, "placed": placed}


@st.composite
def threat_layouts(draw: st.DrawFn, area: dict[str, Any], keep_clear: Sequence[tuple[float, float]] = (), *, max_threats: int = 2,
                   clearance_m: float = 3000.0) -> list[dict[str, Any]]:
    """``[[threats]]`` circles of 300-1500 m whose edge lies at least ``clearance_m`` from every
    point of ``keep_clear`` (the UAVs' start points: a UAV that starts beside a threat, pointing
    at it, may be unable to turn away in time, and that would be the scenario's fault, not the
    planner's). Fewer threats than asked when the area is too crowded."""
    w, h = area["width_m"], area["height_m"]
    n = draw(st.integers(0, max_threats))
    out = []
    for _ in range(n):
        radius = float(draw(st.integers(3, 15)) * 100)
        x = float(draw(st.integers(0, int(w) // 100)) * 100)
        y = float(draw(st.integers(0, int(h) // 100)) * 100)
        if all(math.hypot(x - px, y - py) >= radius + clearance_m for px, py in keep_clear):
            out.append({"x_m": x, "y_m": y, "radius_m": radius})
    return out


def _star(draw: st.DrawFn, cx: float, cy: float, radius: float, vertices: tuple[int, int] = (5, 9)) -> list[tuple[float, float]]:
    """A closed ring star-shaped about ``(cx, cy)`` (so simple, the centre inside): ``n``
    corners, one in the first half of each of ``n`` equal sectors (so no two closer than half a
    sector in angle), each at 0.55-1 times ``radius`` from the centre."""
    n = draw(st.integers(*vertices))
    sector = 360.0 / n
    ring = []
    for k in range(n):
        a = k * sector + sector * draw(st.sampled_from([0.0, 0.25, 0.5]))
        r = radius * draw(st.sampled_from([1.0, 0.85, 0.7, 0.55]))
        ring.append((cx + r * math.cos(math.radians(a)), cy + r * math.sin(math.radians(a))))
    return [*ring, ring[0]]


@st.composite
def geo_areas(draw: st.DrawFn, min_km: int = 8, max_km: int = 20, cell_m: Sequence[float] = (200.0, 250.0)) -> dict[str, Any]:
    """(issue 33) A geographic area: ``{"geo": {"area": RING}, "area": {"cell_m": ...}}``, the
    ring a star-shaped polygon of 5-9 corners in longitude/latitude (EPSG:4326, 4 decimals)
    somewhere between 60 S and 60 N, ``min_km``-``max_km`` across. :func:`geo_frame` gives its
    local frame (what the other strategies place things in)."""
    lat0 = float(draw(st.integers(-60, 60)))
    lon0 = float(draw(st.integers(-170, 170)))
    radius_km = draw(st.integers(min_km, max_km)) / 2.0
    rad = math.radians(lat0)
    ring = _star(draw, 0.0, 0.0, radius_km)
    pts = [[round(lon0 + x / (111.32 * math.cos(rad)), 4), round(lat0 + y / 110.57, 4)] for x, y in ring]
    pts[-1] = list(pts[0])
    return {"geo": {"area": pts}, "area": {"cell_m": float(draw(st.sampled_from(list(cell_m))))}}


def geo_frame(doc: Mapping[str, Any]) -> Any:
    """The local frame (:class:`swarm.geo.frame.GeoFrame`) of a document's ``[geo]`` area."""
    from swarm.geo.frame import frame_for

    return frame_for(doc["geo"].get("crs", "EPSG:4326"), doc["geo"]["area"], float(doc["area"]["cell_m"]))


@st.composite
def no_fly_polygons(draw: st.DrawFn, area: dict[str, Any], keep_clear: Sequence[tuple[float, float]] = (), *,
                    max_zones: int = 2, clearance_m: float = 3000.0, frame: Any = None) -> list[dict[str, Any]]:
    """(issue 33) ``[[no_fly]]`` polygons: star-shaped, 0.5-1.5 km across their widest, whose
    every point lies at least ``clearance_m`` from each point of ``keep_clear`` (as
    :func:`threat_layouts`). With ``frame`` (a geographic scenario's) the rings are written in
    lon/lat, else in local metres. Fewer zones than asked when the area is too crowded."""
    w, h = area["width_m"], area["height_m"]
    out: list[dict[str, Any]] = []
    for _ in range(draw(st.integers(0, max_zones))):
        radius = float(draw(st.integers(5, 15)) * 100)
        cx = float(draw(st.integers(0, int(w) // 100)) * 100)
        cy = float(draw(st.integers(0, int(h) // 100)) * 100)
        if not all(math.hypot(cx - px, cy - py) >= radius + clearance_m for px, py in keep_clear):
            continue
        ring = _star(draw, cx, cy, radius)
        if frame is not None:
            lon, lat = frame.to_lonlat([p[0] for p in ring], [p[1] for p in ring])
            pts = [[round(float(a), 6), round(float(b), 6)] for a, b in zip(lon, lat)]
        else:
            pts = [[round(x, 1), round(y, 1)] for x, y in ring]
        pts[-1] = list(pts[0])
        zone: dict[str, Any] = {"name": f"zone {len(out)}", "polygon": pts}
        if draw(st.booleans()):
            zone["influence_m"] = float(draw(st.integers(10, 30)) * 100)
        out.append(zone)
    return out


@st.composite
def wind_tables(draw: st.DrawFn, max_speed_mps: int = 8) -> dict[str, Any]:
    """(issue 33) A ``[wind]`` table: a mean of 0-``max_speed_mps`` m/s from anywhere, gusts
    or none. Shrinks to calm."""
    table: dict[str, Any] = {"speed_mps": float(draw(st.integers(0, max_speed_mps))),
                             "direction_deg": float(draw(st.integers(0, 23)) * 15)}
    if draw(st.booleans()):
        table["gust_sigma_mps"] = float(draw(st.sampled_from([1.0, 0.5, 2.0])))
        table["gust_tau_s"] = float(draw(st.sampled_from([10.0, 5.0, 30.0])))
    return table


@st.composite
def endurance_tables(draw: st.DrawFn, doc: Mapping[str, Any], base: tuple[float, float]) -> dict[str, Any]:
    """(issue 33) An ``[endurance]`` table for a document's UAVs: the base at ``base`` (local
    metres), and for each type flown a battery for 0.4-3 times the run's length at full speed
    (so UAVs go home, land, turn around in 10-60 s and relaunch within a run), never less than
    twice what reaching its farthest launch point and coming back against the wind takes (what
    validation asks, with a margin)."""
    from swarm.scenario.mission import EnergySpec, min_power_speed, power_w
    from swarm.scenario.tables import DEFAULT_UAV_TYPES

    specs = {**{n: t.model_dump() for n, t in DEFAULT_UAV_TYPES.items()}, **doc.get("uav_types", {})}
    wind = doc.get("wind") or {}
    gusty = float(wind.get("speed_mps", 0.0)) + 3.0 * float(wind.get("gust_sigma_mps", 0.0))
    reserve = draw(st.sampled_from([0.1, 0.2, 0.3]))
    types = {}
    for name in sorted({u["type"] for u in doc["uavs"]}):
        t = specs[name]
        e = EnergySpec(capacity_wh=1.0)
        v_mp = min_power_speed(e, t["speed_min"], t["speed_max"])
        far = max(math.hypot(u["x_m"] - base[0], u["y_m"] - base[1]) for u in doc["uavs"] if u["type"] == name)
        ground = max(v_mp - gusty, 1.0)
        need = 2.0 * far / ground * power_w(e, v_mp, v_mp) / 3600.0 / (1.0 - reserve)
        flight = doc["duration_s"] * draw(st.sampled_from([3.0, 1.0, 0.6, 0.4]))
        types[name] = {"capacity_wh": round(max(power_w(e, v_mp, t["speed_max"]) * flight / 3600.0, 2.0 * need, 0.01), 4)}
    return {"x_m": base[0], "y_m": base[1], "types": types, "reserve_frac": reserve,
            "handover_s": float(draw(st.sampled_from([30.0, 0.0, 60.0]))),
            "turnaround_s": float(draw(st.sampled_from([30.0, 10.0, 60.0]))),
            "land_radius_m": float(draw(st.sampled_from([500.0, 300.0])))}


#: (issue 33) Whether :func:`scenario_documents` may draw ``[endurance]`` where a caller asks for
#: it with ``endurance=None`` (what the rule tests of ``tests/test_assignment_rules.py`` do). On
#: since the relief rule (rule 6 of docs/modelling.md's assignment rules) is settled; a switch to
#: leave batteries out of those tests should a change need to.
ENDURANCE_IN_RULE_TESTS = True


@st.composite
def radio_tables(draw: st.DrawFn, *, max_range_m: float = 20_000.0, lossy: bool = True,
                 bandwidth: bool = False) -> dict[str, Any]:
    """A ``[radio]`` table from :func:`swarm.testing.fault_strategies.link_models` (plus a mailbox size)."""
    m = draw(link_models(max_range_m=max_range_m, lossy=lossy, bandwidth=bandwidth))
    table: dict[str, Any] = {"loss_base": m.loss_base, "loss_at_range": m.loss_at_range,
                             "latency_s": m.latency_s, "jitter_s": m.jitter_s}
    if m.range_m is not None:
        table["range_m"] = m.range_m
    if m.bandwidth_bytes_per_s is not None:
        table["bandwidth_bytes_per_s"] = m.bandwidth_bytes_per_s
    table["mailbox_capacity"] = draw(st.sampled_from([1024, 64, 8]))
    return table


# --- whole scenarios -------------------------------------------------------------------------


@st.composite
def scenario_documents(
    draw: st.DrawFn,
    *,
    min_uavs: int = 1,
    max_uavs: int = 4,
    min_duration_s: int = 20,
    max_duration_s: int = 60,
    area_km: tuple[int, int] = (5, 15),
    planners: Sequence[str] = ("greedy", "dacmp"),
    surveillance: bool | None = None,
    extra_types: bool = True,
    rule_abiding_types: bool = True,
    late_joiners: bool = True,
    max_targets: int = 3,
    max_threats: int = 2,
    faults: bool = True,
    fault_kinds: Sequence[str] | None = None,
    max_faults: int = 5,
    lossy_radio: bool = True,
    swarm: bool | None = None,
    geo: bool = False,
    max_no_fly: int = 0,
    wind: bool = False,
    endurance: bool | None = False,
) -> dict[str, Any]:
    """A scenario document (a dict, as parsed from TOML) that :func:`parse_scenario` accepts.
    :func:`scenarios` validates it; the fuzz tests mutate it into wrong documents.

    With ``extra_types`` some examples fly a generated third type ``C``
    (:func:`uav_type_specs`); ``rule_abiding_types`` (default) keeps its weights within the
    assignment rules' preconditions (docs/modelling.md, "Assignment rules"), False lets them
    break those rules (for tests of the warning and of the checkers' scope).

    ``swarm`` (default: :func:`swarm_testing_enabled`, on under the ``swarm`` Hypothesis
    profile): swarm testing, as FoundationDB's simulation does it: each example also draws its
    configuration (see :func:`configurations`: which UAV types fly, the radio model, the map's
    tau, the replanning period) and which of ``fault_kinds`` it may use at all, so examples
    differ in kind and not only in values. Off, those stay at their defaults (disk radio, the
    scenario's default tau, replanning every 10 s, every kind of ``fault_kinds``). ``fault_kinds``
    defaults to every registered kind with a strategy
    (:func:`swarm.testing.fault_strategies.fault_kinds`, read when the example is drawn).

    Real missions (issue 33), each drawn or not per example when asked for: ``geo``, the area
    a lon/lat polygon (:func:`geo_areas`; UAVs, placed targets and the base inside it);
    ``max_no_fly`` polygon no-fly zones (:func:`no_fly_polygons`); ``wind``
    (:func:`wind_tables`); ``endurance``, batteries and a base (:func:`endurance_tables`; a
    battery fault also brings one). ``endurance=None``: as :data:`ENDURANCE_IN_RULE_TESTS` says."""
    swarm = swarm_testing_enabled() if swarm is None else swarm
    endurance = ENDURANCE_IN_RULE_TESTS if endurance is None else endurance
    duration = draw(st.integers(min_duration_s, max_duration_s))
    geo_doc = (draw(geo_areas(max(10, area_km[0]), max(20, area_km[1]))) if geo and draw(st.booleans(), label="geographic")
               else None)
    frame = None
    if geo_doc is not None:
        frame = geo_frame(geo_doc)
        area = {"width_m": frame.width_m, "height_m": frame.height_m, "cell_m": geo_doc["area"]["cell_m"]}
    else:
        area = draw(areas(*area_km))
    inside = _inside(frame)
    config = draw(configurations(float(duration))) if swarm else {}
    type_specs: dict[str, dict[str, Any]] = {}
    types = ["B", "A"]
    if extra_types and draw(st.booleans()):
        type_specs["C"] = draw(uav_type_specs(rule_abiding=rule_abiding_types))
        types.append("C")
    if swarm:
        types = draw(_subsets(types), label="types flown")
    uavs = draw(fleets(area, types, min_uavs=min_uavs, max_uavs=max_uavs, duration_s=float(duration),
                       late_joiners=late_joiners, type_specs=type_specs, where=inside,
                       spacing_m=2000.0 if inside is None else 1000.0))
    names = [u["name"] for u in uavs]
    starts = [(u["x_m"], u["y_m"]) for u in uavs]
    doc: dict[str, Any] = {
        "name": "generated",
        "seed": draw(st.integers(0, 2**16)),
        "duration_s": float(duration),
        "area": area if geo_doc is None else dict(geo_doc["area"]),
        "uavs": uavs,
        "targets": draw(target_layouts(area, max_targets=max_targets, where=inside)),
        "threats": draw(threat_layouts(area, starts, max_threats=max_threats)),
        "radio": draw(radio_tables(lossy=lossy_radio)),
    }
    if geo_doc is not None:
        doc["geo"] = geo_doc["geo"]
    if max_no_fly > 0:
        zones = draw(no_fly_polygons(area, starts, max_zones=max_no_fly, frame=frame))
        if zones:
            doc["no_fly"] = zones
    if wind and draw(st.booleans(), label="wind"):
        doc["wind"] = draw(wind_tables())
    # The log-distance model is lossy by nature: only where loss is wanted (lossy_radio).
    if config.get("radio_model") == "log_distance" and lossy_radio:
        doc["radio"].pop("loss_at_range", None)  # the link budget gives the loss over distance
        doc["radio"]["model"] = "log_distance"
    if config.get("tau") is not None:
        doc["map"] = {"tau": config["tau"]}
    if type_specs:
        doc["uav_types"] = type_specs
    planner = draw(st.sampled_from(list(planners)))
    doc["planner"] = {"name": planner,
                      "surveillance": draw(st.booleans()) if surveillance is None else surveillance}
    if planner == "dacmp":
        particles, iterations = draw(st.sampled_from([(10, 5), (20, 10), (40, 25)]))
        doc["planner"]["dacmp"] = {"particles": particles, "iterations": iterations}
    if "replan_s" in config:
        doc["planner"]["replan_s"] = config["replan_s"]
    if faults and max_faults > 0:
        # The first UAV flies from the start (someone must); a UAV can only be told once when it joins.
        joinable = [u["name"] for u in uavs[1:] if "join_s" not in u]
        kinds = list(registered_fault_kinds() if fault_kinds is None else fault_kinds)
        if swarm and kinds:  # swarm testing: this example may only use some kinds
            kinds = draw(_subsets(kinds), label="fault kinds used")
        schedule = draw(fault_schedules(names, float(duration), kinds=kinds, max_faults=max_faults,
                                        joinable=joinable, area=(area["width_m"], area["height_m"])))
        doc["faults"] = [_fault_doc(f) for f in schedule.faults]
        if any(f.kind == "battery" for f in schedule.faults):
            doc["endurance"] = _endurance_for(doc, area)
    if endurance and "endurance" not in doc and draw(st.booleans(), label="endurance"):
        doc["endurance"] = draw(endurance_tables(doc, starts[0]))
    return doc


def _inside(frame: Any) -> Callable[[float, float], bool] | None:
    """For a geographic area: whether a point lies 1 km or more inside its polygon."""
    if frame is None:
        return None
    import shapely

    poly = shapely.Polygon(frame.area).buffer(-1000.0)
    return lambda x, y: bool(poly.contains(shapely.Point(x, y)))


def _endurance_for(doc: dict[str, Any], area: dict[str, Any]) -> dict[str, Any]:
    """(issue 26) An ``[endurance]`` table under which a battery fault acts: every type flown
    gets ten times the energy of flying the whole run at full speed (default power curve), so
    only a fault sends a UAV home early; the base is where the first UAV starts."""
    from swarm.scenario.mission import EnergySpec, min_power_speed, power_w
    from swarm.scenario.tables import DEFAULT_UAV_TYPES

    specs = {**{n: t.model_dump() for n, t in DEFAULT_UAV_TYPES.items()}, **doc.get("uav_types", {})}
    types = {}
    for name in sorted({u["type"] for u in doc["uavs"]}):
        t = specs[name]
        e = EnergySpec(capacity_wh=1.0)
        p = power_w(e, min_power_speed(e, t["speed_min"], t["speed_max"]), t["speed_max"])
        # (and ten times a round trip across the area, so that any launch point is in reach)
        across = 2.0 * math.hypot(area["width_m"], area["height_m"]) / t["speed_min"]
        types[name] = {"capacity_wh": 10.0 * p * (doc["duration_s"] + across) / 3600.0}
    first = doc["uavs"][0]
    return {"x_m": first["x_m"], "y_m": first["y_m"], "types": types}


# --- swarm testing ---------------------------------------------------------------------------------

_SWARM_TESTING = False


def set_swarm_testing(enabled: bool) -> None:
    """Turn swarm testing on or off for scenario strategies that do not say (``swarm=None``);
    ``tests/conftest.py`` turns it on under the ``swarm`` Hypothesis profile. Read when an
    example is drawn, so it applies to strategies built before the call."""
    global _SWARM_TESTING
    _SWARM_TESTING = bool(enabled)


def swarm_testing_enabled() -> bool:
    """Whether scenario strategies draw their configuration (see :func:`set_swarm_testing`)."""
    return _SWARM_TESTING


#: Values a swarm-tested configuration draws from, the scenario defaults first (they shrink there).
SWARM_RADIO_MODELS: tuple[str, ...] = ("disk", "log_distance")
SWARM_TAUS: tuple[float | None, ...] = (None, 0.001, 0.005, 0.02, 0.1)
SWARM_REPLAN_S: tuple[float, ...] = (10.0, 5.0, 2.0, 20.0, 1.0)


def _subsets(items: Sequence[str]) -> st.SearchStrategy[list[str]]:
    """A non-empty subset of ``items`` in their order: all of them (where it shrinks to) or a
    few. (Swarm testing: most examples leave most features out, so that a feature that masks
    another, e.g. a partition hiding what a delay would show, is often absent.)"""
    items = list(items)
    few = st.lists(st.sampled_from(items), min_size=1, max_size=len(items), unique=True).map(
        lambda chosen: [k for k in items if k in chosen])
    return st.one_of(st.just(items), few)


@st.composite
def configurations(draw: st.DrawFn, duration_s: float = 60.0) -> dict[str, Any]:
    """A swarm-testing configuration: ``radio_model`` (disk or log_distance), ``tau`` (None: the
    scenario's default, else a memory factor in 1/s) and ``replan_s`` (at most the run's
    length). Shrinks to the defaults (disk, default tau, 10 s)."""
    replan = [r for r in SWARM_REPLAN_S if r <= max(duration_s, 1.0)] or [1.0]
    return {"radio_model": draw(st.sampled_from(SWARM_RADIO_MODELS), label="radio model"),
            "tau": draw(st.sampled_from(SWARM_TAUS), label="tau"),
            "replan_s": draw(st.sampled_from(replan), label="replan_s")}


def _fault_doc(fault: Fault) -> dict[str, Any]:
    d = fault_to_dict(fault)
    out: dict[str, Any] = {}
    for k, v in d.items():
        if v is None or (k in ("uavs", "links") and not v):
            continue
        if k == "links":
            v = [list(p) for p in v]
        elif k == "groups":
            v = [list(g) for g in v]
        elif k == "uavs":
            v = list(v)
        out[k] = v
    if isinstance(fault, Join):
        out.pop("start_s", None)
    return out


def fault_schedule_of(scenario: Scenario) -> FaultSchedule:
    """A scenario's ``[[faults]]`` as a :class:`~faults.schedule.FaultSchedule` (what the injector runs)."""
    return FaultSchedule([fault_from_dict(f.model_dump(mode="python")) for f in scenario.faults])


def scenarios(**kwargs: Any) -> st.SearchStrategy[Scenario]:
    """Validated :class:`~swarm.scenario.Scenario` objects (see :func:`scenario_documents` for
    the options). A document the model rejects is a bug in these strategies and raises. The
    ``planners`` named here are the caller's choice, so a ``module:Class`` among them may be
    imported (:mod:`swarm.scenario.trust`)."""
    allow = tuple(kwargs.get("planners", ()))
    return scenario_documents(**kwargs).map(lambda doc: parse_scenario(doc, GENERATED_SOURCE,
                                                                       allow_planner_imports=allow))


# --- reproducing an example --------------------------------------------------------------------

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _toml_str(s: str) -> str:
    out = ['"']
    for ch in s:
        code = ord(ch)
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif code < 0x20 or code == 0x7F:
            out.append(f"\\u{code:04X}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def _toml_key(k: str) -> str:
    return k if _BARE_KEY.fullmatch(k) else _toml_str(k)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _toml_str(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items() if x is not None) + "}"
    raise TypeError(f"cannot write {type(v).__name__} as TOML: {v!r}")


def _is_table_array(v: Any) -> bool:
    return isinstance(v, (list, tuple)) and bool(v) and all(isinstance(x, dict) for x in v)


def _emit(lines: list[str], table: dict[str, Any], path: list[str]) -> None:
    for k, v in table.items():
        if v is None or isinstance(v, dict) or _is_table_array(v):
            continue
        lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
    for k, v in table.items():
        if isinstance(v, dict):
            sub = path + [_toml_key(k)]
            lines.extend(["", f"[{'.'.join(sub)}]"])
            _emit(lines, v, sub)
    for k, v in table.items():
        if _is_table_array(v):
            sub = path + [_toml_key(k)]
            for item in v:
                lines.extend(["", f"[[{'.'.join(sub)}]]"])
                _emit(lines, item, sub)


def scenario_toml(scenario: Scenario | dict[str, Any], comment: str = "") -> str:
    """The scenario as a TOML document that loads back to an equal :class:`Scenario`."""
    # to_document: what validates to the scenario again (a [geo] area's size left to its polygon)
    doc = scenario.to_document() if isinstance(scenario, Scenario) else scenario
    lines = [f"# {line}" for line in comment.splitlines()]
    _emit(lines, doc, [])
    return "\n".join(lines).strip("\n") + "\n"


def reproduce_command(path: str | os.PathLike[str], seed: int, planner: str | None = None) -> str:
    """The ``swarm run`` command replaying a written scenario; a ``module:Class`` planner is
    typed on it (a file alone may not import one: :mod:`swarm.scenario.trust`)."""
    typed = f" --planner {planner}" if planner is not None and is_module_ref(planner) else ""
    return f"swarm run {os.fspath(path)} --seed {seed}{typed}"


def reproduction(scenario: Scenario, directory: str | os.PathLike[str] | None = None,
                 comment: str = "") -> tuple[Path, str]:
    """Write ``scenario`` as TOML and return ``(path, command)``: the ``swarm run`` command
    that replays it. ``directory`` defaults to ``$SWARM_REPRO_DIR`` or ``<tmp>/swarm-repro``;
    the file name is derived from the content, so the same example always lands in one file."""
    text = scenario_toml(scenario, comment)
    folder = Path(directory or os.environ.get("SWARM_REPRO_DIR") or Path(tempfile.gettempdir()) / "swarm-repro")
    folder.mkdir(parents=True, exist_ok=True)
    digest = hashlib.sha256(text.encode()).hexdigest()[:12]
    path = folder / f"{scenario.name}-{digest}.toml"
    path.write_text(text, encoding="utf-8")
    return path, reproduce_command(path, scenario.seed, scenario.planner.name)


@contextlib.contextmanager
def reproducible(scenario: Scenario, directory: str | os.PathLike[str] | None = None) -> Iterator[None]:
    """Run a test body; if it fails, write the scenario (seed and fault schedule included) with
    :func:`reproduction` and attach the ``swarm run`` command to the failure: as a Hypothesis
    :func:`~hypothesis.note` (printed with the minimal failing example) and as a note on the
    exception itself (printed by pytest whatever the runner)::

        @given(scenarios())
        def test_something(scenario):
            with reproducible(scenario):
                ...

    Inside a Hypothesis test only the failing example Hypothesis reports is written: the
    shrunk one, which Hypothesis runs once more at the end (its *final* run). The failing
    examples met while generating and shrinking are not, so a failing test leaves one file
    per distinct failure Hypothesis reports, not one per example it tried. Outside Hypothesis
    every failure is written.
    """
    try:
        yield
    except BaseException as exc:
        if isinstance(exc, (KeyboardInterrupt, SystemExit, GeneratorExit)):
            raise
        if not _reported_example():
            raise
        faults = ", ".join(f.kind for f in scenario.faults) or "none"
        try:
            path, command = reproduction(scenario, directory,
                                         comment=f"Failing example: {type(exc).__name__}: {exc}".replace("\n", " ")[:500])
            text = f"reproduce (seed {scenario.seed}, faults: {faults}): {command}"
        except OSError as err:  # a read-only disk must not hide the real failure
            text = f"reproduce: could not write the scenario ({err}); seed {scenario.seed}, faults: {faults}"
        with contextlib.suppress(InvalidArgument):  # outside a Hypothesis test there is nothing to note in
            note(text)
        if hasattr(exc, "add_note"):
            exc.add_note(text)
        raise


def _reported_example() -> bool:
    """False while Hypothesis is generating or shrinking (a failing example there is not the one
    it will report); True in its final run of the reported example, and outside Hypothesis."""
    if not currently_in_test_context():
        return True
    return current_build_context().is_final
