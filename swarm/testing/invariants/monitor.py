"""Feeding events to checkers: :class:`Monitor` (live or from a log), the default sets of
checkers, :func:`check_events` and :func:`load_run_log`."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import swarm.events as event_schema
from faults.base import FaultKind
from swarm.errors import UsageError
from swarm.outputs import read_run_dir
from swarm.scenario import Scenario, parse_scenario
from swarm.testing.invariants.assignment import HandoverChecker, NoDropChecker, SingleWatcherChecker
from swarm.testing.invariants.checker import Checker
from swarm.testing.invariants.context import InvariantViolation, RunContext, Violation
from swarm.testing.invariants.maps import JoinerCatchUpChecker, MapAgreementChecker, MapMonotonicityChecker
from swarm.testing.invariants.radio import RadioChecker
from swarm.testing.invariants.safety import DynamicsChecker, SeparationChecker, ThreatClearanceChecker

# --- running checkers ------------------------------------------------------------------------------


class Monitor:
    """Feeds events, grouped by instant, to a set of checkers; from a log (:meth:`feed` each
    event, then :meth:`finish`) or live (:meth:`attach` to a simulation, :meth:`flush` after
    each ``step``)."""

    def __init__(self, checkers: Iterable[Checker], scenario: Scenario | None = None, *,
                 faults: Iterable[FaultKind] | None = None):
        self.checkers = list(checkers)
        self.scenario = scenario
        self._faults = faults
        self.ctx: RunContext | None = RunContext(scenario, faults=faults) if scenario is not None else None
        if self.ctx is not None:
            for c in self.checkers:
                c.bind(self.ctx)
        self._t: float | None = None
        self._group: list[event_schema.Event] = []
        self._decode = event_schema.Decoder()  # (for events given as the log's arrays)
        self._unsubscribe = None
        self.t_end = 0.0
        self.events = 0

    def attach(self, sim: Any) -> Monitor:
        """Check ``sim`` live from now on (subscribes to its events)."""
        self.scenario = sim.scenario
        self.ctx = RunContext(sim.scenario, sim=sim, faults=self._faults)
        for c in self.checkers:
            c.bind(self.ctx)
        for c in self.checkers:
            c.attach(sim)
        self._unsubscribe = sim.subscribe(self.feed)
        return self

    def detach(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None

    def feed(self, ev: event_schema.Event | Sequence[Any]) -> None:
        """One event: a record of :mod:`swarm.events`, or an array as the log holds it
        (``[kind, t, ...]``: decoded here, so a hand-written log can be checked)."""
        if self.ctx is None:
            raise UsageError("Monitor needs the run's scenario: Monitor(checkers, scenario) or .attach(sim)")
        if not isinstance(ev, event_schema.Event):
            ev = self._decode(ev)
        self.events += 1
        self.ctx.on_event(ev)
        if ev.kind == "start":
            return
        t = float(ev.t)
        if self._t is not None and t != self._t:
            self.flush()
        self._t = t
        self._group.append(ev)

    def flush(self) -> None:
        """Hand the buffered events (one instant) to the checkers."""
        t, group = self._t, self._group
        if not group or t is None:  # t is set whenever there is a group (see feed)
            return
        self._group = []
        self.t_end = max(self.t_end, t)
        for c in self.checkers:
            c.on_group(t, group)

    def finish(self) -> list[Violation]:
        self.flush()
        for c in self.checkers:
            c.finish(self.t_end)
        return self.violations

    @property
    def violations(self) -> list[Violation]:
        out = [v for c in self.checkers for v in c.violations]
        return sorted(out, key=lambda v: (v.t, v.invariant))

    def raise_if(self) -> None:
        if self.violations:
            raise InvariantViolation(self.violations)

    @property
    def unchecked(self) -> dict[str, str]:
        """Checkers that could not judge the run, with why (e.g. ``radio`` on a summary log)."""
        return {c.name: c.unchecked for c in self.checkers if c.unchecked is not None}

    @property
    def notes(self) -> dict[str, str]:
        """Checkers that judged the run only in part, with what they left out (e.g. ``dynamics``
        skips the bodies a host drives)."""
        return {c.name: c.note for c in self.checkers if c.note is not None}

    def by_name(self, name: str) -> Checker:
        for c in self.checkers:
            if c.name == name:
                return c
        raise KeyError(name)


def safety_checkers() -> list[Checker]:
    """Separation, threat clearance and dynamic limits: hold for any planner."""
    return [SeparationChecker(), ThreatClearanceChecker(), DynamicsChecker()]


def handover_checkers(settle_s: float = 30.0, takeover_s: float = 60.0, release_s: float = 60.0,
                      grace_s: float = 10.0) -> list[Checker]:
    """The DACMP assignment invariants (planner-specific)."""
    return [SingleWatcherChecker(settle_s), HandoverChecker(takeover_s, release_s, settle_s=settle_s), NoDropChecker(grace_s)]


def default_checkers(*, live: bool = False, handover: bool = False, liveness: bool = False) -> list[Checker]:
    """Checkers that hold for any planner: safety, dynamics, radio; with ``live`` also map
    monotonicity; with ``liveness`` (live only) map agreement and joiner catch-up; with
    ``handover`` the DACMP assignment invariants."""
    out: list[Checker] = [*safety_checkers(), RadioChecker()]
    if live:
        out.append(MapMonotonicityChecker())
        if liveness:
            out += [MapAgreementChecker(), JoinerCatchUpChecker()]
    if handover:
        out += handover_checkers()
    return out


def check_events(events: Iterable[event_schema.Event | Sequence[Any]] | bytes, scenario: Scenario,
                 checkers: Iterable[Checker] | None = None, *, faults: Iterable[FaultKind] | None = None) -> list[Violation]:
    """Run ``checkers`` over a run's events: records (:func:`swarm.events.read_events`), arrays
    as the log holds them, or the event log's bytes as ``RunResult.events`` and
    ``events.msgpack`` hold them. Returns the violations (empty: all
    invariants held).

    By default, every checker a log can judge, with its default parameters:
    ``default_checkers(handover=True)``, that is ``separation``, ``threat``, ``dynamics``,
    ``radio``, ``single_watcher``, ``handover`` and ``no_drop``. (The live checkers,
    ``map_monotonic``, ``map_agreement`` and ``joiner_catch_up``, read the UAVs' maps and
    need :class:`Monitor` attached to a simulation.) The last three are the assignment
    invariants of the surveillance handover (DACMP's, which the built-in planners share); for
    a planner of your own that watches targets by other rules, pass
    ``checkers=default_checkers()``: the first four."""
    if isinstance(events, (bytes, bytearray, memoryview)):
        events = event_schema.read_events(bytes(events))
    checkers = list(checkers) if checkers is not None else default_checkers(handover=True)
    live = [c.name for c in checkers if c.live_only]
    if live:
        raise UsageError(f"checker(s) {live} need a live simulation; use Monitor(...).attach(sim)")
    monitor = Monitor(checkers, scenario, faults=faults)
    for ev in events:
        monitor.feed(ev)
    return monitor.finish()


def load_run_log(out_dir: str | Path, *, allow_planner_imports: bool | Iterable[str] = False
                 ) -> tuple[Scenario, list[event_schema.Event]]:
    """The validated scenario (``scenario.json``) and the events (``events.msgpack``) of a
    ``swarm run --out`` folder (read by :func:`swarm.outputs.read_run_dir`). A run folder is data:
    a ``module:Class`` planner in its ``scenario.json`` is refused unless allowed here
    (``True``, or its name; :mod:`swarm.scenario.trust`)."""
    run = read_run_dir(out_dir)
    scenario = parse_scenario(run.scenario, str(run.path / "scenario.json"), truncated=True,  # may be cut short
                              allow_planner_imports=allow_planner_imports)
    return scenario, list(event_schema.read_events(run.events))
