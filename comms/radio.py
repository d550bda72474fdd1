"""The simulated radio: a networkx graph of who can hear whom, and a per-link loss model.

Every tick the simulator hands the radio the positions of the live UAVs (and, with the tick
plane, the pairs in range that the tick's one pair query found: :class:`swarm.pairs.TickPairs`;
else the radio finds them with a k-d tree, scipy ``cKDTree``). The model's graph is a
``networkx.Graph`` (nodes are live UAV ids, edges carry ``distance`` and ``loss``): the
per-actor path (``tick_plane=False``) updates it in place every tick (edges that left range
removed, new ones added, the rest refreshed: the same graph a rebuild would give); the tick plane
keeps the links as arrays (the link table: pairs, neighbour lists) and brings the graph to the
same state only when something reads :attr:`Radio.graph`. A broadcast frame becomes one copy per
neighbour; each copy is decided with the random stream of its own directed link, so one link's
draws never depend on another's (or on task interleaving):

1. the sender's bandwidth budget (optional) — a frame over budget is not transmitted;
2. the link filter (fault injection: partitions, drops, bursts, corruption, duplication, delay);
3. the link's own loss probability (:class:`LinkModel`: the disk model's, a function of distance
   alone, or the log-distance model's, which adds the link's slowly varying shadowing, drawn
   from the same stream);
4. latency and jitter.

Surviving copies are returned as :class:`Delivery` records; the simulator schedules them on its
clock. When nothing can happen to a copy and nothing is drawn (no active link fault, a lossless
radio, no log-distance model, no jitter), the tick plane sends all of a tick's frames at once
(:meth:`Radio.broadcast_all`): the same copies as arrays, a :class:`DeliveryBatch`. The radio
never delivers to a node that is not in the graph (failed or not yet joined) and never beyond
range (for the log-distance model: the range its link budget implies, :attr:`LogDistance.range_m`).
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
__all__ = ["Adjacency", "Delivery", "DeliveryBatch", "LinkFilter", "LinkModel", "LogDistance", "Radio", "RadioCounters",
           "RadioGraph", "SPOOF_SENDER"]

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


# Below this many directed links, broadcast_all leaves a tick's frames to broadcast, copy by copy:
# its fixed cost (a dozen numpy calls, and as many again to deliver) is more than the copies'
# (measured on paper-fig11, 30 links and about 36 copies a tick: 4 us more per UAV-tick).
BATCH_MIN_LINKS = 64

# The sender of a spoofer's frames in deliveries and ``rx`` events: no member has this id (they
# are numbered from 0), so a checker tells a spoof from a member's frame.
SPOOF_SENDER = -1


class Delivery(NamedTuple):
    arrival_t: float
    sender: int
    receiver: int
    data: bytes


@dataclass(slots=True)
class DeliveryBatch:
    """The copies of a tick's frames that all arrive at ``arrival_t`` (the tick plane's
    :meth:`Radio.broadcast_all`), as arrays: copy ``k`` carries ``frames[frame[k]]`` from
    ``senders[frame[k]]`` to ``receivers[k]``, in the order :meth:`Radio.broadcast` would have
    listed them as :class:`Delivery` records (:meth:`deliveries`)."""

    arrival_t: float
    frames: list[bytes]
    senders: np.ndarray  # per frame
    frame: np.ndarray  # per copy: its frame's index
    receivers: np.ndarray  # per copy

    def __len__(self) -> int:
        return len(self.receivers)

    def deliveries(self) -> list[Delivery]:
        """The copies as :class:`Delivery` records, in order."""
        frames, senders = self.frames, self.senders.tolist()
        return [Delivery(self.arrival_t, senders[f], r, frames[f])
                for f, r in zip(self.frame.tolist(), self.receivers.tolist())]


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
        tick_plane: bool = False,
        batch_min_links: int | None = None,
    ):
        """``link_rng(src, dst)``: the stream of a directed link; ``link_rngs(links)`` (optional):
        the streams of many links at once, the same as ``link_rng`` gives each.

        ``tick_plane`` (issue 36): keep the links as arrays (the link table) and bring the
        networkx graph up to date only when something reads :attr:`graph`; a tick's frames may
        then go out together (:meth:`broadcast_all`). ``False``: the graph is updated every
        tick (the per-actor path, the oracle). Either way the graph read, the neighbours, the
        copies and every draw are the same. ``batch_min_links``: :meth:`broadcast_all` works from
        this many directed links (default :data:`BATCH_MIN_LINKS`; below, copy by copy costs less)."""
        self.model = model
        self.tick_plane = tick_plane
        self.batch_min_links = BATCH_MIN_LINKS if batch_min_links is None else batch_min_links
        self._link_rng_factory = link_rng
        self._link_rngs: dict[tuple[int, int], np.random.Generator] = {}
        # With link_rngs: the directed links of edges added since their streams were last made.
        # The first copy that needs a stream makes those of all of them at once (a stream does
        # not depend on when it is made; a dense swarm's first tick makes tens of thousands).
        self._bulk = link_rngs
        self._new_links: list[tuple[int, int]] = []
        self.filter = link_filter
        self._graph = RadioGraph()
        self._edges = self._graph.edge_data  # (the graph's own: read and updated in place)
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
        # --- the link table (tick_plane) ---
        empty = np.empty(0, np.int64)
        self._index: dict[int, int] = {}  # uid -> its row (position in _ids)
        self._xy = np.zeros((0, 2))  # the positions of the last update (a copy)
        self._ii, self._jj = empty, empty  # the links: rows i < j, in (i, j) order
        self._codes = empty  # (u << 32) | v of the links (ids, u < v)
        self._start: list[int] = [0]  # neighbours of row k: _nb[_start[k]:_start[k + 1]]
        self._nb_arr = empty  # the neighbour lists (ids, ascending per row), end to end
        self._start_arr = np.zeros(1, np.int64)  # _start as an array
        self._nb_list: list[int] | None = None  # _nb_arr as a list, when made
        self._nb_keys: np.ndarray | None = None  # row * (max id + 1) + id per entry (ascending), when made
        self._nb_link = empty  # each _nb entry's link (index into _ii/_jj)
        self._values: tuple[np.ndarray, np.ndarray | None, np.ndarray] | None = None  # (d, margin, loss), when made
        self._adj: dict[int, dict[int, dict[str, float]]] = {}  # per sender, this tick: its links' data
        self._stale = False  # the graph's edges are not those of the table
        self._streamed = empty  # codes of links whose streams have been made (with link_rngs)

    # --- topology ---------------------------------------------------------------------------

    @property
    def graph(self) -> RadioGraph:
        """The radio graph now: nodes the live UAV ids, an edge per link in range with its
        ``distance`` and ``loss`` (and ``margin_db`` with the log-distance model). With the tick
        plane it is brought up to date here, when read (then the same nodes, in the same order,
        edges and edge data as the per-actor path's graph)."""
        if self._stale:
            self._sync_graph()
        return self._graph

    def update_topology(self, ids: list[int], xy: np.ndarray, dt: float,
                        pairs: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """Bring the links up to date with positions (``ids`` sorted, ``xy`` shape (n, 2)).

        ``pairs``: the rows ``(i, j)``, ``i < j``, of the pairs within range, in ``(i, j)`` order,
        if the caller has them (the tick plane's one pair query, :class:`swarm.pairs.TickPairs`);
        else a k-d tree finds them (or all pairs when the range is unlimited)."""
        if self.tick_plane:
            self._update_table(ids, xy, dt, pairs)
        else:
            self._update_graph(ids, xy, dt)

    def _update_nodes(self, ids: list[int]) -> None:
        """The graph's nodes: the dead removed (with their edges), the new added, in id order."""
        g, adj = self._graph, self._edges
        alive = set(ids)
        dead = [u for u in g if u not in alive]
        if dead:
            g.remove_nodes_from(dead)
        new_nodes = [u for u in ids if u not in adj]
        if new_nodes:
            g.add_nodes_from(new_nodes)

    def _pairs(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rows ``(i, j)``, ``i < j``, of the pairs within range, in ``(i, j)`` order."""
        n = len(xy)
        rng_m = self.model.radius_m
        empty = np.empty(0, np.int64)
        if n < 2:
            return empty, empty
        if not math.isfinite(rng_m):
            if self._all_pairs[0] != n:
                self._all_pairs = (n, np.triu_indices(n, 1))
            return self._all_pairs[1]
        from scipy.spatial import cKDTree

        pairs = cKDTree(xy).query_pairs(rng_m, output_type="ndarray")
        if not len(pairs):
            return empty, empty
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
        return pairs[:, 0], pairs[:, 1]

    def _update_table(self, ids: list[int], xy: np.ndarray, dt: float,
                      pairs: tuple[np.ndarray, np.ndarray] | None) -> None:
        """The tick plane's :meth:`update_topology`: the link table (arrays) and the neighbour
        lists; the graph's nodes now (cheap, and only when somebody came or went), its edges
        when it is read."""
        same_ids = ids == self._ids
        if not same_ids:
            self._update_nodes(ids)
            self._index = {u: k for k, u in enumerate(ids)}
        ii, jj = self._pairs(xy) if pairs is None else pairs
        ida = np.asarray(ids, dtype=np.int64)
        if same_ids and ii is self._ii and jj is self._jj:
            same, codes = True, self._codes  # (the very same pair arrays: every pair, as last tick)
        else:
            codes = (ida[ii] << 32) | ida[jj]
            same = same_ids and codes.tobytes() == self._codes.tobytes()
        self._xy = np.array(xy, dtype=np.float64)
        self._values = None
        self._adj = {}
        self._stale = True
        self._ids = list(ids)
        if not same:  # (else the same links: the neighbour lists stand)
            n, m = len(ids), len(ii)
            self._ii, self._jj, self._codes = ii, jj, codes
            # Each link both ways, by sender: a sender's lower neighbours (the links (i, k) it is
            # the j of, in i order) then its higher ones (k < j, in j order): ascending ids.
            src = np.concatenate((jj, ii))
            # (a stable sort: radix on 16-bit rows)
            order = np.argsort(src.astype(np.int16) if n < 1 << 15 else src, kind="stable")
            nb_rows = np.concatenate((ii, jj))[order]
            self._nb_link = np.concatenate((np.arange(m), np.arange(m)))[order]
            self._nb_arr = ida[nb_rows]
            self._nb_list = None
            self._nb_keys = None
            start = np.zeros(n + 1, np.int64)
            np.cumsum(np.bincount(src, minlength=n), out=start[1:])
            self._start_arr = start
            self._start = start.tolist()
        self._refill_tokens(ids, dt)

    def _link_values(self, xy: np.ndarray, ii: np.ndarray, jj: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """``(distance, margin_db or None, loss)`` of the links ``(ii, jj)`` at ``xy``."""
        d = np.hypot(xy[ii, 0] - xy[jj, 0], xy[ii, 1] - xy[jj, 1])
        # (the log-distance margin is kept on the edge: broadcast adds the shadowing)
        ld = self.model.log_distance
        margin = ld.margins_db(d) if ld is not None else None
        return d, margin, self.model.losses(d, margin)

    def _table_values(self) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """:meth:`_link_values` of the link table (made once per update, when first needed)."""
        if self._values is None:
            self._values = self._link_values(self._xy, self._ii, self._jj)
        return self._values

    def _set_edges(self, a: np.ndarray, b: np.ndarray, codes: np.ndarray, d: np.ndarray, loss: np.ndarray,
                   margin: np.ndarray | None) -> list[tuple[int, int, dict[str, float]]]:
        """Make the graph's edges those ``(a, b)`` (ids, ``codes``) with this data: edges that left
        range removed, the others' data refreshed, new ones added (returned)."""
        g, adj = self._graph, self._edges
        old = self._edge_codes
        if len(old) and not (len(old) == len(codes) and np.array_equal(old, codes)):
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
        return add

    def _sync_graph(self) -> None:
        """The graph's edges brought to the link table's (the tick plane, when the graph is read)."""
        self._stale = False
        d, margin, loss = self._table_values()
        ida = np.asarray(self._ids, dtype=np.int64)
        self._set_edges(ida[self._ii], ida[self._jj], self._codes, d, loss, margin)

    def _update_graph(self, ids: list[int], xy: np.ndarray, dt: float) -> None:
        """The per-actor path's (``tick_plane=False``) :meth:`update_topology`: the networkx
        graph itself brought up to date every tick. Pairs in range come from a k-d tree (or all
        pairs when the range is unlimited). The graph is updated in place: edges that left range
        are removed, new ones added, and the ``distance``/``loss`` of the others refreshed; the
        result equals a graph rebuilt from scratch (same nodes, edges and attributes).
        """
        adj = self._edges  # the edge data dicts themselves
        same_ids = ids == self._ids
        if not same_ids:  # (else the nodes are those of the last update: nobody came or went)
            self._update_nodes(ids)
        n = len(ids)
        model = self.model
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
        d, margin, loss = self._link_values(xy, ii, jj)
        codes = (a << 32) | b
        same_edges = len(self._edge_codes) == len(codes) and np.array_equal(self._edge_codes, codes)
        add = self._set_edges(a, b, codes, d, loss, margin)
        if add and self._bulk is not None:
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
        """The ids of ``uid``'s neighbours now, ascending (a new list)."""
        if self.tick_plane:
            k = self._index.get(uid)
            return [] if k is None or k >= len(self._start) - 1 else self._nb[self._start[k]:self._start[k + 1]]
        return self._neighbours.get(uid, [])

    @property
    def _nb(self) -> list[int]:
        """The neighbour lists as a Python list (made once per change of links, when needed)."""
        if self._nb_list is None:
            self._nb_list = self._nb_arr.tolist()
        return self._nb_list

    def _links_of(self, src: int) -> dict[int, dict[str, float]]:
        """(tick plane) ``src``'s links' data by neighbour, as the graph's edge data holds it
        (``loss``, and ``margin_db`` with the log-distance model): made from the link table
        when a copy needs it this tick."""
        got = self._adj.get(src)
        if got is None:
            k = self._index[src]
            lo, hi = self._start[k], self._start[k + 1]
            _d, margin, loss = self._table_values()
            links = self._nb_link[lo:hi]
            if margin is None:
                got = {v: {"loss": p} for v, p in zip(self._nb[lo:hi], loss[links].tolist())}
            else:
                got = {v: {"loss": p, "margin_db": m}
                       for v, p, m in zip(self._nb[lo:hi], loss[links].tolist(), margin[links].tolist())}
            self._adj[src] = got
        return got

    def _rng(self, src: int, dst: int) -> np.random.Generator:
        rng = self._link_rngs.get((src, dst))
        if rng is None:
            rng = self._new_rng(src, dst)
        return rng

    def _new_rng(self, src: int, dst: int) -> np.random.Generator:
        """The stream of a link that has none yet (see _new_links), kept."""
        rngs = self._link_rngs
        if self._bulk is not None and self.tick_plane:
            # The links of the table whose streams were not made yet (the per-actor path lists
            # them as it adds edges; the table has no edges to add).
            new = np.setdiff1d(self._codes, self._streamed, assume_unique=True).tolist()
            self._streamed = self._codes
            self._new_links += [(c >> 32, c & 0xFFFFFFFF) for c in new] + [(c & 0xFFFFFFFF, c >> 32) for c in new]
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
        plane = self.tick_plane
        nbrs = self.neighbours(src) if plane else self._neighbours.get(src)
        if to is not None and nbrs:
            nbrs = [to] if (to in nbrs if plane else to in self._edges[src]) else None
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
        adj = self._links_of(src) if plane else self._edges[src]
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

    def broadcast_all(self, t: float, frames: list[tuple[int, bytes, int | None]],
                      on_lost: Callable[[int, int, int, str], object] | None = None) -> DeliveryBatch | None:
        """(tick plane) :meth:`broadcast` of each ``(src, data, to)`` in turn, at once, when no link
        filter acts, no log-distance model and no jitter: every copy arrives at the same time.
        The bandwidth budget is applied frame by frame, and a lossy link's draw made copy by copy
        from its own stream, as there (a lossy radio with a bandwidth cap goes frame by frame,
        which orders the two kinds of loss). Returns the surviving copies as one
        :class:`DeliveryBatch` (the same copies, in the same order, as the :class:`Delivery`
        records broadcast appends; the same counters, ``on_lost`` calls and draws), or None,
        having done nothing, when it does not apply (then broadcast each)."""
        model = self.model
        flt = self.filter
        bw = model.bandwidth_bytes_per_s
        if not self.tick_plane or (flt is not None and not getattr(flt, "idle", False)) \
                or model.log_distance is not None or model.jitter_s > 0.0 or (bw is not None and not self._lossless) \
                or len(self._nb_arr) < self.batch_min_links:
            return None
        index, start = self._index, self._start
        # Each frame's copies: entries lo .. lo + count of the neighbour lists (none for a sender
        # that is down: row -1).
        rows = np.array([index.get(f[0], -1) for f in frames], dtype=np.int64)
        start_arr = self._start_arr
        lo = start_arr[rows]
        cnt = np.where(rows >= 0, start_arr[rows + 1] - lo, 0)
        uni = [(f, fr[2]) for f, fr in enumerate(frames) if fr[2] is not None]
        if uni:  # unicast: the one entry of `to` among the sender's neighbours, if any
            keys = self._nb_keys
            if keys is None:
                width = max(self._ids, default=0) + 1
                keys = self._nb_keys = np.repeat(np.arange(len(start) - 1), np.diff(self._start_arr)) * width \
                    + self._nb_arr
            f_u = np.array([f for f, _ in uni], dtype=np.int64)
            to_u = np.array([to for _, to in uni], dtype=np.int64)
            want = rows[f_u] * (max(self._ids, default=0) + 1) + to_u
            j = np.minimum(np.searchsorted(keys, want), max(len(keys) - 1, 0))
            hit = (rows[f_u] >= 0) & (cnt[f_u] > 0) & (to_u <= max(self._ids, default=0))
            if len(keys):
                hit &= keys[j] == want
            lo[f_u] = np.where(hit, j, lo[f_u])
            cnt[f_u] = hit
        sizes = np.array([len(fr[1]) for fr in frames], dtype=np.int64)
        c = self.counters
        c.sent += int(cnt.sum())
        c.bytes_sent += int((sizes * cnt).sum())
        if bw is not None:  # the senders' budgets, frame by frame in turn
            tokens = self._tokens
            for f, (src, data, _to) in enumerate(frames):
                n = int(cnt[f])
                if not n:
                    continue
                size = len(data)
                if tokens.get(src, 0.0) < size:
                    c.drop("bandwidth", n)
                    if on_lost is not None:
                        for dst in self._nb[lo[f]:lo[f] + n]:
                            on_lost(src, dst, size, "bandwidth")
                    cnt[f] = 0
                    continue
                tokens[src] -= size
        frame = np.repeat(np.arange(len(cnt)), cnt)
        # copy k of frame f: neighbour entry lo[f] + (k - the first copy of f)
        entry = np.repeat(lo - (np.cumsum(cnt) - cnt), cnt) + np.arange(len(frame))
        senders = np.array([fr[0] for fr in frames], dtype=np.int64)
        receivers = self._nb_arr[entry]
        if not self._lossless:  # each copy on a lossy link: one draw from its link's stream, in turn
            p = self._table_values()[2][self._nb_link[entry]]
            drawn = np.flatnonzero(p > 0.0)
            if len(drawn):
                keep = np.ones(len(frame), dtype=bool)
                rngs = self._link_rngs
                fr_d = frame[drawn]
                for k, f, s, d, pk in zip(drawn.tolist(), fr_d.tolist(), senders[fr_d].tolist(),
                                          receivers[drawn].tolist(), p[drawn].tolist()):
                    rng = rngs.get((s, d))
                    if rng is None:
                        rng = self._new_rng(s, d)
                    if rng.random() < pk:
                        keep[k] = False
                        c.drop("loss")
                        if on_lost is not None:
                            on_lost(s, d, len(frames[f][1]), "loss")
                frame, receivers = frame[keep], receivers[keep]
        return DeliveryBatch(t + model.latency_s, [fr[1] for fr in frames], senders, frame, receivers)
