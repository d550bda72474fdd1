"""The tick's transmit phase, and the deliveries it puts on the clock.

Topology from this tick's positions; then the frames of faults that transmit (spoofers: ahead
of the members', so a forged scan wins over the real one of that origin and tick, if auth lets
it in); then every live UAV's frames in UAV-id order through the links and the fault injector;
arrivals are scheduled on the clock in batches by arrival time. A copy that arrives for a UAV
that is down, or finds its mailbox full, is lost (counted by cause).

With the tick plane (issue 36) the topology takes its pairs from the tick's one pair query
(:class:`swarm.pairs.TickPairs`, shared with detect-and-avoid and the safety check), and when
nothing can happen to a copy (:meth:`comms.radio.Radio.broadcast_all`) the tick's copies go out
and arrive as arrays, a :class:`~comms.radio.DeliveryBatch`: one clock entry, the mailboxes filled
receiver by receiver; otherwise copy by copy, as on the per-actor path. Either way the same
copies reach the same mailboxes in the same order, and the same losses are reported in the same
order.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Mapping
from functools import partial
from itertools import repeat
from operator import itemgetter

import numpy as np

from agents.actor import ActorOutput, UavActor
from comms.radio import Delivery, DeliveryBatch, Radio
from swarm.kernel.clock import DELIVERY, Clock
from swarm.kernel.world import ALIVE, World
from swarm.pairs import TickPairs

# Below this many copies, a batch is delivered copy by copy (the arrays' fixed cost is more).
_BATCH_MIN_COPIES = 48

# A lost copy, reported as (t, sender, receiver, bytes, cause).
Lost = Callable[[float, int, int, int, str], None]


class Transmission:
    """Frames from senders to mailboxes: what is on the way, and what was lost."""

    def __init__(self, radio: Radio, clock: Clock, world: World, actors: Mapping[int, UavActor], lost: Lost,
                 pairs: TickPairs | None = None):
        """``pairs``: the tick's shared pair query (the tick plane), or None (the radio finds its own)."""
        self.radio = radio
        self.clock = clock
        self.world = world
        self.actors = actors
        self._lost = lost
        self._pairs = pairs
        self.in_flight = 0  # copies scheduled on the clock, not yet delivered

    def lose(self, src: int, dst: int, nbytes: int, cause: str) -> None:
        """A copy lost now, after the radio let it through (its receiver went down, or is full)."""
        self.radio.counters.drop(cause)
        self._lost(self.clock.now, src, dst, nbytes, cause)

    def transmit(self, t: float, dt: float, alive: list[int], xy: np.ndarray, outputs: Mapping[int, ActorOutput],
                 first: list[Delivery]) -> None:
        """Send this tick's frames: ``first`` (the faults' own, already addressed), then every
        live UAV's, in id order, through the radio's links."""
        radio = self.radio
        pairs: tuple[np.ndarray, np.ndarray] | None = None
        if self._pairs is not None and radio.model.radius_m <= self._pairs.reach_m:
            # (a radio reaching further than the shared query, e.g. a model swapped in: its own pairs)
            pairs = self._pairs.of(alive, xy).within(radio.model.radius_m)[:2]
        radio.update_topology(alive, xy, dt, pairs)
        record_lost = self._lost

        def lost(src: int, dst: int, nbytes: int, cause: str) -> None:
            record_lost(t, src, dst, nbytes, cause)

        if radio.tick_plane and not first:
            outs = [outputs[uid] for uid in alive]
            frames: list[tuple[int, bytes, int | None]] = [
                (uid, frame, None) for uid, out in zip(alive, outs) for frame in out.frames]
            replies: list[tuple[int, bytes, int | None]] = [
                (uid, frame, dst) for uid, out in zip(alive, outs) for dst, frame in out.replies]
            if replies:  # each UAV's frames, then its answers (a stable sort by sender)
                frames = sorted(frames + replies, key=itemgetter(0))
            batch = radio.broadcast_all(t, frames, lost)
            if batch is not None:
                if len(batch):
                    self.in_flight += len(batch)
                    self.clock.schedule(batch.arrival_t, partial(self._deliver_batch, batch), DELIVERY)
                return
        deliveries = first
        broadcast = radio.broadcast
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
            batch_at = by_time[at]
            self.in_flight += len(batch_at)
            self.clock.schedule(at, partial(self._deliver, batch_at), DELIVERY)

    def _deliver(self, batch: list[Delivery]) -> None:
        uavs = self.world.uavs
        actors = self.actors
        self.in_flight -= len(batch)
        for arrival_t, sender, receiver, data in batch:
            if uavs[receiver].state != ALIVE:
                self.lose(sender, receiver, len(data), "receiver_down")
            elif not actors[receiver].mailbox.put(arrival_t, sender, data):
                self.lose(sender, receiver, len(data), "mailbox_full")

    def _deliver_batch(self, batch: DeliveryBatch) -> None:
        """:meth:`_deliver` of a batch's copies: each receiver's copies (in batch order) put into
        its mailbox at once; the copies lost (receiver down, mailbox full) reported in batch
        order, as copy by copy."""
        n = len(batch)
        if n < _BATCH_MIN_COPIES:  # (a few copies: one by one costs less than the arrays)
            self._deliver(batch.deliveries())
            return
        self.in_flight -= n
        uavs, actors = self.world.uavs, self.actors
        recv = batch.receivers
        order = np.argsort(recv, kind="stable")  # by receiver, batch order within
        by_recv = recv[order]
        cuts = (np.flatnonzero(by_recv[1:] != by_recv[:-1]) + 1).tolist()
        starts, ends = [0, *cuts], [*cuts, n]
        frame = batch.frame[order]
        frames = np.empty(len(batch.frames), dtype=object)
        frames[:] = batch.frames
        # Each copy's mailbox entry, by receiver (batch order within)
        entries = list(zip(repeat(batch.arrival_t, n), batch.senders[frame].tolist(), frames[frame].tolist()))
        lost: list[tuple[int, str]] = []  # (copy's position in the batch, cause)
        for r, lo, hi in zip(by_recv[starts].tolist(), starts, ends):
            if uavs[r].state != ALIVE:
                lost += [(k, "receiver_down") for k in order[lo:hi].tolist()]
                continue
            took = actors[r].mailbox.put_many(entries[lo:hi])
            if took < hi - lo:
                lost += [(k, "mailbox_full") for k in order[lo + took:hi].tolist()]
        if lost:
            lost.sort()
            fs, rs = batch.frame.tolist(), recv.tolist()
            snd = batch.senders.tolist()
            for k, cause in lost:
                data = batch.frames[fs[k]]
                self.lose(snd[fs[k]], rs[k], len(data), cause)
