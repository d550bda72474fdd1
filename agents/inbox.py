"""What a receiver accepts of one decoded frame, checked once for all its receivers.

A broadcast frame reaches hundreds of UAVs in a dense swarm as the same bytes, decoded once
(:class:`comms.framecache.DecodeCache`). Checking its numbers (:func:`check_frame`) depends only
on the frame, the receiver's clock ``t`` and the area's bounds, which every receiver in a tick
shares, so the result (:class:`Heard`) is memoised beside the decoded frame
(:attr:`DecodeCache.derived`) and each receiver (:meth:`agents.actor.UavActor._drain_inbox`)
only does what depends on its own state: its knowledge horizon, its scan log, its map, its
peers. A pure function of ``(frame, t, bounds)``: the memo changes how often it runs, never
what a receiver gets.
"""

from __future__ import annotations

from dataclasses import dataclass

from agents.maps.grid import DiskKey, Grid
from comms.codec import Frame
from comms.messages import Hello, Intent, ScanDigest, ScanRecords, Threats, TrackItem, Tracks

# What a receiver accepts of heard numbers: ids below 2**31, speeds and velocities within
# 10 km/s, headings within 1000 rad, track values within 1e12, digest cuts no earlier than
# 1e9 s before the start. Far beyond anything honest, far below overflow.
MAX_ID = 2**31
MAX_SPEED = 1.0e4
MAX_ANGLE = 1.0e3
MAX_VALUE = 1.0e12
MAX_TIME = 1.0e9

# A plausible scan of a frame: (origin, tick, (t, x, y, r), (x, y, r)), the last its disk's key
# in the grid's memo (Grid.disk_lookup). Not the disk itself: kept with the frame, disks would
# outlive the grid's bounded memo (a resent frame can carry hundreds of scans).
HeardScan = tuple[int, int, tuple[float, float, float, float], DiskKey]
Bounds = tuple[float, float, float, float]  # (max scan radius, width, height, dt): see check_frame


@dataclass(frozen=True, slots=True)
class Heard:
    """A frame's messages as a receiver at ``t`` accepts them (in the frame's order per kind)."""

    t: float  # the receiver's clock it was checked for
    bounds: Bounds  # and the bounds
    grid: Grid  # and the grid (whose disks these are)
    t_frame: float  # the frame's time (what heard poses and intents are stamped with)
    scans: tuple[HeardScan, ...]
    ignored: int  # implausible scans (counters.scans_ignored)
    strange: int  # other messages no honest UAV sends (counters.messages_ignored)
    hellos: tuple[Hello, ...]
    intents: tuple[Intent, ...]
    tracks: tuple[TrackItem, ...]  # every sane item of every Tracks message, in order
    threats: tuple[tuple[int, float, float, float, float], ...]
    digests: tuple[ScanDigest, ...]


def check_frame(frame: Frame, t: float, bounds: Bounds, grid: Grid) -> Heard:
    """The messages of ``frame`` a receiver at ``t`` accepts. ``bounds`` = ``(max_r, width,
    height, dt)``: places may lie up to ``max_r`` outside the ``width x height`` area, scan radii
    up to ``max_r``; times not after ``t``; ids and speeds in ranges no arithmetic can overflow.
    A frame stamped in the future (or before the run) is ignored whole. Each plausible scan
    comes with its tick (``round(t / dt)``, the scan log's) and its disk's key. ``grid``: whose
    disks the receivers look up (a Heard is only reused by receivers of the same grid)."""
    max_r, width, height, dt = bounds
    ft = frame.t
    if not 0.0 <= ft <= t:
        return Heard(t, bounds, grid, ft, (), 0, len(frame.messages), (), (), (), (), ())
    lo_x, hi_x, lo_y, hi_y = -max_r, width + max_r, -max_r, height + max_r
    scans: list[HeardScan] = []
    hellos: list[Hello] = []
    intents: list[Intent] = []
    tracks: list[TrackItem] = []
    threats: list[tuple[int, float, float, float, float]] = []
    digests: list[ScanDigest] = []
    ignored = strange = 0
    for m in frame.messages:
        if type(m) is ScanRecords:
            origin = m.uav
            it = iter(m.records)
            for tr, x, y, rr in zip(it, it, it, it):
                # A scan from the future would pin cells at q=0: only accept the past.
                if 0.0 <= tr <= t and 0.0 <= rr <= max_r and lo_x <= x <= hi_x and lo_y <= y <= hi_y:
                    scans.append((origin, round(tr / dt), (tr, x, y, rr), (x, y, rr)))
                else:
                    ignored += 1
        elif type(m) is Hello:
            if (0 <= m.uav < MAX_ID and lo_x <= m.x <= hi_x and lo_y <= m.y <= hi_y
                    and 0.0 <= m.v <= MAX_SPEED and -MAX_ANGLE <= m.theta <= MAX_ANGLE):
                hellos.append(m)
            else:
                strange += 1
        elif type(m) is Intent:
            if 0 <= m.uav < MAX_ID and lo_x <= m.wx <= hi_x and lo_y <= m.wy <= hi_y and -1 <= m.target < MAX_ID:
                intents.append(m)
            else:
                strange += 1
        elif type(m) is Tracks:
            items = m.items
            sane = [it for it in items
                    if 0 <= it.target < MAX_ID and lo_x <= it.x <= hi_x and lo_y <= it.y <= hi_y
                    and -MAX_SPEED <= it.vx <= MAX_SPEED and -MAX_SPEED <= it.vy <= MAX_SPEED
                    and 0.0 <= it.t <= t and -MAX_VALUE <= it.value <= MAX_VALUE]
            strange += len(items) - len(sane)
            tracks.extend(sane)
        elif type(m) is Threats:
            for th in m.items:
                if (0 <= th.threat < MAX_ID and lo_x <= th.x <= hi_x and lo_y <= th.y <= hi_y
                        and 0.0 < th.radius < th.d_max <= 2 * max_r):
                    threats.append((th.threat, th.x, th.y, th.radius, th.d_max))
                else:
                    strange += 1
        elif type(m) is ScanDigest:
            if 0 <= m.uav < MAX_ID and -MAX_TIME <= m.t_cut <= t:
                digests.append(m)
            else:
                strange += 1
    return Heard(t, bounds, grid, ft, tuple(scans), ignored, strange, tuple(hellos), tuple(intents), tuple(tracks),
                 tuple(threats), tuple(digests))


__all__ = ["Bounds", "Heard", "HeardScan", "check_frame"]
