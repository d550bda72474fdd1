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
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol

import networkx as nx
import numpy as np
from scipy.spatial import cKDTree
from scipy.special import expit

# A link whose mean margin is below -(edge_sigmas * sigma + _EDGE_WIDTHS * width) dB is no edge:
# even shadowing edge_sigmas sigma above its mean leaves it losing > 98% of its frames.
_EDGE_WIDTHS = 4.0


@dataclass(frozen=True, slots=True)
class LogDistance:
    """Log-distance path loss with log-normal shadowing, and a logistic frame loss in the margin.

    The received power of a frame on a link ``d`` metres long (``d`` at least 1 m) is::

        rx_dbm = tx_power_dbm + antenna_gain_db - ref_loss_db - 10 * exponent * log10(d) + X

    ``X`` the link's shadowing (dB): normal, mean 0, sd ``sigma_db``, slowly varying (a Gauss-Markov
    process, exact at the frames' times: ``X' = rho X + sigma sqrt(1 - rho^2) N(0, 1)`` with
    ``rho = exp(-dt / corr_s)``), drawn from the directed link's own stream. The frame is lost
    with probability ``1 / (1 + exp(margin / width_db))``, ``margin = rx_dbm - sensitivity_dbm``:
    half the frames at the sensitivity, 10% at 2.2 widths above it, 1% at 4.6.

    The defaults are a small UAV's 2.4 GHz radio in open air (air-to-air, line of sight):
    20 dBm out, 0 dBi antennas, -90 dBm sensitivity; the free-space exponent 2 and 40.05 dB at
    1 m (free space at 2.4 GHz, 20 log10(4 pi f / c)); 3 dB of shadowing. Measurement campaigns
    of small-UAV links in open field report exponents of 2.0-2.3 and shadowing of 2.5-5 dB (the
    campaigns surveyed in Khawaja et al., "A Survey of Air-to-Ground Propagation Channel Modeling
    for Unmanned Aerial Vehicles", IEEE Communications Surveys & Tutorials, 2019). The correlation
    time (5 s: a few hundred metres of relative flight) is our choice. Half the frames get through
    at :attr:`median_range_m` (3.1 km with the defaults); the radio graph's edges reach
    :attr:`range_m` (14 km).

    The one definition of these settings: a scenario's ``[radio.log_distance]`` table is built
    from this class by :mod:`swarm.scenario.model`.
    """

    tx_power_dbm: float = field(default=20.0, metadata={"note": "dBm"})
    antenna_gain_db: float = field(default=0.0, metadata={"note": "dB, the transmit and receive antennas' gains together"})
    ref_loss_db: float = field(default=40.05, metadata={"ge": 0, "note": "dB of path loss at 1 m"})
    exponent: float = field(default=2.0, metadata={"gt": 0, "le": 10, "note": "path-loss exponent; 2 = free space"})
    sigma_db: float = field(default=3.0, metadata={"ge": 0, "le": 30, "note": "dB, sd of the log-normal shadowing"})
    corr_s: float = field(default=5.0, metadata={"gt": 0, "note": "seconds, correlation time of the shadowing"})
    sensitivity_dbm: float = field(default=-90.0, metadata={"note": "dBm, where half the frames are lost"})
    width_db: float = field(default=1.0, metadata={"gt": 0, "note": "dB, scale of the logistic loss curve"})
    edge_sigmas: float = field(default=3.0, metadata={"ge": 0, "le": 10,
                                                      "note": "shadowing sds the radio graph reaches below the sensitivity"})

    @property
    def budget_db(self) -> float:
        """The mean margin at 1 m (dB above the sensitivity)."""
        return self.tx_power_dbm + self.antenna_gain_db - self.ref_loss_db - self.sensitivity_dbm

    def margin_db(self, distance: float) -> float:
        """The mean margin (no shadowing) of a link ``distance`` metres long."""
        return self.budget_db - 10.0 * self.exponent * math.log10(max(distance, 1.0))

    def frame_loss(self, margin_db: float) -> float:
        """The loss probability of a frame received ``margin_db`` above the sensitivity."""
        z = margin_db / self.width_db
        if z >= 0.0:  # (two forms: neither exp overflows)
            e = math.exp(-z)
            return e / (1.0 + e)
        return 1.0 / (1.0 + math.exp(z))

    def _distance_at(self, margin_db: float) -> float:
        return max(1.0, math.pow(10.0, min((self.budget_db - margin_db) / (10.0 * self.exponent), 300.0)))

    @property
    def median_range_m(self) -> float:
        """Where the mean margin is 0: half the frames lost (without shadowing)."""
        return self._distance_at(0.0)

    @property
    def range_m(self) -> float:
        """The radio graph's reach: where the mean margin is ``-(edge_sigmas * sigma_db + 4 *
        width_db)`` dB (beyond it a link loses > 98% of its frames even with shadowing
        ``edge_sigmas`` sd above its mean)."""
        return self._distance_at(-(self.edge_sigmas * self.sigma_db + _EDGE_WIDTHS * self.width_db))


@dataclass(frozen=True, slots=True)
class LinkModel:
    """Range limit, loss and latency of every link (the scenario's ``[radio]`` table).

    Two propagation models. The *disk* model (``log_distance`` None): every pair within
    ``range_m`` is linked, and a frame is lost with probability
    ``loss_base + (loss_at_range - loss_base) * (d / range_m)^2`` (``loss_base`` at distance 0,
    ``loss_at_range`` at the range limit; ``loss_base`` everywhere when the range is unlimited).
    ``loss_at_range`` defaults to ``loss_base`` (the same loss at every distance) and may not be
    below it: loss never falls with distance. The *log-distance* model (:class:`LogDistance`):
    the loss comes from the link budget and the link's shadowing, with ``loss_base`` as a floor
    that hits every frame independently (``loss = loss_base + (1 - loss_base) * link loss``);
    the pairs linked are those within the budget's :attr:`LogDistance.range_m` and within
    ``range_m`` if that is given too; ``loss_at_range`` is not used (the scenario refuses it).
    """

    range_m: float | None = None  # None: unlimited
    loss_base: float = 0.0  # loss probability at distance 0
    loss_at_range: float | None = None  # loss probability at the range limit (quadratic in between); None: loss_base
    latency_s: float = 0.0
    jitter_s: float = 0.0
    bandwidth_bytes_per_s: float | None = None  # per sender; None: unlimited
    log_distance: LogDistance | None = None  # None: the disk model

    def __post_init__(self) -> None:
        at = self.loss_at_range
        if at is None:  # (so LinkModel(loss_base=p) == LinkModel(loss_base=p, loss_at_range=p))
            object.__setattr__(self, "loss_at_range", self.loss_base)
        elif at < self.loss_base and self.log_distance is None:
            raise ValueError(f"loss_at_range ({at}) < loss_base ({self.loss_base}): loss must not fall with distance")

    @property
    def range_loss(self) -> float:
        """The disk model's loss at the range limit: ``loss_at_range`` (``loss_base`` if given as None)."""
        return self.loss_base if self.loss_at_range is None else self.loss_at_range

    @property
    def radius_m(self) -> float:
        """How far links reach (math.inf: unlimited): ``range_m``, and for the log-distance model
        at most its link budget's :attr:`LogDistance.range_m`."""
        r = math.inf if self.range_m is None else self.range_m
        return r if self.log_distance is None else min(r, self.log_distance.range_m)

    def loss(self, distance: float) -> float:
        """The loss probability of a link ``distance`` metres long (log-distance: at its mean,
        without shadowing)."""
        ld = self.log_distance
        if ld is not None:
            return self.loss_base + (1.0 - self.loss_base) * ld.frame_loss(ld.margin_db(distance))
        if self.range_m is None or not math.isfinite(self.range_m):
            return self.loss_base
        f = min(distance / self.range_m, 1.0)
        return self.loss_base + (self.range_loss - self.loss_base) * f * f


# networkx's adjacency dict-of-dicts (node -> neighbour -> edge data), read directly in the hot
# paths below: Graph._adj, which the stubs leave out (it is private; Graph.adj is a view of it).
_Adjacency = dict[int, dict[int, dict[str, float]]]


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
    ):
        self.model = model
        self._link_rng_factory = link_rng
        self._link_rngs: dict[tuple[int, int], np.random.Generator] = {}
        self.filter = link_filter
        self.graph: nx.Graph[int] = nx.Graph()
        self.counters = RadioCounters()
        self._tokens: dict[int, float] = {}
        self._neighbours: dict[int, list[int]] = {}
        self._edge_codes = np.empty(0, np.int64)  # (u << 32) | v of the graph's edges, u < v
        self._ids: list[int] = []  # the ids of the last update
        self._all_pair_ids: list[tuple[int, int]] = []  # unlimited range: the edges, in pair order
        self._all_pairs: tuple[int, tuple[np.ndarray, np.ndarray]] = (-1, (np.empty(0, np.int64),) * 2)
        # Every link's loss probability is 0: no per-link draw is ever made for loss.
        self._lossless = model.log_distance is None and model.loss_base == 0.0 and (
            model.range_m is None or not math.isfinite(model.range_m) or model.range_loss == 0.0
        )
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
        adj: _Adjacency = g._adj  # type: ignore[attr-defined]  # the edge data dicts themselves (see _Adjacency)
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
            loss_base = model.loss_base
            for (u, v), dd in zip(self._all_pair_ids, d.tolist()):
                edge = adj[u][v]
                edge["distance"] = dd
                edge["loss"] = loss_base
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
        # LinkModel.loss, vectorised: the disk model's with the same operations in the same order,
        # the log-distance model's (expit for its two-form logistic) to rounding.
        margin = None
        if ld is not None:  # (the margin is kept on the edge: broadcast adds the shadowing)
            margin = ld.budget_db - 10.0 * ld.exponent * np.log10(np.maximum(d, 1.0))
            loss = model.loss_base + (1.0 - model.loss_base) * expit(-margin / ld.width_db)
        elif unlimited:
            loss = np.full(len(d), model.loss_base)
        else:
            f = np.minimum(d / rng_m, 1.0)
            loss = model.loss_base + (model.range_loss - model.loss_base) * f * f
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
            rng = self._link_rngs[(src, dst)] = self._link_rng_factory(src, dst)
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
        base = self.model.loss_base
        return base + (1.0 - base) * ld.frame_loss(margin_db + x)

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
            nbrs = [to] if to in self.graph._adj[src] else None  # type: ignore[attr-defined]  # see _Adjacency
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
        adj: dict[int, dict[str, float]] = self.graph._adj[src]  # type: ignore[attr-defined]  # see _Adjacency
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
                        rng = rngs[(src, dst)] = self._link_rng_factory(src, dst)
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
