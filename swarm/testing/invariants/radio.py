"""The radio invariant: every frame read was sent, in range, over a link no fault cut."""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import swarm.events as event_schema
from comms.radio import SPOOF_SENDER
from swarm.testing.invariants.checker import Checker, poses_of
from swarm.testing.invariants.context import EPS


class RadioChecker(Checker):
    """The radio never delivers beyond range, across a partition, from a UAV that was not
    flying when it sent, or to a UAV that is not flying (see the module docstring).
    ``max_delay_s``: longest possible delivery delay (default: from scenario and faults)."""

    name = "radio"

    def __init__(self, max_delay_s: float | None = None):
        super().__init__()
        self.max_delay_s = max_delay_s
        self._history: deque[tuple[float, dict[int, tuple[Any, ...]]]] = deque()
        # A paused UAV (the pause fault) reads its mailbox when it resumes: frames sent since
        # its pause began. uid -> (pause start, pauses open: they may overlap, each logs its own
        # pause and resume); after the last resume, uid -> (pause start, resume).
        self._paused: dict[int, tuple[float, int]] = {}
        self._resumed: dict[int, tuple[float, float]] = {}

    def on_group(self, t: float, events: list[event_schema.Event]) -> None:
        if self.context.recording != "frames":
            self.unchecked = (f'the log has no per-frame events (recording level "{self.context.recording}"); '
                              'the radio invariant needs [recording] level = "frames"')
            return
        ctx = self.context
        dt = ctx.dt
        for e in events:
            if isinstance(e, event_schema.Pause):
                start, open_ = self._paused.get(e.uav, (float(e.t), 0))
                self._paused[e.uav] = (start, open_ + 1)
            elif isinstance(e, event_schema.Resume) and e.uav in self._paused:
                start, open_ = self._paused.pop(e.uav)
                if open_ > 1:
                    self._paused[e.uav] = (start, open_ - 1)  # another pause still holds it
                else:
                    self._resumed[e.uav] = (start, float(e.t))
            elif isinstance(e, event_schema.Crash):
                self._paused.pop(e.uav, None)
        for uid in [u for u, (_, tr) in self._resumed.items() if t > tr + dt + EPS]:
            del self._resumed[uid]  # it has read what it held (its first tick after the resume)
        poses = poses_of(events)
        max_delay = self.max_delay_s if self.max_delay_s is not None else ctx.max_delay_s()
        if poses:
            self._history.append((t, poses))
            floor = min([t, *(s for s, _ in self._paused.values()), *(s for s, _ in self._resumed.values())])
            while self._history and self._history[0][0] < floor - dt - max_delay - dt - EPS:
                self._history.popleft()
        rx = [e for e in events if isinstance(e, event_schema.Rx)]
        if not rx:
            return
        for e in rx:
            src, dst = e.src, e.dst
            if src == SPOOF_SENDER:
                self._check_spoof(t, dst, poses, dt, max_delay)
                continue
            if dst not in poses:
                self.violate(t, f"{ctx.name(dst)} read a frame from {ctx.name(src)} while not flying",
                             [src, dst], cause="receiver_down")
                continue
            held = self._resumed.get(dst)
            oldest = (held[0] if held is not None else t) - dt - max_delay - EPS
            reasons: list[str] = []
            legal = False
            for s, ps in reversed(self._history):  # latest candidate send tick first
                if s > t - dt + EPS:
                    continue
                if s < oldest:
                    break
                why = self._illegal(src, dst, s, ps)
                if why is None:
                    legal = True
                    break
                reasons.append(f"at {s:g} s {why}")
            if not legal:
                detail = "; ".join(reasons) if reasons else "no tick it could have been sent in"
                self.violate(t, f"frame {ctx.name(src)} -> {ctx.name(dst)} delivered illegally: {detail}",
                             [src, dst], reasons=reasons)

    def _check_spoof(self, t: float, dst: int, poses: dict[int, tuple[Any, ...]], dt: float, max_delay: float) -> None:
        """A spoofer's frame (sender -1) is legal only at a receiver that is flying when it reads
        it and was within an active spoofer's ``range_m`` at a possible send tick (for one just
        resumed from a pause, back to the pause's start, as for members' frames)."""
        ctx = self.context
        if dst not in poses:
            self.violate(t, f"{ctx.name(dst)} read a spoofed frame while not flying", [dst], cause="receiver_down")
            return
        held = self._resumed.get(dst)  # a UAV resuming from a pause reads what its mailbox held
        oldest = (held[0] if held is not None else t) - dt - max_delay - EPS
        for s, ps in reversed(self._history):
            if s > t - dt + EPS:
                continue
            if s < oldest:
                break
            pd = ps.get(dst)
            if pd is not None and ctx.spoofed(pd, s):
                return
        self.violate(t, f"{ctx.name(dst)} read a frame from a non-member (sender {SPOOF_SENDER}) with no active "
                        "spoofer in range", [dst], cause="spoof")

    def _illegal(self, src: int, dst: int, s: float, poses: dict[int, tuple[Any, ...]]) -> str | None:
        ps, pd = poses.get(src), poses.get(dst)
        if ps is None:
            return "the sender was not flying"
        if pd is None:
            return "the receiver was not flying"
        d = math.hypot(ps[0] - pd[0], ps[1] - pd[1])
        ctx = self.context
        if d > ctx.range_m + EPS:
            return f"they were {d:.0f} m apart (range {ctx.range_m:g} m)"
        if ctx.blocked(src, dst, s):
            return "a partition, bridge or swizzle separated them"
        return None
