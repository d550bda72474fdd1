"""The typed messages UAVs exchange. Plain immutable data: no behaviour, no planner knowledge.

A frame (see :mod:`comms.codec`) carries one or more of these. Ids are the simulator's integer
UAV / target / threat ids; times are simulated seconds; positions metres; angles radians.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

# A UAV's task (Intent.mode, Plan.mode, the ``mode`` of pose events) and its name in outputs
# (timeseries.csv, metrics.json, figures).
MODE_SEARCH = 0
MODE_SURVEIL = 1
MODE_NAMES: dict[int, str] = {MODE_SEARCH: "search", MODE_SURVEIL: "surveil"}
NO_TARGET = -1


# Hello, Intent and TrackItem are what a receiver keeps of every frame it hears (a beacon's
# two, a Tracks message's tens; agents.inbox.Heard): immutable named tuples, built about three
# times faster than frozen dataclasses. The other messages are frozen dataclasses.


class Hello(NamedTuple):
    """Presence and pose: how a UAV learns that another exists and where it is."""

    uav: int
    type: str
    x: float
    y: float
    v: float
    theta: float


class Intent(NamedTuple):
    """The sender's next waypoint and task (eq. 23 needs other UAVs' next waypoints)."""

    uav: int
    wx: float
    wy: float
    mode: int  # MODE_SEARCH or MODE_SURVEIL
    target: int  # target being watched, NO_TARGET when searching


@dataclass(frozen=True, slots=True)
class ScanRecords:
    """Disks the sender scanned: a compact delta of its uncertainty map.

    ``records`` is a flat tuple ``(t, x, y, r, t, x, y, r, ...)``; a receiver applies each as a
    per-cell max, which is all the map CRDT needs.
    """

    uav: int
    records: tuple[float, ...]


class TrackItem(NamedTuple):
    target: int
    x: float
    y: float
    vx: float
    vy: float
    t: float  # time of the sighting
    value: float


@dataclass(frozen=True, slots=True)
class Tracks:
    """Target sightings the sender knows of; newest sighting per target wins on merge."""

    items: tuple[TrackItem, ...]


@dataclass(frozen=True, slots=True)
class ThreatItem:
    threat: int
    x: float
    y: float
    radius: float
    d_max: float


@dataclass(frozen=True, slots=True)
class Threats:
    """Known threats (never forgotten once known)."""

    items: tuple[ThreatItem, ...]


@dataclass(frozen=True, slots=True)
class ScanDigest:
    """Anti-entropy: which scans the sender knows (see :mod:`agents.maps.scanlog`).

    ``bitmaps`` holds ``(origin, bits)`` pairs: bit ``j % 8`` of byte ``j // 8`` set when the
    sender knows ``origin``'s scan of tick ``tick0 + j``, for ticks up to ``t_cut``. The digest
    speaks for the origins ``lo..hi``: one of those not listed is one the sender knows nothing
    of in the window (a swarm's digest may be split over several beacons). A neighbour answers
    with :class:`ScanRecords` of the scans the sender lacks.
    """

    uav: int
    t_cut: float
    tick0: int
    lo: int
    hi: int
    bitmaps: tuple[tuple[int, bytes], ...]


@dataclass(frozen=True, slots=True)
class TrackDigest:
    """Tracks on change (``[radio] tracks = "on_change"``, :mod:`agents.tracksync`): what the
    sender knows of tracks and threats at ``t``: the target of each track it holds with its
    sighting's time (``targets[i]`` seen at ``times[i]``), and the threats' ids. A neighbour
    answers with the tracks and threats the sender lacks, or holds more than
    ``tracks_every_s`` older than its own."""

    uav: int
    t: float
    targets: tuple[int, ...]
    times: tuple[float, ...]
    threats: tuple[int, ...]


Message = Hello | Intent | ScanRecords | Tracks | Threats | ScanDigest | TrackDigest
