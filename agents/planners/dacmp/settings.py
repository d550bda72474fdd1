"""DACMP's settings (paper section 3; defaults from DACMP-SPEC.md): the one definition.

:class:`~agents.planners.dacmp.planner.DacmpPlanner` is built on this class (it adds what a run
gives it: the map's pyramid levels and the other UAV types' speeds and radii), and a scenario's
``[planner.dacmp]`` table is generated from it by :mod:`swarm.scenario.generated`: same fields, same
defaults, and the bounds in each field's metadata (``ge``, ``gt``, ``le``, ``lt``, a ``note`` on
the unit; ``each``: bounds of every item of an array; ``expected``: the words of an error about a
value that is not a number). The scenario also checks what needs more than this table:
``level_weights`` has one weight per map level (``map.levels``) with a positive sum.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

__all__ = ["DacmpSettings"]

_AT_LEAST_0 = {"ge": 0}
_RADII = "times the detection radius"


@dataclass(frozen=True, kw_only=True)
class DacmpSettings:
    """PSO and fitness settings (section 3; defaults from DACMP-SPEC.md)."""

    particles: int = field(default=40, metadata={"ge": 1})
    iterations: int = field(default=25, metadata={"ge": 1})
    w_start: float = field(default=0.9, metadata=_AT_LEAST_0)
    w_end: float = field(default=0.4, metadata=_AT_LEAST_0)
    c1_start: float = field(default=2.5, metadata=_AT_LEAST_0)
    c1_end: float = field(default=0.5, metadata=_AT_LEAST_0)
    c2_start: float = field(default=0.5, metadata=_AT_LEAST_0)
    c2_end: float = field(default=2.5, metadata=_AT_LEAST_0)
    ring_mean_factor: float = field(default=1.5, metadata={"gt": 0, "note": _RADII})
    ring_sd_factor: float = field(default=0.5, metadata={"ge": 0, "note": _RADII})
    # Our choice (the paper does not bound them): particles stay within this distance of the UAV,
    # so the waypoint it announces is its next one, not a target 10 km away.
    ring_max_factor: float = field(default=2.5, metadata={"gt": 0, "note": _RADII})
    heading_sd_rad: float = field(default=math.pi / 2, metadata=_AT_LEAST_0)
    eta: float = field(default=0.5, metadata={"ge": 0, "le": 1})
    # The target terms (eq. 22-23) measure distance and speed in this unit (km, km/s): with
    # Table 1's weights that is what makes them outweigh the search term (at most 1) inside D.
    field_unit_m: float = field(default=1000.0, metadata={"gt": 0, "note": "metres per distance unit of eq. 22-23"})
    # Particles closer than this to a known threat's edge are infeasible (on top of the circle).
    threat_margin_m: float = field(default=300.0, metadata=_AT_LEAST_0)
    # Our choice: a track nobody has refreshed for this long no longer attracts (eq. 22 needs the
    # target's state g_m(t): nobody sees it); a watcher that lost its target returns to search.
    # Left out (None): the map's memory time 1 / tau (200 s with the defaults: a cell's
    # uncertainty reaches 1 - 1/e), about the time a target needs to cross a sensor footprint.
    track_max_age_s: float | None = field(default=None, metadata={"gt": 0, "note": "seconds"})
    # lambda_1..lambda_L of eq. 19; None = equal weights summing to 1.
    level_weights: tuple[float, ...] | None = field(default=None, metadata={
        "each": {"ge": 0},
        "expected": "an array of numbers >= 0, one per map level, with a positive sum, or leave it out",
    })
    # Planning budget (issue 36; docs/planners.md, "Planning budget"). "own": a UAV plans on its
    # own map (the paper). "base": a UAV whose map is a member of a MapGroup (agents.maps.mapgroup:
    # a dense map shared by UAVs that hear each other) plans on the group's base, the scans every
    # member has: its own map less the scans of the last tick or two that some member still
    # lacks (its own latest, mostly). One pyramid per group instead of one per UAV.
    member_map: Literal["own", "base"] = "own"
    # Planning budget (issue 36): a UAV's map pyramid (what eq. 19-20 read) is brought up to date
    # with its map at a plan only when its last update is at least this old (or the pyramid's
    # base time moved); plans in between read the map as it was at that update, aged to the
    # plan's time. 0: at every plan (the paper).
    map_refresh_s: float = field(default=0.0, metadata={"ge": 0, "note": "seconds"})
