"""The local planner shared by every planner: an artificial potential field (eq. 28-32).

It turns a waypoint into a command ``(a, omega)``:

* attraction to the waypoint, ``k_att`` times the unit vector towards it (eq. 28-29);
* repulsion from each known threat within its influence radius ``d_max`` (eq. 30, with the
  distance measured from the threat's edge, ``d_0 = R_T``);
* repulsion from UAVs heard closer than ``uav_dmax_m`` (eq. 31-32), with ``b`` and ``c`` set so
  the force is negligible beyond about 1 km.

A fixed-wing UAV cannot stop, so a potential field alone can fly it into a threat it sensed too
late for its turn radius. A guard therefore overrides the field when the UAV is within a turn
radius (plus margin) of a threat edge and heading towards it: full turn away, minimum speed.
The same holds between UAVs: at 180 m/s closing speed the eq. 31-32 field acts for only a few
seconds. So each UAV also predicts the closest point of approach with every other UAV it
knows of (``others``: sensed within its detect-and-avoid range, else as last heard; see
:meth:`agents.actor.UavActor._others`) under constant velocities and, if they would come closer
than twice the minimum separation within ``lookahead_s`` (at the closest point, or at the
lookahead's end when that point is later: two UAVs converging slowly side by side, as two
turning away from the same threat do), turns at full rate away from where the other will be:
right when it will be on its left, left when on its right. When the predicted miss is under the minimum separation
its side, computed from poses heard a second ago, is noise (two B UAVs read a 20 m miss the
same way round, turned into each other and flew 10 s closer than 200 m), so both take the
side given by their relative velocity turned clockwise, which they agree on: head-on both turn
right (the rule of the air), overtaking the two turn apart. (Always turning right, as before,
does not resolve overtaking or side-by-side conflicts: both turn the same way, the slower one
faster.) It also speeds up when the other will pass behind it and slows down when ahead: two
UAVs converging at a shallow angle have that point almost on both headings, where turning
barely helps. Deterministic and without negotiation.
When the guard and collision avoidance both want to act, avoidance wins as long as, after its
step, the full-rate turn away from every threat ahead still clears the threat's edge by
``threat_margin_m`` (:func:`_can_escape`); otherwise the guard turns, at avoidance's speed if
that too leaves the way out. (The guard used to win always: two fast UAVs turning from the
same no-fly zone side by side flew into each other, paper-case2 seed 13.)
The result is clipped to the airframe's limits (:func:`agents.dynamics.limit_command`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from agents.dynamics import integrate, limit_command, wrap_angle
from agents.knowledge import KnownThreat
from agents.types import UavType

if TYPE_CHECKING:
    from agents.zones import Keepout

_POSITIVE = {"gt": 0}


@dataclass(frozen=True, slots=True)
class ApfSettings:
    """Local planner (eq. 28-32). b, c make the UAV-UAV force negligible beyond about 1 km.

    The one definition of these settings: a scenario's ``[planner.apf]`` table is built from
    this class (fields, defaults and the bounds in each field's metadata) by
    :mod:`swarm.scenario.generated`, except ``min_separation_m`` (the scenario's
    ``safety.min_separation_m``, which the invariant checkers read too) and
    ``threat_margin_m`` (not a scenario setting).
    """

    k_att: float = field(default=1.0, metadata=_POSITIVE)
    # m^2: threat repulsion equals attraction ~1.9 km from the edge of a 3 km d_max ring
    k_rep: float = field(default=4.0e6, metadata=_POSITIVE)
    uav_b: float = field(default=400.0, metadata=_POSITIVE)
    uav_c: float = field(default=200.0, metadata=_POSITIVE)
    uav_dmax_m: float = field(default=1000.0, metadata=_POSITIVE)
    min_separation_m: float = field(default=200.0, metadata=_POSITIVE)
    # The guard's margin beyond a turn radius from a threat's edge.
    threat_margin_m: float = 300.0
    # Collision avoidance looks this far ahead for a closest approach under 2 * min separation.
    lookahead_s: float = field(default=15.0, metadata={"gt": 0, "note": "seconds"})


def _can_escape(kind: UavType, x: float, y: float, v: float, theta: float, omega: float, speed: float,
                threats: list[KnownThreat], s: ApfSettings, dt: float, zones: Sequence[Keepout] = ()) -> bool:
    """True if, after flying ``(omega, speed)`` (within limits) for ``dt``, the UAV can still
    turn clear of every known threat it is then heading towards: the full-rate turn away from
    it (towards the side of its outward normal, as the guard turns) stays at least
    ``threat_margin_m`` outside its edge all the way round. (The whole circle: a conservative
    test, since the turn ends once the UAV heads away.)"""
    a, omega = limit_command(kind, v, (speed - v) / dt, omega, dt)
    x, y, v, theta = integrate(x, y, v, theta, a, omega, dt)
    r = kind.r_min(v)
    c, sn = math.cos(theta), math.sin(theta)
    for th in threats:
        ex, ey = x - th.x, y - th.y
        if c * ex + sn * ey >= 0.0:
            continue  # heading away from it (or along its edge): nothing to escape from
        # The outward normal's side: left (+1) if the threat is on the right.
        side = 1.0 if c * ey - sn * ex >= 0.0 else -1.0
        cx, cy = x - side * r * sn, y + side * r * c
        if math.hypot(cx - th.x, cy - th.y) - r < th.radius + s.threat_margin_m:
            return False
    # Polygon zones and the area's boundary (issue 26; none in a run without them): the same
    # test with the polygon's clearance and normal in place of the circle's.
    for z in zones:
        _, ux, uy = z.clearance(x, y)
        if c * ux + sn * uy >= 0.0:
            continue
        side = 1.0 if c * uy - sn * ux >= 0.0 else -1.0
        cx, cy = x - side * r * sn, y + side * r * c
        if z.clearance(cx, cy)[0] - r < s.threat_margin_m:
            return False
    return True


def _clearer_side(kind: UavType, x: float, y: float, v: float, theta: float, threats: list[KnownThreat],
                  zones: Sequence[Keepout], preferred: float) -> float:
    """The turn direction (+1 left, -1 right) whose full-rate turning circle at speed ``v``
    keeps the larger clearance from every threat and zone; ``preferred`` unless the other is
    strictly clearer (issue 26: corners between polygons and the area's boundary)."""
    r = kind.r_min(v)
    c, sn = math.cos(theta), math.sin(theta)
    best, best_clear = preferred, -math.inf
    for side in (preferred, -preferred):
        cx, cy = x - side * r * sn, y + side * r * c
        clear = min([math.hypot(cx - th.x, cy - th.y) - th.radius for th in threats]
                    + [z.clearance(cx, cy)[0] for z in zones]) - r
        if clear > best_clear:
            best, best_clear = side, clear
    return best


def apf_command(
    kind: UavType,
    x: float,
    y: float,
    v: float,
    theta: float,
    wx: float,
    wy: float,
    speed: float,
    threats: list[KnownThreat],
    others: list[tuple[float, float, float, float]],
    s: ApfSettings,
    dt: float,
    zones: Sequence[Keepout] = (),
) -> tuple[float, float]:
    """Command ``(a, omega)`` that steers towards ``(wx, wy)`` at ``speed``, within limits.

    ``zones``: polygon no-fly zones and the area's boundary (:mod:`agents.zones`), repelled and
    guarded like the circles of ``threats`` with their clearance and normal (issue 26)."""
    # Attraction (eq. 28-29).
    dx, dy = wx - x, wy - y
    d = math.hypot(dx, dy)
    fx, fy = (s.k_att * dx / d, s.k_att * dy / d) if d > 1e-9 else (0.0, 0.0)

    guard_turn = 0.0
    r_turn = kind.r_min(v)
    for th in threats:
        ex, ey = x - th.x, y - th.y
        dc = math.hypot(ex, ey)
        if dc < 1e-9:
            continue
        ux, uy = ex / dc, ey / dc
        rho = dc - th.radius  # clearance from the threat's edge
        reach = th.d_max - th.radius
        if rho < reach:
            rho_f = max(rho, 1.0)
            mag = s.k_rep * (1.0 / (rho_f * rho_f) - 1.0 / (reach * reach))  # eq. 30
            fx += mag * ux
            fy += mag * uy
        # Guard: close to the edge and closing in -> turn away at full rate.
        closing = math.cos(theta) * (-ux) + math.sin(theta) * (-uy)
        if rho < r_turn + s.threat_margin_m and closing > 0.0:
            # Turn towards whichever side the outward normal lies.
            side = math.sin(math.atan2(uy, ux) - theta)
            guard_turn = 1.0 if side >= 0 else -1.0
    for z in zones:  # (issue 26: polygons, as the circles above with their clearance and normal)
        rho, ux, uy = z.clearance(x, y)
        reach = z.reach_m
        if rho < reach:
            rho_f = max(rho, 1.0)
            mag = s.k_rep * (1.0 / (rho_f * rho_f) - 1.0 / (reach * reach))  # eq. 30
            fx += mag * ux
            fy += mag * uy
        closing = math.cos(theta) * (-ux) + math.sin(theta) * (-uy)
        if rho < r_turn + s.threat_margin_m and closing > 0.0:
            side = math.sin(math.atan2(uy, ux) - theta)
            guard_turn = 1.0 if side >= 0 else -1.0
    if zones and guard_turn:
        # Polygons make corners (a zone on the area's edge, a concave coast) where turning away
        # from one edge turns into another: take the side whose full-rate turning circle keeps
        # the most clearance from everything known (the guard's own side on a tie).
        guard_turn = _clearer_side(kind, x, y, v, theta, threats, zones, guard_turn)

    vx, vy = v * math.cos(theta), v * math.sin(theta)
    conflict = 0.0  # turn direction for the earliest predicted conflict (+1 left, -1 right)
    conflict_speed = speed
    t_first = math.inf
    for ox, oy, ovx, ovy in others:
        ex, ey = x - ox, y - oy
        dd = math.hypot(ex, ey)
        # Closest point of approach under constant velocities.
        wx_, wy_ = ovx - vx, ovy - vy
        w2 = wx_ * wx_ + wy_ * wy_
        if w2 > 1e-9:
            t_cpa = (ex * wx_ + ey * wy_) / w2  # = -(p . w)/|w|^2 with p = other - me = -e
            if 0.0 < t_cpa:
                mx, my = -ex + wx_ * t_cpa, -ey + wy_ * t_cpa
                miss2 = mx * mx + my * my
                # Closest within the lookahead: at the CPA, or at the lookahead's end if the CPA
                # is later (two UAVs converging slowly, e.g. side by side in the same turn, come
                # closer than 2 d_min long before their CPA: a conflict all the same).
                t_near = t_cpa
                near2 = miss2
                if t_cpa >= s.lookahead_s:
                    t_near = s.lookahead_s
                    qx, qy = -ex + wx_ * t_near, -ey + wy_ * t_near
                    near2 = qx * qx + qy * qy
                if near2 < (2.0 * s.min_separation_m) ** 2 and t_near < t_first:
                    t_first = t_near
                    if miss2 < (0.25 * s.min_separation_m) ** 2:
                        # Nearly a collision course: the side of a miss this small is noise
                        # (heard poses, turning), and the two UAVs could read it the same way
                        # round and turn into each other. Use a side both agree on: the
                        # relative velocity turned clockwise (the other UAV computes the
                        # opposite vector). Head-on, that has both turn right.
                        mx, my = wy_, -wx_
                    # Move away from where the other will be: turn right if it is on our
                    # left, and speed up if it will be behind us, slow down if ahead. (When
                    # two UAVs converge at a shallow angle it lies almost along both headings:
                    # a turn barely moves either away from it, a change of speed does.)
                    conflict = -1.0 if math.cos(theta) * my - math.sin(theta) * mx >= 0.0 else 1.0
                    conflict_speed = kind.speed_min if math.cos(theta) * mx + math.sin(theta) * my > 0.0 else kind.speed_max
        if dd < 1e-9 or dd > s.uav_dmax_m:
            continue
        c = s.uav_c
        denom = math.exp(dd / c) - math.exp(s.min_separation_m / c)
        # eq. 32; inside d_min the denominator vanishes: use a large capped push.
        mag = 50.0 if denom <= 1e-9 else min(50.0, (s.uav_b / c) * math.exp(dd / c) / (denom * denom))
        fx += mag * ex / dd
        fy += mag * ey / dd

    if guard_turn and conflict:
        # Both a threat ahead and a UAV on a conflicting course. Collision avoidance wins as
        # long as the UAV, having followed it for one step, could still turn clear of every
        # threat it knows (_can_escape); only then does the guard's turn win, at collision
        # avoidance's speed where that too leaves a way out (else, as the guard alone, slowest).
        # Before, the guard always won: two fast UAVs turning away from the same no-fly zone
        # side by side flew into each other (paper-case2 seed 13).
        w_max = kind.turn_rate_max(v)
        if _can_escape(kind, x, y, v, theta, conflict * w_max, conflict_speed, threats, s, dt, zones):
            omega, speed = conflict * w_max, conflict_speed
        else:
            omega = guard_turn * w_max
            if not _can_escape(kind, x, y, v, theta, omega, conflict_speed, threats, s, dt, zones):
                speed = kind.speed_min
            else:
                speed = conflict_speed
    elif guard_turn:
        omega = guard_turn * kind.turn_rate_max(v)
        speed = kind.speed_min
    elif conflict:
        omega = conflict * kind.turn_rate_max(v)
        speed = conflict_speed
    elif fx == 0.0 and fy == 0.0:
        omega = 0.0
    else:
        omega = wrap_angle(math.atan2(fy, fx) - theta) / dt
    a = (speed - v) / dt
    return limit_command(kind, v, a, omega, dt)
