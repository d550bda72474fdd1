"""Builders: the pieces of a simulation made from its scenario.

Each function turns one part of a :class:`~swarm.scenario.Scenario` into the objects the kernel
runs (UAV types, target motion, threats, the radio, the actors' settings). They hold no state
and decide nothing at run time; :func:`swarm.kernel.assembly.assemble` composes them.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from agents.apf import ApfSettings
from agents.inputs import ActorSettings
from agents.knowledge import KnownThreat
from agents.types import UavType
from comms.radio import LinkFilter, Radio
from swarm.kernel.rng import RngTree, first_randoms, generator_from_state, stream_states
from swarm.kernel.world import TargetMotion, Targets
from swarm.scenario import Scenario, UavTypeSpec

if TYPE_CHECKING:
    from agents.maps.grid import Grid
    from swarm.geo.geography import Geography

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
          link_rngs: Callable[[list[tuple[int, int]]], list[np.random.Generator]] | None = None,
          tick_plane: bool = False) -> Radio:
    """The radio graph with the scenario's link model; ``link_rng(src, dst)`` gives a directed
    link's own random stream (``link_rngs`` those of many links at once), ``link_filter`` (the
    fault injector) sees every frame copy; ``tick_plane``: a link table, the graph synced when read."""
    return Radio(sc.radio.link_model(), link_rng=link_rng, link_filter=link_filter, link_rngs=link_rngs,
                 tick_plane=tick_plane)


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


def geography(sc: Scenario, grid: Grid) -> Geography | None:
    """The run's areas and zones as polygons (issue 26), or None without ``[geo]`` and
    ``[[no_fly]]`` (then pyproj and shapely are never imported)."""
    if sc.geo is None and not sc.no_fly:
        return None
    from swarm.geo.geography import geography as build_geography

    geo = build_geography(sc, grid)
    assert geo is not None  # (it has [geo] or [[no_fly]])
    return geo


def random_start(g: np.random.Generator, sc: Scenario, geo: Geography | None) -> tuple[float, float, float, float]:
    """A random target's start ``(x, y, heading, speed)``: uniform in the area (inside the area
    polygon, with [geo]: the position drawn again until it is; a rectangle draws exactly as it
    always did), then heading and speed."""
    x, y = float(g.uniform(0, sc.area.width_m)), float(g.uniform(0, sc.area.height_m))
    while geo is not None and geo.area is not None and geo.area.clearance(x, y)[0] < 0.0:
        x, y = float(g.uniform(0, sc.area.width_m)), float(g.uniform(0, sc.area.height_m))
    return x, y, float(g.uniform(-math.pi, math.pi)), float(g.uniform(0, sc.targets.speed_max))


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
