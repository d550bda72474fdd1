"""Hypothesis strategies for link models and fault schedules: import them in your own tests.

Every fault kind the injector supports has a strategy, and :func:`fault_schedules` combines
them. UAV names are an argument (faults may only name UAVs that exist), and every time lies
inside the run (``0 <= t < duration_s``, on multiples of ``step_s``, the physics step)::

    from hypothesis import given
    from swarm.testing.fault_strategies import fault_schedules, link_models

    @given(fault_schedules(uavs=["B1", "B2", "A1"], duration_s=60.0))
    def test_my_property(schedule):
        ...  # schedule is a faults.schedule.FaultSchedule; sim.add_fault(f) for f in schedule.faults

Shrinking goes towards simple cases: the empty schedule, fewer faults, the simplest kinds first
(``drop`` ... ``join``), windows that start at 0 and last to the end of the run, no scope
(all links), round rates (1.0 loses every copy, so a failure does not hang on luck), ideal links.

Needs ``hypothesis`` (the ``test`` extra); nothing in the simulator imports this module.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence

from hypothesis import strategies as st

from comms.radio import LinkModel
from faults.schedule import (
    FAULT_KINDS,
    Burst,
    Corrupt,
    Crash,
    Delay,
    Drop,
    Duplicate,
    Fault,
    FaultSchedule,
    Join,
    Partition,
)

__all__ = [
    "ALL_KINDS",
    "LINK_KINDS",
    "NODE_KINDS",
    "bursts",
    "corrupts",
    "crashes",
    "delays",
    "drops",
    "duplicates",
    "fault_schedules",
    "faults",
    "joins",
    "link_models",
    "partitions",
    "probabilities",
    "scopes",
    "times",
    "windows",
]

#: Every kind the injector supports, simplest first (this is also the shrink order).
ALL_KINDS: tuple[str, ...] = ("drop", "delay", "duplicate", "corrupt", "burst", "partition", "crash", "join")
LINK_KINDS: tuple[str, ...] = ("drop", "delay", "duplicate", "corrupt", "burst")
NODE_KINDS: tuple[str, ...] = ("crash", "join")
# (Interim, while issue 16's strategies for the ten new kinds are written: they must be in ALL_KINDS.)
assert set(ALL_KINDS) <= set(FAULT_KINDS), "a strategy for a fault kind faults.schedule does not define"


# --- building blocks -------------------------------------------------------------------------


@functools.lru_cache(maxsize=256)
def probabilities(min_value: float = 0.0, max_value: float = 1.0, places: int = 3) -> st.SearchStrategy[float]:
    """A probability rounded to ``places`` decimals (readable in a scenario file), shrinking
    towards round values: ``max_value`` first (1.0 = always), then halves and tenths."""
    if not 0.0 <= min_value <= max_value <= 1.0:
        raise ValueError(f"probabilities({min_value}, {max_value}): need 0 <= min_value <= max_value <= 1")
    round_values = [v for v in (max_value, 0.5, 0.1) if min_value <= v <= max_value]
    return st.one_of(
        st.sampled_from(round_values) if round_values else st.nothing(),
        st.floats(min_value, max_value, allow_nan=False).map(lambda p: round(p, places)).filter(
            lambda p: min_value <= p <= max_value
        ),
    )


def _steps(duration_s: float, step_s: float) -> int:
    if not (duration_s > 0 and step_s > 0 and math.isfinite(duration_s)):
        raise ValueError(f"need a finite duration_s > 0 and step_s > 0, got {duration_s}, {step_s}")
    return max(1, int(math.floor(duration_s / step_s + 1e-9)))


def times(duration_s: float, step_s: float = 1.0, *, min_s: float = 0.0) -> st.SearchStrategy[float]:
    """A time on the tick grid inside the run, ``min_s <= t < duration_s``, shrinking to the earliest."""
    n = _steps(duration_s, step_s)
    lo = int(math.ceil(min_s / step_s - 1e-9))
    if lo > n - 1:
        raise ValueError(f"no tick in [{min_s}, {duration_s}) with step {step_s}")
    return st.integers(lo, n - 1).map(lambda k: k * step_s)


@st.composite
def windows(draw: st.DrawFn, duration_s: float, step_s: float = 1.0, *, open_ended: bool = True) -> tuple[float, float]:
    """``(start_s, end_s)`` with ``0 <= start_s < end_s``; ``end_s`` is ``inf`` (until the end of
    the run, the simplest) or a tick ``<= duration_s``. Shrinks to ``(0, inf)``."""
    n = _steps(duration_s, step_s)
    start = draw(st.integers(0, n - 1))
    if open_ended and draw(st.booleans().map(lambda b: not b)):
        return start * step_s, math.inf
    length = draw(st.integers(1, n - start))
    return start * step_s, (start + length) * step_s


def scopes(uavs: Sequence[str]) -> st.SearchStrategy[tuple[tuple[str, ...], tuple[tuple[str, str], ...]]]:
    """``(uavs, links)`` scope of a link fault: all links (simplest), frames from/to some UAVs,
    or some directed links."""
    return _scopes(tuple(uavs))


@functools.lru_cache(maxsize=256)
def _scopes(uavs: tuple[str, ...]) -> st.SearchStrategy[tuple[tuple[str, ...], tuple[tuple[str, str], ...]]]:
    names = list(uavs)
    everything = st.just(((), ()))
    if not names:
        return everything
    some_uavs = st.lists(st.sampled_from(names), min_size=1, max_size=len(names), unique=True).map(
        lambda u: (tuple(u), ())
    )
    if len(names) < 2:
        return st.one_of(everything, some_uavs)
    pairs = [(a, b) for a in names for b in names if a != b]
    some_links = st.lists(st.sampled_from(pairs), min_size=1, max_size=min(4, len(pairs)), unique=True).map(
        lambda p: ((), tuple(p))
    )
    return st.one_of(everything, some_uavs, some_links)


# --- one strategy per fault kind -------------------------------------------------------------


@st.composite
def drops(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> Drop:
    """i.i.d. loss; the rate is at least 0.05 so the fault does something."""
    start, end = draw(windows(duration_s, step_s))
    scope, links = draw(scopes(uavs))
    return Drop(start_s=start, end_s=end, uavs=scope, links=links, rate=draw(probabilities(0.05)))


@st.composite
def bursts(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> Burst:
    """Gilbert-Elliott bursts (a bad state that loses at least half the copies)."""
    start, end = draw(windows(duration_s, step_s))
    scope, links = draw(scopes(uavs))
    return Burst(start_s=start, end_s=end, uavs=scope, links=links,
                 p_enter_bad=draw(probabilities(0.05)), p_exit_bad=draw(probabilities(0.05)),
                 loss_good=draw(st.one_of(st.just(0.0), probabilities(0.0, 0.2))),
                 loss_bad=draw(probabilities(0.5)))


@st.composite
def delays(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0, max_extra_s: float = 5.0) -> Delay:
    """Extra latency (whole ticks, at least one) plus optional jitter."""
    start, end = draw(windows(duration_s, step_s))
    scope, links = draw(scopes(uavs))
    extra = draw(st.integers(1, max(1, int(max_extra_s / step_s)))) * step_s
    jitter = draw(st.one_of(st.just(0.0), st.floats(0.0, 2.0 * step_s).map(lambda j: round(j, 3))))
    return Delay(start_s=start, end_s=end, uavs=scope, links=links, extra_s=extra, jitter_s=jitter)


@st.composite
def duplicates(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> Duplicate:
    start, end = draw(windows(duration_s, step_s))
    scope, links = draw(scopes(uavs))
    return Duplicate(start_s=start, end_s=end, uavs=scope, links=links, rate=draw(probabilities(0.05)))


@st.composite
def corrupts(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> Corrupt:
    start, end = draw(windows(duration_s, step_s))
    scope, links = draw(scopes(uavs))
    return Corrupt(start_s=start, end_s=end, uavs=scope, links=links, rate=draw(probabilities(0.05)),
                   bytes=draw(st.integers(1, 8)))


@st.composite
def partitions(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> Partition:
    """Two or more disjoint, non-empty groups (not every UAV need be in one), both ways or one way."""
    names = list(uavs)
    if len(names) < 2:
        raise ValueError("a partition needs at least 2 UAV names")
    n_groups = draw(st.integers(2, min(3, len(names))))
    chosen = draw(st.lists(st.sampled_from(names), min_size=n_groups, max_size=len(names), unique=True))
    # Group labels: the first n_groups members seed one group each, the rest join any group.
    labels = list(range(n_groups)) + [draw(st.integers(0, n_groups - 1)) for _ in chosen[n_groups:]]
    groups = tuple(tuple(n for n, g in zip(chosen, labels) if g == k) for k in range(n_groups))
    start, end = draw(windows(duration_s, step_s))
    return Partition(groups=groups, start_s=start, end_s=end, one_way=draw(st.booleans()))


def crashes(uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> st.SearchStrategy[Crash]:
    """Fail-stop of one UAV at a tick inside the run."""
    if not uavs:
        return st.nothing()
    return st.builds(Crash, uav=st.sampled_from(list(uavs)), at_s=times(duration_s, step_s))


def joins(uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> st.SearchStrategy[Join]:
    """A late join (``at_s >= step_s``: a join at 0 is no fault) of one UAV."""
    if not uavs or _steps(duration_s, step_s) < 2:
        return st.nothing()
    return st.builds(Join, uav=st.sampled_from(list(uavs)), at_s=times(duration_s, step_s, min_s=step_s))


_BUILDERS: dict[str, Callable[[list[str], float, float], st.SearchStrategy[Fault]]] = {
    "drop": drops, "delay": delays, "duplicate": duplicates, "corrupt": corrupts, "burst": bursts,
    "partition": partitions, "crash": crashes, "join": joins,
}


def faults(uavs: Sequence[str], duration_s: float, *, kinds: Sequence[str] = ALL_KINDS, step_s: float = 1.0,
           joinable: Sequence[str] | None = None) -> st.SearchStrategy[Fault]:
    """One fault of any of ``kinds`` (default: all). ``joinable``: the UAVs a ``join`` may name
    (default: all of ``uavs``)."""
    return _faults(tuple(uavs), float(duration_s), tuple(kinds), float(step_s),
                   tuple(joinable) if joinable is not None else None)


@functools.lru_cache(maxsize=512)  # strategies are immutable; building one is the costly part
def _faults(uavs: tuple[str, ...], duration_s: float, kinds: tuple[str, ...], step_s: float,
            joinable: tuple[str, ...] | None) -> st.SearchStrategy[Fault]:
    unknown = [k for k in kinds if k not in _BUILDERS]
    if unknown:
        raise ValueError(f"unknown fault kind(s) {unknown}; known: {', '.join(ALL_KINDS)}")
    options: list[st.SearchStrategy[Fault]] = []
    for kind in ALL_KINDS:  # fixed order: the simplest kinds shrink first
        if kind not in kinds:
            continue
        if kind == "partition" and len(uavs) < 2:
            continue
        names = list(joinable if joinable is not None else uavs) if kind == "join" else list(uavs)
        if kind == "join" and (not names or _steps(duration_s, step_s) < 2):
            continue
        if kind in NODE_KINDS and not names:
            continue
        options.append(_BUILDERS[kind](names, duration_s, step_s))
    if not options:
        return st.nothing()
    return st.one_of(options)


@st.composite
def fault_schedules(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, *, kinds: Sequence[str] = ALL_KINDS,
                    min_faults: int = 0, max_faults: int = 6, step_s: float = 1.0,
                    joinable: Sequence[str] | None = None) -> FaultSchedule:
    """A :class:`~faults.schedule.FaultSchedule` of ``min_faults..max_faults`` faults naming only
    ``uavs``, each inside ``[0, duration_s)``. At most one ``join`` per UAV (a scenario can only
    say once when a UAV enters); ``joinable`` restricts which UAVs may join late (default: all).
    Shrinks to the empty schedule."""
    if min_faults < 0 or max_faults < min_faults:
        raise ValueError(f"need 0 <= min_faults <= max_faults, got {min_faults}, {max_faults}")
    one = faults(uavs, duration_s, kinds=kinds, step_s=step_s, joinable=joinable)
    # Only joins must be unique (per UAV); any other fault is keyed by its own identity, so it
    # never collides (two equal drops are a legitimate, if redundant, schedule).
    items = draw(st.lists(one, min_size=min_faults, max_size=max_faults,
                          unique_by=lambda f: ("join", f.uav) if isinstance(f, Join) else ("fault", id(f))))
    return FaultSchedule(list(items))


# --- link models -------------------------------------------------------------------------------


@st.composite
def link_models(draw: st.DrawFn, *, min_range_m: float = 1000.0, max_range_m: float = 20_000.0, lossy: bool = True,
                max_latency_s: float = 2.0, bandwidth: bool = True) -> LinkModel:
    """A :class:`~comms.radio.LinkModel`; shrinks to the ideal radio (unlimited range, no loss,
    no latency). Ranges are whole metres; loss grows from ``loss_base`` at distance 0 to
    ``loss_at_range`` at the range limit."""
    range_m = draw(st.one_of(st.none(), st.integers(int(min_range_m), int(max_range_m)).map(float)))
    base = at_range = 0.0
    if lossy:
        base = at_range = draw(st.one_of(st.just(0.0), probabilities(0.0, 0.5)))
        if range_m is not None:
            at_range = draw(st.one_of(st.just(base), probabilities(base, 1.0)))
    latency = draw(st.one_of(st.just(0.0), st.floats(0.0, max_latency_s).map(lambda x: round(x, 3))))
    jitter = draw(st.one_of(st.just(0.0), st.floats(0.0, max_latency_s).map(lambda x: round(x, 3))))
    bw = draw(st.one_of(st.none(), st.integers(2_000, 200_000).map(float))) if bandwidth else None
    return LinkModel(range_m=range_m, loss_base=base, loss_at_range=at_range, latency_s=latency, jitter_s=jitter,
                     bandwidth_bytes_per_s=bw)
