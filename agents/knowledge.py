"""What a UAV knows besides its map: target tracks, threats, and the other UAVs it has heard.

All of it comes from its own sensor or from frames it decoded; merges are "newest wins" for
tracks and peers and "never forget" for threats, so duplicated or reordered frames are harmless.
"""

from __future__ import annotations

import math
from bisect import insort
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from operator import attrgetter
from typing import TYPE_CHECKING

from comms.messages import NO_TARGET, TrackItem

if TYPE_CHECKING:
    from agents.zones import Keepout


@dataclass(slots=True)
class Track:
    target: int
    x: float
    y: float
    vx: float
    vy: float
    t: float
    value: float = 1.0

    def predict(self, t: float, horizon_s: float = 60.0) -> tuple[float, float]:
        """Dead-reckoned position, extrapolated at most ``horizon_s`` past the sighting."""
        dt = min(max(t - self.t, 0.0), horizon_s)
        return self.x + self.vx * dt, self.y + self.vy * dt


# A heard track item's fields: (target, x, y, vx, vy, t, value) (Knowledge.merge_track_rows).
TrackRow = tuple[int, float, float, float, float, float, float]


@dataclass(frozen=True, slots=True)
class KnownThreat:
    threat: int
    x: float
    y: float
    radius: float
    d_max: float


@dataclass(slots=True)
class Peer:
    """Another UAV as last heard: pose from its Hello, plan from its Intent."""

    uav: int
    type: str = ""
    x: float = math.nan
    y: float = math.nan
    v: float = 0.0
    theta: float = 0.0
    t_pose: float = -math.inf
    wx: float = math.nan
    wy: float = math.nan
    mode: int = 0
    target: int = NO_TARGET
    t_intent: float = -math.inf
    # (issue 33) It watches ``target`` and asks for relief (its intent: search with the target's
    # id); ``mode`` is then surveillance: the planners see it watching, as it does.
    asks: bool = False


_uav_of = attrgetter("uav")


def threat_clearance(th: KnownThreat, x: float, y: float) -> tuple[float, float, float]:
    """``(rho, ux, uy)`` of a circular zone, as :meth:`agents.zones.Keepout.clearance` gives
    for a polygon: the signed distance from its edge (negative inside) and the unit normal
    pointing away from it at ``(x, y)``."""
    ex, ey = x - th.x, y - th.y
    dc = math.hypot(ex, ey)
    if dc <= 1e-9:
        return -th.radius, 1.0, 0.0
    return dc - th.radius, ex / dc, ey / dc


def zone_clearance(zone: KnownThreat | Keepout, x: float, y: float) -> tuple[float, float, float]:
    """``(rho, ux, uy)`` of a no-fly zone, a circle (sensed or heard) or a polygon (known before
    take-off), alike (see :func:`threat_clearance`)."""
    if isinstance(zone, KnownThreat):
        return threat_clearance(zone, x, y)
    return zone.clearance(x, y)


class Knowledge:
    __slots__ = ("tracks", "threats", "no_fly", "peers", "_by_id", "changed", "new_threats")

    def __init__(self, no_fly: Sequence[Keepout] = ()) -> None:
        self.tracks: dict[int, Track] = {}
        self.threats: dict[int, KnownThreat] = {}
        # (issue 33) The polygon no-fly zones (agents.zones, not the area's boundary): known
        # before take-off, never learned or sent.
        self.no_fly: tuple[Keepout, ...] = tuple(no_fly)
        self.peers: dict[int, Peer] = {}
        # The peers in id order, kept as they are added (peer()): recent_peers() runs for every
        # UAV every tick and peers only grow (issue 25: it sorted them all each time).
        self._by_id: list[Peer] = []
        # (issue 36, M1) What changed since the UAV last sent it (agents.tracksync takes them):
        # the targets whose track was added or updated, the threats added.
        self.changed: set[int] = set()
        self.new_threats: list[int] = []

    def see_target(self, target: int, x: float, y: float, vx: float, vy: float, t: float, value: float) -> bool:
        """Record a sighting; True if the target was unknown before."""
        tr = self.tracks.get(target)
        if tr is None:
            self.tracks[target] = Track(target, x, y, vx, vy, t, value)
            self.changed.add(target)
            return True
        if t >= tr.t:
            tr.x, tr.y, tr.vx, tr.vy, tr.t, tr.value = x, y, vx, vy, t, value
            self.changed.add(target)
        return False

    def merge_track(self, item: TrackItem) -> None:
        self.see_target(item.target, item.x, item.y, item.vx, item.vy, item.t, item.value)

    def merge_tracks(self, items: Iterable[TrackItem]) -> None:
        """:meth:`merge_track` of each item in order (a heard Tracks message): :meth:`merge_track_rows`
        of their fields."""
        self.merge_track_rows([(it.target, it.x, it.y, it.vx, it.vy, it.t, it.value) for it in items])

    def merge_track_rows(self, rows: Iterable[TrackRow]) -> None:
        """:meth:`see_target` of each ``(target, x, y, vx, vy, t, value)`` in order, its rule
        written out (one call per message instead of one per item): the receive service keeps a
        heard Tracks message's items as such rows for all its receivers (agents.inbox.Taken)."""
        tracks = self.tracks
        changed = self.changed.add
        for target, x, y, vx, vy, t, value in rows:
            tr = tracks.get(target)
            if tr is None:
                tracks[target] = Track(target, x, y, vx, vy, t, value)
                changed(target)
            elif t >= tr.t:
                tr.x, tr.y, tr.vx, tr.vy, tr.t, tr.value = x, y, vx, vy, t, value
                changed(target)

    def inside_threat(self, x: float, y: float, margin: float = 0.0) -> KnownThreat | None:
        """The first known threat (by id) whose circle, widened by ``margin``, holds ``(x, y)``,
        or None."""
        for _, th in sorted(self.threats.items()):
            if math.hypot(x - th.x, y - th.y) < th.radius + margin:
                return th
        return None

    def near_no_fly(self, x: float, y: float, reach: float = 0.0) -> KnownThreat | Keepout | None:
        """The first no-fly zone, circle (by id) then polygon (in order), that holds ``(x, y)``
        or lies within ``reach`` of it, or None: circles and polygons alike (docs/modelling.md,
        "Assignment rules", rule 5)."""
        th = self.inside_threat(x, y, reach) if self.threats else None
        if th is not None:
            return th
        for z in self.no_fly:
            if z.clearance(x, y)[0] < reach:
                return z
        return None

    def add_threat(self, threat: int, x: float, y: float, radius: float, d_max: float) -> None:
        if threat not in self.threats:
            self.threats[threat] = KnownThreat(threat, x, y, radius, d_max)
            self.new_threats.append(threat)

    def peer(self, uav: int) -> Peer:
        p = self.peers.get(uav)
        if p is None:
            p = self.peers[uav] = Peer(uav)
            by_id = self._by_id
            if by_id and by_id[-1].uav > uav:
                insort(by_id, p, key=_uav_of)
            else:
                by_id.append(p)
        return p

    def recent_peers(self, t: float, max_age_s: float) -> list[Peer]:
        """Peers heard from within ``max_age_s``, in id order (deterministic)."""
        if len(self._by_id) != len(self.peers):  # (peers added to the dict directly: sort them)
            self._by_id = [p for _, p in sorted(self.peers.items())]
        return [p for p in self._by_id if t - p.t_pose <= max_age_s]
