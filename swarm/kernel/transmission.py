"""The tick's transmit phase, and the deliveries it puts on the clock.

Topology from this tick's positions; then the frames of faults that transmit (spoofers: ahead
of the members', so a forged scan wins over the real one of that origin and tick, if auth lets
it in); then every live UAV's frames in UAV-id order through the links and the fault injector;
arrivals are scheduled on the clock in batches by arrival time. A copy that arrives for a UAV
that is down, or finds its mailbox full, is lost (counted by cause).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Mapping
from functools import partial

import numpy as np

from agents.actor import ActorOutput, UavActor
from comms.radio import Delivery, Radio
from swarm.kernel.clock import DELIVERY, Clock
from swarm.kernel.world import ALIVE, World

# A lost copy, reported as (t, sender, receiver, bytes, cause).
Lost = Callable[[float, int, int, int, str], None]


class Transmission:
    """Frames from senders to mailboxes: what is on the way, and what was lost."""

    def __init__(self, radio: Radio, clock: Clock, world: World, actors: Mapping[int, UavActor], lost: Lost):
        self.radio = radio
        self.clock = clock
        self.world = world
        self.actors = actors
        self._lost = lost
        self.in_flight = 0  # copies scheduled on the clock, not yet delivered

    def lose(self, t: float, src: int, dst: int, nbytes: int, cause: str) -> None:
        """A copy lost after the radio let it through (its receiver went down, or is full)."""
        self.radio.counters.drop(cause)
        self._lost(t, src, dst, nbytes, cause)

    def transmit(self, t: float, dt: float, alive: list[int], xy: np.ndarray, outputs: Mapping[int, ActorOutput],
                 first: list[Delivery]) -> None:
        """Send this tick's frames: ``first`` (the faults' own, already addressed), then every
        live UAV's, in id order, through the radio's links."""
        self.radio.update_topology(alive, xy, dt)
        deliveries = first
        record_lost = self._lost

        def lost(src: int, dst: int, nbytes: int, cause: str) -> None:
            record_lost(t, src, dst, nbytes, cause)

        broadcast = self.radio.broadcast
        for uid in alive:
            out = outputs[uid]
            for frame in out.frames:
                broadcast(t, uid, frame, deliveries, lost)
            for dst, frame in out.replies:  # anti-entropy answers, to one neighbour each
                broadcast(t, uid, frame, deliveries, lost, to=dst)
        by_time: dict[float, list[Delivery]] = defaultdict(list)
        arrivals = {d[0] for d in deliveries}
        if len(arrivals) == 1:
            by_time[arrivals.pop()] = deliveries  # one arrival time (no jitter or delay): one batch
        else:
            for d in deliveries:
                by_time[d[0]].append(d)
        for at in sorted(by_time):
            batch = by_time[at]
            self.in_flight += len(batch)
            self.clock.schedule(at, partial(self._deliver, batch), DELIVERY)

    def _deliver(self, batch: list[Delivery]) -> None:
        uavs = self.world.uavs
        actors = self.actors
        now = self.clock.now
        self.in_flight -= len(batch)
        for arrival_t, sender, receiver, data in batch:
            if uavs[receiver].state != ALIVE:
                self.lose(now, sender, receiver, len(data), "receiver_down")
            elif not actors[receiver].mailbox.put(arrival_t, sender, data):
                self.lose(now, sender, receiver, len(data), "mailbox_full")
