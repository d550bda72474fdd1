"""Builders: the pieces of a simulation made from its scenario.

Each function turns one part of a :class:`~swarm.scenario.Scenario` into the objects the kernel
runs (UAV types, target motion, threats, the radio, the actors' settings). They hold no state
and decide nothing at run time; :class:`swarm.kernel.simulation.Simulation` composes them.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.actor import ActorSettings
from agents.apf import ApfSettings
from agents.knowledge import KnownThreat
from agents.types import UavType
from comms.radio import LinkFilter, Radio
from swarm.errors import UsageError
from swarm.kernel.rng import RngTree, first_randoms, generator_from_state, stream_states
from swarm.kernel.world import TargetMotion, Targets
from swarm.scenario import Scenario, UavTypeSpec, load_scenario
from swarm.scenario.trust import allowed

if TYPE_CHECKING:
    from agents.maps.grid import Grid
    from swarm.geo.geography import Geography
    from swarm.kernel.mission import Mission

__all__ = ["actor_settings", "add_random_targets", "auth_key", "geography", "radio", "random_targets", "target_motion", "threats",
           "uav_type_from_spec", "uav_types"]


def uav_type_from_spec(name: str, spec: UavTypeSpec) -> UavType:
    """A scenario's ``[uav_types.NAME]`` table as the agents' :class:`UavType`."""
    return spec.uav_type(name)


def uav_types(sc: Scenario) -> dict[str, UavType]:
    return {name: uav_type_from_spec(name, spec) for name, spec in sc.uav_types.items()}


def target_motion(sc: Scenario) -> TargetMotion:
    tm = sc.targets
    return TargetMotion(tm.speed_max, tm.accel_max, tm.accel_sigma, tm.turn_sigma, tm.turn_rate_max, tm.turn_reversion_s)


def random_targets(sc: Scenario, seed: int, first: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float,
                                                                  Callable[[int], np.random.Generator]]:
    """The scenario's ``targets.count`` random targets, ids ``first, first + 1, ...``, as
    :meth:`swarm.kernel.world.Targets.add_many` takes them: ``x, y, theta, v, value, make``.

    Target ``i``'s place, heading and speed are the first four uniforms of its own stream
    ``("target", i)``, computed for all targets at once (:func:`swarm.kernel.rng.first_randoms`, the
    same numbers as making each generator, which costs 35 us: issue 25, a million targets build
    in a second); ``make(i)`` gives the stream after those four, made only when the target's
    motion first draws from it."""
    tm, area = sc.targets, sc.area
    ids = range(first, first + tm.count)
    states = stream_states(seed, ("target",), ids)
    u = first_randoms(states, 4)
    lo_th, hi_th = -math.pi, math.pi
    # (Generator.uniform(lo, hi) = lo + (hi - lo) * random())
    return (0.0 + area.width_m * u[:, 0], 0.0 + area.height_m * u[:, 1], lo_th + (hi_th - lo_th) * u[:, 2],
            0.0 + tm.speed_max * u[:, 3], tm.value, partial(_target_stream, states, first))


def add_random_targets(sc: Scenario, targets: Targets, rng: RngTree, geo: Geography | None) -> list[int]:
    """Add the scenario's ``targets.count`` random targets; returns their ids. In a rectangle
    they are placed at once (:func:`random_targets`); inside an area polygon each is drawn
    again from its own stream until it is inside (:func:`random_start`)."""
    tm = sc.targets
    if geo is None or geo.area is None:
        return list(targets.add_many(*random_targets(sc, rng.seed, len(targets)))) if tm.count else []
    ids = []
    for _ in range(tm.count):
        g = rng.generator("target", len(targets))
        ids.append(targets.add(*random_start(g, sc, geo), tm.value, g))
    return ids


def _target_stream(states: np.ndarray, first: int, tid: int) -> np.random.Generator:
    """Target ``tid``'s stream (``RngTree.generator("target", tid)``, from its seed words: row
    ``tid - first`` of ``states``) after the four uniforms that placed it (random_targets)."""
    g = generator_from_state(states[tid - first])
    bits = g.bit_generator
    assert isinstance(bits, np.random.PCG64)
    bits.advance(4)  # (= four random() draws: one 64-bit output each)
    return g


def threats(sc: Scenario) -> list[KnownThreat]:
    return [KnownThreat(i, th.x_m, th.y_m, th.radius_m, th.d_max) for i, th in enumerate(sc.threats)]


def radio(sc: Scenario, link_rng: Callable[[int, int], np.random.Generator], link_filter: LinkFilter,
          link_rngs: Callable[[list[tuple[int, int]]], list[np.random.Generator]] | None = None) -> Radio:
    """The radio graph with the scenario's link model; ``link_rng(src, dst)`` gives a directed
    link's own random stream (``link_rngs`` those of many links at once), ``link_filter`` (the
    fault injector) sees every frame copy."""
    return Radio(sc.radio.link_model(), link_rng=link_rng, link_filter=link_filter, link_rngs=link_rngs)


def auth_key(sc: Scenario) -> bytes | None:
    """The swarm key of ``[radio] auth`` (None when it is off): ``radio.auth_key`` as UTF-8, or when
    absent SHA-256 of ``"uav-swarm-sim swarm key <seed>"`` (the run's seed: deterministic, never
    from a clock or the OS, and different for every seed)."""
    r = sc.radio
    if not r.auth:
        return None
    if r.auth_key is not None:
        return r.auth_key.encode("utf-8")
    return hashlib.sha256(f"uav-swarm-sim swarm key {sc.seed}".encode()).digest()


def geography(sc: Scenario, grid: Grid, world: Any = None, metrics: Any = None) -> Geography | None:
    """The run's areas and zones as polygons (issue 26), or None without ``[geo]`` and
    ``[[no_fly]]`` (then pyproj and shapely are never imported); placed in the ``world`` (its
    no-fly polygons) and the ``metrics`` (the cells inside the area) if given."""
    if sc.geo is None and not sc.no_fly:
        return None
    from swarm.geo.geography import geography as build_geography

    geo = build_geography(sc, grid)
    assert geo is not None  # (it has [geo] or [[no_fly]])
    if world is not None:
        world.zones = geo.zones
    if metrics is not None:
        metrics.inside = geo.inside
    return geo


def random_start(g: np.random.Generator, sc: Scenario, geo: Geography | None) -> tuple[float, float, float, float]:
    """A random target's start ``(x, y, heading, speed)``: uniform in the area (inside the area
    polygon, with [geo]: the position drawn again until it is; a rectangle draws exactly as it
    always did), then heading and speed."""
    x, y = float(g.uniform(0, sc.area.width_m)), float(g.uniform(0, sc.area.height_m))
    while geo is not None and geo.area is not None and geo.area.clearance(x, y)[0] < 0.0:
        x, y = float(g.uniform(0, sc.area.width_m)), float(g.uniform(0, sc.area.height_m))
    return x, y, float(g.uniform(-math.pi, math.pi)), float(g.uniform(0, sc.targets.speed_max))


def mission(sim: Any) -> Mission | None:
    """(issues 26, 33) The run's wind and endurance (:mod:`swarm.kernel.mission`), its batteries handed
    to the run's fault host (the battery fault's access), or None for a scenario without
    ``[wind]`` and ``[endurance]``."""
    sc, geo = sim.scenario, sim._geography
    if sc.wind is None and sc.endurance is None:
        return None
    from swarm.kernel.mission import mission as build_mission

    m = build_mission(sc, sim._world, sim._fleet, sim._log, sim.dt, (sim._grid.width_m, sim._grid.height_m),
                      sim._rng.generator("wind"), list(geo.zones) if geo is not None else [],
                      geo.area.vertices if geo is not None and geo.area is not None else None)
    if m is not None:
        sim._faults.batteries = m.battery_of
    return m


def actor_settings(sc: Scenario, geo: Geography | None = None) -> ActorSettings:
    """What every UAV actor of the run is configured with (the scenario's [radio] settings: frame
    cap, timers, anti-entropy; loitering, APF; with ``geo``, the zones and the outside mask)."""
    settings = _actor_settings(sc)
    if geo is not None:
        settings = replace(settings, zones=geo.keepouts, outside=geo.outside)
    if sc.endurance is not None and sc.planner.surveillance:  # (issue 33: relief on station)
        settings = replace(settings, relief=True, uav_types=tuple(uav_types(sc).values()))
    return settings


def _actor_settings(sc: Scenario) -> ActorSettings:
    p = sc.planner
    ap = p.apf
    return ActorSettings(
        dt=sc.dt_s,
        replan_s=p.replan_s,
        radio=sc.radio.settings(),
        surveillance=p.surveillance,
        loiter_radius_factor=p.loiter_radius_factor,
        loiter_turn_factor=p.loiter_turn_factor,
        loiter_gain=p.loiter_gain,
        loiter_threat_weight=p.loiter_threat_weight,
        apf=ApfSettings(ap.k_att, ap.k_rep, ap.uav_b, ap.uav_c, ap.uav_dmax_m, sc.safety.min_separation_m,
                        lookahead_s=ap.lookahead_s),
        auth_key=auth_key(sc),
    )


def configured(scenario: Scenario | str | Path, seed: int | None, planner: str | type | None,
                planner_options: Mapping[str, Any] | None, duration_s: float | None,
                allow_planner_imports: bool | Iterable[str], dt_s: float | None = None) -> Scenario:
    """The scenario with :class:`swarm.kernel.simulation.Simulation`'s arguments applied."""
    # A class is named by where it lives (module:Class), as a scenario would name it.
    name = planner if planner is None or isinstance(planner, str) else f"{planner.__module__}:{planner.__qualname__}"
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario, planner=name, allow_planner_imports=allow_planner_imports)
    overrides: dict[str, object] = {}
    if name is not None:
        overrides["planner.name"] = name
    if planner_options is not None:
        if not isinstance(planner_options, Mapping) or not all(isinstance(k, str) and k.isidentifier()
                                                              for k in planner_options):
            raise UsageError(f"planner_options {planner_options!r}: expected a dict of option names "
                             f"(Python identifiers) to values")
        overrides.update({f"planner.options.{key}": value for key, value in planner_options.items()})
    if duration_s is not None:
        overrides["duration_s"] = duration_s
    if not overrides and seed is not None and not isinstance(seed, bool) and isinstance(seed, int) and seed >= 0:
        # Only the seed: nothing validated depends on it, so the scenario is not judged again
        # (a scenario validated as a run cut short, with joiners after its end, stays valid).
        return scenario.model_copy(update={"seed": seed})
    if seed is not None:
        overrides["seed"] = seed
    if dt_s is not None:
        overrides["dt_s"] = dt_s
    if not overrides:
        return scenario
    from swarm.scenario import apply_overrides

    return apply_overrides(scenario, overrides, truncated=duration_s is not None,
                           allow_planner_imports=allowed(allow_planner_imports, name))
