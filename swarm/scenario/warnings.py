"""Warnings about a valid scenario: values that run but under which a documented rule no longer
holds, or that are most likely not what was meant.

A mistake that cannot run is an error (:class:`~swarm.errors.ScenarioError`, one line, exit
status 2). What follows runs, so it is only a warning: ``swarm validate``, ``swarm run`` and
``swarm sweep`` (at its end) print each as one ``warning:`` line on stderr and go on. Each
starts with the key path (or the run) and says why:

* UAV types the assignment rules do not cover (docs/modelling.md, "Assignment rules"): the
  checkers do not judge them;
* a fault that happens or starts at or after the scenario's own ``duration_s`` never fires:
  the crash at 900 s of a 600 s scenario (one warning per fault). A warning, not an error: the
  scenario runs, and a longer ``--duration`` would fire it;
* a run shortened by ``--duration`` (``Simulation(duration_s=...)``) that ends before some
  faults or late joins of the scenario: one warning listing them. (A join at or after the
  scenario's own ``duration_s`` is an error: ``join_s`` must be ``< duration_s``);
* an angle in degrees small enough to be radians: ``uav_types.X.bank_max_deg <= pi/2``
  (0.44 was meant as 0.44 rad = 25 degrees: read as degrees it gives a turn radius of tens of
  kilometres). A warning, not an error: such a bank limit is legal, only implausible;
* two ``[[uavs]]`` entering at the same time closer than ``safety.min_separation_m`` (from a
  ``[[fleet]]`` layout it is an error: :mod:`swarm.scenario.placement`).
"""

from __future__ import annotations

import math

from agents.assignment import rule_breaks
from agents.types import GRAVITY
from swarm.scenario.model import Scenario
from swarm.scenario.placement import close_starts

__all__ = ["scenario_warnings"]


def _s(x: float) -> str:
    return f"{x:g} s"


def _list(items: list[str], most: int = 4) -> str:
    return ", ".join(items[:most]) + (f" and {len(items) - most} more" if len(items) > most else "")


def scenario_warnings(scenario: Scenario, duration_s: float | None = None) -> list[str]:
    """The warnings of ``scenario`` run for ``duration_s`` (default: its own ``duration_s``),
    one line each, without the ``warning:`` prefix (see the module docstring)."""
    own_end = scenario.duration_s
    end = own_end if duration_s is None else float(duration_s)
    out: list[str] = []
    if scenario.planner.surveillance:
        flown = sorted({u.type for u in scenario.uavs})
        kinds = [s.uav_type(n) for n, s in sorted(scenario.uav_types.items()) if n in flown]
        out += [f"uav_types: {m}; the assignment rules (docs/modelling.md, \"Assignment rules\") do not cover "
                f"these types and the checkers do not judge them"
                for m in rule_breaks(kinds, scenario.planner.dacmp.field_unit_m)]
    cut: list[str] = []  # what a shortened run leaves out (one warning for all of them)
    for i, fault in enumerate(scenario.faults):
        if fault.kind == "join":
            continue  # said for the UAV (below)
        at = getattr(fault, "at_s", None)
        start = float(at if at is not None else getattr(fault, "start_s", 0.0))
        if start >= own_end:
            what = "happens" if at is not None else "starts"
            out.append(f"faults[{i}] ({fault.kind}) {what} at {_s(start)}, at or after the end of the run ({_s(own_end)}): "
                       f"it never fires")
        elif start >= end:
            cut.append(f"faults[{i}] ({fault.kind} at {_s(start)})")
    for i, uav in enumerate(scenario.uavs):
        if uav.join_s is not None and end <= uav.join_s < own_end:  # (at or after own_end: an error)
            cut.append(f"uavs[{i}] ({uav.name} joining at {_s(uav.join_s)})")
    if cut:
        out.append(f"the run ends at {_s(end)}, before the scenario's end ({_s(own_end)}): {_list(cut)} "
                   f"never {'happens' if len(cut) == 1 else 'happen'}")
    close = close_starts(scenario)
    if close:
        words = [f"uavs[{j}] ({scenario.uavs[j].name}) {d:.0f} m from uavs[{i}] ({scenario.uavs[i].name})"
                 for i, j, d, _t in close]
        out.append(f"uavs: {_list(words)} at the start, closer than safety.min_separation_m = "
                   f"{scenario.safety.min_separation_m:g} m: the separation rule is broken from their first tick")
    for name, spec in scenario.uav_types.items():
        bank = spec.bank_max_deg
        if bank <= math.pi / 2:
            radius_km = spec.speed_max**2 / (GRAVITY * math.tan(math.radians(bank))) / 1000.0
            out.append(f"uav_types.{name}.bank_max_deg = {bank:g} looks like radians ({bank:g} rad = "
                       f"{math.degrees(bank):.1f} degrees); it is read as degrees: a turn radius of {radius_km:,.0f} km "
                       f"at {spec.speed_max:g} m/s")
    return out
