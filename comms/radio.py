"""The simulated radio: a networkx graph of who can hear whom, and a per-link loss model.

Every tick the simulator hands the radio the positions of the live UAVs; the radio finds the
pairs in range with a k-d tree (scipy ``cKDTree``) and updates its ``networkx.Graph`` (nodes are
live UAV ids, edges carry ``distance`` and ``loss``). A broadcast frame becomes one copy per
neighbour; each copy is decided with the random stream of its own directed link, so one link's
draws never depend on another's (or on task interleaving):

1. the sender's bandwidth budget (optional) — a frame over budget is not transmitted;
2. the link filter (fault injection: partitions, drops, bursts, corruption, duplication, delay);
3. the link's own loss probability (base plus distance-dependent);
4. latency and jitter.

Surviving copies are returned as :class:`Delivery` records; the simulator schedules them on its
clock. The radio never delivers to a node that is not in the graph (failed or not yet joined)
and never beyond range.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import networkx as nx
import numpy as np
from scipy.spatial import cKDTree


@dataclass(frozen=True, slots=True)
class LinkModel:
    """Range limit, loss and latency of every link (the scenario's ``[radio]`` table)."""

    range_m: float | None = None  # None: unlimited
    loss_base: float = 0.0  # loss probability at distance 0
    loss_at_range: float = 0.0  # loss probability at the range limit (quadratic in between)
    latency_s: float = 0.0
    jitter_s: float = 0.0
    bandwidth_bytes_per_s: float | None = None  # per sender; None: unlimited

    def loss(self, distance: float) -> float:
        if self.range_m is None or not math.isfinite(self.range_m):
            return self.loss_base
        f = min(distance / self.range_m, 1.0)
        return self.loss_base + (self.loss_at_range - self.loss_base) * f * f


@dataclass(frozen=True, slots=True)
class Delivery:
    arrival_t: float
    sender: int
    receiver: int
    data: bytes


class LinkFilter(Protocol):
    """What fault injection plugs into: decides the fate of one copy on one directed link.

    Returns ``(copies, cause)``: a list of ``(extra_delay_s, data)`` to deliver (empty when the
    copy is lost) and, when lost, a short cause name for the counters.
    """

    def filter(self, t: float, src: int, dst: int, data: bytes, rng: np.random.Generator) -> tuple[list[tuple[float, bytes]], str | None]: ...


@dataclass(slots=True)
class RadioCounters:
    sent: int = 0  # link copies offered (one per in-range neighbour)
    bytes_sent: int = 0
    duplicated: int = 0  # extra copies created by duplication faults
    dropped: dict[str, int] = field(default_factory=dict)  # by cause

    def drop(self, cause: str, n: int = 1) -> None:
        self.dropped[cause] = self.dropped.get(cause, 0) + n

    @property
    def dropped_total(self) -> int:
        return sum(self.dropped.values())


class Radio:
    def __init__(
        self,
        model: LinkModel,
        link_rng: Callable[[int, int], np.random.Generator],
        link_filter: LinkFilter | None = None,
    ):
        self.model = model
        self._link_rng_factory = link_rng
        self._link_rngs: dict[tuple[int, int], np.random.Generator] = {}
        self.filter = link_filter
        self.graph = nx.Graph()
        self.counters = RadioCounters()
        self._tokens: dict[int, float] = {}
        self._neighbours: dict[int, list[int]] = {}

    # --- topology ---------------------------------------------------------------------------

    def update_topology(self, ids: list[int], xy: np.ndarray, dt: float) -> None:
        """Rebuild the edges from positions (``ids`` sorted, ``xy`` shape (n, 2))."""
        g = self.graph
        alive = set(ids)
        g.remove_nodes_from([n for n in list(g.nodes) if n not in alive])
        g.add_nodes_from(ids)
        g.clear_edges()
        n = len(ids)
        if n >= 2:
            r = self.model.range_m
            if r is None or not math.isfinite(r):
                ii, jj = np.triu_indices(n, 1)
            else:
                pairs = cKDTree(xy).query_pairs(r, output_type="ndarray")
                if len(pairs):
                    order = np.lexsort((pairs[:, 1], pairs[:, 0]))
                    pairs = pairs[order]
                ii, jj = (pairs[:, 0], pairs[:, 1]) if len(pairs) else (np.empty(0, int), np.empty(0, int))
            d = np.hypot(xy[ii, 0] - xy[jj, 0], xy[ii, 1] - xy[jj, 1])
            g.add_edges_from(
                (ids[i], ids[j], {"distance": float(dd), "loss": self.model.loss(float(dd))})
                for i, j, dd in zip(ii.tolist(), jj.tolist(), d.tolist())
            )
        self._neighbours = {u: sorted(g.adj[u]) for u in ids}
        bw = self.model.bandwidth_bytes_per_s
        if bw is not None:
            # Token bucket refilled each tick, holding at most one second of traffic.
            for u in ids:
                self._tokens[u] = min(self._tokens.get(u, bw) + bw * dt, bw)

    def neighbours(self, uid: int) -> list[int]:
        return self._neighbours.get(uid, [])

    def _rng(self, src: int, dst: int) -> np.random.Generator:
        rng = self._link_rngs.get((src, dst))
        if rng is None:
            rng = self._link_rngs[(src, dst)] = self._link_rng_factory(src, dst)
        return rng

    # --- transmission -----------------------------------------------------------------------

    def broadcast(self, t: float, src: int, data: bytes, out: list[Delivery], on_lost=None) -> None:
        """Offer one frame to every neighbour of ``src``; surviving copies are appended to ``out``.

        ``on_lost(src, dst, nbytes, cause)`` is called for every lost copy (for the event log).
        """
        nbrs = self._neighbours.get(src)
        if not nbrs:
            return
        c = self.counters
        size = len(data)
        c.sent += len(nbrs)
        c.bytes_sent += size * len(nbrs)
        if self.model.bandwidth_bytes_per_s is not None:
            if self._tokens.get(src, 0.0) < size:
                c.drop("bandwidth", len(nbrs))
                if on_lost is not None:
                    for dst in nbrs:
                        on_lost(src, dst, size, "bandwidth")
                return
            self._tokens[src] -= size
        model = self.model
        adj = self.graph.adj[src]
        for dst in nbrs:
            rng = self._rng(src, dst)
            copies: list[tuple[float, bytes]] = [(0.0, data)]
            if self.filter is not None:
                copies, cause = self.filter.filter(t, src, dst, data, rng)
                if not copies:
                    c.drop(cause or "fault")
                    if on_lost is not None:
                        on_lost(src, dst, size, cause or "fault")
                    continue
                c.duplicated += len(copies) - 1
            p = adj[dst]["loss"]
            for extra, payload in copies:
                if p > 0.0 and rng.random() < p:
                    c.drop("loss")
                    if on_lost is not None:
                        on_lost(src, dst, size, "loss")
                    continue
                delay = model.latency_s + extra
                if model.jitter_s > 0.0:
                    delay += model.jitter_s * rng.random()
                out.append(Delivery(t + delay, src, dst, payload))
