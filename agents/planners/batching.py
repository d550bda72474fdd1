"""Plan requests of one tick, served together.

Numpy's per-call overhead dominates one UAV's PSO (~40 particles, a few dozen array operations
per iteration). When several UAVs replan in the same tick, evaluating all their particles in one
pass costs little more than evaluating one UAV's, so the simulator lets the actors *ask* for
plans (``await batcher.request(actor, view)``) and serves all outstanding requests at once when
every actor still working on the tick is waiting for a plan.

A planner opts in with ``plan_many(views) -> list[Plan]``; it must return exactly what
``[plan(v) for v in views]`` would (each view carries its UAV's own map, knowledge and random
stream, and the batch only shares array operations, not decisions). ``tests/test_batching.py``
checks that through the event-log hash. Requests are grouped by equal planners (same class and
settings); anything else is planned one by one. Grouping and order follow UAV ids, so the result
does not depend on the order in which the event loop ran the actors.

Planners that are not equal (each UAV's own instance, with state of its own) can still share
work: a planner class may define ``prepare_many(requests)``, a static or class method called
once per flush, before any plan, with every ``(planner, view)`` of its class in UAV-id order. It
must not change what any plan will be, only do ahead, for all of them at once, work the plans
would each do alone (:meth:`agents.planners.surveillance.SharedSurveillance.prepare_many`
brings the watchers' map pyramids up to date together).
"""

from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING

from agents.planners.base import Plan, Planner, PlanView

if TYPE_CHECKING:
    from agents.actor import UavActor


class PlanBatcher:
    def __init__(self) -> None:
        self._requests: list[tuple[int, Planner, PlanView, asyncio.Future[Plan]]] = []
        self.batches = 0  # planner calls made (one per group per flush)
        self.plans = 0

    @property
    def pending(self) -> int:
        return len(self._requests)

    def request(self, actor: UavActor, view: PlanView) -> asyncio.Future[Plan]:
        """Queue a plan request; the future resolves at the next :meth:`flush`."""
        fut: asyncio.Future[Plan] = asyncio.get_running_loop().create_future()
        self._requests.append((actor.uid, actor.planner, view, fut))
        return fut

    def flush(self) -> None:
        """Plan every queued request, grouped by equal planners, and resolve the futures."""
        requests = sorted(self._requests, key=lambda r: r[0])
        self._requests = []
        failed = self._prepare(requests)
        groups: list[tuple[Planner, list[tuple[PlanView, asyncio.Future[Plan]]]]] = []
        for _uid, planner, view, fut in requests:
            for p, members in groups:
                if type(p) is type(planner) and p == planner:
                    members.append((view, fut))
                    break
            else:
                groups.append((planner, [(view, fut)]))
        for planner, members in groups:
            views = [v for v, _ in members]
            try:
                if type(planner) in failed:
                    raise failed[type(planner)]
                many = getattr(planner, "plan_many", None)
                plans = many(views) if many is not None and len(views) > 1 else [planner.plan(v) for v in views]
            except Exception as exc:
                for _, fut in members:
                    if not fut.done():
                        fut.set_exception(exc)
                continue
            self.batches += 1
            self.plans += len(plans)
            for (_, fut), plan in zip(members, plans):
                if not fut.done():
                    fut.set_result(plan)

    @staticmethod
    def _prepare(requests: list[tuple[int, Planner, PlanView, asyncio.Future[Plan]]]) -> dict[type, Exception]:
        """Each planner class's ``prepare_many`` with its requests (see the module docstring);
        returns the classes whose ``prepare_many`` raised, with the error, which their plans
        then raise (each actor reports it with its name)."""
        by_class: dict[type, list[tuple[Planner, PlanView]]] = {}
        for _uid, planner, view, _fut in requests:
            if getattr(type(planner), "prepare_many", None) is not None:
                by_class.setdefault(type(planner), []).append((planner, view))
        failed: dict[type, Exception] = {}
        for cls, pairs in by_class.items():
            try:
                cls.prepare_many(pairs)  # type: ignore[attr-defined]  # (checked above)
            except Exception as exc:
                failed[cls] = exc
        return failed


__all__ = ["PlanBatcher"]
