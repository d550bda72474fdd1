"""The tick plane against its oracle (issue 36): two simulations in lockstep, compared every tick.

``Simulation(..., tick_plane=True)`` does the tick's array work in per-tick services for all
UAVs at once; ``tick_plane=False`` runs the per-actor code those services replace, kept as the
specification. The two must agree exactly: not only the event log (which records what UAVs
did), but every actor's state after every tick (what they know, which decides what they do
later, possibly after the run a test looks at). :func:`lockstep` builds both from the same
scenario and arguments, steps them one tick at a time, compares :func:`tick_state` after each
tick and the event logs' bytes, and returns the first :class:`Difference` (the tick, the UAV and
the field), or None::

    from swarm.testing.oracle import assert_lockstep
    assert_lockstep("paper-case1", duration_s=60, seed=3)

What a UAV's state is here (:func:`actor_state`): its map cell for cell (a digest of the
last-seen times' bytes), its scan log (a digest of every scan held, in order, and the count), its peers,
tracks and threats (in the order its dictionaries hold them: insertion order is state too), its
counters, its mailbox (frames waiting, and the mailbox's statistics), the digests it heard and
has not answered, its plan and its frame sequence number. Values are compared by ``repr`` (so a
NaN equals a NaN, and ``0.1`` and ``0.1000000001`` differ).

Needs nothing but the simulator (no Hypothesis): a script can call it too.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agents.actor import UavActor
from agents.maps.scanlog import ScanLog
from agents.maps.umap import NEVER, UncertaintyMap
from swarm.kernel.simulation import Simulation
from swarm.scenario import Scenario

__all__ = ["FIELDS", "Difference", "actor_state", "assert_lockstep", "compare", "lockstep", "tick_state"]

# The fields of actor_state, in the order they are compared (the first that differs is reported).
FIELDS = ("map", "scans", "peers", "tracks", "threats", "counters", "mailbox", "digests", "plan", "seq")

State = dict[str, Any]
Tamper = Callable[[Simulation, int], None]


@dataclass(frozen=True)
class Difference:
    """Where the tick plane first departs from the oracle."""

    tick: int  # ticks run when it was seen (0: as built, before the first tick)
    uav: int | None  # the UAV whose state differs (None: the event log, or which UAVs have actors)
    field: str  # a name of FIELDS, "actors" or "events"
    plane: str  # what the tick-plane simulation holds (shortened)
    oracle: str  # what the oracle holds (shortened)

    def __str__(self) -> str:
        who = f"UAV {self.uav}" if self.uav is not None else "the simulation"
        return (f"tick {self.tick}: {who} differs in {self.field}:\n  tick plane: {self.plane}\n"
                f"  oracle:     {self.oracle}")


def _digest(data: bytes | memoryview) -> str:
    return hashlib.blake2b(data, digest_size=16).hexdigest()


def map_digest(umap: UncertaintyMap) -> str:
    """A digest of a map's cells: of the whole grid for a dense map; for a tiled one, of each
    tile that holds a cell ever seen, with its key (an allocated tile still all ``-inf`` counts
    as absent: storage, not content). Cheap on a large tiled map, unlike a dense copy."""
    if umap.dense:
        return _digest(umap.to_dense().tobytes())
    h = hashlib.blake2b(digest_size=16)
    th, tw = umap.tile_shape
    ntx = -(-umap.grid.nx // tw)
    for r0, _r1, c0, _c1 in umap.written_boxes():
        key = (r0 // th) * ntx + c0 // tw
        tile = umap.tile(key)
        if tile is not None and bool((tile != NEVER).any()):
            h.update(key.to_bytes(8, "little"))
            h.update(tile.tobytes())
    return h.hexdigest()


def scans_digest(log: ScanLog) -> tuple[int, str]:
    """A scan log's count and a digest of every scan it holds, in its order, as doubles
    ``(origin, t, x, y, r)`` (a cheap stand-in for the list, which grows over a run)."""
    rows = [(origin, *scan) for origin, scan in log.scans()]
    return log.count, _digest(np.array(rows, dtype=np.float64).tobytes())


def actor_state(actor: UavActor) -> State:
    """One actor's state as comparable values (see the module docstring), by field of :data:`FIELDS`."""
    k = actor.knowledge
    mailbox = actor.mailbox
    return {
        "map": map_digest(actor.umap),
        "scans": scans_digest(actor.scans),
        "peers": list(k.peers.values()),
        "tracks": list(k.tracks.values()),
        "threats": list(k.threats.values()),
        "counters": actor.counters,
        # (read without draining: the simulation's own mailbox is not to be disturbed)
        "mailbox": (list(mailbox._items), mailbox.stats),
        "digests": list(actor.inbox.digests),
        "plan": actor.plan,
        "seq": actor._seq,
    }


def tick_state(sim: Simulation) -> dict[int, State]:
    """Every actor's :func:`actor_state`, by UAV id (crashed UAVs' actors included: their state
    is what a restart would not keep, but it must still agree)."""
    return {uid: actor_state(actor) for uid, actor in sorted(sim.actors.items())}


def _short(value: Any, limit: int = 300) -> str:
    s = repr(value)
    return s if len(s) <= limit else s[:limit] + f"... ({len(s)} characters)"


def _first_difference(a: Any, b: Any) -> tuple[str, str]:
    """Short descriptions of ``a`` and ``b`` around where they first differ (lists: the item)."""
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        for i, (x, y) in enumerate(zip(a, b)):
            if repr(x) != repr(y):
                px, py = _first_difference(x, y)
                return f"[{i}] {px}", f"[{i}] {py}"
        if len(a) != len(b):
            return f"{len(a)} items, extra: {_short(a[len(b):])}", f"{len(b)} items, extra: {_short(b[len(a):])}"
    return _short(a), _short(b)


def compare(tick: int, plane: dict[int, State], oracle: dict[int, State]) -> Difference | None:
    """The first difference between two :func:`tick_state` results (UAV by UAV, field by field)."""
    if list(plane) != list(oracle):
        return Difference(tick, None, "actors", _short(list(plane)), _short(list(oracle)))
    for uid, sa in plane.items():
        so = oracle[uid]
        for name in FIELDS:
            a, b = sa[name], so[name]
            if repr(a) != repr(b):
                pa, pb = _first_difference(a, b)
                return Difference(tick, uid, name, pa, pb)
    return None


def lockstep(scenario: Scenario | str | Path, *, ticks: int | None = None, tamper: Tamper | None = None,
             **kw: Any) -> Difference | None:
    """Run ``scenario`` twice, ``tick_plane=True`` and ``False`` (other keyword arguments, e.g.
    ``seed``, ``duration_s``, ``planner``, go to both :class:`Simulation` s), one tick at a
    time for ``ticks`` ticks (default: the whole run); after every tick compare
    :func:`tick_state` and the event logs so far; at the end the event logs' bytes. Returns the
    first :class:`Difference`, or None when they agree throughout.

    ``tamper(sim, tick)``: called on the tick-plane simulation after each tick (``tick`` ticks
    run), before the comparison: a test's planted fault, to show a difference is found."""
    with Simulation(scenario, tick_plane=True, **kw) as plane, Simulation(scenario, tick_plane=False, **kw) as oracle:
        n = plane.n_ticks if ticks is None else min(ticks, plane.n_ticks)
        diff = compare(0, tick_state(plane), tick_state(oracle))
        if diff is not None:
            return diff
        for tick in range(1, n + 1):
            plane.step()
            oracle.step()
            if tamper is not None:
                tamper(plane, tick)
            diff = compare(tick, tick_state(plane), tick_state(oracle))
            if diff is not None:
                return diff
            ha, hb = plane._log.sha256(), oracle._log.sha256()
            if ha != hb:
                return Difference(tick, None, "events", f"log sha256 {ha[:16]}", f"log sha256 {hb[:16]}")
        ea, eb = plane._log.to_bytes(), oracle._log.to_bytes()
        if ea != eb:
            i = next((i for i, (x, y) in enumerate(zip(ea, eb)) if x != y), min(len(ea), len(eb)))
            return Difference(n, None, "events", f"{len(ea)} bytes, first difference at byte {i}",
                              f"{len(eb)} bytes")
    return None


def assert_lockstep(scenario: Scenario | str | Path, **kw: Any) -> None:
    """:func:`lockstep`, raising ``AssertionError`` with the first difference."""
    diff = lockstep(scenario, **kw)
    assert diff is None, str(diff)

