"""Where a run's CPU time goes, by component of the tick (``swarm bench --components``).

Nine components, each the code that does one part of a UAV-tick's work (the list issue 36 and
the tick-plane study attribute every change to):

* ``receive``: frames into a UAV: the mailboxes filled (``Transmission._deliver``,
  ``_deliver_batch``, ``Mailbox``), the drain loop (the receive service,
  ``swarm.kernel.receiving`` and ``agents.inbox.Inbox.take``, or each actor's
  ``Inbox.merge`` without the tick plane), decoding and checking frames, the scan log's adds,
  heard scans stamped into the UAV's map, track merges;
* ``outbox``: the frames a UAV sends, built and encoded (``UavActor._outbox``, ``_frame``, a
  liar's fabrications: ``faults.adversary.Lies``);
* ``anti_entropy``: digests built (``ScanLog.digest``, ``forget_before``) and answered
  (``agents.antientropy``, ``ScanLog.missing``);
* ``geometry``: a UAV's own scan and sightings (``UavActor.observe`` apart from its drain,
  ``claim_scan``) and the tick's disks built together (``Grid.prefetch_disks``);
* ``radio``: topology and per-link decisions (``comms.radio``), the transmit phase around them and
  the fault injector (``swarm.kernel.faulting``, ``faults``);
* ``observer``: the ground truth stamped and sampled, the metrics, events, paths and the event log
  (``swarm.kernel.observer``, ``metrics``, ``recorder``, ``results``, the safety check,
  ``Simulation._end_tick``);
* ``world``: sensing, detect-and-avoid, physics, targets, the mission phase (``swarm.kernel.world``,
  ``Simulation._sense``, ``_integrate``, ``mission``, ``homeway``);
* ``actors``: the rest of an actor's step (APF, peers, the task loop), waking the actors and
  collecting their outputs (``swarm.kernel.fleet``), the tick's own code and the asyncio event
  loop;
* ``planning``: anything under ``agents/planners`` (a plan, batched or not, with the map reads it
  makes) and the fleet's plan batching.

A sample is filed by its Python stack: a planner frame anywhere on it makes it ``planning``;
otherwise the innermost frame that a rule below names decides (so a map stamp is ``receive``
inside the drain, ``geometry`` inside ``observe`` and ``observer`` for the ground truth, and the
digest built inside the outbox is ``anti_entropy``); a stack no rule names is ``actors`` (the event
loop's own frames). Rules name modules by their ``__file__`` and functions by name: a function
renamed or added falls to its module's default, never out of the table.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from types import CodeType, FrameType, ModuleType
from typing import Any

import agents.actor
import agents.antientropy
import agents.apf
import agents.inbox
import agents.knowledge
import agents.maps.grid
import agents.maps.scanlog
import agents.planners
import comms.mailbox
import comms.radio
import faults
import faults.adversary
import swarm.events
import swarm.kernel.faulting
import swarm.kernel.fleet
import swarm.kernel.homeway
import swarm.kernel.metrics
import swarm.kernel.mission
import swarm.kernel.mission_phase
import swarm.kernel.observer
import swarm.kernel.receiving
import swarm.kernel.recorder
import swarm.kernel.results
import swarm.kernel.simulation
import swarm.kernel.transmission
import swarm.kernel.world

COMPONENTS = ("receive", "outbox", "anti_entropy", "geometry", "radio", "observer", "world", "actors", "planning")

# module -> (component of its functions not named, or None: not decided here, look further out;
#            {function name: component})
_RULES: list[tuple[ModuleType, str | None, Mapping[str, str]]] = [
    (agents.actor, "actors", {"_outbox": "outbox", "_frame": "outbox", "observe": "geometry", "claim_scan": "geometry",
                              "receive": "receive"}),
    (agents.antientropy, "anti_entropy", {}),
    (agents.apf, "actors", {}),
    (agents.inbox, "receive", {}),
    (faults.adversary, "radio", {"observed": "outbox", "beacon": "outbox"}),
    (agents.knowledge, None, {"merge_tracks": "receive", "merge_track": "receive", "recent_peers": "actors"}),
    (agents.maps.scanlog, None, {"add": "receive", "add_tick": "receive", "merge": "receive",
                                 "forget_before": "anti_entropy", "window": "anti_entropy", "_cut": "anti_entropy",
                                 "digest": "anti_entropy", "missing": "anti_entropy",
                                 "_rows_window": "anti_entropy"}),
    (agents.maps.grid, None, {"prefetch_disks": "geometry", "_prefetch_stamps": "geometry"}),
    (comms.mailbox, "receive", {}),
    (comms.radio, "radio", {}),
    (swarm.kernel.transmission, "radio", {"_deliver": "receive", "_deliver_batch": "receive"}),
    (swarm.kernel.receiving, "receive", {}),
    (swarm.kernel.faulting, "radio", {}),
    (swarm.kernel.observer, "observer", {}),
    (swarm.kernel.metrics, "observer", {}),
    (swarm.kernel.recorder, "observer", {}),
    (swarm.kernel.results, "observer", {}),
    (swarm.events, "observer", {}),
    (swarm.kernel.world, "world", {"check_safety": "observer"}),
    (swarm.kernel.mission, "world", {}),
    (swarm.kernel.mission_phase, "world", {}),
    (swarm.kernel.homeway, "world", {}),
    (swarm.kernel.fleet, "actors", {"_plan_for": "planning", "_flush_plans_if_all_waiting": "planning"}),
    (swarm.kernel.simulation, None, {"_sense": "world", "_integrate": "world", "_end_tick": "observer"}),
]
_FILES: dict[str, tuple[str | None, Mapping[str, str]]] = {m.__file__: (d, f) for m, d, f in _RULES if m.__file__}
_FAULTS_DIR = str(Path(faults.__file__).parent) if faults.__file__ else "\0"
_PLANNER_DIR = str(Path(agents.planners.__file__).parent) if agents.planners.__file__ else "\0"
_PLANNING = "planning"


def _rule(code: CodeType) -> str | None:
    """The component a frame of ``code`` decides, or None (look further out)."""
    path = code.co_filename
    if path.startswith(_PLANNER_DIR):
        return _PLANNING
    rule = _FILES.get(path)
    if rule is None:
        return "radio" if path.startswith(_FAULTS_DIR) else None
    default, by_name = rule
    return by_name.get(code.co_name, default)


class Classifier:
    """Files a stack under a component; the rule of each code object is looked up once."""

    def __init__(self) -> None:
        self._memo: dict[CodeType, str | None] = {}

    def __call__(self, frame: FrameType | None) -> str:
        memo = self._memo
        found: str | None = None
        while frame is not None:
            code = frame.f_code
            try:
                c = memo[code]
            except KeyError:
                c = memo[code] = _rule(code)
            if c == _PLANNING:
                return c
            if found is None:
                found = c
            frame = frame.f_back
        return found or "actors"


def component_of(frame: FrameType | None) -> str:
    """The component a stack (innermost frame given) is in; see the module docstring."""
    return Classifier()(frame)


def table(rows: list[dict[str, Any]], key: str = "components_us_per_uav_tick") -> str:
    """The components of several bench lines side by side, as a Markdown table: us per UAV-tick
    and, in brackets, the share of the run."""
    head = "| component | " + " | ".join(r["case"] for r in rows) + " |"
    lines = [head, "|---|" + "---|" * len(rows)]
    for name in (*COMPONENTS, "total"):
        cells = []
        for r in rows:
            us = r[key]
            total = us["total"]
            cells.append(f"{us[name]:.1f}" if name == "total" else
                         f"{us[name]:.1f} ({100 * us[name] / total:.1f}%)" if total else "0")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)

