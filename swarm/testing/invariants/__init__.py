"""Invariants of a run, as a library: check a finished run's event log, or a simulation live.

Each invariant is a *checker*: an object fed the run's events in order (the records of
:mod:`swarm.events`) that collects :class:`Violation` records saying what went
wrong, when, and which UAVs / target. A :class:`Monitor` feeds several checkers at once, from a
log or live from ``sim.subscribe``::

    # after the run: `swarm run my.toml --out out/` wrote scenario.json and events.msgpack
    from swarm.testing.invariants import check_events, load_run_log
    scenario, events = load_run_log("out/")
    for v in check_events(events, scenario):   # the seven checkers a log can judge
        print(v)

    # live, e.g. in a test or a Hypothesis state machine
    from swarm.testing.invariants import Monitor, default_checkers
    monitor = Monitor(default_checkers(live=True)).attach(sim)
    sim.step(10)
    monitor.flush()
    monitor.raise_if()            # InvariantViolation listing every violation so far

What the events alone cannot tell (radio range, threats, UAV type limits, the fault schedule)
comes from the :class:`~swarm.scenario.Scenario`. Faults added while a run goes
(``sim.add_fault``) are not in the event log: give them as ``faults=`` when checking a log, or
check live (the monitor then reads the simulation's own schedule). Checkers marked *live* also
read each UAV's map through ``sim.uav_map(name)`` and only work attached to a simulation.

The invariants (``name``: class, parameters and their defaults):

* ``separation`` / ``threat``: :class:`SeparationChecker`, :class:`ThreatClearanceChecker`:
  the planner's own moves never bring two UAVs closer than ``safety.min_separation_m`` or a
  UAV inside a threat circle. A pair (or UAV) already in violation when it first appears (a
  start or join position) is excused until it has cleared once: that is the scenario's doing.
* ``dynamics``: :class:`DynamicsChecker`: consecutive poses of a UAV respect its type's limits
  (speed range, ``|a| <= accel_max``, turn radius) and the kinematics (no jumps). It judges the
  bodies the simulator flies: a body a host drives (between its ``take_control`` and
  ``release_control`` ``host`` events) is not judged, and the checker's ``note`` (the
  monitor's ``notes``) names it.
* ``radio``: :class:`RadioChecker`: every ``rx`` has a legal send tick: sender and receiver both
  flying, within range, not separated by an active partition or bridge (its bridge UAV talks
  to every side), neither clogged by a swizzle; and the receiver is flying when it reads the
  frame. A frame from sender -1 (a spoofer's) is legal only within an active spoofer's
  ``range_m``. A jammer's losses are losses: nothing to check on an ``rx``. Send ticks
  considered: ``dt`` plus up to the largest possible delay (radio latency + jitter + every
  delay fault) before the ``rx``. It needs the per-frame events of ``[recording] level =
  "frames"``; on a ``"summary"`` log it checks nothing and says so in its ``unchecked`` (and
  :attr:`Monitor.unchecked`).
* ``map_monotonic`` (live): :class:`MapMonotonicityChecker`: no cell's last-seen time ever
  decreases in any UAV's map.
* ``map_agreement`` (live, liveness): :class:`MapAgreementChecker(quiet_s=20, lag_s=10)`: once the
  swarm has been connected, with no active link fault or partition and no crash or join, for
  ``quiet_s``, every live UAV knows every cell any live UAV knew ``lag_s`` earlier. With a
  knowledge horizon ``H`` (``radio.sync_horizon_m`` finite) "agree" is local: every live UAV
  knows every cell a UAV it can talk to knew ``lag_s`` earlier, among the cells within
  ``H - slack`` of both (``slack``: the largest detection radius plus the farthest a UAV flies
  in ``lag_s``, so the scans of those cells were inside both horizons all along).
* ``joiner_catch_up`` (live, liveness): :class:`JoinerCatchUpChecker(bound_s=20)`: within
  ``bound_s`` of joining, a late joiner knows everything its radio neighbours knew when it
  joined (judged only while it can talk to one of them with no link fault active); with a
  knowledge horizon, those of them within ``H - slack`` of the joiner (as for ``map_agreement``).
* ``single_watcher``, ``handover``, ``no_drop``: the assignment rules, stated once in
  docs/modelling.md ("Assignment rules"), rules 1 (:class:`SingleWatcherChecker(settle_s=30)`:
  exclusion), 2-4 (:class:`HandoverChecker(takeover_s=60, release_s=60)`: takeover, release,
  after release) and 5 (:class:`NoDropChecker(grace_s=10)`: no drop; a lost target is no
  drop). They judge only the types and pairs whose weights meet the rules' preconditions
  (:mod:`agents.assignment`, paper eq. 25-27; :meth:`RunContext.exclusion_judged`,
  :meth:`RunContext.handover_judged`).

"Can talk" means: both flying, within radio range, no active partition or bridge between them
(either way), neither clogged by a swizzle, and neither inside an active jammer of rate 1.
Times are simulated seconds; UAVs are named by their scenario names.

Node faults (docs/scenarios.md, "Node and sensing faults"): a ``restart`` is a crash then a
rejoin (the UAV is not flying in between, and ``radio`` judges it so); its new map may be
emptier than the old (``map_monotonic`` starts over with a new actor) and must catch up like
a joiner's (``joiner_catch_up``). A UAV resuming from a ``pause`` reads frames its mailbox held
since the pause began (``radio`` accepts send ticks back to then). ``map_agreement`` is not
judged while a pause lasts or a clock skew's lead does (:meth:`RunContext.node_faults_disturb`),
``joiner_catch_up``'s obligation lapses then. The checkers of the planner's behaviour excuse a
UAV under a node fault (:meth:`RunContext.impaired`): ``separation`` and ``threat`` a paused
one, one with a skewed clock or a navigation error, while the fault acts and for
``RECOVER_S`` (30 s) after; ``single_watcher``, ``handover`` and ``no_drop`` those and one
under a ``sensor`` fault, while it acts. A phantom target (id >= ``PHANTOM_TARGET_ID``: a false
alarm's or a liar's) is never judged.

Why these defaults: the planners replan every 10 s (``planner.replan_s``), so a settled
assignment may take a few replans (settle 30 s; takeover and release 60 s; a target may go
unwatched for one replan, 10 s). Maps: a neighbour's scans arrive with its next beacon (1 s);
everything else (lost, from beyond one hop, from before a heal or a join) comes back through
anti-entropy (:mod:`agents.maps.scanlog`): a digest every ``radio.sync_every_s`` (5 s) covering scans
up to ``radio.sync_settle_s`` (2 s) old, answered the next tick. A scan can therefore reach a UAV
two hops away up to about 5 + 2 + 1 s late: ``lag_s = 10``; 20 s of quiet lets that settle. Each
further hop is one more round: ``map_agreement`` allows :meth:`RunContext.relay_lag_s` of the
radio graph's diameter when that is more (and waits that much longer).

Known breaks of the current simulator (pinned as xfails in ``tests/test_invariants.py``):
``separation`` whenever UAVs cannot hear each other (they learn of each other only over the
radio).
"""

from swarm.testing.invariants.assignment import HandoverChecker, NoDropChecker, SingleWatcherChecker
from swarm.testing.invariants.checker import Checker
from swarm.testing.invariants.context import RECOVER_S, InvariantViolation, RunContext, Violation, describe_fault, owed_map
from swarm.testing.invariants.maps import JoinerCatchUpChecker, MapAgreementChecker, MapMonotonicityChecker
from swarm.testing.invariants.monitor import (
    Monitor,
    check_events,
    default_checkers,
    handover_checkers,
    load_run_log,
    safety_checkers,
)
from swarm.testing.invariants.radio import RadioChecker
from swarm.testing.invariants.safety import DynamicsChecker, SeparationChecker, ThreatClearanceChecker

__all__ = [
    "RECOVER_S",
    "owed_map",
    "Checker",
    "DynamicsChecker",
    "HandoverChecker",
    "InvariantViolation",
    "JoinerCatchUpChecker",
    "MapAgreementChecker",
    "MapMonotonicityChecker",
    "Monitor",
    "NoDropChecker",
    "RadioChecker",
    "RunContext",
    "SeparationChecker",
    "SingleWatcherChecker",
    "ThreatClearanceChecker",
    "Violation",
    "check_events",
    "default_checkers",
    "describe_fault",
    "handover_checkers",
    "load_run_log",
    "safety_checkers",
]

