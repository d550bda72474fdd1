"""What every fault kind is: a frozen dataclass (its schema) that registers by kind name and
carries its own behaviour and its own excuses.

A kind's class is its one definition (see :mod:`faults.registry` for the list of kinds):

* **schema**: its dataclass fields, with defaults and bounds in the field metadata (``ge``,
  ``gt``, ``le``, ``lt``, a ``note`` on the unit, the ``expected`` words of an error message);
  ``swarm.scenario`` builds each ``[[faults]]`` table from them;
* **behaviour**: what it does to a run, through the hook of its family (none is required):
  :meth:`FaultKind.install` (on the clock, through a :class:`FaultHost`), a
  :class:`LinkBehaviour` (frame copies, applied by :mod:`faults.injector`), a tick behaviour
  (:class:`faults.tick.TickFault`: a UAV's reading or actor, tick by tick) or a
  :class:`Transmitter` (frames of its own);
* **counters**: ``fired[kind]``, counted by its behaviour each time it changed something;
* **excuses**: what the invariant checkers (``swarm.testing``) grant it, as the class variables
  and methods below: who it concerns and when (:meth:`FaultKind.span`,
  :meth:`FaultKind.concerns`), whether it impairs a UAV's control or sensing, disturbs the links
  or the maps, cuts links, silences a place or reaches it with forged frames;
* **how tests draw it**: :meth:`FaultKind.generate`, one instance drawn through a :class:`Draws`
  (the testing toolkit, ``swarm.testing.fault_strategies``, hands it one built on Hypothesis, so
  this package never imports Hypothesis), with what a draw needs (:attr:`FaultKind.min_uavs`,
  :attr:`FaultKind.min_ticks`) and where the kind comes in the shrink order
  (:attr:`FaultKind.shrink_rank`).

Adding a kind is one new class decorated with :func:`faults.registry.register` (plus its
tests): the scenario's ``[[faults]]`` tables, the simulation, the actor, the checkers and the
testing toolkit's strategies ask these hooks, never a kind by name.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

if TYPE_CHECKING:
    from agents.types import UavType
    from comms.radio import Delivery, RadioCounters

# Field metadata shared by the kinds' windows (see the module docstring).
START = {"ge": 0}
END = {"gt": 0, "note": "> start_s; absent = until the end"}  # math.inf: absent from a scenario
PROBABILITY = {"ge": 0, "le": 1}
UAV = {"expected": "a UAV name defined in [[uavs]]"}
UAVS = {"expected": "an array of UAV names (empty = all)"}

# Ids of phantom targets (false alarms, liars' tracks): far above any real target's.
PHANTOM_TARGET_ID = 1_000_000_000

FaultRng = Callable[[str, int], np.random.Generator]


class FaultHost(Protocol):
    """What a fault kind may do to a run from :meth:`FaultKind.install`: the simulation's
    side of the contract (``swarm.kernel.simulation`` implements it). Times are seconds of world time."""

    @property
    def now(self) -> float: ...

    def uid(self, name: str) -> int:
        """The id of the UAV named ``name``."""
        ...

    def at(self, t: float, action: Callable[[], None]) -> None:
        """Run ``action`` at ``t`` (no earlier than now), before the tick of ``t``."""
        ...

    def fired(self, kind: str, n: int = 1) -> None:
        """Count ``n`` times a fault of ``kind`` changed something."""
        ...

    def state(self, uid: int) -> str:
        """``"pending"``, ``"alive"`` or ``"crashed"``."""
        ...

    def fail_stop(self, uid: int, back_at: float | None = None) -> None:
        """Take a pending or flying UAV down (no sensing, sending, receiving or moving; a
        ``crash`` event); ``back_at``: when it will be revived, if it will."""
        ...

    def revive(self, uid: int, key: tuple[str | int, ...]) -> None:
        """Bring a UAV that is down back where it went down, with a fresh actor (empty memory, a
        new planner, the random stream ``("uav", name, *key)``); a ``restart`` event."""
        ...

    def set_join(self, uid: int, at_s: float) -> None:
        """A pending UAV joins at ``at_s`` instead."""
        ...

    def open_window(self, index: int, fault: FaultKind) -> None:
        """A tick fault starts acting (:mod:`faults.tick`)."""
        ...

    def close_window(self, index: int, fault: FaultKind) -> None:
        """A tick fault stops acting."""
        ...

    def battery(self, uid: int) -> BatteryLike | None:
        """The UAV's battery (issue 26: a type with an ``[endurance]`` budget), or None."""
        ...


class BatteryLike(Protocol):
    """What the ``battery`` fault (:mod:`faults.energy`) changes of a UAV's energy."""

    drain_factor: float

    def lose(self, frac: float) -> None:
        """Lose ``frac`` of the energy left at once."""
        ...


class RadioHost(Protocol):
    """What a fault that transmits frames of its own (:meth:`FaultKind.transmitter`) may read
    and use of a run, in the tick's transmit phase."""

    @property
    def area(self) -> tuple[float, float]: ...

    @property
    def latency_s(self) -> float: ...

    @property
    def counters(self) -> RadioCounters: ...

    def members(self) -> list[int]:
        """Every UAV id, in id order (flying or not)."""
        ...

    def uid(self, name: str) -> int: ...

    def uav_type(self, uid: int) -> UavType: ...


class Transmitter:
    """A fault's own transmitter (a spoofer): frames it sends each tick while active."""

    def __init__(self, fault: Windowed):
        self.fault = fault

    def transmit(self, host: RadioHost, t: float, dt: float, alive: Sequence[int], xy: np.ndarray,
                 out: list[Delivery]) -> int:
        """Append this tick's frame copies to ``out``; returns how many frames it sent (fired)."""
        return 0


# The stages of a frame copy's way through the active link behaviours (lower first). Cuts
# (stage < COPY_STAGES) block a link outright, without a draw.
COPY_STAGES = 10


class Copy:
    """A frame copy on its way through the link behaviours: what they make of it."""

    __slots__ = ("data", "extra_s", "copies", "lost")

    def __init__(self, data: bytes):
        self.data = data
        self.extra_s = 0.0  # added latency
        self.copies = 1  # duplicates share the data and the latency
        self.lost = False


class LinkBehaviour:
    """What one fault does to frame copies (subclassed by the link kinds' families)."""

    stage: ClassVar[int]

    def __init__(self, fault: Windowed):
        self.fault = fault

    def begin_tick(self, t: float) -> None:
        """The tick at ``t`` begins (the fault is active)."""

    def set_positions(self, ids: Sequence[int], xy: np.ndarray) -> None:
        """The live UAVs' positions of this tick (for behaviours that care where UAVs are)."""

    def cut(self, src: int, dst: int) -> bool:
        """A cut (stage < COPY_STAGES): whether it blocks ``src -> dst`` this tick."""
        return False

    def on_copy(self, c: Copy, src: int, dst: int, rng: np.random.Generator) -> bool:
        """Act on one copy (stage >= COPY_STAGES); True if it changed something (fired). Set
        ``c.lost`` to lose the copy."""
        return False

    def drawn(self) -> Any:
        """What the fault drew for itself (:meth:`faults.base.FaultKind.draw`), or None."""
        return None


class Draws(Protocol):
    """What a kind's :meth:`FaultKind.generate` draws with: the UAV names it may use, the run's
    length and area, and strategies that shrink towards simple cases (Hypothesis's, built by
    ``swarm.testing.fault_strategies``: windows shrink to the whole run, scopes to all links,
    probabilities to 1.0, then 0.5 and 0.1, times to the earliest tick, points to the origin)."""

    @property
    def uavs(self) -> Sequence[str]:
        """The UAV names it may name (for a kind that :attr:`FaultKind.joins_late`: those that may)."""
        ...

    @property
    def duration_s(self) -> float: ...

    @property
    def step_s(self) -> float:
        """The tick: every time drawn is a multiple of it."""
        ...

    @property
    def steps(self) -> int:
        """Ticks in the run."""
        ...

    @property
    def area(self) -> tuple[float, float]:
        """``(width_m, height_m)``: where a fault placed in space lies."""
        ...

    @property
    def st(self) -> Any:
        """``hypothesis.strategies``, for values of the kind's own."""
        ...

    def draw(self, strategy: Any) -> Any:
        """A value of ``strategy``."""
        ...

    def windows(self, open_ended: bool = True) -> Any:
        """``(start_s, end_s)``, ``end_s`` inf (the run's end) only if ``open_ended``."""
        ...

    def scopes(self) -> Any:
        """``(uavs, links)`` of a link fault: all links, frames from/to some UAVs, or some links."""
        ...

    def probabilities(self, min_value: float = 0.0, max_value: float = 1.0) -> Any: ...

    def times(self, min_s: float = 0.0) -> Any:
        """A tick in ``[min_s, duration_s)``."""
        ...

    def names(self) -> Any:
        """One of :attr:`uavs`."""
        ...

    def points(self) -> Any:
        """A point of the area on a 100 m grid."""
        ...

    def among(self, uavs: Sequence[str]) -> Draws:
        """The same, naming only ``uavs`` (a bridge draws its sides as a partition of the others)."""
        ...


class RunView(Protocol):
    """What a checker knows of a run, as a fault kind's excuses need it."""

    @property
    def names(self) -> dict[int, str]: ...

    @property
    def uid(self) -> dict[str, int]: ...

    def drawn(self, fault: FaultKind) -> Any:
        """What ``fault`` drew from its own stream when it started (:meth:`FaultKind.draw`)."""
        ...


class FaultKind:
    """The base of every fault kind (see the module docstring). Subclasses are frozen,
    keyword-only dataclasses with a ``kind`` tag."""

    kind: ClassVar[str]

    # --- excuses: what the invariant checkers grant a fault of this kind ---------------------
    # Its UAV's control is impaired while it acts (pause, clock skew, navigation error): checkers
    # of what the planner does excuse that UAV, and for a while after.
    impairs_control: ClassVar[bool] = False
    # Its UAVs' sensing is impaired (misses, false alarms): watching checkers excuse them.
    impairs_sensing: ClassVar[bool] = False
    # While active, frame copies may be lost, late or forged: maps need not agree.
    disturbs_links: ClassVar[bool] = False

    def span(self) -> tuple[float, float]:
        """When it acts, ``(from, until)`` in seconds (an instant: ``(at, at)``)."""
        at = getattr(self, "at_s", None)
        if at is not None:
            return (at, at)
        return (getattr(self, "start_s", 0.0), getattr(self, "end_s", math.inf))

    def concerns(self, names: Collection[str | None]) -> bool:
        """Whether it may explain something these UAVs did: it acts on one of them (its ``uav``,
        or its ``uavs``, empty meaning all), or, naming no UAV of its own, on anyone."""
        uav: str | None = getattr(self, "uav", None)
        if uav is not None:
            return uav in names
        uavs: tuple[str, ...] | None = getattr(self, "uavs", None)
        if uavs is not None:
            return not uavs or any(n in uavs for n in names)
        return True

    def acts_on(self, name: str | None, t: float, after_s: float = 0.0) -> bool:
        """Whether it acts on the UAV ``name`` at ``t``, or did until less than ``after_s`` ago."""
        lo, hi = self.span()
        if not lo <= t < hi + after_s:
            return False
        uav: str | None = getattr(self, "uav", None)
        if uav is not None:
            return uav == name
        uavs: tuple[str, ...] = getattr(self, "uavs", ())
        return not uavs or name in uavs

    def absence(self) -> tuple[float, float] | None:
        """When its UAV (``uav``) does not work at all, ``(from, until)`` (a crash: until the
        end), or None: checkers do not count on that UAV's plan then."""
        return None

    def disturbs_maps(self, t: float) -> bool:
        """Whether it keeps the UAVs' maps from agreeing at ``t`` (a paused UAV merges nothing)."""
        return False

    def blocks(self, t: float, src: int, dst: int, view: RunView) -> bool:
        """Whether it cuts the link ``src -> dst`` (UAV ids) at ``t`` (a partition, a swizzle):
        the checkers' view of what its link behaviour does."""
        return False

    def silences(self, pos: Sequence[float], t: float) -> bool:
        """Whether every frame copy to or from a UAV at ``pos`` is lost at ``t`` (a jammer)."""
        return False

    def forges_at(self, pos: Sequence[float], t: float) -> bool:
        """Whether frames forged by a non-member reach ``pos`` at ``t`` (a spoofer)."""
        return False

    def draw(self, pool: Sequence[int], rng: np.random.Generator) -> Any:
        """What it draws from its own stream when it starts (``pool``: the UAV ids it may act
        on, in id order), for the checkers to draw again as the run did (a swizzle's plan)."""
        return None

    def max_extra_delay_s(self) -> float:
        """The most it delays a frame copy, in s."""
        return 0.0

    # --- how tests draw it (swarm.testing.fault_strategies) --------------------------------
    # Its place in the shrink order, simplest first (loss on links, whole links cut, whole UAVs,
    # UAVs that are wrong, UAVs and transmitters that lie); kinds of one rank in registration order.
    shrink_rank: ClassVar[int] = 1000
    # What a draw needs: UAV names, and ticks in the run (a restart must come back before the end).
    min_uavs: ClassVar[int] = 0
    min_ticks: ClassVar[int] = 1
    # Its UAV enters the run late: drawn among the UAVs that may (a UAV is told once when it enters).
    joins_late: ClassVar[bool] = False

    @classmethod
    def generate(cls, d: Draws) -> FaultKind:
        """One fault of this kind drawn through ``d``, never an inert one (its values change
        something); called only with at least :attr:`min_uavs` names and :attr:`min_ticks` ticks.
        A kind that does not override it has no strategy (the coverage gate says so)."""
        raise NotImplementedError(f"fault kind {cls.kind!r} has no generate(): tests cannot draw it")

    @classmethod
    def has_strategy(cls) -> bool:
        """Whether the kind says how tests draw it (overrides :meth:`generate`)."""
        return cls.generate.__func__ is not FaultKind.generate.__func__  # type: ignore[attr-defined]

    # --- behaviour -------------------------------------------------------------------------

    # Whether a scenario's loader applies it to the scenario itself (a join: the UAV's join_s),
    # so that a simulation built from that scenario does not add it again.
    applied_by_loader: ClassVar[bool] = False

    def check(self, now: float) -> str | None:
        """What is wrong with adding it at ``now`` to a running simulation, or None."""
        lo, hi = self.span()
        if hasattr(self, "start_s") and hi <= lo:
            return f"{self.kind} ends at {hi} s, not after its start at {lo} s"
        if hasattr(self, "at_s") and lo < now:
            return f"{self.kind} at {lo} s is in the past (now {now} s)"
        return None

    def install(self, host: FaultHost, index: int) -> None:
        """Schedule what it does on the clock (``index``: its place in the run's schedule, which
        names its random streams). Default: nothing (a link fault acts through the radio)."""

    def link_behaviour(self, ids: Mapping[str, int], fault_rng: FaultRng,
                       rank: int) -> LinkBehaviour | None:
        """Its behaviour on frame copies, if any (:mod:`faults.injector`); ``rank``: its index
        among the faults of its kind (its stream ``fault_rng(kind, rank)``)."""
        return None

    def transmitter(self, fault_rng: FaultRng, rank: int) -> Transmitter | None:
        """Its own transmitter, if it sends frames (a spoofer); ``rank`` as for links."""
        return None

    def pool(self, ids: Mapping[str, int]) -> list[int]:
        """The ids of the UAVs it may act on, in id order: its ``uav``, its ``uavs`` (empty:
        every UAV in ``ids``), or every UAV; names not in ``ids`` are left out."""
        named: tuple[str, ...] | None = (self.uav,) if hasattr(self, "uav") else getattr(self, "uavs", None)
        if not named:
            return sorted(ids.values())
        return sorted({ids[n] for n in named if n in ids})


class Windowed(FaultKind):
    """A fault that lasts over the half-open window ``[start_s, end_s)`` (the subclasses'
    fields: each declares its own defaults and bounds)."""

    start_s: float
    end_s: float

    def active(self, t: float) -> bool:
        return self.start_s <= t < self.end_s
