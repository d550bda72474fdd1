"""The base of every checker: it is fed the events of one instant at a time."""

from __future__ import annotations

import abc
from collections.abc import Iterable, Sequence
from typing import Any

import swarm.events as event_schema
from comms.messages import MODE_NAMES, MODE_SURVEIL
from swarm.errors import UsageError
from swarm.testing.invariants.context import InvariantViolation, RunContext, Violation, describe_fault

# --- checkers ------------------------------------------------------------------------------------


# A pose's mode when the UAV watches a target (poses carry mode names: swarm.events).
SURVEIL = MODE_NAMES[MODE_SURVEIL]


def poses_of(events: Sequence[event_schema.Event]) -> dict[int, tuple[Any, ...]]:
    """uid -> (x, y, v, theta, mode name, target) of the pose events in a group."""
    return {e.uav: (e.x, e.y, e.v, e.theta, e.mode, e.target) for e in events if isinstance(e, event_schema.Pose)}


class Checker(abc.ABC):
    """Base class: implement :meth:`on_group` (events of one instant, in log order) and, for
    liveness properties, override :meth:`finish` (end of the run)."""

    name = "checker"
    live_only = False  # True: needs the simulation (reads maps), cannot run on a log alone
    max_violations = 200  # keep memory bounded when something is badly wrong

    def __init__(self) -> None:
        self.violations: list[Violation] = []
        self.ctx: RunContext | None = None
        self.truncated = 0
        # Why this checker could not judge the run (None: it could): no violations then means
        # nothing, and Monitor.unchecked says so.
        self.unchecked: str | None = None

    @property
    def note(self) -> str | None:
        """What it judged only in part, and why (None: all of it); see :attr:`unchecked` for
        a run it could not judge at all."""
        return None

    def bind(self, ctx: RunContext) -> None:
        self.ctx = ctx

    @property
    def context(self) -> RunContext:
        """The run's context, which :meth:`bind` gives (a :class:`Monitor` binds its checkers
        before it feeds them any event)."""
        if self.ctx is None:
            raise UsageError(f"the {self.name!r} checker is not bound to a run: feed it through a Monitor "
                             "(or call bind(RunContext(scenario)) first)")
        return self.ctx

    def attach(self, sim: Any) -> None:  # noqa: B027  (an optional hook, empty by default)
        """Called once when a monitor attaches to a live simulation (after :meth:`bind`)."""

    @abc.abstractmethod
    def on_group(self, t: float, events: list[event_schema.Event]) -> None:
        """The events of one tick at time ``t``; every checker implements it."""

    def finish(self, t_end: float) -> None:  # noqa: B027  (an optional hook, empty by default)
        """The run ended at ``t_end`` (judge pending liveness obligations)."""

    def violate(self, t: float, message: str, uavs: Iterable[int] = (), target: int | None = None, **data: Any) -> None:
        if len(self.violations) >= self.max_violations:
            self.truncated += 1
            return
        uavs = list(uavs)
        names = tuple(self.ctx.name(u) for u in uavs) if self.ctx else tuple(str(u) for u in uavs)
        since = data.get("since", t)
        faults = self.ctx.explaining(uavs, float(since), float(t)) if self.ctx else []
        self.violations.append(Violation(self.name, float(t), message, names, target, dict(data),
                                         tuple(describe_fault(f) for f in faults)))

    def raise_if(self) -> None:
        if self.violations:
            raise InvariantViolation(self.violations)
