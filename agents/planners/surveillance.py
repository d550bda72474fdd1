"""The one surveillance and handover logic, around a planner that only searches.

DACMP decides when a UAV watches a target and when it lets go with its fitness (eq. 16): the
target attraction of eq. 22 less the competing repulsion of eq. 23 (``f_t``) against the search
value (``f_S``), with its keep rule (a watcher keeps its target while that target's own term
beats ``f_S`` on the target itself) and its mode rule (surveillance of the target whose own
term is the strongest at the chosen waypoint and above ``f_S``). :class:`SharedSurveillance` makes that decision for a
UAV whose planner searches its own way (``greedy``, ``lawnmower``, ``formation``, ``levy``, or a
user's planner that declares ``surveils = "shared"``):

* already watching target ``m`` (its current plan is in surveillance mode of ``m``): DACMP's
  keep rule, unchanged (``DacmpPlanner.keep``): keep ``m`` with ``g_m`` pulled to within one
  planning step as the waypoint, or let go;
* otherwise, for the known targets in scope (``DacmpPlanner``'s: tracks fresh enough, within
  ``D + 2 R_s``), the candidate waypoints are the targets themselves pulled to within one
  planning step (where DACMP's particle swarm looks over the ring around the UAV); the best of
  them by eq. 16 goes through DACMP's mode rule (``UavSearch.decide``): surveillance of the
  target with the strongest pull, or nothing;
* no watch: the wrapped planner's own search plan.

So the assignment rules are DACMP's own code: its eq. 23 rivals (one count per other UAV, a
watcher at its target, the nearer same-type claimant keeps it), its keep rule and its mode rule
(``agents/planners/dacmp/planner.py``), with the scenario's ``[planner.dacmp]`` settings and
each type's ``w_t``, ``w_r``. A fix there is a fix here. While watching, the wrapped planner is
not asked: a pattern planner goes back to its pattern afterwards the way it rejoins after an
avoidance manoeuvre. Search-mode draws from the UAV's stream are the search planner's; the
decision adds the guide point's tie draw (``Layers``) only while a target is in scope.

With ``planner.surveillance = false`` nothing of this runs (the registry does not wrap), so a
search planner's runs are exactly what they were.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from agents.planners.base import Plan, Planner, PlanView
from agents.planners.dacmp.maintained import MaintainedPyramid
from agents.planners.dacmp.planner import Batch, DacmpPlanner, Layers, UavSearch
from comms.messages import MODE_SURVEIL

if TYPE_CHECKING:
    from agents.planners.base import PlannerContext

__all__ = ["SharedSurveillance"]


class SharedSurveillance:
    """A search planner with DACMP's surveillance and handover decision (module docstring).

    ``search``: the UAV's own search planner instance; ``dacmp``: a :class:`DacmpPlanner` with
    the scenario's settings (:meth:`of`), used only for its surveillance decision. The search
    planner's own state stays on ``search``. No ``plan_many``: the simulator plans each UAV
    with it one by one (its identity equality keeps UAVs apart); :meth:`prepare_many` shares the
    map work of the UAVs that replan in the same tick."""

    surveils = True

    def __init__(self, search: Planner, dacmp: DacmpPlanner):
        self.search = search
        self.dacmp = dacmp
        # The UavSearch prepare_many built for the view about to be planned (view, its search).
        self._prepared: tuple[PlanView, UavSearch] | None = None

    @staticmethod
    def prepare_many(requests: list[tuple[SharedSurveillance, PlanView]]) -> None:
        """Before the plans of one tick (agents.planners.batching): bring the map pyramids of
        every UAV that will weigh a target (a known one in scope) up to date in one
        :meth:`MaintainedPyramid.update_many`, whose shared array calls give each pyramid bit
        for bit what its own update would (so :meth:`watch` finds nothing left to do and its
        plan is unchanged). Each one's :class:`UavSearch` is kept for its :meth:`watch`."""
        pyramids: list[MaintainedPyramid] = []
        ts: list[float] = []
        dacmp = None
        for planner, view in requests:
            if not view.surveillance:
                continue
            u = UavSearch.build(planner.dacmp, view, 0)
            planner._prepared = (view, u)
            if u.targets:
                dacmp = planner.dacmp
                pyramids.append(dacmp.planning_pyramid(view.umap))
                ts.append(view.t)
        if dacmp is not None and len(pyramids) > 1:
            dacmp.refresh(pyramids, ts)  # (every watcher's dacmp has the scenario's settings)

    @classmethod
    def of(cls, search: Planner, context: PlannerContext) -> SharedSurveillance:
        return cls(search, DacmpPlanner.from_context(context))

    @property
    def name(self) -> str:
        return self.search.name

    def plan(self, view: PlanView) -> Plan:
        if view.surveillance:
            watch = self.watch(view)
            if watch is not None:
                return watch
        return self.search.plan(view)

    def watch(self, view: PlanView) -> Plan | None:
        """A plan in surveillance mode if DACMP's rules have this UAV watch a target, else None."""
        dacmp, g = self.dacmp, view.grid
        prepared, self._prepared = self._prepared, None
        u = prepared[1] if prepared is not None and prepared[0] is view else UavSearch.build(dacmp, view, 0)
        if not u.targets:
            return None
        layers = Layers(dacmp, [u])  # (the UAV's guide point: f_Sg of eq. 20)
        kept = dacmp.keep(u, g, layers)
        if kept is not None:
            return kept
        n = len(u.targets)
        z = np.array([[[tx for _, tx, _, _ in u.targets]], [[ty for _, _, ty, _ in u.targets]]])
        batch = Batch(dacmp, [u], g, layers, n)
        z = batch.keep_near(z)
        f, f_s, _ = batch.fitness(z, kept=True)
        best = int(np.argmax(f[0]))  # (ties: the first target in id order)
        if not np.isfinite(f[0, best]):
            return None
        unit = dacmp.field_unit_m
        plan = u.decide(float(z[0, 0, best]), float(z[1, 0, best]), float(f_s[0, best]), unit, g.cell_m / unit)
        return plan if plan.mode == MODE_SURVEIL else None
