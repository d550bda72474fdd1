"""Faults that cut links or silence places: partition, bridge, swizzle, jammer."""

from __future__ import annotations

import abc
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar, Literal

import numpy as np

from faults.base import COPY_STAGES, END, PROBABILITY, START, UAV, UAVS, Copy, Draws, FaultRng, LinkBehaviour, RunView, Windowed
from faults.registry import register

_GROUPS = {"expected": "an array of at least 2 non-empty arrays of UAV names"}


class _Cuts(Windowed, abc.ABC):
    """What partitions and bridges share: the partition they are, who it separates."""

    groups: tuple[tuple[str, ...], ...]
    disturbs_links: ClassVar[bool] = True

    @abc.abstractmethod
    def as_partition(self) -> Partition:
        """The partition it is (a bridge: without its bridge UAV)."""

    @cached_property
    def _group_of(self) -> dict[str, int]:
        return {n: g for g, grp in enumerate(self.as_partition().groups) for n in grp}

    def blocks(self, t: float, src: int, dst: int, view: RunView) -> bool:
        if not self.active(t):
            return False
        g = self._group_of
        return self.as_partition().separates(g.get(view.names.get(src, "")), g.get(view.names.get(dst, "")))

    def link_behaviour(self, ids: Mapping[str, int], fault_rng: FaultRng, rank: int) -> LinkBehaviour:
        return _Cut(self, {ids[n]: g for n, g in self._group_of.items()})


@register
@dataclass(frozen=True, kw_only=True)
class Partition(_Cuts):
    """Cut the links between groups from ``start_s`` until ``end_s`` (the heal time).

    ``one_way``: only frames from an earlier-listed group to a later-listed one are blocked.
    UAVs in no group are unaffected.
    """

    groups: tuple[tuple[str, ...], ...] = field(metadata=_GROUPS)
    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(default=math.inf, metadata=END)
    one_way: bool = False
    kind: ClassVar[Literal["partition"]] = "partition"
    shrink_rank: ClassVar[int] = 70
    min_uavs: ClassVar[int] = 2

    @classmethod
    def generate(cls, d: Draws) -> Partition:
        """Two or more disjoint, non-empty groups (not every UAV need be in one), both ways or one way."""
        names = list(d.uavs)
        n_groups = d.draw(d.st.integers(2, min(3, len(names))))
        chosen = d.draw(d.st.lists(d.st.sampled_from(names), min_size=n_groups, max_size=len(names), unique=True))
        # Group labels: the first n_groups members seed one group each, the rest join any group.
        labels = list(range(n_groups)) + [d.draw(d.st.integers(0, n_groups - 1)) for _ in chosen[n_groups:]]
        groups = tuple(tuple(n for n, g in zip(chosen, labels) if g == k) for k in range(n_groups))
        start, end = d.draw(d.windows())
        return cls(groups=groups, start_s=start, end_s=end, one_way=d.draw(d.st.booleans()))

    def separates(self, group_of_src: int | None, group_of_dst: int | None) -> bool:
        """Whether this partition, while active, blocks a frame from a UAV of group
        ``group_of_src`` to one of group ``group_of_dst`` (indices into ``groups``; None: the
        UAV is in no group)."""
        if group_of_src is None or group_of_dst is None or group_of_src == group_of_dst:
            return False
        return not self.one_way or group_of_src < group_of_dst

    def as_partition(self) -> Partition:
        return self


class _Cut(LinkBehaviour):
    stage = 0

    def __init__(self, fault: _Cuts, group_of: dict[int, int]):
        super().__init__(fault)
        self.partition = fault.as_partition()
        self.group_of = group_of

    def cut(self, src: int, dst: int) -> bool:
        return self.partition.separates(self.group_of.get(src), self.group_of.get(dst))


@register
@dataclass(frozen=True, kw_only=True)
class Bridge(_Cuts):
    """A partition between ``groups`` in which the ``bridge`` UAV (taken out of any group that
    lists it) still talks to every side (Jepsen's bridge)."""

    groups: tuple[tuple[str, ...], ...] = field(metadata=_GROUPS)
    bridge: str = field(metadata=UAV)
    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(default=math.inf, metadata=END)
    kind: ClassVar[Literal["bridge"]] = "bridge"
    shrink_rank: ClassVar[int] = 80
    min_uavs: ClassVar[int] = 3

    @classmethod
    def generate(cls, d: Draws) -> Bridge:
        """A partition of the other UAVs into 2 or 3 groups, the ``bridge`` UAV in none of them."""
        bridge = d.draw(d.names())
        side = Partition.generate(d.among([n for n in d.uavs if n != bridge]))
        return cls(groups=side.groups, bridge=bridge, start_s=side.start_s, end_s=side.end_s)

    def as_partition(self) -> Partition:
        """The partition this bridge is: its groups without the bridge UAV (which is then in no
        group, so :meth:`Partition.separates` never blocks it), same window. The one definition
        of who a bridge separates, for the injector and the invariant checkers alike."""
        groups = tuple(tuple(n for n in g if n != self.bridge) for g in self.groups)
        return Partition(groups=groups, start_s=self.start_s, end_s=self.end_s)

    def partition(self) -> Partition:
        return self.as_partition()


@register
@dataclass(frozen=True, kw_only=True)
class Swizzle(Windowed):
    """FoundationDB's swizzle-clog: at ``start_s`` a random ``count`` UAVs of ``uavs`` (empty:
    all) are drawn; their links are cut one UAV at a time over the first half of the window,
    then restored one at a time, in a random order, over the second half."""

    uavs: tuple[str, ...] = field(default=(), metadata=UAVS)
    count: int = field(metadata={"ge": 1, "note": "UAVs clogged"})
    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(metadata={"gt": 0, "note": "> start_s: when the last link is restored"})
    kind: ClassVar[Literal["swizzle"]] = "swizzle"
    disturbs_links: ClassVar[bool] = True
    shrink_rank: ClassVar[int] = 90
    min_uavs: ClassVar[int] = 1
    min_ticks: ClassVar[int] = 2

    @classmethod
    def generate(cls, d: Draws) -> Swizzle:
        """A finite window (at least 2 ticks: a cutting half and a restoring half), a pool
        (empty: all) and ``1 <= count <=`` the pool's size."""
        names = list(d.uavs)
        pool = d.draw(d.st.one_of(d.st.just(()), d.st.lists(d.st.sampled_from(names), min_size=1, max_size=len(names),
                                                              unique=True).map(tuple)))
        count = d.draw(d.st.integers(1, len(pool) if pool else len(names)))
        start = d.draw(d.st.integers(0, d.steps - 2))
        length = d.draw(d.st.integers(2, d.steps - start))
        return cls(uavs=pool, count=count, start_s=start * d.step_s, end_s=(start + length) * d.step_s)

    def check(self, now: float) -> str | None:
        if not self.start_s < self.end_s < math.inf:
            return (f"swizzle needs start_s < end_s < inf (its links are restored by end_s), "
                    f"got start_s={self.start_s}, end_s={self.end_s}")
        return super().check(now)

    def plan(self, pool: Sequence[int], rng: np.random.Generator) -> dict[int, tuple[float, float]]:
        """Who is clogged when: ``{uav: (cut_s, restore_s)}``, the UAV clogged while
        ``cut_s <= t < restore_s``. ``pool``: the candidate UAV ids (``uavs`` resolved, or every
        UAV), in id order; ``rng``: the fault's own stream. ``min(count, len(pool))`` of them are
        drawn, in the order they are cut; the k-th is cut at ``start_s + k * step`` (``step`` =
        half the window / the number drawn), and they are restored in a second random order,
        the k-th at ``start_s + half + (k + 1) * step``: the last one at ``end_s``. The one
        definition, for the injector and the invariant checkers."""
        n = min(self.count, len(pool))
        if n == 0:
            return {}
        chosen = [int(u) for u in rng.choice(np.asarray(pool, dtype=np.int64), size=n, replace=False)]
        restore_order = [chosen[int(i)] for i in rng.permutation(n)]
        half = 0.5 * (self.end_s - self.start_s)
        step = half / n
        cut = {u: self.start_s + k * step for k, u in enumerate(chosen)}
        return {u: (cut[u], self.start_s + half + (k + 1) * step) for k, u in enumerate(restore_order)}

    def draw(self, pool: Sequence[int], rng: np.random.Generator) -> dict[int, tuple[float, float]]:
        return self.plan(pool, rng)

    def blocks(self, t: float, src: int, dst: int, view: RunView) -> bool:
        if not self.active(t):
            return False
        plan = view.drawn(self) or {}
        for u in (src, dst):
            window = plan.get(u)
            if window is not None and window[0] <= t < window[1]:
                return True
        return False

    def link_behaviour(self, ids: Mapping[str, int], fault_rng: FaultRng, rank: int) -> LinkBehaviour:
        return _Clog(self, ids, lambda: fault_rng(self.kind, rank))


class _Clog(LinkBehaviour):
    """A swizzle's plan (drawn when its window opens) and the UAVs clogged at this tick."""

    stage = 1

    def __init__(self, fault: Swizzle, ids: Mapping[str, int], stream: Any):
        super().__init__(fault)
        self.swizzle = fault
        self.ids = ids  # (names added later resolve: the simulation's own table)
        self.stream = stream
        self.plan: dict[int, tuple[float, float]] | None = None
        self.clogged: frozenset[int] = frozenset()

    def begin_tick(self, t: float) -> None:
        if self.plan is None:
            # Drawn once, when the window opens (or at the first tick after a late add_fault).
            self.plan = self.swizzle.plan(self.swizzle.pool(self.ids), self.stream())
        self.clogged = frozenset(u for u, (cut, restore) in self.plan.items() if cut <= t < restore)

    def cut(self, src: int, dst: int) -> bool:
        return src in self.clogged or dst in self.clogged

    def drawn(self) -> dict[int, tuple[float, float]] | None:
        return self.plan


@register
@dataclass(frozen=True, kw_only=True)
class Jammer(Windowed):
    """A circle in which every frame copy to or from a UAV inside is lost with probability
    ``rate``."""

    x_m: float = field(metadata={"note": "m, the centre"})
    y_m: float = field(metadata={"note": "m, the centre"})
    radius_m: float = field(metadata={"gt": 0, "note": "m"})
    rate: float = field(default=1.0, metadata=PROBABILITY)
    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(default=math.inf, metadata=END)
    kind: ClassVar[Literal["jammer"]] = "jammer"
    disturbs_links: ClassVar[bool] = True
    shrink_rank: ClassVar[int] = 60

    @classmethod
    def generate(cls, d: Draws) -> Jammer:
        """A circle centred inside the area, 100 m up to half the area's larger side (whole 100 m),
        losing at least 5% of the copies to or from a UAV inside."""
        x, y = d.draw(d.points())
        k_max = max(1, int(max(d.area) / 2) // 100)
        radius = d.draw(d.st.one_of(d.st.just(float(k_max * 100)), d.st.integers(1, k_max).map(lambda k: k * 100.0)))
        start, end = d.draw(d.windows())
        return cls(x_m=x, y_m=y, radius_m=radius, rate=d.draw(d.probabilities(0.05)), start_s=start, end_s=end)

    def silences(self, pos: Sequence[float], t: float) -> bool:
        return (self.rate >= 1.0 and self.active(t)
                and math.hypot(pos[0] - self.x_m, pos[1] - self.y_m) <= self.radius_m)

    def link_behaviour(self, ids: Mapping[str, int], fault_rng: FaultRng, rank: int) -> LinkBehaviour:
        return _Jam(self)


class _Jam(LinkBehaviour):
    """Who is inside the jammer's circle this tick; their copies are lost with its ``rate``."""

    stage = COPY_STAGES

    def __init__(self, fault: Jammer):
        super().__init__(fault)
        self.jammer = fault
        self.inside: frozenset[int] = frozenset()

    def begin_tick(self, t: float) -> None:
        self.inside = frozenset()  # until set_positions: nobody is inside

    def set_positions(self, ids: Sequence[int], xy: np.ndarray) -> None:
        j = self.jammer
        inside = np.hypot(xy[:, 0] - j.x_m, xy[:, 1] - j.y_m) <= j.radius_m
        self.inside = frozenset(u for u, k in zip(ids, inside.tolist()) if k)

    def on_copy(self, c: Copy, src: int, dst: int, rng: np.random.Generator) -> bool:
        if (src in self.inside or dst in self.inside) and rng.random() < self.jammer.rate:
            c.lost = True
            return True
        return False
