"""The simulated radio: a networkx graph of who can hear whom, and a per-link loss model.

Every tick the simulator hands the radio the positions of the live UAVs; the radio finds the
pairs in range with a k-d tree (scipy ``cKDTree``) and updates its ``networkx.Graph`` in place
(nodes are live UAV ids, edges carry ``distance`` and ``loss``; edges that left range are removed,
new ones added, the rest refreshed: the same graph a rebuild would give, for a fraction of the
cost when most links persist). A broadcast frame becomes one copy per
neighbour; each copy is decided with the random stream of its own directed link, so one link's
draws never depend on another's (or on task interleaving):

1. the sender's bandwidth budget (optional) — a frame over budget is not transmitted;
2. the link filter (fault injection: partitions, drops, bursts, corruption, duplication, delay);
3. the link's own loss probability (:class:`LinkModel`: the disk model's, a function of distance
   alone, or the log-distance model's, which adds the link's slowly varying shadowing, drawn
   from the same stream);
4. latency and jitter.

Surviving copies are returned as :class:`Delivery` records; the simulator schedules them on its
clock. The radio never delivers to a node that is not in the graph (failed or not yet joined)
and never beyond range (for the log-distance model: the range its link budget implies,
:attr:`LogDistance.range_m`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, MutableMapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol, cast

import networkx as nx
import numpy as np

from comms.settings import LinkModel, LogDistance

# LinkModel and LogDistance are defined in comms.settings (with RadioSettings, the [radio] table);
# they are named here too, where the radio's users have always found them.
__all__ = ["Adjacency", "Delivery", "LinkFilter", "LinkModel", "LogDistance", "Radio", "RadioCounters", "RadioGraph",
           "SPOOF_SENDER"]

# networkx's adjacency dict-of-dicts: node -> neighbour -> edge data (RadioGraph.edge_data).
Adjacency = dict[int, dict[int, dict[str, float]]]

if TYPE_CHECKING:
    _Graph = nx.Graph[int]
else:
    _Graph = nx.Graph


class RadioGraph(_Graph):
    """The radio's graph: a ``networkx.Graph`` (nodes are live UAV ids, edges carry ``distance``
    and ``loss``, and ``margin_db`` with the log-distance model) that names its adjacency
    dict-of-dicts, :attr:`edge_data`, so that the radio's hot paths read and update edge data
    with plain dict operations instead of through ``Graph.adj``'s read-only views (networkx's
    own subclassing hook, ``adjlist_outer_dict_factory``, makes the graph keep it)."""

    def __init__(self, incoming_graph_data: Any = None, **attr: Any):
        # node -> neighbour -> edge data: the graph's own storage (not a copy), live
        self.edge_data: Adjacency = {}
        super().__init__(incoming_graph_data, **attr)

    def adjlist_outer_dict_factory(self) -> MutableMapping[str, Any]:
        """The outermost dict of the adjacency structure (networkx calls this once, in
        ``Graph.__init__``): :attr:`edge_data`. (Typed as the networkx stubs type every factory.)"""
        return cast("MutableMapping[str, Any]", self.edge_data)


# The sender of a spoofer's frames in deliveries and ``rx`` events: no member has this id (they
# are numbered from 0), so a checker tells a spoof from a member's frame.
SPOOF_SENDER = -1


class Delivery(NamedTuple):
    arrival_t: float
    sender: int
    receiver: int
    data: bytes


class LinkFilter(Protocol):
    """What fault injection plugs into: decides the fate of one copy on one directed link.

    Returns ``(copies, cause)``: a list of ``(extra_delay_s, data)`` to deliver (empty when the
    copy is lost) and, when lost, a short cause name for the counters.
    """

    def filter(self, t: float, src: int, dst: int, data: bytes,
               rng: np.random.Generator) -> tuple[list[tuple[float, bytes]], str | None]: ...


@dataclass(slots=True)
class RadioCounters:
    sent: int = 0  # link copies offered (one per in-range neighbour; spoofers' copies included)
    spoofed: int = 0  # of those, copies from spoofers (faults.schedule.Spoofer; sender SPOOF_SENDER)
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
        link_rngs: Callable[[list[tuple[int, int]]], list[np.random.Generator]] | None = None,
    ):
        """``link_rng(src, dst)``: the stream of a directed link; ``link_rngs(links)`` (optional):
        the streams of many links at once, the same as ``link_rng`` gives each."""
        self.model = model
        self._link_rng_factory = link_rng
        self._link_rngs: dict[tuple[int, int], np.random.Generator] = {}
        # With link_rngs: the directed links of edges added since their streams were last made.
        # The first copy that needs a stream makes those of all of them at once (a stream does
        # not depend on when it is made; a dense swarm's first tick makes tens of thousands).
        self._bulk = link_rngs
        self._new_links: list[tuple[int, int]] = []
        self.filter = link_filter
        self.graph = RadioGraph()
        self._edges = self.graph.edge_data  # (the graph's own: read and updated in place)
        self.counters = RadioCounters()
        self._tokens: dict[int, float] = {}
        self._neighbours: dict[int, list[int]] = {}
        self._edge_codes = np.empty(0, np.int64)  # (u << 32) | v of the graph's edges, u < v
        self._ids: list[int] = []  # the ids of the last update
        self._all_pair_ids: list[tuple[int, int]] = []  # unlimited range: the edges, in pair order
        self._all_pairs: tuple[int, tuple[np.ndarray, np.ndarray]] = (-1, (np.empty(0, np.int64),) * 2)
        # Every link's loss probability is 0: no per-link draw is ever made for loss.
        self._lossless = model.lossless
        # The log-distance model's shadowing per directed link: (time of its last value, dB).
        self._shadow: dict[tuple[int, int], tuple[float, float]] = {}

    # --- topology ---------------------------------------------------------------------------

    def update_topology(self, ids: list[int], xy: np.ndarray, dt: float) -> None:
        """Bring the edges up to date with positions (``ids`` sorted, ``xy`` shape (n, 2)).

        Pairs in range come from a k-d tree (or all pairs when the range is unlimited). The
        graph is updated in place: edges that left range are removed, new ones added, and the
        ``distance``/``loss`` of the others refreshed; the result equals a graph rebuilt from
        scratch (same nodes, edges and attributes).
        """
        g = self.graph
        adj = self._edges  # the edge data dicts themselves
        same_ids = ids == self._ids
        if not same_ids:  # (else the nodes are those of the last update: nobody came or went)
            alive = set(ids)
            dead = [u for u in g if u not in alive]
            if dead:
                g.remove_nodes_from(dead)
            new_nodes = [u for u in ids if u not in adj]
            if new_nodes:
                g.add_nodes_from(new_nodes)
        n = len(ids)
        model = self.model
        ld = model.log_distance
        rng_m = model.radius_m
        unlimited = not math.isfinite(rng_m)
        if unlimited and n >= 2 and same_ids:
            # Everyone hears everyone and nobody came or went: same edges, new distances.
            ii, jj = self._all_pairs[1]
            dxy = xy[ii] - xy[jj]
            d = np.hypot(dxy[:, 0], dxy[:, 1])
            uniform = model.loss(0.0)  # (unlimited range: the same at every distance)
            for (u, v), dd in zip(self._all_pair_ids, d.tolist()):
                edge = adj[u][v]
                edge["distance"] = dd
                edge["loss"] = uniform
            self._refill_tokens(ids, dt)
            return
        empty = np.empty(0, np.int64)
        ii = jj = empty
        if n >= 2:
            if unlimited:
                if self._all_pairs[0] != n:
                    self._all_pairs = (n, np.triu_indices(n, 1))
                ii, jj = self._all_pairs[1]
            else:
                from scipy.spatial import cKDTree  # (only runs with a finite range pay for scipy)

                pairs = cKDTree(xy).query_pairs(rng_m, output_type="ndarray")
                if len(pairs):
                    order = np.lexsort((pairs[:, 1], pairs[:, 0]))
                    pairs = pairs[order]
                    ii, jj = pairs[:, 0], pairs[:, 1]
        ida = np.asarray(ids, dtype=np.int64)
        a, b = ida[ii], ida[jj]
        if unlimited:
            self._all_pair_ids = list(zip(a.tolist(), b.tolist()))
        d = np.hypot(xy[ii, 0] - xy[jj, 0], xy[ii, 1] - xy[jj, 1])
        # (the log-distance margin is kept on the edge: broadcast adds the shadowing)
        margin = ld.margins_db(d) if ld is not None else None
        loss = model.losses(d, margin)
        codes = (a << 32) | b
        old = self._edge_codes
        same_edges = len(old) == len(codes) and np.array_equal(old, codes)
        if len(old) and not same_edges:
            stale = np.setdiff1d(old, codes, assume_unique=True)
            for code in stale.tolist():
                u, v = code >> 32, code & 0xFFFFFFFF
                if u in adj and v in adj[u]:  # edges of dead nodes went with them
                    g.remove_edge(u, v)
        self._edge_codes = codes
        add: list[tuple[int, int, dict[str, float]]] = []
        if margin is not None:
            for u, v, dd, ll, mm in zip(a.tolist(), b.tolist(), d.tolist(), loss.tolist(), margin.tolist()):
                e = adj[u].get(v)
                if e is None:
                    add.append((u, v, {"distance": dd, "loss": ll, "margin_db": mm}))
                else:
                    e["distance"] = dd
                    e["loss"] = ll
                    e["margin_db"] = mm
        else:
            for u, v, dd, ll in zip(a.tolist(), b.tolist(), d.tolist(), loss.tolist()):
                e = adj[u].get(v)
                if e is None:
                    add.append((u, v, {"distance": dd, "loss": ll}))
                else:
                    e["distance"] = dd
                    e["loss"] = ll
        if add:
            g.add_edges_from(add)
            if self._bulk is not None:
                self._new_links += [(u, v) for u, v, _ in add] + [(v, u) for u, v, _ in add]
        # Neighbour lists (sorted ids) straight from the pairs (unless nothing changed).
        if same_edges and same_ids:
            pass
        elif len(a):
            src = np.concatenate([ii, jj])
            dst = np.concatenate([b, a])
            order = np.lexsort((dst, src))
            dst_l = dst[order].tolist()
            ends = np.cumsum(np.bincount(src, minlength=n)).tolist()
            start = 0
            nb = {}
            for u, end in zip(ids, ends):
                nb[u] = dst_l[start:end]
                start = end
            self._neighbours = nb
        else:
            self._neighbours = {u: [] for u in ids}
        self._ids = list(ids)
        self._refill_tokens(ids, dt)

    def _refill_tokens(self, ids: list[int], dt: float) -> None:
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
            rng = self._new_rng(src, dst)
        return rng

    def _new_rng(self, src: int, dst: int) -> np.random.Generator:
        """The stream of a link that has none yet (see _new_links), kept."""
        rngs = self._link_rngs
        if self._bulk is not None and self._new_links:
            todo = [link for link in dict.fromkeys(self._new_links) if link not in rngs]
            self._new_links = []
            rngs.update(zip(todo, self._bulk(todo)))
            rng = rngs.get((src, dst))
            if rng is not None:
                return rng
        rng = rngs[(src, dst)] = self._link_rng_factory(src, dst)
        return rng

    def _faded_loss(self, t: float, src: int, dst: int, margin_db: float, ld: LogDistance,
                    rng: np.random.Generator) -> float:
        """The log-distance model's loss probability of a copy sent at ``t`` on ``src -> dst``:
        its mean margin plus the link's shadowing, brought up to ``t`` first (one normal draw
        from the link's stream when time has passed since its last value; its first value is
        drawn from the stationary distribution)."""
        sigma = ld.sigma_db
        x = 0.0
        if sigma > 0.0:
            key = (src, dst)
            state = self._shadow.get(key)
            if state is None:
                x = sigma * float(rng.standard_normal())
            elif t > state[0]:
                rho = math.exp(-(t - state[0]) / ld.corr_s)
                x = rho * state[1] + sigma * math.sqrt(1.0 - rho * rho) * float(rng.standard_normal())
            else:
                t, x = state
            self._shadow[key] = (t, x)
        return self.model.floored(ld.frame_loss(margin_db + x))

    # --- transmission -----------------------------------------------------------------------

    def broadcast(self, t: float, src: int, data: bytes, out: list[Delivery],
                  on_lost: Callable[[int, int, int, str], object] | None = None, to: int | None = None) -> None:
        """Offer one frame to every neighbour of ``src``; surviving copies are appended to ``out``.

        ``on_lost(src, dst, nbytes, cause)`` is called for every lost copy (for the event log).
        ``to``: a unicast frame, offered to that neighbour only (nothing if it is out of range);
        the same link, loss and faults as its copy of a broadcast.
        """
        nbrs = self._neighbours.get(src)
        if to is not None and nbrs:
            nbrs = [to] if to in self._edges[src] else None
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
        ld = model.log_distance
        flt = self.filter
        if flt is not None and getattr(flt, "idle", False):
            flt = None  # an idle filter passes every copy unchanged and draws nothing
        if flt is None and self._lossless and ld is None and model.jitter_s <= 0.0:
            # Nothing can happen to any copy and nothing is drawn: one delivery per neighbour.
            arrival = t + model.latency_s
            new = tuple.__new__  # = Delivery(...), without the namedtuple's Python-level __new__
            out.extend([new(Delivery, (arrival, src, dst, data)) for dst in nbrs])
            return
        adj = self._edges[src]
        if flt is None and ld is None:
            # No fault acts: only the link's own loss and jitter draw (in that order).
            base = model.latency_s + 0.0
            jitter = model.jitter_s
            rngs = self._link_rngs
            new = tuple.__new__
            append = out.append
            for dst in nbrs:
                p = adj[dst]["loss"]
                if p > 0.0 or jitter > 0.0:
                    rng = rngs.get((src, dst))
                    if rng is None:
                        rng = self._new_rng(src, dst)
                    if p > 0.0 and rng.random() < p:
                        c.drop("loss")
                        if on_lost is not None:
                            on_lost(src, dst, size, "loss")
                        continue
                    if jitter > 0.0:
                        append(new(Delivery, (t + (base + jitter * rng.random()), src, dst, data)))
                        continue
                append(new(Delivery, (t + base, src, dst, data)))
            return
        for dst in nbrs:
            rng = self._rng(src, dst)
            copies: list[tuple[float, bytes]] = [(0.0, data)]
            if flt is not None:
                copies, cause = flt.filter(t, src, dst, data, rng)
                if not copies:
                    c.drop(cause or "fault")
                    if on_lost is not None:
                        on_lost(src, dst, size, cause or "fault")
                    continue
                c.duplicated += len(copies) - 1
            # Log-distance: the shadowing draws after the filter's, before the loss draw.
            p = adj[dst]["loss"] if ld is None else self._faded_loss(t, src, dst, adj[dst]["margin_db"], ld, rng)
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
