"""Keeping a target: where a watcher flies while it watches one (docs/modelling.md, "Assignment
rules", rule 5).

:func:`loiter` circles the target inside the detection radius, or from outside a no-fly zone at
its edge nearest to the target; once nobody has seen a target that is predicted inside a zone,
:func:`patrol` flies round the zone's boundary so that its exit is seen wherever it comes out.
Both give the local planner (:func:`agents.apf.apf_command`) a goal and a speed; they read the
UAV's own reading, knowledge and settings and change nothing.
"""

from __future__ import annotations

import math

from agents.inputs import ActorSettings, SensorReading
from agents.knowledge import Knowledge, KnownThreat, Track, zone_clearance
from agents.types import GRAVITY, UavType
from agents.zones import Keepout


def loiter(kind: UavType, s: ActorSettings, knowledge: Knowledge, r: SensorReading, track: Track,
           threat_margin_m: float) -> tuple[float, float, float, bool]:
    """Goal and speed for a watcher, and whether it patrols a zone's boundary: circle the
    target inside the detection radius.

    A vector field (Nelson et al., 2007) around the target's predicted position: far out it
    points at the target, on the circle of radius ``r_l`` along it (keeping the UAV's
    current sense of rotation), with the target's velocity added so the circle moves with
    it. Full speed until it must brake to reach the detection radius at the loiter speed
    (the fastest whose turn radius fits the circle), never faster inside it. Flying *at*
    the target instead overflies it and comes back on a turn of at least the turn radius,
    which for a fast UAV (1 km at 60 m/s, 2.3 km at 90 m/s) takes it out of its 2 km
    detection circle on every pass.

    A target predicted inside a known no-fly zone (targets may enter one; we may not), or so
    close to one that a circle around it would cross the threat guard's band (a turn radius
    at the loiter speed plus ``threat_margin_m``, agents.apf), is circled from outside while
    it is in sight: the circle's centre moves out along the line from the zone's centre
    through the target to where the circle just clears that band, at the edge nearest to
    the target. Once nobody has seen it for a replanning period and it is predicted inside
    the zone, the watcher patrols the zone's boundary instead (:func:`patrol`), so that it
    sees the target come out wherever it does (docs/modelling.md, "Assignment rules", rule 5).
    """
    t = r.t
    tx, ty = track.predict(t)
    fresh = t - track.t <= s.replan_s
    tvx, tvy = (track.vx, track.vy) if fresh else (0.0, 0.0)
    r_l = max(s.loiter_radius_factor * kind.detect_radius, s.loiter_turn_factor * kind.r_min(kind.speed_min))
    # Loiter at the fastest speed whose turn radius fits the circle (with the same margin);
    # brake to it in time to arrive on the circle at that speed.
    v_l = min(max(math.sqrt(r_l / s.loiter_turn_factor * GRAVITY * math.tan(kind.bank_max_rad)),
                  kind.speed_min), kind.speed_max)
    # The circle stays clear of the threat guard's band (a turn radius at the loiter speed
    # plus threat_margin_m, agents.apf) around every known zone: a target inside one, or
    # too close to one to be circled, is circled from outside, on the line from the zone's
    # centre through it (the edge nearest to it).
    standoff = kind.r_min(v_l) + threat_margin_m + r_l
    if not fresh:
        lost_at = knowledge.near_no_fly(tx, ty)  # (predicted inside one)
        if lost_at is not None:
            return (*patrol(kind, r, track, lost_at, kind.r_min(v_l) + threat_margin_m + s.patrol_margin_m, r_l, v_l),
                    True)
    zone = knowledge.inside_threat(tx, ty, standoff) if knowledge.threats else None
    if zone is not None:
        ux, uy = tx - zone.x, ty - zone.y
        n = math.hypot(ux, uy)
        ux, uy = (ux / n, uy / n) if n > 1e-9 else (1.0, 0.0)
        out = zone.radius + standoff
        tx, ty, tvx, tvy = zone.x + out * ux, zone.y + out * uy, 0.0, 0.0
    for z in s.zones:  # (issue 26) a polygon zone: the same stand-off, along its normal
        rho, ux, uy = z.clearance(tx, ty)
        if rho < standoff:
            tx, ty, tvx, tvy = tx + (standoff - rho) * ux, ty + (standoff - rho) * uy, 0.0, 0.0
    ex, ey = r.x - tx, r.y - ty
    d = math.hypot(ex, ey)
    gamma = math.atan2(ey, ex) if d > 1e-6 else r.theta - math.pi / 2
    sense = 1.0 if ex * math.sin(r.theta) - ey * math.cos(r.theta) >= 0.0 else -1.0
    chi = gamma + sense * (math.pi / 2 + math.atan(s.loiter_gain * (d - r_l) / r_l))
    brake = max(r.v * r.v - v_l * v_l, 0.0) / (2.0 * kind.accel_max)
    speed = v_l if d <= kind.detect_radius + brake else kind.speed_max
    dx, dy = speed * math.cos(chi) + tvx, speed * math.sin(chi) + tvy
    n = math.hypot(dx, dy)
    if n < 1e-9:
        return tx, ty, speed, False
    return r.x + 1000.0 * dx / n, r.y + 1000.0 * dy / n, speed, False


def patrol(kind: UavType, r: SensorReading, track: Track, zone: KnownThreat | Keepout, clearance: float,
           scale: float, v_patrol: float) -> tuple[float, float, float]:
    """Goal and speed for a watcher whose target went out of sight in or by a no-fly zone
    (circle or polygon): fly along the zone's boundary at ``clearance`` from it, round and
    round, so that the target is seen again wherever it comes out (docs/modelling.md,
    "Assignment rules", rule 5).

    A vector field on the zone's clearance ``rho`` (signed distance, outward normal ``n``,
    :func:`agents.knowledge.zone_clearance`): along the boundary's tangent, turned towards
    the patrol line by ``atan((clearance - rho) / scale)``: straight at the zone from far
    out, straight out from too near. The sense round the zone is against the target's last
    known motion round it (its velocity across the zone's normal where it was last seen: a
    patrol that goes the target's way overtakes it inside and may pass its exit just before
    it comes out; going the other way it meets it more often); a target that went straight
    in gives no sense, and the UAV keeps the one its heading has. Both are fixed while
    nobody sees the target, so the sense holds. Full speed until within a detection radius
    (plus braking) of the line, then ``v_patrol`` (the loiter speed: the threat guard's band
    was reckoned with its turn radius)."""
    rho, ux, uy = zone_clearance(zone, r.x, r.y)
    _, nx, ny = zone_clearance(zone, track.x, track.y)
    across = -ny * track.vx + nx * track.vy  # > 0: the target moved counter-clockwise round the zone
    if abs(across) > 0.25 * math.hypot(track.vx, track.vy):
        sense = -1.0 if across > 0.0 else 1.0
    else:
        sense = 1.0 if -uy * math.cos(r.theta) + ux * math.sin(r.theta) >= 0.0 else -1.0
    phi = math.atan((clearance - rho) / scale)
    c, s_ = math.cos(phi), math.sin(phi)
    dx, dy = sense * -uy * c + ux * s_, sense * ux * c + uy * s_
    brake = max(r.v * r.v - v_patrol * v_patrol, 0.0) / (2.0 * kind.accel_max)
    speed = v_patrol if rho <= clearance + kind.detect_radius + brake else kind.speed_max
    return r.x + 1000.0 * dx, r.y + 1000.0 * dy, speed
