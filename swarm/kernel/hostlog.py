"""Host changes as data: how each change a host program makes is applied, logged and replayed.

Every change the embedding API makes to a running simulation (``add_target``, ``add_uav``,
``add_fault``, ``take_control``, ``release_control``, ``set_state``, ``set_waypoint``) is applied
here, by :func:`apply_change`, from its name and a table of plain arguments (UAVs by name,
headings in degrees for what is added and in radians for ``set_state``, times in seconds): the
call checked its input first (:mod:`swarm.kernel.host`). The change is logged as a ``host`` event
(:class:`swarm.events.Host`) at the tick boundary where it takes effect, before anything else of
that tick, so an embedded run can be replayed from its event log:
:func:`schedule_recorded_host_changes` schedules every recorded change of a run on a fresh
simulation of the same scenario and seed, to be applied again at the same tick boundary in the
same order; the replay then logs the same bytes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

import swarm.events as ev
from faults.registry import fault_from_dict
from swarm.errors import UsageError
from swarm.events import Event
from swarm.scenario import UavSpec

if TYPE_CHECKING:
    from swarm.kernel.simulation import Simulation

__all__ = ["CHANGES", "apply_change", "schedule_recorded_host_changes"]


def _add_target(sim: Simulation, a: dict[str, Any]) -> None:
    tid = len(sim._targets)
    sim._add_target_rng(a["x"], a["y"], math.radians(a["heading_deg"]), a["speed"], a["value"],
                        sim._rng.generator("target", tid))


def _add_uav(sim: Simulation, a: dict[str, Any]) -> None:
    sim._add_uav_spec(UavSpec(name=a["name"], type=a["type"], x_m=a["x"], y_m=a["y"],
                              heading_deg=a["heading_deg"], speed=a["speed"], join_s=a["join_s"]))


def _add_fault(sim: Simulation, a: dict[str, Any]) -> None:
    sim._faults.add(fault_from_dict(a["fault"]))


def _take_control(sim: Simulation, a: dict[str, Any]) -> None:
    sim._host.controlled.add(sim._names[a["uav"]])


def _release_control(sim: Simulation, a: dict[str, Any]) -> None:
    sim._host.controlled.discard(sim._names[a["uav"]])


def _set_state(sim: Simulation, a: dict[str, Any]) -> None:
    b = sim._world.uavs[sim._names[a["uav"]]]
    b.x, b.y, b.theta, b.v = a["x"], a["y"], a["heading"], a["speed"]


def _set_waypoint(sim: Simulation, a: dict[str, Any]) -> None:
    sim._fleet.actors[sim._names[a["uav"]]].goto(a["x"], a["y"])


#: change name -> how it is applied (its arguments as :func:`apply_change` gets them).
CHANGES: dict[str, Callable[[Simulation, dict[str, Any]], None]] = {
    "add_target": _add_target,
    "add_uav": _add_uav,
    "add_fault": _add_fault,
    "take_control": _take_control,
    "release_control": _release_control,
    "set_state": _set_state,
    "set_waypoint": _set_waypoint,
}


def apply_change(sim: Simulation, change: str, args: dict[str, Any]) -> None:
    """Apply one host change now: ``sim`` is at a tick boundary (``sim.now``), nothing of that
    tick has run yet. Logs it first (so the log reads cause, then effects)."""
    sim._clock.advance_to(sim.now)
    sim._log.emit(ev.host(t=sim.now, change=change, args=args))
    CHANGES[change](sim, args)


def schedule_recorded_host_changes(sim: Simulation, events: Iterable[Event]) -> int:
    """Schedule on ``sim`` (freshly built from the same scenario and seed, not yet advanced)
    every host change recorded in ``events`` (the decoded events of the original run, e.g.
    ``swarm.testing.invariants.load_run_log(run_dir)[1]``), each to be applied again at the
    tick boundary it was applied at, in the same order. Returns how many. Running ``sim`` to
    the original's end then logs the original's bytes."""
    if sim._tick_index:
        raise UsageError("schedule_recorded_host_changes needs a simulation that has not run yet")
    n = 0
    for e in events:
        if e.kind != "host":
            continue
        change, args = e.change, e.args  # type: ignore[attr-defined]
        if change not in CHANGES:
            raise UsageError(f"a recorded host change {change!r} is not one this version knows ({', '.join(CHANGES)})")
        sim._host.replay_at(int(round(e.t / sim.dt)), change, dict(args))
        n += 1
    return n
