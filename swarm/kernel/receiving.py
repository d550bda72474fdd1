"""The receive service (issue 36, T4): every live actor's inbox merged at once, at the start of
the wake phase, in UAV-id order.

Without the tick plane each actor drains and merges its own mailbox as the first thing of its
step (:meth:`agents.actor.UavActor.observe`). With it, :meth:`Receiving.receive` does that for
every actor about to be woken (live, not paused) just before they are woken, and their steps
skip it (:attr:`UavActor.served`): nothing happens between the two (the frames of this tick were
delivered before it began, sensing is done), and a receiver's merge reads only its own state,
its own reading (where it is, its clock) and the frames delivered to it, so each actor ends up
with exactly the state its own step would have given it. What the service shares between
receivers is what is the same for all of them: a frame delivered to k receivers is looked up in
the decode cache (checked, if no receiver checked it yet) and its messages flattened into the
tuples a receiver copies once, not k times (the per-tick memo of :meth:`agents.inbox.Inbox.take`).
What is left per (receiver, frame) is what depends on the receiver: its horizon, its scan log,
its map, its peers and tracks.

Maps shared in a :class:`~agents.maps.mapgroup.MapGroup` see their stamps in another order (every
heard scan before the tick's own scans, instead of actor by actor); a group only shares storage,
so the cells, which are the max of the same disks, are the same (``tests/test_tick_plane.py``
compares them tick by tick against the per-actor path).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from agents.actor import UavActor
from agents.inbox import HeardMemo
from agents.inputs import SensorReading
from swarm.errors import SimulationError

__all__ = ["Receiving"]


class Receiving:
    """Merges the inboxes of the actors it is given (:meth:`receive`)."""

    __slots__ = ("actors",)

    def __init__(self, actors: Mapping[int, UavActor]):
        """``actors``: the run's actors by UAV id (the fleet's, filled as UAVs are added)."""
        self.actors = actors

    def receive(self, uids: Iterable[int], readings: Mapping[int, SensorReading]) -> None:
        """Merge the mailbox of each actor of ``uids`` (in that order: UAV ids ascending) with
        its reading of this tick, sharing one memo of the frames heard."""
        memo: HeardMemo = {}
        actors = self.actors
        for uid in uids:
            actor = actors[uid]
            try:
                actor.receive(readings[uid], memo)
            except Exception as exc:  # as the actor's own step would report it (swarm.kernel.fleet)
                raise SimulationError(f"UAV {actor.name} raised {type(exc).__name__}: {exc}") from exc
