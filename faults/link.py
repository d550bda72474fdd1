"""Link faults: drop, burst, delay, duplicate, corrupt. Each acts on frame copies while
``start_s <= t < end_s``, on every link or on those from or to ``uavs`` (empty: all) and on the
directed ``links`` (empty: all), drawing from the link's own stream (:mod:`faults.injector`)."""

from __future__ import annotations

import abc
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar, Literal

import numpy as np

from faults.base import COPY_STAGES, END, PROBABILITY, START, UAVS, Copy, Draws, FaultRng, LinkBehaviour, Windowed
from faults.registry import register


@dataclass(frozen=True, kw_only=True)
class LinkFault(Windowed, abc.ABC):
    """A fault on frame copies while ``start_s <= t < end_s``, on every link or on those from or
    to ``uavs`` (empty: all) and on the directed ``links`` (empty: all)."""

    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(default=math.inf, metadata=END)
    uavs: tuple[str, ...] = field(default=(), metadata=UAVS)
    links: tuple[tuple[str, str], ...] = field(
        default=(), metadata={"expected": "an array of [sender, receiver] UAV name pairs (empty = all)"}
    )
    # Each kind's tag: a class variable, not a field (the subclasses give the value).
    kind: ClassVar[str]
    disturbs_links: ClassVar[bool] = True
    # Its place among the copy stages (faults.injector): drop, burst, corrupt, duplicate, delay.
    stage: ClassVar[int]

    def link_behaviour(self, ids: Mapping[str, int], fault_rng: FaultRng, rank: int) -> LinkBehaviour:
        return _Scoped(self, ids)

    @abc.abstractmethod
    def copy(self, c: Copy, rng: np.random.Generator, state: dict[tuple[int, int], bool],
             src: int, dst: int) -> bool:
        """What the fault does to one copy it covers; True if it changed something."""


class _Scoped(LinkBehaviour):
    """A link fault's behaviour: its kind's :meth:`LinkFault.copy` on the links it covers."""

    def __init__(self, fault: LinkFault, ids: Mapping[str, int]):
        super().__init__(fault)
        self.link_fault = fault
        self.stage = fault.stage  # type: ignore[misc]  # (per fault: the kind's stage)
        self.uavs = frozenset(ids[n] for n in fault.uavs)
        self.links = frozenset((ids[a], ids[b]) for a, b in fault.links)
        self.state: dict[tuple[int, int], bool] = {}  # per directed link (a burst's chain)

    def on_copy(self, c: Copy, src: int, dst: int, rng: np.random.Generator) -> bool:
        if self.uavs and src not in self.uavs and dst not in self.uavs:
            return False
        if self.links and (src, dst) not in self.links:
            return False
        return self.link_fault.copy(c, rng, self.state, src, dst)


@register
@dataclass(frozen=True, kw_only=True)
class Drop(LinkFault):
    """i.i.d. loss of each frame copy with probability ``rate``."""

    rate: float = field(metadata=PROBABILITY)
    kind: ClassVar[Literal["drop"]] = "drop"
    stage: ClassVar[int] = COPY_STAGES + 1
    shrink_rank: ClassVar[int] = 10

    @classmethod
    def generate(cls, d: Draws) -> Drop:
        """i.i.d. loss; the rate is at least 0.05 so the fault does something."""
        start, end = d.draw(d.windows())
        scope, links = d.draw(d.scopes())
        return cls(start_s=start, end_s=end, uavs=scope, links=links, rate=d.draw(d.probabilities(0.05)))

    def copy(self, c: Copy, rng: np.random.Generator, state: dict[tuple[int, int], bool],
             src: int, dst: int) -> bool:
        if rng.random() < self.rate:
            c.lost = True
            return True
        return False


@register
@dataclass(frozen=True, kw_only=True)
class Burst(LinkFault):
    """Gilbert-Elliott burst loss: a two-state chain per directed link, stepped per copy."""

    p_enter_bad: float = field(metadata=PROBABILITY)
    p_exit_bad: float = field(metadata={"gt": 0, "le": 1})
    loss_good: float = field(default=0.0, metadata=PROBABILITY)
    loss_bad: float = field(default=1.0, metadata=PROBABILITY)
    kind: ClassVar[Literal["burst"]] = "burst"
    stage: ClassVar[int] = COPY_STAGES + 2
    shrink_rank: ClassVar[int] = 50

    @classmethod
    def generate(cls, d: Draws) -> Burst:
        """A bad state that loses at least half the copies."""
        start, end = d.draw(d.windows())
        scope, links = d.draw(d.scopes())
        return cls(start_s=start, end_s=end, uavs=scope, links=links,
                   p_enter_bad=d.draw(d.probabilities(0.05)), p_exit_bad=d.draw(d.probabilities(0.05)),
                   loss_good=d.draw(d.st.one_of(d.st.just(0.0), d.probabilities(0.0, 0.2))),
                   loss_bad=d.draw(d.probabilities(0.5)))

    def copy(self, c: Copy, rng: np.random.Generator, state: dict[tuple[int, int], bool],
             src: int, dst: int) -> bool:
        bad = state.get((src, dst), False)
        bad = (rng.random() >= self.p_exit_bad) if bad else (rng.random() < self.p_enter_bad)
        state[(src, dst)] = bad
        if rng.random() < (self.loss_bad if bad else self.loss_good):
            c.lost = True
            return True
        return False


@register
@dataclass(frozen=True, kw_only=True)
class Delay(LinkFault):
    """Extra latency plus uniform jitter in ``[0, jitter_s)``."""

    extra_s: float = field(metadata={"ge": 0})
    jitter_s: float = field(default=0.0, metadata={"ge": 0})
    kind: ClassVar[Literal["delay"]] = "delay"
    stage: ClassVar[int] = COPY_STAGES + 5
    shrink_rank: ClassVar[int] = 20

    @classmethod
    def generate(cls, d: Draws) -> Delay:
        """Extra latency (whole ticks, at least one, up to 5 s) plus optional jitter."""
        start, end = d.draw(d.windows())
        scope, links = d.draw(d.scopes())
        extra = d.draw(d.st.integers(1, max(1, int(5.0 / d.step_s)))) * d.step_s
        jitter = d.draw(d.st.one_of(d.st.just(0.0), d.st.floats(0.0, 2.0 * d.step_s).map(lambda j: round(j, 3))))
        return cls(start_s=start, end_s=end, uavs=scope, links=links, extra_s=extra, jitter_s=jitter)

    def max_extra_delay_s(self) -> float:
        return self.extra_s + self.jitter_s

    def copy(self, c: Copy, rng: np.random.Generator, state: dict[tuple[int, int], bool],
             src: int, dst: int) -> bool:
        c.extra_s += self.extra_s + (self.jitter_s * rng.random() if self.jitter_s > 0 else 0.0)
        return True


@register
@dataclass(frozen=True, kw_only=True)
class Duplicate(LinkFault):
    """One more copy of a frame with probability ``rate``."""

    rate: float = field(metadata=PROBABILITY)
    kind: ClassVar[Literal["duplicate"]] = "duplicate"
    stage: ClassVar[int] = COPY_STAGES + 4
    shrink_rank: ClassVar[int] = 30

    @classmethod
    def generate(cls, d: Draws) -> Duplicate:
        start, end = d.draw(d.windows())
        scope, links = d.draw(d.scopes())
        return cls(start_s=start, end_s=end, uavs=scope, links=links, rate=d.draw(d.probabilities(0.05)))

    def copy(self, c: Copy, rng: np.random.Generator, state: dict[tuple[int, int], bool],
             src: int, dst: int) -> bool:
        if rng.random() < self.rate:
            c.copies += 1
            return True
        return False


@register
@dataclass(frozen=True, kw_only=True)
class Corrupt(LinkFault):
    """Flip ``bytes`` random bytes of a copy with probability ``rate``."""

    rate: float = field(metadata=PROBABILITY)
    bytes: int = field(default=1, metadata={"ge": 1, "note": "bytes flipped per corrupted frame"})
    kind: ClassVar[Literal["corrupt"]] = "corrupt"
    stage: ClassVar[int] = COPY_STAGES + 3
    shrink_rank: ClassVar[int] = 40

    @classmethod
    def generate(cls, d: Draws) -> Corrupt:
        start, end = d.draw(d.windows())
        scope, links = d.draw(d.scopes())
        return cls(start_s=start, end_s=end, uavs=scope, links=links, rate=d.draw(d.probabilities(0.05)),
                   bytes=d.draw(d.st.integers(1, 8)))

    def copy(self, c: Copy, rng: np.random.Generator, state: dict[tuple[int, int], bool],
             src: int, dst: int) -> bool:
        if rng.random() < self.rate and c.data:
            buf = bytearray(c.data)
            pos = rng.choice(len(buf), size=min(self.bytes, len(buf)), replace=False)
            flips = rng.integers(1, 256, size=len(pos))  # never 0: each byte really changes
            for p, x in zip(pos.tolist(), flips.tolist()):
                buf[p] ^= x
            c.data = bytes(buf)
            return True
        return False
