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
its map, its peers and tracks. Where receivers hear many frames each (a dense swarm), the
service does it in three passes, the knowledge horizon tested for every (receiver, scan) pair
of the tick at once as arrays and each receiver's scans logged in one call
(:meth:`Receiving.receive`); elsewhere each actor's :meth:`~agents.inbox.Inbox.take` does the
same per receiver (bench-100 and bench-1000 hear 4.5-7 frames a receiver: too few for
gathering the pairs to pay clearly).

Maps shared in a :class:`~agents.maps.mapgroup.MapGroup` see their stamps in another order (every
heard scan before the tick's own scans, instead of actor by actor); a group only shares storage,
so the cells, which are the max of the same disks, are the same (``tests/test_tick_plane.py``
compares them tick by tick against the per-actor path).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from itertools import compress

import numpy as np

from agents.actor import UavActor
from agents.inbox import HeardMemo, HeardScan, Inbox
from agents.inputs import SensorReading
from swarm.errors import SimulationError

__all__ = ["Receiving"]

# The receivers of a tick merge one by one (each actor's receive: Inbox.take, the scalar horizon
# test) when they are fewer than SMALL_SWARM or heard fewer than DENSE_FRAMES frames each on
# average; else in the three passes of Receiving.receive, the horizon test as arrays over all
# (receiver, scan) pairs. Measured on the 2-core VM (swarm bench's receive component, per actor
# against three passes, alternately, load 4-11, us per UAV-tick): bench-dense-300 (about 280
# frames a receiver-tick) 2673 -> 1973 and 2306 -> 1987; bench-1000-greedy (7.2) a mean of 120
# -> 111 over 6 pairs, within the noise (one round equal); bench-100-greedy (4.5) 116 -> 126
# over 4. So only clearly dense ticks take the passes (docs/speed.md).
# Below SMALL_PAIRS pairs within_horizons tests them one by one.
SMALL_SWARM = 16
DENSE_FRAMES = 24
SMALL_PAIRS = 64
# The band around the horizon where numpy's d*d and Python's d**2 (the oracle's: C pow, which
# may differ from the product in the last bit) could decide differently: relative to H^2, far
# wider than the few ulp they can differ by. Pairs in it are decided by the scalar formula.
BAND = 1e-12


class Receiving:
    """Merges the inboxes of the actors it is given (:meth:`receive`)."""

    __slots__ = ("actors",)

    def __init__(self, actors: Mapping[int, UavActor]):
        """``actors``: the run's actors by UAV id (the fleet's, filled as UAVs are added)."""
        self.actors = actors

    def receive(self, uids: Iterable[int], readings: Mapping[int, SensorReading]) -> None:
        """Merge the mailbox of each actor of ``uids`` (in that order: UAV ids ascending) with
        its reading of this tick, sharing one memo of the frames heard.

        A small or sparse tick (:data:`SMALL_SWARM`, :data:`DENSE_FRAMES`): each actor's
        :meth:`~agents.actor.UavActor.receive`, one by one. Else in three passes: every
        receiver's frames looked up, counted and merged into its knowledge, its heard scans
        gathered (:meth:`~agents.actor.UavActor.heard`); the knowledge horizon tested for all
        (receiver, scan) pairs of the tick at once (:func:`within_horizons`); each receiver's
        scans within it logged and stamped (:meth:`~agents.actor.UavActor.apply_heard`), in
        UAV-id order. A receiver's merge reads only its own state and the frames, and its
        knowledge, scan log and map are apart (the first pass changes only the tick's memo and
        the receiver's counters, knowledge and record of what it received), so the passes give
        each the state its own merge would; every map, the grid's shared disk memo and the
        resend archive see their calls in the same order as receiver after receiver.
        """
        memo: HeardMemo = {}
        actors = self.actors
        uids = list(uids)
        if len(uids) < SMALL_SWARM or sum([len(actors[uid].mailbox) for uid in uids]) < DENSE_FRAMES * len(uids):
            for uid in uids:
                actor = actors[uid]
                try:
                    actor.receive(readings[uid], memo)
                except Exception as exc:
                    raise _failed(actor, exc) from exc
            return
        # 1. Each receiver's frames, merged into its knowledge; its heard scans.
        jobs: list[tuple[UavActor, SensorReading, list[HeardScan] | None]] = []
        centres: list[float] = []  # of the pairs of the receivers with a horizon, x0, y0, x1, y1, ...
        here: list[tuple[float, float, float]] = []  # of those receivers: x, y, H^2
        counts: list[int] = []  # and their pairs
        for uid in uids:
            actor = actors[uid]
            r = readings[uid]
            if type(actor.inbox) is not Inbox:  # (a test's stand-in: merged in the third pass)
                jobs.append((actor, r, None))
                continue
            try:
                heard = actor.heard(r, memo)
            except Exception as exc:
                raise _failed(actor, exc) from exc
            if heard:
                jobs.append((actor, r, heard))
                h2 = actor.inbox.horizon2
                if h2 is not None:
                    centres += [v for hs in heard for v in hs[2][1:3]]
                    here.append((r.x, r.y, h2))
                    counts.append(len(heard))
        # 2. The horizon test of every pair at once.
        inside = within_horizons(centres, here, counts) if here else []
        # 3. Each receiver's scans within its horizon logged and stamped, in UAV-id order.
        i = 0
        for actor, r, got in jobs:
            try:
                if got is None:
                    actor.receive(r, memo)
                    continue
                h2 = actor.inbox.horizon2
                if h2 is None:
                    near = got
                else:
                    near = list(compress(got, inside[i:i + len(got)]))
                    i += len(got)
                actor.apply_heard(r, near, len(got) - len(near))
            except Exception as exc:
                raise _failed(actor, exc) from exc


def within_horizons(centres: list[float], here: list[tuple[float, float, float]], counts: list[int]) -> list[bool]:
    """For each (receiver, scan) pair, whether the scan's centre lies within the receiver's
    knowledge horizon, exactly as :meth:`agents.inbox.Inbox.merge` decides it: ``(x - hx) ** 2
    + (y - hy) ** 2 <= H^2``. ``centres``: the pairs' scan centres ``x0, y0, x1, y1, ...``,
    receiver by receiver; ``here``: per receiver ``(hx, hy, H^2)``; ``counts``: its pairs."""
    n = len(centres) // 2
    if n < SMALL_PAIRS:
        out: list[bool] = []
        j = 0
        for (hx, hy, h2), c in zip(here, counts):
            for k in range(j, j + 2 * c, 2):
                out.append((centres[k] - hx) ** 2 + (centres[k + 1] - hy) ** 2 <= h2)
            j += 2 * c
        return out
    p = np.array(centres, np.float64).reshape(n, 2)
    h = np.array(here, np.float64)
    reps = np.array(counts, np.intp)
    p -= np.repeat(h[:, :2], reps, axis=0)
    d = p * p
    d2 = d[:, 0] + d[:, 1]
    hh2 = np.repeat(h[:, 2], reps)
    inside = d2 <= hh2
    np.subtract(d2, hh2, out=d2)
    close = np.flatnonzero(np.abs(d2, out=d2) <= BAND * hh2)
    if len(close):
        owner = np.repeat(np.arange(len(reps)), reps)  # (the receiver of each pair)
        for k in close.tolist():
            hx, hy, hh = here[int(owner[k])]
            inside[k] = (centres[2 * k] - hx) ** 2 + (centres[2 * k + 1] - hy) ** 2 <= hh
    return inside.tolist()  # type: ignore[no-any-return]


def _failed(actor: UavActor, exc: Exception) -> SimulationError:
    """The error of an actor's merge, as the actor's own step would report it (swarm.kernel.fleet)."""
    return SimulationError(f"UAV {actor.name} raised {type(exc).__name__}: {exc}")
