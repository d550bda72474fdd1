"""The radio's settings and what they mean for a link: each fact defined once, here.

* :class:`RadioSettings`: every key of a scenario's ``[radio]`` table, with its default, its
  bounds and the words of an error (field metadata, as :mod:`faults.schedule`'s fault kinds).
  :mod:`swarm.scenario` generates the table from it; the actors take their radio settings
  (frame cap, beacon and tracks timers, anti-entropy) from one
  (:attr:`agents.inputs.ActorSettings.radio`); the radio runs its :meth:`~RadioSettings.link_model`.
* :class:`LogDistance`: the ``[radio.log_distance]`` table, and its link budget.
* :class:`LinkModel`: the link model the radio runs (range, loss, latency, bandwidth), its
  defaults those of :class:`RadioSettings`. Its loss rules are written once each, for one
  distance (:meth:`LinkModel.loss`) and for an array of them (:meth:`LinkModel.losses`, the
  radio's per-tick update): the disk model's quadratic rise from ``loss_base`` to
  ``loss_at_range``, and the log-distance model's ``loss_base`` floor.

The frame size cap's default is the codec's (:data:`comms.codec.DEFAULT_MAX_BYTES`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, TypeVar

import numpy as np
import numpy.typing as npt

from comms.codec import DEFAULT_MAX_BYTES

__all__ = ["LinkModel", "LogDistance", "RADIO_MODELS", "RadioSettings", "loss_falls"]

# A link whose mean margin is below -(edge_sigmas * sigma + _EDGE_WIDTHS * width) dB is no edge:
# even shadowing edge_sigmas sigma above its mean leaves it losing > 98% of its frames.
_EDGE_WIDTHS = 4.0

Floats = npt.NDArray[np.float64]
# A float or an array of them: the loss rules below are plain arithmetic, the same operations in
# the same order (so the same bits) for one link and for the radio's array of links.
_F = TypeVar("_F", float, Floats)


@dataclass(frozen=True, slots=True)
class LogDistance:
    """Log-distance path loss with log-normal shadowing, and a logistic frame loss in the margin.

    The received power of a frame on a link ``d`` metres long (``d`` at least 1 m) is::

        rx_dbm = tx_power_dbm + antenna_gain_db - ref_loss_db - 10 * exponent * log10(d) + X

    ``X`` the link's shadowing (dB): normal, mean 0, sd ``sigma_db``, slowly varying (a Gauss-Markov
    process, exact at the frames' times: ``X' = rho X + sigma sqrt(1 - rho^2) N(0, 1)`` with
    ``rho = exp(-dt / corr_s)``), drawn from the directed link's own stream. The frame is lost
    with probability ``1 / (1 + exp(margin / width_db))``, ``margin = rx_dbm - sensitivity_dbm``:
    half the frames at the sensitivity, 10% at 2.2 widths above it, 1% at 4.6.

    The defaults are a small UAV's 2.4 GHz radio in open air (air-to-air, line of sight):
    20 dBm out, 0 dBi antennas, -90 dBm sensitivity; the free-space exponent 2 and 40.05 dB at
    1 m (free space at 2.4 GHz, 20 log10(4 pi f / c)); 3 dB of shadowing. Measurement campaigns
    of small-UAV links in open field report exponents of 2.0-2.3 and shadowing of 2.5-5 dB (the
    campaigns surveyed in Khawaja et al., "A Survey of Air-to-Ground Propagation Channel Modeling
    for Unmanned Aerial Vehicles", IEEE Communications Surveys & Tutorials, 2019). The correlation
    time (5 s: a few hundred metres of relative flight) is our choice. Half the frames get through
    at :attr:`median_range_m` (3.1 km with the defaults); the radio graph's edges reach
    :attr:`range_m` (14 km).

    The one definition of these settings: a scenario's ``[radio.log_distance]`` table is built
    from this class by :mod:`swarm.scenario`.
    """

    tx_power_dbm: float = field(default=20.0, metadata={"note": "dBm"})
    antenna_gain_db: float = field(default=0.0, metadata={"note": "dB, the transmit and receive antennas' gains together"})
    ref_loss_db: float = field(default=40.05, metadata={"ge": 0, "note": "dB of path loss at 1 m"})
    exponent: float = field(default=2.0, metadata={"gt": 0, "le": 10, "note": "path-loss exponent; 2 = free space"})
    sigma_db: float = field(default=3.0, metadata={"ge": 0, "le": 30, "note": "dB, sd of the log-normal shadowing"})
    corr_s: float = field(default=5.0, metadata={"gt": 0, "note": "seconds, correlation time of the shadowing"})
    sensitivity_dbm: float = field(default=-90.0, metadata={"note": "dBm, where half the frames are lost"})
    width_db: float = field(default=1.0, metadata={"gt": 0, "note": "dB, scale of the logistic loss curve"})
    edge_sigmas: float = field(default=3.0, metadata={"ge": 0, "le": 10,
                                                      "note": "shadowing sds the radio graph reaches below the sensitivity"})

    @property
    def budget_db(self) -> float:
        """The mean margin at 1 m (dB above the sensitivity)."""
        return self.tx_power_dbm + self.antenna_gain_db - self.ref_loss_db - self.sensitivity_dbm

    def margin_db(self, distance: float) -> float:
        """The mean margin (no shadowing) of a link ``distance`` metres long."""
        return self.budget_db - 10.0 * self.exponent * math.log10(max(distance, 1.0))

    def margins_db(self, distance: Floats) -> Floats:
        """:meth:`margin_db` of each distance (numpy's log10: equal to rounding)."""
        return self.budget_db - 10.0 * self.exponent * np.log10(np.maximum(distance, 1.0))

    def frame_loss(self, margin_db: float) -> float:
        """The loss probability of a frame received ``margin_db`` above the sensitivity."""
        z = margin_db / self.width_db
        if z >= 0.0:  # (two forms: neither exp overflows)
            e = math.exp(-z)
            return e / (1.0 + e)
        return 1.0 / (1.0 + math.exp(z))

    def frame_losses(self, margin_db: Floats) -> Floats:
        """:meth:`frame_loss` of each margin (scipy's ``expit``, which never overflows: equal to rounding)."""
        from scipy.special import expit  # (only the log-distance model pays for scipy)

        return expit(-margin_db / self.width_db)

    def _distance_at(self, margin_db: float) -> float:
        return max(1.0, math.pow(10.0, min((self.budget_db - margin_db) / (10.0 * self.exponent), 300.0)))

    @property
    def median_range_m(self) -> float:
        """Where the mean margin is 0: half the frames lost (without shadowing)."""
        return self._distance_at(0.0)

    @property
    def range_m(self) -> float:
        """The radio graph's reach: where the mean margin is ``-(edge_sigmas * sigma_db + 4 *
        width_db)`` dB (beyond it a link loses > 98% of its frames even with shadowing
        ``edge_sigmas`` sd above its mean)."""
        return self._distance_at(-(self.edge_sigmas * self.sigma_db + _EDGE_WIDTHS * self.width_db))


RADIO_MODELS = ("disk", "log_distance")


@dataclass(frozen=True, slots=True, kw_only=True)
class RadioSettings:
    """The paper says nothing about the radio; the defaults are the ideal radio used to
    reproduce it (unlimited range, no loss, no authentication).

    ``model``: ``"disk"`` (every pair within ``range_m`` linked; loss ``loss_base`` at distance 0
    rising quadratically to ``loss_at_range`` at the range limit; ``loss_at_range`` absent = the
    same loss at every distance, and never below ``loss_base``) or ``"log_distance"`` (loss from
    the link budget of ``[radio.log_distance]`` and each link's shadowing, ``loss_base`` a floor
    on every frame, ``range_m`` an optional extra cap, ``loss_at_range`` not allowed); see
    :class:`LinkModel` and :class:`LogDistance`. ``auth``: frames carry a MAC under the swarm key
    (``auth_key`` as UTF-8, or when absent one derived from the scenario's seed), and receivers
    reject frames without the right one.

    The one definition of these settings (a scenario's ``[radio]`` table is generated from this
    class, as the ``[[faults]]`` tables are from :mod:`faults.schedule`): field metadata carries
    the bounds (``gt``, ``ge``, ``lt``, ``le``), a ``note``, ``inf`` for a number that may be
    infinite, and for a field that is not a number the ``expected`` words of an error. Settings
    made in Python are taken as given.
    """

    # None (or inf: TOML can write `inf`): unlimited.
    range_m: float | None = field(default=None, metadata={"gt": 0, "inf": True, "note": "metres; inf = unlimited"})
    model: Literal["disk", "log_distance"] = "disk"
    loss_base: float = field(default=0.0, metadata={"ge": 0, "le": 1})
    # None: loss_base (loss never falls with distance: loss_falls).
    loss_at_range: float | None = field(default=None, metadata={"ge": 0, "le": 1,
                                                                "note": '>= loss_base; model = "disk" only'})
    latency_s: float = field(default=0.0, metadata={"ge": 0})
    jitter_s: float = field(default=0.0, metadata={"ge": 0})
    bandwidth_bytes_per_s: float | None = field(default=None, metadata={"gt": 0})  # per sender; None: unlimited
    frame_max_bytes: int = field(default=DEFAULT_MAX_BYTES, metadata={"ge": 256})
    mailbox_capacity: int = field(default=1024, metadata={"ge": 1})
    beacon_every_s: float = field(default=1.0, metadata={"gt": 0})
    tracks_every_s: float = field(default=5.0, metadata={"gt": 0})
    # (issue 36, M1) How tracks and threats are sent (agents.tracksync): "periodic", every one a
    # UAV knows every tracks_every_s; "on_change", a track when it is new or newer than what the
    # UAV last sent of it (at most every tracks_every_s per track), a threat once, and a track
    # digest on the beacon every sync_every_s (tracks_every_s with anti-entropy off) that
    # neighbours answer with what it lacks.
    tracks: Literal["periodic", "on_change"] = field(default="periodic", metadata={
        "note": "periodic: every track every tracks_every_s; on_change: new or newer tracks, and a digest for repair"})
    # Anti-entropy (agents.maps.scanlog): every sync_every_s a UAV's beacon carries a digest of the
    # scans it knows from the last sync_horizon_s up to sync_settle_s ago; neighbours resend what
    # it lacks, at most sync_max_records scans each time. sync_every_s = 0 turns it off.
    sync_every_s: float = field(default=5.0, metadata={"ge": 0, "note": "seconds; 0 = no anti-entropy"})
    sync_settle_s: float = field(default=2.0, metadata={"ge": 0})
    sync_max_records: int = field(default=4000, metadata={"ge": 0})
    sync_horizon_s: float = field(default=600.0, metadata={"gt": 0, "note": "seconds; scans older than this are not resent"})
    # Anti-entropy flow control (issue 36, M2; agents.antientropy): an answer to one digest carries
    # at most sync_resend_cap scans, the latest first (0 = unlimited); with sync_split the about two
    # answerers of a digest each send only their share of the scans it lacks (a hash of the scan and
    # the round picks which), instead of both sending all of them.
    sync_resend_cap: int = field(default=0, metadata={"ge": 0, "note": "scans per answer, latest first; 0 = unlimited"})
    sync_split: bool = False
    # The knowledge horizon (agents.maps.scanlog, "Knowledge horizon"): a UAV applies, logs, relays
    # and compares only scans whose centre lies within sync_horizon_m of itself (its own always), and
    # answers a digest only with scans within sync_horizon_m of the digest's sender. So its map and
    # log grow with the area around its path, not with the swarm. None (or inf) = no horizon (every
    # heard scan); a run folder's scenario.json writes inf as null. As a number: horizon_m.
    sync_horizon_m: float | None = field(default=None, metadata={"gt": 0, "inf": True, "note": "metres; inf = no horizon"})
    # Authenticated frames (comms.codec): HMAC-SHA256 truncated to 16 bytes, counted in the bytes
    # sent. Off by default (the paper is silent). auth_key is read only with auth = true.
    auth: bool = False
    auth_key: str | None = field(default=None, metadata={
        "min_length": 1,
        "expected": "a non-empty string (the swarm's key), or leave it out (a key derived from the seed)"})
    log_distance: LogDistance = field(default_factory=LogDistance)

    @property
    def horizon_m(self) -> float:
        """The knowledge horizon as a number: ``sync_horizon_m``, math.inf when absent (none)."""
        return math.inf if self.sync_horizon_m is None else self.sync_horizon_m

    def link_model(self) -> LinkModel:
        """The link model the radio runs with these settings."""
        return LinkModel(self.range_m, self.loss_base, self.loss_at_range, self.latency_s, self.jitter_s,
                         self.bandwidth_bytes_per_s,
                         log_distance=self.log_distance if self.model == "log_distance" else None)

    @property
    def effective_loss_at_range(self) -> float:
        """The disk model's loss at the range limit (``loss_base`` when ``loss_at_range`` is absent)."""
        return self.link_model().range_loss

    @property
    def loses_nothing(self) -> bool:
        """Whether the radio, without faults, delivers every frame copy in range: no link ever
        loses one (:attr:`LinkModel.lossless`) and no bandwidth cap drops one."""
        return self.link_model().lossless and self.bandwidth_bytes_per_s is None

    @property
    def range_limit_m(self) -> float:
        """How far links reach, as a number (math.inf when unlimited): ``range_m``, and with the
        log-distance model at most its link budget's range (:attr:`LinkModel.radius_m`)."""
        return self.link_model().radius_m


def loss_falls(loss_base: float, loss_at_range: float | None) -> bool:
    """Whether a disk model's loss would fall with distance (refused): ``loss_at_range`` below
    ``loss_base`` (absent: ``loss_base``, which never falls)."""
    return loss_at_range is not None and loss_at_range < loss_base


_IDEAL = RadioSettings()  # whose link model is LinkModel()'s


@dataclass(frozen=True, slots=True)
class LinkModel:
    """Range limit, loss and latency of every link (made from a scenario's ``[radio]`` table by
    :meth:`RadioSettings.link_model`; its defaults are that table's).

    Two propagation models. The *disk* model (``log_distance`` None): every pair within
    ``range_m`` is linked, and a frame is lost with probability
    ``loss_base + (loss_at_range - loss_base) * (d / range_m)^2`` (``loss_base`` at distance 0,
    ``loss_at_range`` at the range limit; ``loss_base`` everywhere when the range is unlimited).
    ``loss_at_range`` defaults to ``loss_base`` (the same loss at every distance) and may not be
    below it: loss never falls with distance. The *log-distance* model (:class:`LogDistance`):
    the loss comes from the link budget and the link's shadowing, with ``loss_base`` as a floor
    that hits every frame independently (``loss = loss_base + (1 - loss_base) * link loss``);
    the pairs linked are those within the budget's :attr:`LogDistance.range_m` and within
    ``range_m`` if that is given too; ``loss_at_range`` is not used (the scenario refuses it).
    """

    range_m: float | None = _IDEAL.range_m  # None: unlimited
    loss_base: float = _IDEAL.loss_base  # loss probability at distance 0
    loss_at_range: float | None = _IDEAL.loss_at_range  # at the range limit (quadratic in between); None: loss_base
    latency_s: float = _IDEAL.latency_s
    jitter_s: float = _IDEAL.jitter_s
    bandwidth_bytes_per_s: float | None = _IDEAL.bandwidth_bytes_per_s  # per sender; None: unlimited
    log_distance: LogDistance | None = None  # None: the disk model (RadioSettings.model = "disk")

    def __post_init__(self) -> None:
        at = self.loss_at_range
        if at is None:  # (so LinkModel(loss_base=p) == LinkModel(loss_base=p, loss_at_range=p))
            object.__setattr__(self, "loss_at_range", self.loss_base)
        elif self.log_distance is None and loss_falls(self.loss_base, at):
            raise ValueError(f"loss_at_range ({at}) < loss_base ({self.loss_base}): loss must not fall with distance")

    @property
    def range_loss(self) -> float:
        """The disk model's loss at the range limit: ``loss_at_range`` (``loss_base`` if given as None)."""
        return self.loss_base if self.loss_at_range is None else self.loss_at_range

    @property
    def radius_m(self) -> float:
        """How far links reach (math.inf: unlimited): ``range_m``, and for the log-distance model
        at most its link budget's :attr:`LogDistance.range_m`."""
        r = math.inf if self.range_m is None else self.range_m
        return r if self.log_distance is None else min(r, self.log_distance.range_m)

    @property
    def lossless(self) -> bool:
        """Whether every link's loss probability is 0 (no draw is ever made for loss)."""
        return self.log_distance is None and self.loss_base == 0.0 and (
            not math.isfinite(self.radius_m) or self.range_loss == 0.0)

    # --- the loss rules: plain arithmetic on a float or an array ---------------------------------

    def _disk(self, f: _F) -> _F:
        """The disk model's loss at ``f = distance / range`` (at most 1; 0 when unlimited)."""
        return self.loss_base + (self.range_loss - self.loss_base) * f * f

    def floored(self, p: _F) -> _F:
        """The log-distance model's loss of a copy whose link loses it with probability ``p``:
        ``loss_base`` is a floor that hits every frame independently."""
        return self.loss_base + (1.0 - self.loss_base) * p

    def loss(self, distance: float) -> float:
        """The loss probability of a link ``distance`` metres long (log-distance: at its mean,
        without shadowing)."""
        ld = self.log_distance
        if ld is not None:
            return self.floored(ld.frame_loss(ld.margin_db(distance)))
        return self._disk(min(distance / self.radius_m, 1.0))

    def losses(self, distance: Floats, margin_db: Floats | None = None) -> Floats:
        """:meth:`loss` of each distance, vectorised (the radio's update of its edges): the disk
        model's the same bits, the log-distance model's equal to rounding (numpy's log10,
        scipy's expit). ``margin_db``: the log-distance model's mean margins of these distances
        (:meth:`LogDistance.margins_db`), if already computed."""
        ld = self.log_distance
        if ld is not None:
            return self.floored(ld.frame_losses(ld.margins_db(distance) if margin_db is None else margin_db))
        return self._disk(np.minimum(distance / self.radius_m, 1.0))
