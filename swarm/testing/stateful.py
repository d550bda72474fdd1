"""A Hypothesis state machine that drives one simulation and checks invariants every step.

:class:`SwarmMachine` draws a small scenario (:func:`swarm.testing.strategies.scenarios`), builds a
:class:`~swarm.kernel.simulation.Simulation` and drives it synchronously. Its rules advance time, crash
UAVs, add late joiners, cut and heal partitions, change the loss on every link and add targets
(all through the public API: ``step``, ``add_fault``, ``add_uav``, ``add_target``). After every
rule its ``@invariant`` feeds the new events to a :class:`swarm.testing.invariants.Monitor` and fails
with an :class:`~swarm.testing.invariants.InvariantViolation` naming what broke, when and who; the
failure notes a scenario file and the ``swarm run`` command that replays the run.

Use it as it is::

    from swarm.testing.stateful import SwarmMachine
    TestSwarm = SwarmMachine.TestCase

or subclass it to add rules, invariants or checkers::

    from hypothesis.stateful import invariant, rule
    from swarm.testing.stateful import SwarmMachine

    class MyMachine(SwarmMachine):
        checkers = SwarmMachine.checkers + ("single_watcher",)

        @rule()
        def heal_everything(self):
            self.cuts.clear()

        @invariant()
        def coverage_never_drops(self):
            ...

    TestMine = MyMachine.TestCase

Partitions and loss are applied as fault windows covering each ``advance`` (a cut stays in
force, window after window, until a ``heal`` rule removes it), so everything that happened is
in the simulation's fault schedule and can be written to a scenario file. The node faults of
issue 16 are added at run time, each with its own finite window: ``pause`` (a window),
``restart`` (a downtime), ``clock_skew`` (an offset and a drift for a window) and ``liar`` (fake
scans and tracks for a window).

Liveness mode (``liveness = True``, the default): at the end of every example (in
:meth:`SwarmMachine.teardown`, unless the example already failed) the machine heals every cut,
ends the loss, lets every windowed fault end, then runs a quiet period and checks that the maps
of connected live UAVs agree and that targets whose watcher a node fault took are watched again,
within bounds stated from the settings (:mod:`swarm.testing.liveness`). The scenario runs
``liveness_room_s`` longer than ``max_time_s`` to leave room for it.

Needs ``hypothesis`` (the ``test`` extra).
"""

from __future__ import annotations

import swarm.testing._hypothesis  # noqa: F401  (first: a clear error without Hypothesis)

# isort: split

import math
import sys
from collections.abc import Callable
from typing import Any, ClassVar

from hypothesis import note
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, precondition, rule

from faults.schedule import ClockSkew, Crash, Drop, Fault, Join, Liar, Partition, Pause, Restart
from swarm.kernel.simulation import Simulation
from swarm.scenario import Scenario, parse_scenario
from swarm.testing.invariants import (
    Checker,
    DynamicsChecker,
    HandoverChecker,
    InvariantViolation,
    JoinerCatchUpChecker,
    MapAgreementChecker,
    MapMonotonicityChecker,
    Monitor,
    NoDropChecker,
    RadioChecker,
    SeparationChecker,
    SingleWatcherChecker,
    ThreatClearanceChecker,
)
from swarm.testing.liveness import LivenessReport, RecoveryWatch, quiesce
from swarm.testing.strategies import _fault_doc, reproduction, scenarios

__all__ = ["CHECKERS", "SwarmMachine"]

#: Checker factories by name (see :mod:`swarm.testing.invariants` for what each checks).
CHECKERS: dict[str, Callable[[], Checker]] = {
    "separation": SeparationChecker,
    "threat": ThreatClearanceChecker,
    "dynamics": DynamicsChecker,
    "radio": RadioChecker,
    "map_monotonic": MapMonotonicityChecker,
    "map_agreement": MapAgreementChecker,
    "joiner_catch_up": JoinerCatchUpChecker,
    "single_watcher": SingleWatcherChecker,
    "handover": HandoverChecker,
    "no_drop": NoDropChecker,
}


class SwarmMachine(RuleBasedStateMachine):
    """Drives one simulation; see the module docstring. Class attributes to override:

    * ``checkers``: names from :data:`CHECKERS` checked after every rule (default: those that
      the current simulator keeps under any planner and any fault: threat clearance, dynamic
      limits, radio legality, map monotonicity, and, thanks to anti-entropy, map agreement once
      quiet and late-joiner catch-up);
    * ``max_time_s``: no ``advance`` past this simulated time (keeps examples cheap);
    * ``max_uavs``: no ``join`` beyond this many UAVs;
    * ``max_steps_per_advance``: ticks one ``advance`` may take;
    * :meth:`scenario_strategy`: the scenarios to start from;
    * :meth:`on_start`: called once the simulation exists (e.g. to plant a bug, or to swap a
      UAV's planner);
    * :meth:`make_checkers`: to build checkers with other parameters than their defaults.

    Separation is not checked by default: UAVs learn of each other only over the radio, so
    with frames cut (partitions, loss) the current simulator does let them collide; add
    ``"separation"`` to ``checkers`` to see it.
    """

    checkers: ClassVar[tuple[str, ...]] = ("threat", "dynamics", "radio", "map_monotonic", "map_agreement",
                                           "joiner_catch_up")
    max_time_s: ClassVar[float] = 90.0
    max_uavs: ClassVar[int] = 6
    max_steps_per_advance: ClassVar[int] = 30
    #: A joiner enters at least this far from threat edges and from other flying UAVs (as the
    #: scenario strategies place UAVs): appearing in front of someone is the scenario's doing,
    #: not the planner's.
    threat_clearance_m: ClassVar[float] = 3000.0
    uav_clearance_m: ClassVar[float] = 2000.0
    #: End each example with the liveness phase (see the module docstring).
    liveness: ClassVar[bool] = True
    #: The longest window (s) a pause, restart, clock_skew or liar rule gives its fault.
    max_fault_s: ClassVar[int] = 20
    #: Simulated time after ``max_time_s`` for the faults to end and the quiet period.
    liveness_room_s: ClassVar[float] = 150.0

    def __init__(self) -> None:
        super().__init__()
        self.sim: Simulation | None = None
        self.monitor: Monitor | None = None
        self.scenario: Scenario | None = None
        self.cuts: list[tuple[tuple[tuple[str, ...], ...], bool]] = []  # (groups, one_way) in force
        self.loss = 0.0
        self.joiners: list[dict] = []
        self.late_targets: list[str] = []
        self.history: list[str] = []
        self.faults_end_s = 0.0  # when the last fault a rule added ends
        self.watch: RecoveryWatch | None = None
        self.liveness_report: LivenessReport | None = None

    # --- what to start from and what to check ---------------------------------------------

    def scenario_strategy(self) -> st.SearchStrategy[Scenario]:
        """Small scenarios without scheduled faults (the rules add them), 2-4 UAVs; with
        liveness, half on a radio that loses nothing by itself (where map agreement has a bound)."""
        d = int(self.max_time_s + (self.liveness_room_s if self.liveness else 0))
        return st.booleans().flatmap(lambda lossless: scenarios(
            min_uavs=2, max_uavs=4, faults=False, late_joiners=False, min_duration_s=d, max_duration_s=d,
            area_km=(5, 10), lossy_radio=not (lossless and self.liveness)))

    def make_checkers(self) -> list[Checker]:
        unknown = [n for n in self.checkers if n not in CHECKERS]
        if unknown:
            raise ValueError(f"unknown checker(s) {unknown}; known: {', '.join(CHECKERS)}")
        return [CHECKERS[n]() for n in self.checkers]

    # --- helpers -------------------------------------------------------------------------------

    @property
    def now(self) -> float:
        return self.sim.now if self.sim is not None else 0.0

    def alive(self) -> list[str]:
        if self.sim is None:
            return []
        return [b.name for _, b in sorted(self.sim._world.uavs.items()) if b.state == "alive"]

    def flying_or_pending(self) -> list[str]:
        if self.sim is None:
            return []
        return [b.name for _, b in sorted(self.sim._world.uavs.items()) if b.state != "crashed"]

    def _clear(self, x: float, y: float) -> bool:
        assert self.scenario is not None and self.sim is not None  # (started: rules run after start)
        far_from_threats = all(math.hypot(x - th.x_m, y - th.y_m) >= th.radius_m + self.threat_clearance_m
                               for th in self.scenario.threats)
        far_from_uavs = all(math.hypot(x - b.x, y - b.y) >= self.uav_clearance_m
                            for b in self.sim._world.uavs.values() if b.state != "crashed")
        return far_from_threats and far_from_uavs

    def reproduction_scenario(self) -> Scenario:
        """The run so far as a scenario: the start scenario plus every fault and joiner added
        (targets added while running cannot be written in a scenario; they are listed in the
        file's comment). Its duration is the time reached."""
        assert self.scenario is not None and self.sim is not None  # (started: a failure comes after start)
        doc = self.scenario.model_dump(mode="python")
        doc["uavs"] = list(doc["uavs"]) + self.joiners
        doc["faults"] = [_fault_doc(f) for f in self.sim.injector.schedule.faults if not isinstance(f, Join)]
        doc["duration_s"] = max(self.now, self.scenario.dt_s)
        return parse_scenario(doc, "<state machine>")

    def _explain(self) -> str:
        sc = self.reproduction_scenario()
        comment = "Written by swarm.testing.stateful.SwarmMachine: the run that failed.\nSteps:\n" + "\n".join(
            f"  {h}" for h in self.history)
        if self.late_targets:
            comment += "\nTargets added while running (not in this file): " + "; ".join(self.late_targets)
        path, command = reproduction(sc, comment=comment)
        return f"replay: {command}  (scenario written to {path})"

    # --- rules -------------------------------------------------------------------------------

    @initialize(data=st.data())
    def start(self, data: Any) -> None:
        self.scenario = data.draw(self.scenario_strategy(), label="scenario")
        self.sim = Simulation(self.scenario)
        self.monitor = Monitor(self.make_checkers()).attach(self.sim)
        self.watch = RecoveryWatch(self.sim)
        self.history.append(f"start: {len(self.scenario.uavs)} UAVs, seed {self.scenario.seed}")
        self.on_start()

    def add_fault(self, fault: Fault, until_s: float) -> None:
        """Add ``fault`` to the run, over by ``until_s`` (the liveness phase waits for it)."""
        assert self.sim is not None and self.watch is not None  # (rules run after start)
        self.sim.add_fault(fault)
        self.watch.fault(fault)
        self.faults_end_s = max(self.faults_end_s, until_s)

    def _step(self, ticks: int) -> None:
        assert self.sim is not None and self.monitor is not None and self.watch is not None
        for _ in range(ticks):
            self.sim.step(1)
            self.watch.observe()
        self.monitor.flush()

    def on_start(self) -> None:
        """Hook for subclasses, called once the simulation exists (override this rather than
        :meth:`start`: a method that replaces a decorated rule is no longer a rule)."""

    @precondition(lambda self: self.sim is not None and self.now < self.max_time_s)
    @rule(ticks=st.integers(1, 10))
    def advance(self, ticks: int) -> None:
        sim = self.sim
        assert sim is not None and self.monitor is not None  # (started: see the precondition)
        ticks = max(1, min(ticks, self.max_steps_per_advance, int(round((self.max_time_s - sim.now) / sim.dt)) or 1))
        t0, t1 = sim.now, sim.now + ticks * sim.dt
        for groups, one_way in self.cuts:
            sim.add_fault(Partition(groups=groups, start_s=t0, end_s=t1, one_way=one_way))
        if self.loss > 0:
            sim.add_fault(Drop(rate=self.loss, start_s=t0, end_s=t1))
        self._step(ticks)
        self.history.append(f"t={t0:g}: advance {ticks} tick(s)")

    @precondition(lambda self: self.sim is not None and self.now < self.max_time_s)
    @rule(ticks=st.integers(10, 30))
    def advance_long(self, ticks: int) -> None:
        """A longer stretch with nothing new happening (lets liveness checks see quiet periods)."""
        self.advance(ticks)

    @precondition(lambda self: len(self.alive()) >= 1)
    @rule(data=st.data())
    def crash(self, data: Any) -> None:
        name = data.draw(st.sampled_from(self.alive()), label="crash")
        self.add_fault(Crash(uav=name, at_s=self.now), self.now)
        self.history.append(f"t={self.now:g}: crash {name}")

    def _window(self, data: Any, label: str) -> tuple[float, float]:
        assert self.sim is not None
        ticks = data.draw(st.integers(1, max(1, int(self.max_fault_s / self.sim.dt))), label=label)
        return self.now, self.now + ticks * self.sim.dt

    @precondition(lambda self: len(self.alive()) >= 1)
    @rule(data=st.data())
    def pause(self, data: Any) -> None:
        """A process pause: the actor sleeps for a window, its airframe flies on."""
        name = data.draw(st.sampled_from(self.alive()), label="pause")
        start, end = self._window(data, "pause_ticks")
        self.add_fault(Pause(uav=name, start_s=start, end_s=end), end)
        self.history.append(f"t={start:g}: pause {name} until {end:g}")

    @precondition(lambda self: len(self.alive()) >= 1)
    @rule(data=st.data())
    def restart(self, data: Any) -> None:
        """A crash now and a rejoin with an empty memory after a downtime."""
        name = data.draw(st.sampled_from(self.alive()), label="restart")
        at, back = self._window(data, "downtime_ticks")
        self.add_fault(Restart(uav=name, at_s=at, downtime_s=back - at), back + (self.sim.dt if self.sim else 0.0))
        self.history.append(f"t={at:g}: restart {name}, back at {back:g}")

    @precondition(lambda self: len(self.alive()) >= 1)
    @rule(data=st.data(), offset=st.sampled_from([5.0, -5.0, 1.0, -1.0, 10.0, -10.0, 0.0]),
          drift=st.sampled_from([0.0, 0.1, -0.1, 0.5, -0.5]))
    def clock_skew(self, data: Any, offset: float, drift: float) -> None:
        """A clock off by ``offset`` s and drifting ``drift`` s per s, for a window."""
        name = data.draw(st.sampled_from(self.alive()), label="clock_skew")
        start, end = self._window(data, "skew_ticks")
        if offset == 0.0 and drift == 0.0:
            offset = 1.0  # never an inert fault
        self.add_fault(ClockSkew(uav=name, start_s=start, end_s=end, offset_s=offset, drift=drift), end)
        self.history.append(f"t={start:g}: clock of {name} off by {offset:g} s, drift {drift:g}, until {end:g}")

    @precondition(lambda self: len(self.alive()) >= 1)
    @rule(data=st.data(), scans=st.sampled_from([1.0, 5.0, 0.0]), tracks=st.sampled_from([0.0, 1.0]))
    def liar(self, data: Any, scans: float, tracks: float) -> None:
        """A Byzantine member sends fake scans and/or fake tracks for a window."""
        name = data.draw(st.sampled_from(self.alive()), label="liar")
        start, end = self._window(data, "liar_ticks")
        if scans == 0.0 and tracks == 0.0:
            scans = 1.0
        self.add_fault(Liar(uav=name, start_s=start, end_s=end, scans_per_s=scans, tracks_per_s=tracks), end)
        self.history.append(f"t={start:g}: {name} lies ({scans:g} scans/s, {tracks:g} tracks/s) until {end:g}")

    @precondition(lambda self: self.sim is not None and len(self.sim._world.uavs) < self.max_uavs)
    @rule(data=st.data())
    def join(self, data: Any) -> None:
        sc = self.scenario
        assert sc is not None and self.sim is not None  # (started: see the precondition)
        kind = data.draw(st.sampled_from(sorted(sc.uav_types)), label="type")
        x = data.draw(st.integers(0, int(sc.area.width_m) // 100), label="x_hm") * 100.0
        y = data.draw(st.integers(0, int(sc.area.height_m) // 100), label="y_hm") * 100.0
        heading = data.draw(st.integers(0, 23), label="heading_15deg") * 15.0
        if not self._clear(x, y):
            self.history.append(f"t={self.now:g}: join skipped (too close to a threat or a UAV)")
            return
        name = self.sim.add_uav(type=kind, x=x, y=y, heading_deg=heading)
        self.joiners.append({"name": name, "type": kind, "x_m": x, "y_m": y, "heading_deg": heading,
                             "join_s": self.now})
        self.history.append(f"t={self.now:g}: join {name} ({kind}) at ({x:g}, {y:g})")

    @precondition(lambda self: len(self.flying_or_pending()) >= 2)
    @rule(data=st.data(), one_way=st.booleans())
    def cut(self, data: Any, one_way: bool) -> None:
        names = self.flying_or_pending()
        side = data.draw(st.lists(st.booleans(), min_size=len(names), max_size=len(names)), label="sides")
        a = tuple(n for n, s in zip(names, side) if s)
        b = tuple(n for n, s in zip(names, side) if not s)
        if not a or not b:
            a, b = (names[0],), tuple(names[1:])
        self.cuts.append(((a, b), one_way))
        self.history.append(f"t={self.now:g}: cut {list(a)} | {list(b)}{' one way' if one_way else ''}")

    @precondition(lambda self: bool(self.cuts))
    @rule()
    def heal(self) -> None:
        groups, _ = self.cuts.pop(0)
        self.history.append(f"t={self.now:g}: heal {[list(g) for g in groups]}")

    @precondition(lambda self: self.sim is not None)
    @rule(rate=st.sampled_from([0.0, 1.0, 0.5, 0.2, 0.8]))
    def change_loss(self, rate: float) -> None:
        self.loss = rate
        self.history.append(f"t={self.now:g}: loss {rate:g} on every link")

    @precondition(lambda self: self.sim is not None)
    @rule(data=st.data())
    def add_target(self, data: Any) -> None:
        sc = self.scenario
        assert sc is not None and self.sim is not None  # (started: see the precondition)
        x = data.draw(st.integers(0, int(sc.area.width_m) // 100), label="x_hm") * 100.0
        y = data.draw(st.integers(0, int(sc.area.height_m) // 100), label="y_hm") * 100.0
        heading = data.draw(st.integers(0, 23), label="heading_15deg") * 15.0
        speed = float(data.draw(st.integers(0, int(sc.targets.speed_max)), label="speed"))
        tid = self.sim.add_target(x, y, heading_deg=heading, speed=speed)
        self.late_targets.append(f"t={self.now:g} id={tid} ({x:g}, {y:g}) heading {heading:g} speed {speed:g}")
        self.history.append(f"t={self.now:g}: target {tid} at ({x:g}, {y:g})")

    # --- invariants -----------------------------------------------------------------------------

    @invariant()
    def invariants_hold(self) -> None:
        if self.monitor is None:
            return
        self.monitor.flush()
        violations = self.monitor.violations
        if violations:
            err = InvariantViolation(violations)
            explanation = self._explain()
            note(explanation)
            err.add_note(explanation)
            raise err

    def check_liveness(self) -> LivenessReport:
        """The liveness phase: heal every cut, end the loss, let the faults end, run the quiet
        period and judge (:func:`swarm.testing.liveness.quiesce`); raises
        :class:`InvariantViolation` (with the replay note) if the swarm did not recover. The
        safety invariants stay checked all along."""
        assert self.sim is not None and self.monitor is not None
        if self.cuts or self.loss:
            self.history.append(f"t={self.now:g}: liveness: heal every cut, no loss")
        self.cuts.clear()
        self.loss = 0.0
        t0 = self.now

        def step(n: int) -> None:
            self._step(n)
            self.invariants_hold()

        report = quiesce(self.sim, faults_end_s=self.faults_end_s, watch=self.watch, step=step)
        self.liveness_report = report
        self.history.append(f"t={t0:g}: liveness: faults over at {report.t0:g} s, quiet {report.quiet_s:g} s; "
                            f"judged {report.judged}; not judged {report.not_judged}")
        if report.violations:
            err = InvariantViolation(report.violations)
            explanation = self._explain()
            note(explanation)
            err.add_note(explanation)
            raise err
        return report

    def teardown(self) -> None:
        try:
            # Only after an example that passed: a failure in flight must not be replaced.
            if self.liveness and self.sim is not None and sys.exc_info()[0] is None:
                self.check_liveness()
        finally:
            if self.monitor is not None:
                self.monitor.detach()
            if self.sim is not None:
                self.sim.close()
