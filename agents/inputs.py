"""What an actor is given: its settings once (:class:`ActorSettings`) and, each tick, what its
own sensors read (:class:`SensorReading`: the targets, threats and UAVs it senses and, with an
energy budget, :class:`EnergyReading`).

Records only, read by the actor (:mod:`agents.actor`) and by the modules that do part of its
work (:mod:`agents.relief`, :mod:`agents.station`), and written by the simulation and the
faults that act on readings. Kept apart from the actor so that those modules need not import it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from agents.apf import ApfSettings
from agents.knowledge import KnownThreat
from agents.maps.grid import Disk
from agents.types import UavType
from agents.zones import Keepout
from comms.settings import RadioSettings

__all__ = ["ActorSettings", "EnergyReading", "SensedTarget", "SensedUav", "SensorReading"]


@dataclass(frozen=True, slots=True)
class EnergyReading:
    """What a UAV with an energy budget knows of it this tick (issues 26, 33, swarm.kernel.mission):
    its pad at the base; the next point of its way home (round the no-fly zones); ``must_go``:
    its energy left is down to what that way home takes against the mean wind, plus the
    reserve; ``spare_s``: the seconds of flight it has beyond what the way home takes with the
    worst turn onto it (a half turn at its present speed) plus the reserve, at the most power
    its type can draw (0 when none); ``home_s_per_m``: what each metre it flies farther from
    home takes of those seconds (the way's energy a metre against the mean wind, at that
    power); ``handover_s``: the setting of that name; ``wind_mps``: the mean wind's speed (what
    it budgets a relief's way against)."""

    home_x: float
    home_y: float
    way_x: float
    way_y: float
    must_go: bool
    cruise_mps: float  # the airspeed it flies home at (its type's minimum-power speed)
    spare_s: float = math.inf
    handover_s: float = 60.0
    wind_mps: float = 0.0
    home_s_per_m: float = 0.0


@dataclass(frozen=True, slots=True)
class SensedTarget:
    target: int
    x: float
    y: float
    vx: float
    vy: float
    value: float


# Another UAV as the detect-and-avoid sensor gives it: (uav id, x, y, vx, vy).
SensedUav = tuple[int, float, float, float, float]


@dataclass(slots=True)
class SensorReading:
    """What the UAV's own sensors give it this tick (ground truth inside its detection radius).

    ``uavs``: the other UAVs inside its detect-and-avoid range (``UavType.daa_range``), in id
    order, placed relative to where the UAV believes it is (a sensor measures range and bearing);
    ``None`` when it has no such sensor (range 0)."""

    t: float
    x: float
    y: float
    v: float
    theta: float
    targets: list[SensedTarget]
    threats: list[KnownThreat]
    uavs: list[SensedUav] | None = None
    energy: EnergyReading | None = None  # (issue 26: only UAVs with an energy budget)


@dataclass(frozen=True, slots=True)
class ActorSettings:
    dt: float = 1.0
    replan_s: float = 10.0
    surveillance: bool = True
    peer_timeout_s: float = 5.0
    # A watcher circles its target at max(loiter_radius_factor * R_s, loiter_turn_factor * its
    # turn radius at minimum speed), steered by a vector field whose approach gain is loiter_gain.
    loiter_radius_factor: float = 0.5
    loiter_turn_factor: float = 1.25
    loiter_gain: float = 1.0
    # ... and feels the threats' repulsion (eq. 30) with apf.k_rep times this (see UavActor.act).
    loiter_threat_weight: float = 0.15
    # A watcher whose target went out of sight inside (or by) a no-fly zone patrols the zone's
    # boundary this far beyond the threat guard's band (agents.station.patrol; our choice: the
    # guard, which turns a UAV closing on an edge within a turn radius plus threat_margin_m,
    # stays quiet on the patrol line, and a type-A UAV sees 0.6 km into the zone).
    patrol_margin_m: float = 150.0
    # The scenario's [radio] settings (comms.settings.RadioSettings, their one definition): the
    # frame size cap, the beacon and tracks periods, and anti-entropy (sync_*: agents.maps.scanlog),
    # with its knowledge horizon (horizon_m: heard scans centred farther than this from the UAV
    # are neither applied nor logged, and digests are answered with scans within it of the
    # digest's sender only).
    radio: RadioSettings = field(default_factory=RadioSettings)
    apf: ApfSettings = field(default_factory=ApfSettings)
    # The swarm key ([radio] auth): frames are sent with their MAC and heard frames without the
    # right one are rejected (comms.codec). None: no authentication.
    auth_key: bytes | None = None
    # Geographic scenarios (issue 26; empty / None otherwise, and then nothing below runs):
    # polygon no-fly zones and the area's boundary, known before take-off (agents.zones), which
    # the APF repels and guards like the circles; and the cells outside the area polygon as one
    # disk-like mask, stamped into the map as seen at every tick before planning, so that q = 0
    # there: nothing to search (the pyramids, guide points and every planner read q).
    zones: tuple[Keepout, ...] = ()
    outside: Disk | None = None
    # (issue 33) [endurance]: free UAVs answer watchers' relief requests (rule 6 of
    # docs/modelling.md's assignment rules; agents.relief). Off without endurance.
    relief: bool = False
    uav_types: tuple[UavType, ...] = ()  # (the run's types: a relief's turn radius, agents.relief)
