"""The assembly: the scenario a simulation runs (validated once) and the parts built from it.

:func:`configured` applies :class:`~swarm.kernel.simulation.Simulation`'s arguments (seed,
planner, its options, duration, tick) to the scenario, judging the result once.
:func:`assemble` builds the parts of :mod:`swarm.kernel` in dependency order, each given what
it works with when it is made: no part is patched after it was built. The simulation then
places the scenario's targets, UAVs and faults on them (the same calls a host's changes make).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from agents.actor import UavActor
from agents.maps.grid import Grid
from agents.maps.mapgroup import MapGroup, maps_share
from agents.types import UavType
from comms.framecache import DecodeCache
from comms.radio import Radio
from faults.base import BatteryLike
from faults.injector import FaultInjector
from faults.registry import FaultSchedule
from swarm.errors import UsageError
from swarm.kernel import build
from swarm.kernel.clock import Clock
from swarm.kernel.faulting import RunFaults
from swarm.kernel.fleet import Fleet
from swarm.kernel.metrics import Metrics
from swarm.kernel.observer import Observer
from swarm.kernel.recorder import EventLog
from swarm.kernel.rng import RngTree
from swarm.kernel.transmission import Transmission
from swarm.kernel.world import Targets, World
from swarm.scenario import Scenario, apply_overrides, load_scenario
from swarm.scenario.trust import allowed

if TYPE_CHECKING:
    from swarm.geo.geography import Geography
    from swarm.kernel.mission import Mission

__all__ = ["Parts", "assemble", "configured"]


def configured(scenario: Scenario | str | Path, seed: int | None, planner: str | type | None,
               planner_options: Mapping[str, Any] | None, duration_s: float | None,
               allow_planner_imports: bool | Iterable[str], dt_s: float | None = None) -> Scenario:
    """The scenario with the simulation's arguments applied, judged once.

    A scenario named by path or built-in name is loaded with the arguments set in its document
    (``duration_s``: judged as run for that long, as ``--duration``; late joiners against its
    own end). A :class:`Scenario` given with arguments is judged again with them (a different
    scenario); with none, or only a seed (nothing judged depends on it), it is not."""
    # A class is named by where it lives (module:Class), as a scenario would name it.
    name = planner if planner is None or isinstance(planner, str) else f"{planner.__module__}:{planner.__qualname__}"
    overrides: dict[str, object] = {}
    if planner_options is not None:
        if not isinstance(planner_options, Mapping) or not all(isinstance(k, str) and k.isidentifier()
                                                              for k in planner_options):
            raise UsageError(f"planner_options {planner_options!r}: expected a dict of option names "
                             f"(Python identifiers) to values")
        overrides.update({f"planner.options.{key}": value for key, value in planner_options.items()})
    if dt_s is not None:
        overrides["dt_s"] = dt_s
    valid_seed = seed is not None and not isinstance(seed, bool) and isinstance(seed, int) and seed >= 0
    if not isinstance(scenario, Scenario):
        if seed is not None:
            overrides["seed"] = seed
        loaded = load_scenario(scenario, planner=name, allow_planner_imports=allow_planner_imports,
                               overrides=overrides, run_duration_s=duration_s)
        # (judged as run for duration_s, returned with its own end: the run's is that judged one)
        return loaded if duration_s is None else loaded.model_copy(update={"duration_s": float(duration_s)})
    if name is not None:
        overrides["planner.name"] = name
    if duration_s is not None and (isinstance(duration_s, bool) or duration_s != scenario.duration_s):
        overrides["duration_s"] = duration_s
    if not overrides and valid_seed:
        # Only the seed: nothing validated depends on it, so the scenario is not judged again
        # (a scenario validated as a run cut short, with joiners after its end, stays valid).
        return scenario.model_copy(update={"seed": seed})
    if seed is not None:
        overrides["seed"] = seed
    if not overrides:
        return scenario
    return apply_overrides(scenario, overrides, truncated=duration_s is not None,
                           allow_planner_imports=allowed(allow_planner_imports, name))


@dataclass(frozen=True, slots=True)
class Parts:
    """The parts of one simulation, as :func:`assemble` built them."""

    rng: RngTree
    clock: Clock
    log: EventLog
    names: dict[str, int]  # UAV name -> id, filled as UAVs are added (the faults resolve names in it)
    grid: Grid
    types: dict[str, UavType]
    targets: Targets
    geography: Geography | None  # (issue 26: polygons; None without [geo] and [[no_fly]])
    world: World
    metrics: Metrics
    observer: Observer
    map_group: MapGroup | None
    decoder: DecodeCache
    radio: Radio
    transmission: Transmission
    fleet: Fleet
    mission: Mission | None  # (issues 26, 33: wind and endurance; None without)
    faults: RunFaults
    tick_plane: bool  # (issue 36) the per-tick services, or the per-actor code (the oracle)


def assemble(sc: Scenario, batch_planning: bool, tick_plane: bool = True) -> Parts:
    """Every part of a simulation of ``sc``, each built once its inputs are (module docstring).
    ``tick_plane``: :class:`~swarm.kernel.simulation.Simulation`'s (the parts that have a
    per-tick service and the per-actor oracle it replaces are given it)."""
    rng, clock, log = RngTree(sc.seed), Clock(), EventLog()
    names: dict[str, int] = {}
    dt, tau = sc.dt_s, sc.effective_tau
    # Ground truth (area grid, targets, threats, polygons) and the metrics that observe it.
    grid = Grid(sc.area.width_m, sc.area.height_m, sc.area.cell_m)
    area = (grid.width_m, grid.height_m)
    geo = build.geography(sc, grid)
    targets = Targets(build.target_motion(sc), boundary=geo.polygon if geo is not None else None)
    world = World(grid, targets, build.threats(sc), zones=geo.zones if geo is not None else None)
    metrics = Metrics(grid, tau, inside=geo.inside if geo is not None else None)
    observer = Observer(world, metrics, log, dt, sc.recording.level == "summary", sc.safety.min_separation_m)
    # The UAVs' maps share storage where they agree (same cells as maps of their own;
    # agents.maps.mapgroup): on areas small enough for dense maps, unless a knowledge horizon
    # keeps scans from ever reaching every map (maps_share).
    map_group = (MapGroup(grid, tau, dt) if maps_share(grid.nx * grid.ny, grid.width_m, grid.height_m,
                                                       sc.radio.horizon_m) else None)
    # Each broadcast frame decoded once (with the swarm key, if [radio] auth).
    decoder = DecodeCache(sc.radio.frame_max_bytes, key=build.auth_key(sc))
    # The radio: every frame copy through the fault injector, each link its own random stream.
    injector = FaultInjector(FaultSchedule([]), names, fault_rng=lambda kind, k: rng.generator("fault", kind, k))
    uavs = world.uavs
    radio = build.radio(
        sc, link_rng=lambda s, d: rng.generator("link", uavs[s].name, uavs[d].name), link_filter=injector,
        link_rngs=lambda links: rng.generators([("link", uavs[s].name, uavs[d].name) for s, d in links]))
    # The actors (filled as UAVs are added), shared by the fleet that runs them and the
    # transmission that fills their mailboxes (a down UAV's unread frames: lost there).
    actors: dict[int, UavActor] = {}
    transmission = Transmission(radio, clock, world, actors, observer.lost)
    types = build.uav_types(sc)
    fleet = Fleet(sc, world, grid, tau, rng, log, build.actor_settings(sc, geo), decoder, map_group, batch_planning,
                  types, actors, transmission.lose, receive_service=tick_plane)
    mission = _mission(sc, world, fleet, log, rng, geo)
    batteries = mission.battery_of if mission is not None else _no_battery
    faults = RunFaults(clock, world, fleet, log, rng, names, area, dt, sc.radio.latency_s, injector, radio, batteries)
    return Parts(rng, clock, log, names, grid, types, targets, geo, world, metrics, observer, map_group, decoder,
                 radio, transmission, fleet, mission, faults, tick_plane)


def _mission(sc: Scenario, world: World, fleet: Fleet, log: EventLog, rng: RngTree,
             geo: Geography | None) -> Mission | None:
    """(issues 26, 33) The run's wind and endurance (:mod:`swarm.kernel.mission`, imported with
    shapely only by runs that have them), or None without ``[wind]`` and ``[endurance]``."""
    if sc.wind is None and sc.endurance is None:
        return None
    from swarm.kernel.mission import mission

    return mission(sc, world, fleet, log, sc.dt_s, (world.grid.width_m, world.grid.height_m), rng.generator("wind"),
                   list(geo.zones) if geo is not None else [],
                   geo.area.vertices if geo is not None and geo.area is not None else None)


def _no_battery(uid: int) -> BatteryLike | None:
    """A run without ``[endurance]``: no UAV has a battery (for the battery fault to act on)."""
    return None
