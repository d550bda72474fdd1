"""Hypothesis strategies for link models and fault schedules: import them in your own tests.

Every registered fault kind (:data:`faults.registry.FAULT_KINDS`) that says how tests draw it
(:meth:`faults.base.FaultKind.generate`, beside its schema in its family module) has a strategy,
:func:`fault_strategy`, and :func:`fault_schedules` combines them: a kind registered later (a
user's, a test's) is drawn as soon as it is registered. UAV names are an argument (faults may
only name UAVs that exist), and every time lies inside the run (``0 <= t < duration_s``, on
multiples of ``step_s``, the physics step)::

    from hypothesis import given
    from swarm.testing.fault_strategies import fault_schedules, link_models

    @given(fault_schedules(uavs=["B1", "B2", "A1"], duration_s=60.0))
    def test_my_property(schedule):
        ...  # schedule is a faults.schedule.FaultSchedule; sim.add_fault(f) for f in schedule.faults

Shrinking goes towards simple cases: the empty schedule, fewer faults, the simplest kinds first
(the order of :func:`fault_kinds`, by each kind's ``shrink_rank``: ``drop`` ... ``battery``),
windows that start at 0 and last to the end of the run, no scope (all links), round rates (1.0
loses every copy, so a failure does not hang on luck), ideal links.

Faults placed in space (``jammer``, ``spoofer``) are put inside the area: pass ``area=(width_m,
height_m)`` (the scenario strategies do); without it they lie in :data:`DEFAULT_AREA_M`.

Needs ``hypothesis`` (the ``test`` extra); nothing in the simulator imports this module.
"""

from __future__ import annotations

import swarm.testing._hypothesis  # noqa: F401  (first: a clear error without Hypothesis)

# isort: split

import functools
import math
from collections.abc import Sequence
from typing import Any

from hypothesis import strategies as st

from comms.settings import LinkModel
from faults.base import Draws, FaultKind
from faults.registry import FAULT_KINDS
from faults.schedule import Fault, FaultSchedule

__all__ = [
    "DEFAULT_AREA_M",
    "fault_kinds",
    "fault_schedules",
    "fault_strategy",
    "faults",
    "link_models",
    "probabilities",
    "scopes",
    "times",
    "windows",
]

#: Where a fault placed in space lies when no ``area`` is given: a 10 km square.
DEFAULT_AREA_M: tuple[float, float] = (10_000.0, 10_000.0)


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


# --- one strategy per fault kind: the kind's own generate() --------------------------------------


def fault_kinds() -> tuple[str, ...]:
    """Every registered fault kind with a strategy (:meth:`faults.base.FaultKind.generate`), in
    shrink order: by ``shrink_rank``, then in registration order."""
    ranked = sorted(enumerate(FAULT_KINDS.items()), key=lambda item: (item[1][1].shrink_rank, item[0]))
    return tuple(kind for _, (kind, cls) in ranked if cls.has_strategy())


def _point(area: tuple[float, float]) -> st.SearchStrategy[tuple[float, float]]:
    """A point of the area on a 100 m grid (shrinking to the origin corner)."""
    w, h = area
    return st.tuples(st.integers(0, int(w) // 100).map(lambda k: k * 100.0),
                     st.integers(0, int(h) // 100).map(lambda k: k * 100.0))


class _Draws:
    """:class:`faults.base.Draws` on Hypothesis: what a kind's ``generate`` draws with."""

    st = st

    def __init__(self, draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float,
                 area: tuple[float, float]):
        self._draw = draw
        self.uavs = tuple(uavs)
        self.duration_s = duration_s
        self.step_s = step_s
        self.area = area
        self.steps = _steps(duration_s, step_s)

    def draw(self, strategy: st.SearchStrategy[Any]) -> Any:
        return self._draw(strategy)

    def windows(self, open_ended: bool = True) -> st.SearchStrategy[tuple[float, float]]:
        return windows(self.duration_s, self.step_s, open_ended=open_ended)

    def scopes(self) -> st.SearchStrategy[tuple[tuple[str, ...], tuple[tuple[str, str], ...]]]:
        return scopes(self.uavs)

    def probabilities(self, min_value: float = 0.0, max_value: float = 1.0) -> st.SearchStrategy[float]:
        return probabilities(min_value, max_value)

    def times(self, min_s: float = 0.0) -> st.SearchStrategy[float]:
        return times(self.duration_s, self.step_s, min_s=min_s)

    def names(self) -> st.SearchStrategy[str]:
        return st.sampled_from(list(self.uavs))

    def points(self) -> st.SearchStrategy[tuple[float, float]]:
        return _point(self.area)

    def among(self, uavs: Sequence[str]) -> _Draws:
        return _Draws(self._draw, uavs, self.duration_s, self.step_s, self.area)


def _possible(cls: type[FaultKind], names: Sequence[str], n_steps: int) -> bool:
    """Whether a fault of ``cls`` can be drawn with these UAV names and this many ticks."""
    return len(names) >= cls.min_uavs and n_steps >= cls.min_ticks


def fault_strategy(kind: str, uavs: Sequence[str], duration_s: float, step_s: float = 1.0,
                   area: tuple[float, float] = DEFAULT_AREA_M) -> st.SearchStrategy[Fault]:
    """Faults of the registered ``kind`` naming only ``uavs`` inside the run (its class's
    ``generate``). ``ValueError`` for a kind that is not registered, that has no strategy, or
    that cannot be drawn here (a partition needs 2 names, a bridge 3, a restart 3 ticks...)."""
    cls = FAULT_KINDS.get(kind)
    if cls is None or not cls.has_strategy():
        raise ValueError(f"no strategy for fault kind {kind!r}; known: {', '.join(fault_kinds())}")
    n_steps = _steps(duration_s, step_s)
    if not _possible(cls, uavs, n_steps):
        raise ValueError(f"a {kind} fault needs at least {cls.min_uavs} UAV name(s) and a run of {cls.min_ticks} "
                         f"tick(s); got {len(uavs)} and {n_steps}")
    return _kind_strategy((kind, cls), tuple(uavs), float(duration_s), float(step_s),
                          (float(area[0]), float(area[1])))


@functools.lru_cache(maxsize=512)  # strategies are immutable; building one is the costly part
def _kind_strategy(kind: tuple[str, type[FaultKind]], uavs: tuple[str, ...], duration_s: float, step_s: float,
                   area: tuple[float, float]) -> st.SearchStrategy[Fault]:
    cls = kind[1]

    @st.composite
    def one(draw: st.DrawFn) -> Fault:
        d: Draws = _Draws(draw, uavs, duration_s, step_s, area)
        return cls.generate(d)

    return one()


def faults(uavs: Sequence[str], duration_s: float, *, kinds: Sequence[str] | None = None, step_s: float = 1.0,
           joinable: Sequence[str] | None = None, area: tuple[float, float] | None = None) -> st.SearchStrategy[Fault]:
    """One fault of any of ``kinds`` (default: every kind of :func:`fault_kinds`) that can be
    drawn with these names and this run (a partition needs 2 names, a bridge 3, a restart 3
    ticks: each kind's ``min_uavs`` and ``min_ticks``; the others are left out). ``joinable``:
    the UAVs a kind that joins late (``join``) may name (default: all of ``uavs``); ``area``:
    ``(width_m, height_m)`` where jammers and spoofers lie (default :data:`DEFAULT_AREA_M`)."""
    known = fault_kinds()
    chosen = known if kinds is None else tuple(kinds)
    unknown = [k for k in chosen if k not in known]
    if unknown:
        raise ValueError(f"unknown fault kind(s) {unknown}; known: {', '.join(known)}")
    # Keyed by the kinds' classes too: a kind name registered again by another class is another strategy.
    return _faults(tuple(uavs), float(duration_s), tuple((k, FAULT_KINDS[k]) for k in known if k in chosen),
                   float(step_s), tuple(joinable) if joinable is not None else None,
                   (float(area[0]), float(area[1])) if area is not None else DEFAULT_AREA_M)


@functools.lru_cache(maxsize=512)  # strategies are immutable; building one is the costly part
def _faults(uavs: tuple[str, ...], duration_s: float, kinds: tuple[tuple[str, type[FaultKind]], ...], step_s: float,
            joinable: tuple[str, ...] | None, area: tuple[float, float]) -> st.SearchStrategy[Fault]:
    if not (area[0] > 0 and area[1] > 0):
        raise ValueError(f"area must be (width_m, height_m) > 0, got {area}")
    n_steps = _steps(duration_s, step_s)
    options: list[st.SearchStrategy[Fault]] = []
    for kind in kinds:  # in shrink order: the simplest kinds shrink first
        names = joinable if joinable is not None and kind[1].joins_late else uavs
        if _possible(kind[1], names, n_steps):
            options.append(_kind_strategy(kind, names, duration_s, step_s, area))
    if not options:
        return st.nothing()
    return st.one_of(options)


def _unique_key(f: Fault) -> tuple[str, Any]:
    """What must differ between two faults of a schedule: the UAV of a kind that joins late (a
    UAV is told once when it enters); any other fault is keyed by its identity, so it never
    collides (two equal drops are a legitimate, if redundant, schedule)."""
    return ("joins", getattr(f, "uav", None)) if f.joins_late else ("fault", id(f))


@st.composite
def fault_schedules(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, *, kinds: Sequence[str] | None = None,
                    min_faults: int = 0, max_faults: int = 6, step_s: float = 1.0,
                    joinable: Sequence[str] | None = None, area: tuple[float, float] | None = None) -> FaultSchedule:
    """A :class:`~faults.schedule.FaultSchedule` of ``min_faults..max_faults`` faults of
    ``kinds`` (default: every kind of :func:`fault_kinds`) naming only ``uavs``, each inside
    ``[0, duration_s)`` (and jammers and spoofers inside ``area``, see :func:`faults`). At most
    one ``join`` per UAV (a scenario can only say once when a UAV enters); ``joinable``
    restricts which UAVs may join late (default: all). Shrinks to the empty schedule."""
    if min_faults < 0 or max_faults < min_faults:
        raise ValueError(f"need 0 <= min_faults <= max_faults, got {min_faults}, {max_faults}")
    one = faults(uavs, duration_s, kinds=kinds, step_s=step_s, joinable=joinable, area=area)
    if one.is_empty:  # no kind can be drawn here (say, only joins and nobody may join)
        if min_faults > 0:
            raise ValueError(f"no fault of kinds {list(kinds or fault_kinds())} can be drawn for UAVs {list(uavs)} "
                             f"in {duration_s:g} s")
        return FaultSchedule([])
    items = draw(st.lists(one, min_size=min_faults, max_size=max_faults, unique_by=_unique_key))
    return FaultSchedule(list(items))


# --- link models -------------------------------------------------------------------------------


@st.composite
def link_models(draw: st.DrawFn, *, min_range_m: float = 1000.0, max_range_m: float = 20_000.0, lossy: bool = True,
                max_latency_s: float = 2.0, bandwidth: bool = True) -> LinkModel:
    """A :class:`~comms.settings.LinkModel`; shrinks to the ideal radio (unlimited range, no loss,
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
