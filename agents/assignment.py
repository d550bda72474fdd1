"""When the assignment rules hold: the weight conditions of DACMP's handover analysis (paper eq. 25-27).

The rules themselves (same-type exclusion, fast-to-slow handover, what a released UAV may do,
when a watcher may drop a target) are stated once, in words, in docs/modelling.md ("Assignment
rules"); the checkers of :mod:`swarm.testing.invariants` test them and cite that page. This
module holds the one fact they share with the planner and the scenario validator: for which
UAV types the rules can hold at all.

DACMP decides who watches a target by comparing, at the target, its attraction (eq. 22:
``w_t / (d v_i^2)``) with the competing repulsion of the UAV already there (eq. 23:
``w_r / (d v_i v_j)``). Both share the distance ``d``, so the outcome depends on the weights and
top speeds alone (target value 1):

* **exclusion** (eq. 27), one type: two UAVs of the type repel each other off a target more than
  it attracts them: ``w_t < w_r``. A type with ``w_t = 0`` never watches: nothing to exclude.
* **takeover** (eq. 25), a slower type ``s`` near a target that a faster type ``f`` watches is
  drawn in: ``w_t,s / v_s > w_r,s / v_f``, with ``w_t,s > 0``.
  And drawn in from afar: the target's net pull on it, ``(w_t,s / v_s - w_r,s / v_f) / (v_s d)``
  in the planner's field units (km, km/s: ``planner.dacmp.field_unit_m``), must beat the search
  term (at most 1) at ``d = D_s``, its influence radius, or it may never switch to
  surveillance (with eq. 25 met by a hair, a generated type was never drawn in).
* **release** (eq. 26), the faster one is pushed off once the slower one is there:
  ``w_t,f / v_f < w_r,f / v_s``. (The paper prints eq. 26 with the two speeds swapped; as
  printed, its own Table 1 would break it: ``2.0 / 50 < 2.1 / 90`` is false. Derived from eq.
  22-23 as above, Table 1 meets it: ``2.0 / 90 < 2.1 / 50``.)

Table 1's A and B meet all three. One more is geometry, not weights: a type must be able to
turn inside its own detection radius (at its minimum speed) to keep a watched target in sight
(:func:`watch_break`). A type that breaks one is allowed (types are data), but the
rule it breaks is then the weights' doing, not the planner's: the scenario validator warns, and
the checkers do not judge it.
"""

from __future__ import annotations

from collections.abc import Iterable

from agents.types import UavType

__all__ = ["exclusion_break", "handover_break", "rule_breaks", "takeover_pull", "watch_break"]


def _g(x: float) -> str:
    return f"{x:.3g}"


def watch_break(k: UavType) -> str | None:
    """Why a UAV of type ``k`` cannot keep a target in sight while it watches it (its tightest
    turn, at its minimum speed, is wider than its detection radius: every circle it can fly
    around the target leaves the target outside its sensor part of the way), or None. Rule 5
    (no drop) is not judged for such a type."""
    if k.w_t > 0 and not k.r_min(k.speed_min) < k.detect_radius:
        return (f"type {k.name}: its tightest turn ({_g(k.r_min(k.speed_min))} m at {_g(k.speed_min)} m/s) is not "
                f"inside its detection radius ({_g(k.detect_radius)} m), so it cannot keep a target in sight "
                f"while it circles it")
    return None


def exclusion_break(k: UavType) -> str | None:
    """Why two UAVs of type ``k`` may both keep one target (eq. 27 broken), or None."""
    if k.w_t > 0 and not k.w_t < k.w_r:
        return (f"type {k.name}: w_t = {_g(k.w_t)} is not below w_r = {_g(k.w_r)} (eq. 27), so two UAVs of "
                f"this type may both keep one target")
    return None


def takeover_pull(slow: UavType, fast: UavType, d_m: float, unit_m: float = 1000.0) -> float:
    """The net pull, in the planner's field units, of a target that a UAV of type ``fast``
    watches on a UAV of type ``slow`` whose waypoint is ``d_m`` metres from it: eq. 22's
    attraction ``w_t,s / (d v_s^2)`` less eq. 23's repulsion of the watcher standing at the
    target, ``w_r,s / (d v_s v_f)`` (target value 1; distances and speeds in ``unit_m``, the
    planner's ``field_unit_m``). The planner's own term for one target
    (:meth:`agents.planners.dacmp.planner.UavSearch.own_pull`) is this number inside ``D``."""
    vs, vf, d = slow.speed_max / unit_m, fast.speed_max / unit_m, d_m / unit_m
    return (slow.w_t / vs - slow.w_r / vf) / (vs * d)


def handover_break(slow: UavType, fast: UavType, unit_m: float = 1000.0) -> str | None:
    """Why a target watched by a UAV of type ``fast`` may not pass to one of the slower type
    ``slow`` (eq. 25 or 26 broken, or the pull too weak to draw it in from its influence radius;
    ``unit_m``: the planner's field unit), or None (also None when ``slow`` is not slower)."""
    vs, vf = slow.speed_max, fast.speed_max
    if not vs < vf:
        return None
    if not slow.w_t > 0:
        return f"type {slow.name} has w_t = 0: it never watches, so it cannot take a target over from type {fast.name}"
    if not slow.w_t * vf > slow.w_r * vs:
        return (f"types {slow.name} and {fast.name}: w_t,{slow.name} / v_{slow.name} = {_g(slow.w_t / vs)} is not above "
                f"w_r,{slow.name} / v_{fast.name} = {_g(slow.w_r / vf)} (eq. 25), so type {slow.name} does not take "
                f"targets over from type {fast.name}")
    net = takeover_pull(slow, fast, slow.influence_radius, unit_m)
    if not net > 1.0:
        return (f"types {slow.name} and {fast.name}: a target type {fast.name} watches pulls type {slow.name} at its "
                f"influence radius ({_g(slow.influence_radius)} m) by {_g(net)} (eq. 22-23), not more than the search "
                f"term can (1), so type {slow.name} may never be drawn in to take it over")
    if fast.w_t > 0 and not fast.w_t * vs < fast.w_r * vf:
        return (f"types {slow.name} and {fast.name}: w_t,{fast.name} / v_{fast.name} = {_g(fast.w_t / vf)} is not below "
                f"w_r,{fast.name} / v_{slow.name} = {_g(fast.w_r / vs)} (eq. 26), so type {fast.name} does not release "
                f"targets to type {slow.name}")
    return None


def rule_breaks(kinds: Iterable[UavType], unit_m: float = 1000.0) -> list[str]:
    """Every weight condition that these types (those that fly in a scenario) break, one line
    each; empty when the assignment rules can hold (``unit_m``: the planner's field unit)."""
    ks = sorted({k.name: k for k in kinds}.values(), key=lambda k: k.name)
    out = [m for k in ks if (m := watch_break(k)) is not None]
    out += [m for k in ks if (m := exclusion_break(k)) is not None]
    out += [m for s in ks for f in ks if s is not f and (m := handover_break(s, f, unit_m)) is not None]
    return out
