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
(the order of :data:`ALL_KINDS`: ``drop`` ... ``spoofer``), windows that start at 0 and last to
the end of the run, no scope (all links), round rates (1.0 loses every copy, so a failure does
not hang on luck), ideal links.

Faults placed in space (``jammer``, ``spoofer``) are put inside the area: pass ``area=(width_m,
height_m)`` (the scenario strategies do); without it they lie in :data:`DEFAULT_AREA_M`.

Needs ``hypothesis`` (the ``test`` extra); nothing in the simulator imports this module.
"""

from __future__ import annotations

import swarm.testing._hypothesis  # noqa: F401  (first: a clear error without Hypothesis)

# isort: split

import functools
import math
from collections.abc import Callable, Sequence

from hypothesis import strategies as st

from comms.settings import LinkModel
from faults.schedule import (
    FAULT_KINDS,
    Bridge,
    Burst,
    ClockSkew,
    Corrupt,
    Crash,
    Delay,
    Drop,
    Duplicate,
    Fault,
    FaultSchedule,
    Jammer,
    Join,
    Liar,
    NavError,
    Partition,
    Pause,
    Restart,
    Sensor,
    Spoofer,
    Swizzle,
)

__all__ = [
    "ALL_KINDS",
    "DEFAULT_AREA_M",
    "LINK_KINDS",
    "NODE_KINDS",
    "RADIO_KINDS",
    "SENSING_KINDS",
    "bridges",
    "bursts",
    "clock_skews",
    "corrupts",
    "crashes",
    "delays",
    "drops",
    "duplicates",
    "fault_schedules",
    "faults",
    "jammers",
    "joins",
    "liars",
    "link_models",
    "nav_errors",
    "partitions",
    "pauses",
    "probabilities",
    "restarts",
    "scopes",
    "sensors",
    "spoofers",
    "swizzles",
    "times",
    "windows",
]

#: Faults on frame copies, scoped by UAVs and links (:class:`faults.schedule.LinkFault`).
LINK_KINDS: tuple[str, ...] = ("drop", "delay", "duplicate", "corrupt", "burst")
#: Other radio faults: a place (jammer), groups (partition, bridge), a drawn subset (swizzle),
#: a transmitter outside the swarm (spoofer).
RADIO_KINDS: tuple[str, ...] = ("jammer", "partition", "bridge", "swizzle", "spoofer")
#: Faults of one named UAV (they need a name to draw; ``join`` from the ``joinable`` ones).
NODE_KINDS: tuple[str, ...] = ("crash", "join", "pause", "restart", "nav_error", "clock_skew", "liar", "battery")
#: Faults of the sensors of some UAVs.
SENSING_KINDS: tuple[str, ...] = ("sensor",)

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


def _name(uavs: Sequence[str]) -> st.SearchStrategy[str]:
    return st.sampled_from(list(uavs))


def _short_window(draw: st.DrawFn, duration_s: float, step_s: float, open_ended: bool) -> tuple[float, float]:
    return draw(windows(duration_s, step_s, open_ended=open_ended))


@st.composite
def pauses(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> Pause:
    """A process pause of one UAV for a finite window (at least one tick) inside the run."""
    start, end = _short_window(draw, duration_s, step_s, open_ended=False)
    return Pause(uav=draw(_name(uavs)), start_s=start, end_s=end)


@st.composite
def restarts(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> Restart:
    """A crash at a tick and a rejoin (with an empty memory) at least one tick later and before
    the end of the run, so the restart can complete: ``at_s + downtime_s < duration_s``."""
    n = _steps(duration_s, step_s)
    if n < 3:
        raise ValueError(f"a restart needs a run of at least 3 ticks, got {duration_s} s at {step_s} s")
    at = draw(st.integers(0, n - 3))
    down = draw(st.integers(1, n - 2 - at))
    return Restart(uav=draw(_name(uavs)), at_s=at * step_s, downtime_s=down * step_s)


@st.composite
def clock_skews(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> ClockSkew:
    """A clock that is off (whole seconds, either way) and/or drifts (within the +-0.5 s/s
    bounds); never both zero, so the fault changes something."""
    start, end = _short_window(draw, duration_s, step_s, open_ended=True)
    offset = draw(st.one_of(st.sampled_from([5.0, -5.0, 30.0, -30.0]), st.integers(-120, 120).map(float)))
    drift = draw(st.one_of(st.just(0.0), st.sampled_from([0.1, -0.1, 0.5, -0.5]),
                           st.floats(-0.5, 0.5).map(lambda d: round(d, 3))))
    if offset == 0.0 and drift == 0.0:
        offset = 1.0
    return ClockSkew(uav=draw(_name(uavs)), start_s=start, end_s=end, offset_s=offset, drift=drift)


@st.composite
def nav_errors(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0,
               max_bias_m: int = 1000, max_noise_m: int = 200) -> NavError:
    """A navigation bias (whole 10 m) and/or noise (whole metres); never all zero."""
    start, end = _short_window(draw, duration_s, step_s, open_ended=True)
    k = max_bias_m // 10
    bx = draw(st.one_of(st.sampled_from([100.0, -100.0, 500.0]), st.integers(-k, k).map(lambda b: b * 10.0)))
    by = draw(st.one_of(st.just(0.0), st.integers(-k, k).map(lambda b: b * 10.0)))
    noise = draw(st.one_of(st.just(0.0), st.integers(1, max_noise_m).map(float)))
    if bx == 0.0 and by == 0.0 and noise == 0.0:
        bx = 100.0
    return NavError(uav=draw(_name(uavs)), start_s=start, end_s=end, bias_x_m=bx, bias_y_m=by, noise_m=noise)


@st.composite
def sensors(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> Sensor:
    """Missed detections (``p_detect < 1``, shrinking to 0: blind) and/or false alarms (up to one
    phantom per UAV-second); never a perfect sensor."""
    start, end = _short_window(draw, duration_s, step_s, open_ended=True)
    scope = draw(st.one_of(st.just(()), st.lists(_name(uavs), min_size=1, max_size=len(uavs), unique=True)
                           .map(tuple))) if uavs else ()
    p = draw(st.one_of(st.just(0.0), probabilities(0.0, 0.95)))
    far = draw(st.one_of(st.just(0.0), st.sampled_from([0.1, 1.0]), st.floats(0.0, 1.0).map(lambda r: round(r, 3))))
    return Sensor(uavs=scope, start_s=start, end_s=end, p_detect=p, false_alarm_rate=far)


def _point(area: tuple[float, float]) -> st.SearchStrategy[tuple[float, float]]:
    """A point of the area on a 100 m grid (shrinking to the origin corner)."""
    w, h = area
    return st.tuples(st.integers(0, int(w) // 100).map(lambda k: k * 100.0),
                     st.integers(0, int(h) // 100).map(lambda k: k * 100.0))


@st.composite
def jammers(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0,
            area: tuple[float, float] = DEFAULT_AREA_M) -> Jammer:
    """A jamming circle centred inside the area, 100 m up to half the area's larger side (whole
    100 m), losing at least 5% of the copies to or from a UAV inside."""
    x, y = draw(_point(area))
    k_max = max(1, int(max(area) / 2) // 100)
    radius = draw(st.one_of(st.just(float(k_max * 100)), st.integers(1, k_max).map(lambda k: k * 100.0)))
    start, end = _short_window(draw, duration_s, step_s, open_ended=True)
    return Jammer(x_m=x, y_m=y, radius_m=radius, rate=draw(probabilities(0.05)), start_s=start, end_s=end)


@st.composite
def bridges(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> Bridge:
    """Jepsen's bridge: a partition of the other UAVs into 2 or 3 disjoint non-empty groups, with
    the ``bridge`` UAV in none of them (it talks to every side)."""
    names = list(uavs)
    if len(names) < 3:
        raise ValueError("a bridge needs at least 3 UAV names (two sides and the bridge)")
    bridge = draw(st.sampled_from(names))
    side = draw(partitions([n for n in names if n != bridge], duration_s, step_s))
    return Bridge(groups=side.groups, bridge=bridge, start_s=side.start_s, end_s=side.end_s)


@st.composite
def swizzles(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> Swizzle:
    """FoundationDB's swizzle-clog: a finite window (at least 2 ticks: a cutting half and a
    restoring half), a pool (empty: all) and ``1 <= count <= `` the pool's size."""
    names = list(uavs)
    if not names or _steps(duration_s, step_s) < 2:
        raise ValueError("a swizzle needs a UAV name and a run of at least 2 ticks")
    pool = draw(st.one_of(st.just(()), st.lists(st.sampled_from(names), min_size=1, max_size=len(names),
                                                 unique=True).map(tuple)))
    count = draw(st.integers(1, len(pool) if pool else len(names)))
    n = _steps(duration_s, step_s)
    start = draw(st.integers(0, n - 2))
    length = draw(st.integers(2, n - start))
    return Swizzle(uavs=pool, count=count, start_s=start * step_s, end_s=(start + length) * step_s)


@st.composite
def liars(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> Liar:
    """A Byzantine member sending fake scans and/or fake tracks (never neither)."""
    start, end = _short_window(draw, duration_s, step_s, open_ended=True)
    scans = draw(st.one_of(st.just(1.0), st.sampled_from([0.0, 5.0]), st.integers(1, 20).map(lambda k: k / 2)))
    tracks = draw(st.one_of(st.just(0.0), st.sampled_from([1.0, 0.2]), st.integers(1, 10).map(lambda k: k / 5)))
    if scans == 0.0 and tracks == 0.0:
        tracks = 1.0
    return Liar(uav=draw(_name(uavs)), start_s=start, end_s=end, scans_per_s=scans, tracks_per_s=tracks)


@st.composite
def spoofers(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0,
             area: tuple[float, float] = DEFAULT_AREA_M) -> Spoofer:
    """A transmitter inside the area reaching 500 m up to the area's diagonal (whole 100 m),
    sending 0.5-10 frames a second as a named member or as a random one (``as_uav = ""``)."""
    x, y = draw(_point(area))
    k_max = max(5, int(math.hypot(*area)) // 100)
    reach = draw(st.one_of(st.just(float(k_max * 100)), st.integers(5, k_max).map(lambda k: k * 100.0)))
    start, end = _short_window(draw, duration_s, step_s, open_ended=True)
    rate = draw(st.one_of(st.just(1.0), st.integers(1, 20).map(lambda k: k / 2)))
    as_uav = draw(st.one_of(st.just(""), _name(uavs))) if uavs else ""
    return Spoofer(x_m=x, y_m=y, range_m=reach, start_s=start, end_s=end, rate_per_s=rate, as_uav=as_uav)


@st.composite
def batteries(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, step_s: float = 1.0) -> Fault:
    """(issue 26) A battery fault: a loss of part of the energy left and/or a faster drain over
    a window (nothing happens to a UAV without an [endurance] budget)."""
    from faults.energy import Battery

    if not uavs:
        raise ValueError("a battery fault needs a UAV name")
    start, end = _short_window(draw, duration_s, step_s, open_ended=True)
    loss = draw(st.sampled_from([0.0, 0.25, 0.5, 0.9]))
    factor = draw(st.sampled_from([1.0, 2.0, 5.0])) if loss else draw(st.sampled_from([2.0, 5.0]))
    return Battery(uav=draw(_name(uavs)), start_s=start, end_s=end, loss_frac=loss, drain_factor=factor)


_Builder = Callable[..., st.SearchStrategy[Fault]]
# Each kind's strategy, simplest first (this is also the shrink order): loss on links, then
# whole links cut, then whole UAVs, then UAVs that are wrong (clocks, positions, sensors), then
# UAVs and transmitters that lie.
_BUILDERS: dict[str, _Builder] = {
    "drop": drops, "delay": delays, "duplicate": duplicates, "corrupt": corrupts, "burst": bursts,
    "jammer": jammers, "partition": partitions, "bridge": bridges, "swizzle": swizzles, "crash": crashes,
    "join": joins, "pause": pauses, "restart": restarts, "sensor": sensors, "nav_error": nav_errors,
    "clock_skew": clock_skews, "liar": liars, "spoofer": spoofers, "battery": batteries,
}
#: Every fault kind with a strategy here, in shrink order (every built-in kind of
#: :data:`faults.registry.FAULT_KINDS`; a kind registered elsewhere brings its own strategy).
ALL_KINDS: tuple[str, ...] = tuple(_BUILDERS)
assert set(ALL_KINDS) >= set(FAULT_KINDS), "a strategy per built-in fault kind"
assert set(LINK_KINDS + RADIO_KINDS + NODE_KINDS + SENSING_KINDS) == set(ALL_KINDS)
_PLACED = ("jammer", "spoofer")  # built with the area


def _possible(kind: str, names: Sequence[str], n_steps: int) -> bool:
    """Whether ``kind`` can be drawn with these UAV names and this many ticks."""
    need_names = {"partition": 2, "bridge": 3, "swizzle": 1, **{k: 1 for k in NODE_KINDS}}.get(kind, 0)
    need_steps = {"join": 2, "swizzle": 2, "restart": 3}.get(kind, 1)
    return len(names) >= need_names and n_steps >= need_steps


def faults(uavs: Sequence[str], duration_s: float, *, kinds: Sequence[str] = ALL_KINDS, step_s: float = 1.0,
           joinable: Sequence[str] | None = None, area: tuple[float, float] | None = None) -> st.SearchStrategy[Fault]:
    """One fault of any of ``kinds`` (default: all) that can be drawn with these names and this
    run (a partition needs 2 names, a bridge 3, a restart 3 ticks; the others are left out).
    ``joinable``: the UAVs a ``join`` may name (default: all of ``uavs``); ``area``: ``(width_m,
    height_m)`` where jammers and spoofers lie (default :data:`DEFAULT_AREA_M`)."""
    return _faults(tuple(uavs), float(duration_s), tuple(kinds), float(step_s),
                   tuple(joinable) if joinable is not None else None,
                   (float(area[0]), float(area[1])) if area is not None else DEFAULT_AREA_M)


@functools.lru_cache(maxsize=512)  # strategies are immutable; building one is the costly part
def _faults(uavs: tuple[str, ...], duration_s: float, kinds: tuple[str, ...], step_s: float,
            joinable: tuple[str, ...] | None, area: tuple[float, float]) -> st.SearchStrategy[Fault]:
    unknown = [k for k in kinds if k not in _BUILDERS]
    if unknown:
        raise ValueError(f"unknown fault kind(s) {unknown}; known: {', '.join(ALL_KINDS)}")
    if not (area[0] > 0 and area[1] > 0):
        raise ValueError(f"area must be (width_m, height_m) > 0, got {area}")
    n_steps = _steps(duration_s, step_s)
    options: list[st.SearchStrategy[Fault]] = []
    for kind in ALL_KINDS:  # fixed order: the simplest kinds shrink first
        if kind not in kinds:
            continue
        names = list(joinable if joinable is not None else uavs) if kind == "join" else list(uavs)
        if not _possible(kind, names, n_steps):
            continue
        if kind in _PLACED:
            options.append(_BUILDERS[kind](names, duration_s, step_s, area=area))
        else:
            options.append(_BUILDERS[kind](names, duration_s, step_s))
    if not options:
        return st.nothing()
    return st.one_of(options)


@st.composite
def fault_schedules(draw: st.DrawFn, uavs: Sequence[str], duration_s: float, *, kinds: Sequence[str] = ALL_KINDS,
                    min_faults: int = 0, max_faults: int = 6, step_s: float = 1.0,
                    joinable: Sequence[str] | None = None, area: tuple[float, float] | None = None) -> FaultSchedule:
    """A :class:`~faults.schedule.FaultSchedule` of ``min_faults..max_faults`` faults naming only
    ``uavs``, each inside ``[0, duration_s)`` (and jammers and spoofers inside ``area``, see
    :func:`faults`). At most one ``join`` per UAV (a scenario can only say once when a UAV
    enters); ``joinable`` restricts which UAVs may join late (default: all). Shrinks to the
    empty schedule."""
    if min_faults < 0 or max_faults < min_faults:
        raise ValueError(f"need 0 <= min_faults <= max_faults, got {min_faults}, {max_faults}")
    one = faults(uavs, duration_s, kinds=kinds, step_s=step_s, joinable=joinable, area=area)
    if one.is_empty:  # no kind can be drawn here (say, only joins and nobody may join)
        if min_faults > 0:
            raise ValueError(f"no fault of kinds {list(kinds)} can be drawn for UAVs {list(uavs)} in {duration_s:g} s")
        return FaultSchedule([])
    # Only joins must be unique (per UAV); any other fault is keyed by its own identity, so it
    # never collides (two equal drops are a legitimate, if redundant, schedule).
    items = draw(st.lists(one, min_size=min_faults, max_size=max_faults,
                          unique_by=lambda f: ("join", f.uav) if isinstance(f, Join) else ("fault", id(f))))
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
