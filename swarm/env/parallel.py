"""``swarm_search_v1``: the simulator as a PettingZoo parallel environment (docs/env.md).

Each controlled UAV is an agent named after it. One :meth:`SwarmSearchEnv.step` advances the
simulation by one replanning period (``scenario.planner.replan_s``, in whole ticks of ``dt``).
An agent's action is its next waypoint, relative to its pose: ``(forward, left)`` in
``[-1, 1]^2``, times the distance it can fly in one period (``speed_max * period``). The
simulator's own APF and dynamics fly it there, so the radio, the faults and the UAVs left to
the scenario's planner behave as in any run.

How the waypoint reaches the UAV, without a hook in the simulator: each controlled UAV's
planner instance is replaced, before the first tick, by an :class:`ExternalPlanner`, which
answers every plan request with the waypoint the environment last set. At each step the
environment sets the waypoints and asks each actor for a plan at its next tick
(:meth:`UavActor.replan_next_tick`), so every action takes effect at the first tick of its
step, even when the UAV reached its previous waypoint early and replanned in between. A UAV
flying home (``[endurance]``) does not replan: it keeps its way home whatever the action, and
stays in ``agents`` while it goes home, lands and relaunches (``infos[agent]["state"]``
``"homebound"``, ``"landed"``; issue 33: clearing its plan instead crashed the env).

A ``restart`` fault gives the UAV a fresh actor with a new planner instance; the environment
hears the ``restart`` event (emitted as the new actor is installed, before its first tick) and
puts the agent's :class:`ExternalPlanner` on it, so a restarted agent stays under the policy.
While it is down it stays in ``agents`` (a restart is not the end of it: PettingZoo never
revives a terminated agent), with ``infos[agent]["state"] == "restarting"``.

Observations come from the UAV's own state, its own uncertainty map and its own tracks (what it
believes, not the truth); rewards from the ground truth of the step (the event log's ``pose``,
``found`` and ``violation`` events, received through :meth:`Simulation.subscribe`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from agents.planners.base import Plan, PlanView
from comms.messages import MODE_SEARCH, MODE_SURVEIL, NO_TARGET
from swarm.errors import APIMisuseError, UsageError
from swarm.events import Event, Found, Pose, Restart, Violation
from swarm.kernel.mission import LANDED
from swarm.kernel.simulation import Simulation
from swarm.kernel.world import ALIVE, CRASHED, PENDING
from swarm.scenario import Scenario, apply_overrides, load_scenario

__all__ = ["ENV_NAME", "ExternalPlanner", "RewardWeights", "SwarmSearchEnv", "parallel_env"]

# The name carries a version: bump it whenever the same code driving the same scenario and seed
# could get different observations, rewards or episodes (docs/env.md, "Versions").
ENV_NAME = "swarm_search_v1"

# Columns of an agent's "state" observation.
STATE_FIELDS = ("x", "y", "speed", "cos_heading", "sin_heading", "mode", "time", "type_speed")
# Columns of one row of the "tracks" observation.
TRACK_FIELDS = ("present", "forward", "left", "v_forward", "v_left", "age")

# Bounds of those columns (the observation space's).
_STATE_LO = np.array([0, 0, 0, -1, -1, 0, 0, 0], np.float32)
_STATE_HI = np.ones(len(STATE_FIELDS), np.float32)
_TRACK_LO = np.array([0, -1, -1, -1, -1, 0], np.float32)
_TRACK_HI = np.ones(len(TRACK_FIELDS), np.float32)

_SQM_PER_KM2 = 1.0e6


@dataclass(frozen=True)
class RewardWeights:
    """Weights of an agent's reward for one step (each term is the agent's own, from the
    ground truth): ``area`` per km² of the area that nobody had scanned before and this UAV
    scanned this step; ``found`` per target that this UAV found first (the run's ``found``
    events); ``violation`` per violation event it is party to (separation from another UAV or
    inside a threat, one per tick while it lasts)."""

    area: float = 1.0
    found: float = 10.0
    violation: float = -1.0

    @classmethod
    def of(cls, value: RewardWeights | Mapping[str, float] | None) -> RewardWeights:
        if value is None:
            return cls()
        if isinstance(value, RewardWeights):
            return value
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(value) - known)
        if unknown:
            raise UsageError(f"unknown reward weight(s) {unknown}; known: {', '.join(sorted(known))}")
        try:
            return cls(**{k: float(v) for k, v in value.items()})
        except (TypeError, ValueError) as exc:
            raise UsageError(f"reward weights must be numbers: {exc}") from None


class ExternalPlanner:
    """A planner that flies the waypoint someone else chose (the environment's action).

    ``waypoint`` is set from outside; until it is, or for a UAV that joined in the middle of a
    step, a request is answered with the point ``reach`` metres straight ahead of the UAV's
    pose at that request (kept until the next ``waypoint``). Mode: always search."""

    name = "external"

    def __init__(self, reach: float, area_m: tuple[float, float]):
        self.reach = float(reach)
        self.area_m = area_m
        self.waypoint: tuple[float, float] | None = None

    def plan(self, view: PlanView) -> Plan:
        if self.waypoint is None:
            self.waypoint = clip_to_area(view.x + self.reach * math.cos(view.theta),
                                         view.y + self.reach * math.sin(view.theta), self.area_m)
        wx, wy = self.waypoint
        return Plan(wx, wy, MODE_SEARCH, NO_TARGET)


def clip_to_area(x: float, y: float, area_m: tuple[float, float]) -> tuple[float, float]:
    w, h = area_m
    return min(max(x, 0.0), w * (1 - 1e-9)), min(max(y, 0.0), h * (1 - 1e-9))


@dataclass
class _Step:
    """One agent's ground-truth tally for the current step."""

    new_cells: int = 0
    found: int = 0
    violations: int = 0


class SwarmSearchEnv(ParallelEnv):
    """The PettingZoo parallel environment ``swarm_search_v1`` (see the module docstring and
    docs/env.md). Build it with :func:`parallel_env`."""

    metadata = {"name": ENV_NAME, "render_modes": [], "is_parallelizable": True}

    def __init__(
        self,
        scenario: Scenario | str | Path = "paper-case1",
        *,
        controlled: Iterable[str] | None = None,
        planner: str | None = None,
        duration_s: float | None = None,
        map_size: int = 11,
        map_cell_m: float | None = None,
        map_samples: int = 3,
        n_tracks: int = 4,
        rewards: RewardWeights | Mapping[str, float] | None = None,
        flatten: bool = False,
        batch_planning: bool = True,
        render_mode: str | None = None,
    ):
        if render_mode is not None:
            raise UsageError(f"render_mode {render_mode!r}: {ENV_NAME} renders nothing (use swarm animate on a run folder)")
        self.render_mode = None
        # A planner named here is the caller's choice (allowed even as module:Class); one named by a
        # scenario file is not imported (swarm.scenario.trust).
        sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario, planner=planner)
        overrides: dict[str, object] = {}
        if planner is not None:
            overrides["planner.name"] = planner
        if duration_s is not None:
            overrides["duration_s"] = duration_s
        # A shorter episode is the scenario cut short (as `swarm run --duration`): UAVs that would
        # join after its end are not refused, they just never join.
        shorter = duration_s is not None and duration_s < sc.duration_s
        self.scenario = (apply_overrides(sc, overrides, allow_planner_imports=[planner] if planner else False,
                                         truncated=shorter, scenario_duration_s=sc.duration_s if shorter else None)
                         if overrides else sc)
        sc = self.scenario
        if not (isinstance(map_size, int) and map_size >= 1 and map_size % 2 == 1):
            raise UsageError(f"map_size must be an odd number >= 1, got {map_size!r}")
        if not (isinstance(map_samples, int) and map_samples >= 1):
            raise UsageError(f"map_samples must be an int >= 1, got {map_samples!r}")
        if not (isinstance(n_tracks, int) and n_tracks >= 0):
            raise UsageError(f"n_tracks must be an int >= 0, got {n_tracks!r}")
        if map_cell_m is not None and not map_cell_m > 0:
            raise UsageError(f"map_cell_m must be > 0 (or None for the default), got {map_cell_m!r}")
        self.map_size, self.map_samples, self.n_tracks = map_size, map_samples, n_tracks
        self.weights = RewardWeights.of(rewards)
        self.batch_planning = batch_planning

        self.dt = sc.dt_s
        self.ticks_per_step = max(1, round(sc.planner.replan_s / self.dt))
        self.period_s = self.ticks_per_step * self.dt
        self.area_m = (sc.area.width_m, sc.area.height_m)
        self._diag = math.hypot(*self.area_m)
        self._tau = sc.effective_tau
        self._target_speed = max(sc.targets.speed_max, 1.0)
        self._fastest = max(t.speed_max for t in sc.uav_types.values())

        self._types = {u.name: u.type for u in sc.uavs}
        names = [str(u.name) for u in sc.uavs]
        self.possible_agents: list[str] = self._resolve_controlled(names, controlled)
        self.agents: list[str] = []
        self._reach = {a: sc.uav_types[self._types[a]].speed_max * self.period_s for a in self.possible_agents}
        self._offsets = {a: self._window_offsets(a, map_cell_m) for a in self.possible_agents}
        self._track_lo = np.tile(_TRACK_LO, (n_tracks, 1))
        self._track_hi = np.tile(_TRACK_HI, (n_tracks, 1))
        self.flatten = bool(flatten)
        self._dict_spaces = {a: self._observation_space() for a in self.possible_agents}
        self._observation_spaces: dict[str, spaces.Space] = (
            {a: spaces.flatten_space(d) for a, d in self._dict_spaces.items()} if self.flatten else dict(self._dict_spaces))
        self._action_spaces = {a: spaces.Box(-1.0, 1.0, (2,), np.float32) for a in self.possible_agents}

        self.sim: Simulation | None = None
        self._uid: dict[str, int] = {}
        self._agent_of: dict[int, str] = {}
        self._planners: dict[str, ExternalPlanner] = {}
        self._tally: dict[int, _Step] = {}
        self._covered: np.ndarray | None = None
        self._unsubscribe: Any = None

    # --- construction ------------------------------------------------------------------------

    def _resolve_controlled(self, names: list[str], controlled: Iterable[str] | None) -> list[str]:
        if controlled is None:
            return names
        if isinstance(controlled, str):
            controlled = [controlled]
        chosen: set[str] = set()
        for item in controlled:
            if item in self._types:
                chosen.add(item)
            elif item in self.scenario.uav_types:
                chosen.update(n for n in names if self._types[n] == item)
            else:
                raise UsageError(f"controlled: {item!r} is neither a UAV name ({', '.join(names)}) nor a UAV type "
                                 f"({', '.join(self.scenario.uav_types)}) of scenario {self.scenario.name!r}")
        if not chosen:
            raise UsageError(f"controlled={list(controlled)!r} selects no UAV of scenario {self.scenario.name!r}")
        return [n for n in names if n in chosen]

    def _window_offsets(self, agent: str, map_cell_m: float | None) -> tuple[np.ndarray, np.ndarray]:
        """Forward and left offsets (m) of the map window's sample points, shape (W, W, s*s)."""
        kind = self.scenario.uav_types[self._types[agent]]
        cell = map_cell_m if map_cell_m is not None else 2.0 * (self._reach[agent] + kind.detect_radius_m) / self.map_size
        half = self.map_size // 2
        centres = (np.arange(self.map_size) - half) * cell
        sub = ((np.arange(self.map_samples) + 0.5) / self.map_samples - 0.5) * cell
        fwd = centres[:, None, None, None] + sub[None, None, :, None]  # (W, 1, s, 1)
        left = centres[None, :, None, None] + sub[None, None, None, :]  # (1, W, 1, s)
        fwd, left = np.broadcast_arrays(fwd, left)
        shape = (self.map_size, self.map_size, self.map_samples * self.map_samples)
        return fwd.reshape(shape).copy(), left.reshape(shape).copy()

    def _observation_space(self) -> spaces.Dict:
        return spaces.Dict({
            "state": spaces.Box(_STATE_LO, _STATE_HI, dtype=np.float32),
            "map": spaces.Box(0.0, 1.0, (self.map_size, self.map_size), np.float32),
            "tracks": spaces.Box(self._track_lo, self._track_hi, dtype=np.float32),
        })

    # --- the PettingZoo API ----------------------------------------------------------------

    def observation_space(self, agent: str) -> spaces.Space:
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        return self._action_spaces[agent]

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict[str, Any], dict[str, dict]]:
        """A new episode: ``Simulation(scenario, seed=seed)`` (``seed=None``: the scenario's
        seed), so the same seed gives the same episode. ``options`` is accepted and unused."""
        self.close()
        sim = Simulation(self.scenario, seed=None if seed is None else int(seed), batch_planning=self.batch_planning)
        self.sim = sim
        self._uid = {a: sim._names[a] for a in self.possible_agents}
        self._planners = {}
        for a, uid in self._uid.items():
            p = ExternalPlanner(self._reach[a], self.area_m)
            sim.actors[uid].planner = p
            self._planners[a] = p
        self._tally = {uid: _Step() for uid in self._uid.values()}
        self._covered = np.zeros(sim._grid.shape, dtype=bool)
        self._agent_of = {uid: a for a, uid in self._uid.items()}
        self._unsubscribe = sim.subscribe(self._on_event, kinds={"pose", "found", "violation", "restart"})
        self.agents = self._entered()
        if not self.agents:
            self._skip_to_next_agent()
        return {a: self._observe(a) for a in self.agents}, {a: self._info(a) for a in self.agents}

    def step(self, actions: Mapping[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        sim = self.sim
        if sim is None:
            raise APIMisuseError(f"{ENV_NAME}: call reset() before step()")
        unknown = sorted(set(actions) - set(self.possible_agents))
        if unknown:
            raise UsageError(f"actions for unknown agent(s) {unknown}; agents: {', '.join(self.possible_agents)}")
        stepping = list(self.agents)
        if not stepping:
            return {}, {}, {}, {}, {}
        for a in stepping:
            self._set_waypoint(a, actions.get(a))
        for tally in self._tally.values():
            tally.new_cells = tally.found = tally.violations = 0
        sim.step(min(self.ticks_per_step, self._ticks_left()))
        terminated = {a: self._crashed(a) for a in stepping}
        obs = {a: self._observe(a) for a in stepping}
        rewards = {a: self._reward(a) for a in stepping}
        infos = {a: self._info(a) for a in stepping}
        survivors = [a for a in stepping if not terminated[a]]
        entered: list[str] = []
        if not sim.done:
            entered = [a for a in self._entered() if a not in stepping]
            if not survivors and not entered:
                entered = self._skip_to_next_agent()
        done = sim.done
        truncated = {a: done and not terminated[a] for a in stepping}
        for a in entered:  # new agents: their first observation; nothing of the step was theirs
            self._tally[self._uid[a]] = _Step()
            obs[a], rewards[a], terminated[a], truncated[a], infos[a] = self._observe(a), 0.0, False, False, self._info(a)
        self.agents = [] if done else [a for a in self.possible_agents if a in survivors or a in entered]
        return obs, rewards, terminated, truncated, infos

    def render(self) -> None:
        """Nothing: write the run with ``swarm.outputs.write_run(env.sim.result(), out)`` and use
        ``swarm animate`` / ``swarm report`` on that folder."""
        return None

    def close(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None
        if self.sim is not None:
            self.sim.close()
            self.sim = None

    # --- stepping ----------------------------------------------------------------------------

    def _ticks_left(self) -> int:
        sim = self.sim
        assert sim is not None
        return sim.n_ticks - int(round(sim.now / sim.dt))

    def _restarting(self, agent: str) -> bool:
        """Down for a ``restart`` fault: it will fly again (``Fleet.returning``)."""
        sim = self.sim
        assert sim is not None
        return self._uid[agent] in sim._fleet.returning

    def _crashed(self, agent: str) -> bool:
        """Down for good: crashed, and not in a restart's downtime."""
        sim = self.sim
        assert sim is not None
        return sim._world.uavs[self._uid[agent]].state == CRASHED and not self._restarting(agent)

    def _entered(self) -> list[str]:
        """Controlled UAVs in play at the next tick: alive, pending with their join time reached
        (they join at the start of that tick), or down for a restart (they fly again)."""
        sim = self.sim
        assert sim is not None
        now = sim.now + 1e-9
        out = []
        for a in self.possible_agents:
            b = sim._world.uavs[self._uid[a]]
            if b.state == ALIVE or (b.state == PENDING and b.join_s <= now) or self._restarting(a):
                out.append(a)
        return out

    def _skip_to_next_agent(self) -> list[str]:
        """No agent flies but one is still to join: run the others until it does (or the end)."""
        sim = self.sim
        assert sim is not None
        waiting = [a for a in self.possible_agents
                   if sim._world.uavs[self._uid[a]].state == PENDING and sim._world.uavs[self._uid[a]].join_s < sim.duration_s]
        entered: list[str] = []
        while waiting and not entered and not sim.done:
            sim.step(min(self.ticks_per_step, self._ticks_left()))
            entered = [] if sim.done else self._entered()
        self.agents = entered
        return entered

    def _set_waypoint(self, agent: str, action: Any) -> None:
        sim = self.sim
        assert sim is not None
        if action is None:
            a = np.array([1.0, 0.0])
        else:
            a = np.asarray(action, dtype=np.float64)
            if a.shape != (2,):
                raise UsageError(f"action of {agent}: expected shape (2,) (forward, left), got shape {a.shape}")
            a = np.clip(np.nan_to_num(a, nan=0.0), -1.0, 1.0)
        uid = self._uid[agent]
        b = sim._world.uavs[uid]
        reach = self._reach[agent]
        c, s = math.cos(b.theta), math.sin(b.theta)
        fwd, left = float(a[0]) * reach, float(a[1]) * reach
        self._planners[agent].waypoint = clip_to_area(b.x + fwd * c - left * s, b.y + fwd * s + left * c, self.area_m)
        sim.actors[uid].replan_next_tick()  # the new waypoint takes effect at its next tick (not on the way home)

    def _on_event(self, event: Event) -> None:
        tally = self._tally
        if isinstance(event, Pose):
            sim = self.sim
            covered = self._covered
            assert sim is not None and covered is not None
            uid = event.uav
            d = sim._grid.disk_stamp(event.x, event.y, sim._world.uavs[uid].kind.detect_radius)  # the scan just made (a memo hit)
            if d is None:
                return
            block = covered[d.rows, d.cols]
            new = d.mask & ~block
            if uid in tally:
                tally[uid].new_cells += int(np.count_nonzero(new))
            block |= d.mask
        elif isinstance(event, Found):
            if event.uav in tally:
                tally[event.uav].found += 1
        elif isinstance(event, Violation):
            party = (event.uav, event.other) if event.invariant == "separation" else (event.uav,)
            for uid in party:
                if uid in tally:
                    tally[uid].violations += 1
        elif isinstance(event, Restart):
            # A fresh actor with the scenario's planner was just installed (before its first
            # tick): a controlled UAV goes on under the policy, flying the agent's last waypoint.
            agent = self._agent_of.get(event.uav)
            sim = self.sim
            if agent is not None and sim is not None:
                sim.actors[event.uav].planner = self._planners[agent]

    def _reward(self, agent: str) -> float:
        sim = self.sim
        assert sim is not None
        t = self._tally[self._uid[agent]]
        area_km2 = t.new_cells * sim._grid.cell_m ** 2 / _SQM_PER_KM2
        w = self.weights
        return float(w.area * area_km2 + w.found * t.found + w.violation * t.violations)

    # --- observations ------------------------------------------------------------------------

    def _info(self, agent: str) -> dict[str, Any]:
        sim = self.sim
        assert sim is not None
        uid = self._uid[agent]
        t = self._tally[uid]
        b = sim._world.uavs[uid]
        state = "restarting" if self._restarting(agent) else b.state
        if state == ALIVE and sim.actors[uid].homebound:
            state = "homebound"  # (endurance) flying home on its own: the actions wait for its relaunch
        return {"t": sim.now, "state": state, "type": b.kind.name, "new_cells": t.new_cells,
                "new_area_km2": t.new_cells * sim._grid.cell_m ** 2 / _SQM_PER_KM2, "found": t.found,
                "violations": t.violations, "waypoint": self._planners[agent].waypoint}

    def _observe(self, agent: str) -> dict[str, np.ndarray] | np.ndarray:
        obs = self._observe_dict(agent)
        if not self.flatten:
            return obs
        return np.asarray(spaces.flatten(self._dict_spaces[agent], obs), dtype=np.float32)

    def _observe_dict(self, agent: str) -> dict[str, np.ndarray]:
        sim = self.sim
        assert sim is not None
        uid = self._uid[agent]
        b = sim._world.uavs[uid]
        actor = sim.actors[uid]
        now = sim.now
        w, h = self.area_m
        c, s = math.cos(b.theta), math.sin(b.theta)
        plan = actor.plan
        speed = 0.0 if b.state == LANDED else b.v / b.kind.speed_max
        state = np.array([b.x / w, b.y / h, speed, c, s,
                          1.0 if plan is not None and plan.mode == MODE_SURVEIL else 0.0,
                          now / sim.duration_s, b.kind.speed_max / self._fastest], dtype=np.float64)
        # Map window: q of the UAV's own map at the sample points of each window cell, averaged;
        # points outside the area count as q = 0 (nothing to find there).
        fwd, left = self._offsets[agent]
        xs = b.x + fwd * c - left * s
        ys = b.y + fwd * s + left * c
        inside = (xs >= 0.0) & (xs < w) & (ys >= 0.0) & (ys < h)
        q = np.zeros(xs.shape, dtype=np.float64)
        if inside.any():
            ix, iy = sim._grid.cells_of(xs[inside], ys[inside])
            q[inside] = actor.umap.q_at(ix, iy, now)
        window = q.mean(axis=2)
        tracks = np.zeros((self.n_tracks, len(TRACK_FIELDS)), dtype=np.float64)
        if self.n_tracks:
            rows = []
            for tid, tr in actor.knowledge.tracks.items():
                px, py = tr.predict(now)
                dx, dy = px - b.x, py - b.y
                rows.append((math.hypot(dx, dy), tid, dx, dy, tr))
            rows.sort(key=lambda r: (r[0], r[1]))
            for i, (_d, _tid, dx, dy, tr) in enumerate(rows[:self.n_tracks]):
                age = max(now - tr.t, 0.0)
                tracks[i] = (1.0, (dx * c + dy * s) / self._diag, (-dx * s + dy * c) / self._diag,
                             (tr.vx * c + tr.vy * s) / self._target_speed, (-tr.vx * s + tr.vy * c) / self._target_speed,
                             1.0 - math.exp(-self._tau * age))
        return {
            "state": np.clip(state, _STATE_LO, _STATE_HI).astype(np.float32),
            "map": np.clip(window, 0.0, 1.0).astype(np.float32),
            "tracks": np.clip(tracks, self._track_lo, self._track_hi).astype(np.float32),
        }


def parallel_env(scenario: Scenario | str | Path = "paper-case1", **options: Any) -> SwarmSearchEnv:
    """The ``swarm_search_v1`` parallel environment on ``scenario`` (a built-in name, a path or
    a :class:`~swarm.scenario.Scenario`). Options (docs/env.md): ``controlled`` (UAV names and
    types; default all), ``planner`` and ``duration_s`` (scenario overrides), ``map_size``,
    ``map_cell_m``, ``map_samples``, ``n_tracks``, ``rewards`` (:class:`RewardWeights` or a
    dict), ``flatten`` (one float32 vector per observation instead of a dict), ``batch_planning``."""
    return SwarmSearchEnv(scenario, **options)

