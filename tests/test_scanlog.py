"""The scan log behind anti-entropy: digests name exactly what a peer lacks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, rule

from agents.maps.scanlog import FORGET_SLACK_TICKS, ORIGIN_MAX, Near, ScanLog, Share, share_hash, share_hashes
from agents.maps.scanlog_oracle import OracleScanLog
from swarm import Simulation

DT = 1.0


def _scan(origin: int, k: int) -> tuple[int, float, float, float, float]:
    return origin, k * DT, 100.0 * origin + k, 7.0 * k, 1500.0


def _log(scans) -> ScanLog:
    log = ScanLog(DT)
    for s in scans:
        log.add(*s)
    return log


def test_add_tells_new_from_known_and_rejects_negative_ticks():
    log = ScanLog(DT)
    assert log.add(*_scan(3, 5))
    assert not log.add(*_scan(3, 5))  # the same origin and tick: already applied
    assert log.add(*_scan(4, 5))
    assert not log.add(3, -1.0, 0.0, 0.0, 1.0)
    assert log.count == 2


def test_digest_cuts_at_t_cut_and_missing_returns_the_scans_themselves():
    a = _log([_scan(1, k) for k in range(20)])
    tick0, lo, hi, bitmaps, nxt = a.digest(9.0)
    assert (tick0, lo, hi, nxt) == (0, 0, ORIGIN_MAX, 0)
    assert bitmaps == ((1, bytes([0xFF, 0x03])),)  # ticks 0..9
    b = _log([_scan(1, k) for k in (0, 2, 4)])
    got = dict(a.missing(*b.digest(9.0)[:4], t_cut=9.0, limit=100))
    assert [got[1][i] for i in range(0, len(got[1]), 4)] == [1.0, 3.0, 5.0, 6.0, 7.0, 8.0, 9.0]
    assert got[1][0:8] == [*_scan(1, 1)[1:], *_scan(1, 3)[1:]]


ticks = st.sets(st.integers(0, 60), max_size=40)
logs = st.dictionaries(st.integers(0, 5), ticks, max_size=5)


@settings(max_examples=examples(200), deadline=None)
@given(mine=logs, theirs=logs, t_cut=st.integers(-3, 70), max_bytes=st.sampled_from([None, 12, 30]),
       horizon=st.sampled_from([float("inf"), 5.0, 30.0]))
def test_answering_every_digest_leaves_the_peer_knowing_everything_in_the_window(mine, theirs, t_cut, max_bytes,
                                                                                 horizon):
    a = _log(_scan(o, k) for o, ks in mine.items() for k in ks)
    b = ScanLog(DT, horizon)
    for o, ks in theirs.items():
        for k in sorted(ks, reverse=True):  # newest first: the bitmap must grow downwards
            b.add(*_scan(o, k))
    tick0 = b.window(float(t_cut))[0]
    start = 0
    for _ in range(10):  # a split digest covers every origin over successive rounds
        tick0, lo, hi, bitmaps, start = b.digest(float(t_cut), start, max_bytes)
        for origin, flat in a.missing(tick0, lo, hi, bitmaps, float(t_cut), limit=10_000):
            assert flat, "an origin is listed only with something to send"
            for i in range(0, len(flat), 4):
                assert flat[i] <= t_cut
                assert b.add(origin, *flat[i:i + 4]), "only scans the peer lacked are sent"
        if start == 0:
            break
    for o, k in {(o, k) for o, ks in mine.items() for k in ks if tick0 <= k <= t_cut}:
        assert not b.add(*_scan(o, k)), f"still lacks origin {o} tick {k}"


def test_forgetting_keeps_memory_bounded_and_the_own_window_whole():
    log = ScanLog(DT, horizon_s=100.0)
    for k in range(5000):
        log.add(*_scan(1, k))
        if k % 5 == 0:
            log.forget_before(float(k))
    assert log.count <= 100 + 64 + 8 + 5
    tick0, *_ = log.digest(4990.0)
    # every tick of its own digest window is still held: it never asks for what it dropped
    assert list(ScanLog(DT).missing(tick0, 0, ORIGIN_MAX, log.digest(4990.0)[3], 4990.0, 10)) == []
    full = _log(_scan(1, k) for k in range(5000))
    assert list(full.missing(*log.digest(4990.0)[:4], t_cut=4990.0, limit=10_000)) == []
    assert log.add(*_scan(1, 10))  # long forgotten: reported new (harmless to apply), not stored
    assert log.count <= 100 + 64 + 8 + 5


def test_missing_respects_the_limit_oldest_first():
    a = _log([_scan(o, k) for o in (1, 2) for k in range(10)])
    out = list(a.missing(0, 0, ORIGIN_MAX, (), 100.0, limit=12))
    assert [o for o, _ in out] == [1, 2]
    assert len(out[0][1]) == 40 and len(out[1][1]) == 8 and out[1][1][0] == 0.0


@settings(max_examples=examples(100), deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([200.0, 600.0]), st.booleans(), st.integers(1, 4000),
       st.sampled_from([None, 2000.0, 8000.0, 25000.0]))
def test_missing_is_the_lacking_scans_within_the_horizon(seed, horizon_s, forget, limit, h):
    """missing() (every lacking scan tested against the horizon at once, as one array) lists
    exactly the scans a brute-force filter lists: held, lacking from the digest, within the
    horizon, by origin then tick, at most ``limit``."""
    import random

    rnd = random.Random(seed)
    mine, theirs = ScanLog(DT, horizon_s), ScanLog(DT, horizon_s)
    end = rnd.randint(20, 700)
    for origin in range(rnd.randint(1, 5)):
        x, y = rnd.uniform(0, 3e4), rnd.uniform(0, 3e4)
        for k in range(end):
            x, y = x + rnd.uniform(-90, 90), y + rnd.uniform(-90, 90)
            if rnd.random() < 0.9:
                mine.add(origin, k * DT, x, y, 1500.0)
                if rnd.random() < 0.3:  # (an older scan learnt later: the log grows downwards)
                    mine.add(origin, max(0, k - rnd.randint(1, 100)) * DT, x, y, 1500.0)
            if rnd.random() < 0.4:
                theirs.add(origin, k * DT, x, y, 1500.0)
    if forget:
        mine.forget_before(end * DT)
    t_cut = (end - rnd.randint(0, 5)) * DT
    tick0, lo, hi, bitmaps, _ = theirs.digest(t_cut)
    near = None if h is None else (rnd.uniform(0, 3e4), rnd.uniform(0, 3e4), h)
    for _ in range(2):  # (twice: asking changes nothing)
        got = [(o, flat[i:i + 4]) for o, flat in mine.missing(tick0, lo, hi, bitmaps, t_cut, limit, near)
               for i in range(0, len(flat), 4)]
        have = {(o, round(s[0] / DT)) for o, s in theirs.scans()}
        want = [(o, list(s)) for o, s in mine.scans()
                if tick0 <= round(s[0] / DT) <= t_cut / DT and (o, round(s[0] / DT)) not in have
                and (near is None or (s[1] - near[0]) ** 2 + (s[2] - near[1]) ** 2 <= near[2] ** 2)][:limit]
        assert got == want


# --- the scan log against a plain model ----------------------------------------------------------

# What a log is asked to do, in any order: add one scan (any tick, so out of order and repeated
# ticks; a negative one is refused), add a track (an origin's scans over consecutive ticks, the
# usual case), forget. Small integer coordinates put many scans exactly on a horizon's edge.
_coord = st.integers(0, 40).map(float)
_origin = st.sampled_from([0, 1, 2, 3, 9, 2**30])
_ops = st.lists(st.one_of(
    st.tuples(st.just("add"), _origin, st.integers(-2, 300), _coord, _coord),
    st.tuples(st.just("track"), _origin, st.integers(0, 300), st.integers(1, 90), _coord, _coord),
    st.tuples(st.just("forget"), st.integers(0, 400)),
), max_size=40)


class _Model:
    """The log's specification, written plainly: the scans held, keyed by (origin, tick)."""

    def __init__(self, dt: float, horizon_s: float):
        self.dt, self.horizon_s = dt, horizon_s
        self.scans: dict[tuple[int, int], tuple[float, float, float, float]] = {}
        self.floor = 0  # ticks below it are forgotten

    def add(self, origin: int, t: float, x: float, y: float, r: float) -> bool:
        tick = round(t / self.dt)
        if tick < 0 or (origin, tick) in self.scans:
            return False
        if tick >= self.floor:  # (older: reported new, not kept)
            self.scans[origin, tick] = (t, x, y, r)
        return True

    def forget_before(self, t: float) -> None:
        if not math.isinf(self.horizon_s):
            k_min = (round(t / self.dt) - math.ceil(self.horizon_s / self.dt) - FORGET_SLACK_TICKS) // 8 * 8
            self.floor = max(self.floor, k_min)
            self.scans = {key: s for key, s in self.scans.items() if key[1] >= self.floor}

    def window(self, t_cut: float) -> tuple[int, int]:
        k_cut = math.floor(t_cut / self.dt)
        lo = 0 if math.isinf(self.horizon_s) else max(0, k_cut - math.ceil(self.horizon_s / self.dt))
        return lo // 8 * 8, k_cut

    def digest(self, t_cut: float) -> tuple[tuple[int, bytes], ...]:
        """Per origin with a scan in the window, a byte string with bit k - tick0 set for each
        tick k it knows (little-endian; no trailing zero bytes)."""
        tick0, k_cut = self.window(t_cut)
        out = []
        for origin in sorted({o for o, _ in self.scans}):
            ks = [k - tick0 for o, k in self.scans if o == origin and tick0 <= k <= k_cut]
            if ks:
                out.append((origin, sum(1 << j for j in ks).to_bytes(max(ks) // 8 + 1, "little")))
        return tuple(out)

    def missing(self, tick0: int, lo: int, hi: int, bitmaps, t_cut: float, limit: int, near,
                newest: int = 0, share: Share | None = None):
        """The held scans of ticks tick0..t_cut, origins lo..hi, whose bit the digest does not
        set, inside ``near``; of those, with ``share = (slot, of, key)`` the ones whose
        share_hash % of is slot, and with ``newest`` > 0 the ``newest`` of the latest ticks
        (ties: lower origin); by origin then tick, the first ``limit``, grouped by origin."""
        k_cut = math.floor(t_cut / self.dt)
        if k_cut < 0 or tick0 < 0 or tick0 % 8 or tick0 > k_cut:
            return []
        theirs = {o: int.from_bytes(b, "little") for o, b in bitmaps}
        found = []
        for (o, k), (t, x, y, r) in sorted(self.scans.items()):
            if not (lo <= o <= hi and tick0 <= k <= k_cut) or theirs.get(o, 0) >> (k - tick0) & 1:
                continue
            if near is None or (x - near[0]) * (x - near[0]) + (y - near[1]) * (y - near[1]) <= near[2] * near[2]:
                if share is None or share_hash(o, k, share[2]) % share[1] == share[0]:
                    found.append((o, k, [t, x, y, r]))
        if 0 < newest < len(found):
            latest = set(sorted((-k, o) for o, k, _ in found)[:newest])
            found = [f for f in found if (-f[1], f[0]) in latest]
        lacking = [(o, s) for o, _, s in found]
        out: list[tuple[int, list[float]]] = []
        for o, s in lacking[:max(limit, 0)]:
            if out and out[-1][0] == o:
                out[-1][1].extend(s)
            else:
                out.append((o, s))
        return out


def _apply(ops, dt: float, horizon_s: float) -> tuple[ScanLog, _Model]:
    log, model = ScanLog(dt, horizon_s), _Model(dt, horizon_s)
    for op in ops:
        if op[0] == "forget":
            log.forget_before(op[1] * dt)
            model.forget_before(op[1] * dt)
            continue
        if op[0] == "add":
            _, origin, k, x, y = op
            scans = [(k, x, y)]
        else:
            _, origin, k0, length, x, y = op
            scans = [(k, x + (k - k0) % 7, y + (k - k0) % 5) for k in range(k0, k0 + length)]
        for k, x, y in scans:
            assert log.add(origin, k * dt, x, y, 3.0) == model.add(origin, k * dt, x, y, 3.0)
    return log, model


_newest = st.sampled_from([0, 0, 1, 3, 10, 50])  # flow control: the cap (0: none) ...
_share = st.none() | st.tuples(st.integers(0, 1), st.just(2), st.integers(0, 2**64 - 1))  # ... and the split


@settings(max_examples=examples(300), deadline=None)
@given(ops=_ops, peer_ops=_ops, dt=st.sampled_from([1.0, 0.5]), horizon_s=st.sampled_from([math.inf, 40.0, 100.0]),
       t_cut=st.integers(-2, 420), limit=st.integers(-1, 120),
       near=st.none() | st.tuples(_coord, _coord, st.integers(0, 30).map(float)),
       split=st.sampled_from([None, 20, 60]), newest=_newest, share=_share, data=st.data())
def test_the_log_lists_what_a_plain_model_of_it_lists(ops, peer_ops, dt, horizon_s, t_cut, limit, near, split,
                                                      newest, share, data):
    """Random logs (origins, ticks, adds out of order, forgetting) and digests of random peers
    (split or not, or arbitrary bitmaps): count, scans(), digest() and missing() (horizon,
    limit and flow control included) give exactly what the model gives, in its order; so does
    the same log after more scans arrive."""
    log, model = _apply(ops, dt, horizon_s)
    peer, peer_model = _apply(peer_ops, dt, horizon_s)
    for _ in range(2):
        assert log.count == len(model.scans)
        assert list(log.scans()) == [(o, s) for (o, _), s in sorted(model.scans.items())]
        assert log.digest(t_cut * dt)[3] == model.digest(t_cut * dt)
        tick0, lo, hi, bitmaps, _ = peer.digest(t_cut * dt, data.draw(st.integers(0, 3)), split)
        assert bitmaps == tuple((o, b) for o, b in peer_model.digest(t_cut * dt) if lo <= o <= hi)
        arbitrary = data.draw(st.lists(st.tuples(_origin, st.binary(max_size=60)), max_size=4))
        for args in ((tick0, lo, hi, bitmaps), (data.draw(st.integers(-8, 400)), 0, ORIGIN_MAX, tuple(arbitrary))):
            got = list(log.missing(*args, t_cut * dt, limit, near, newest=newest, share=share))
            assert got == model.missing(*args, t_cut * dt, limit, near, newest, share)
        more, _ = _apply(data.draw(_ops), dt, horizon_s)  # (the same log, more scans heard)
        for origin, scan in more.scans():
            assert log.add(origin, *scan) == model.add(origin, *scan)


# --- the array log against the oracle (issue 36, T5 and T6) --------------------------------------

_near = st.none() | st.tuples(_coord, _coord, st.integers(0, 30).map(float))
_back = st.integers(-5, 150)  # ticks before the clock: a scan heard (late, or a few ticks early)
_cut_back = st.integers(-3, 30)  # where digests are cut


class ArrayLogAgainstOracle(RuleBasedStateMachine):
    """Two pairs of logs, each an array :class:`ScanLog` and an :class:`OracleScanLog` built alike
    and driven alike: scans added around a clock that moves on (late ones, repeated ones, a
    few far off), tracks of consecutive ticks, forgetting, digests, answers to the other pair's
    digests and to arbitrary ones, merges. Every result of the array log is the oracle's, and
    so are its count and scans. The clock runs past the ring's size many times over, so the
    ring wraps, grows (a scan far ahead, a long horizon) and is cleared by forgetting."""

    @initialize(dt=st.sampled_from([1.0, 0.5, 0.1]), horizon_s=st.sampled_from([math.inf, 5.0, 20.0, 100.0]),
                now=st.integers(0, 3000), tracks=st.lists(st.tuples(st.integers(0, 1), _origin, _back,
                                                                     st.integers(1, 200), _coord, _coord), max_size=8))
    def start(self, dt: float, horizon_s: float, now: int, tracks: list[tuple[int, int, int, int, float, float]]
              ) -> None:
        self.dt = dt
        self.now = now  # the clock, in ticks
        self.pairs = [(ScanLog(dt, horizon_s), OracleScanLog(dt, horizon_s)) for _ in range(2)]
        for track in tracks:
            self.track(*track, step=1)

    def _tick(self, back: int) -> int:
        return self.now - back

    @rule(ticks=st.integers(1, 80), forget=st.booleans())
    def advance(self, ticks: int, forget: bool) -> None:
        self.now += ticks
        if forget:
            for pair in self.pairs:
                for log in pair:
                    log.forget_before(self.now * self.dt)

    @rule(p=st.integers(0, 1), origin=_origin, back=_back | _back | _back | st.integers(-2000, 2000), x=_coord, y=_coord)
    def add(self, p: int, origin: int, back: int, x: float, y: float) -> None:
        new, oracle = self.pairs[p]
        t = self._tick(back) * self.dt
        assert new.add(origin, t, x, y, 3.0) == oracle.add(origin, t, x, y, 3.0)

    @rule(p=st.integers(0, 1), origin=_origin, back=_back, length=st.integers(1, 200),
          x=_coord, y=_coord, step=st.sampled_from([1, -1]))
    def track(self, p: int, origin: int, back: int, length: int, x: float, y: float, step: int) -> None:
        """An origin's scans over consecutive ticks (the receivers' add_tick), forwards or backwards."""
        new, oracle = self.pairs[p]
        k0 = max(self._tick(back), 0)
        for k in range(k0, k0 + length)[::step]:
            scan = (k * self.dt, x + k % 7, y + k % 5, 3.0)
            assert new.add_tick(origin, k, scan) == oracle.add_tick(origin, k, scan)

    @rule(p=st.integers(0, 1), back=st.integers(-5, 60))
    def forget(self, p: int, back: int) -> None:
        for log in self.pairs[p]:
            log.forget_before(self._tick(back) * self.dt)

    @rule(p=st.integers(0, 1), back=_cut_back, start=st.integers(0, 3), max_bytes=st.sampled_from([None, 20, 60]))
    def digest(self, p: int, back: int, start: int, max_bytes: int | None) -> None:
        new, oracle = self.pairs[p]
        t_cut = self._tick(back) * self.dt
        assert new.digest(t_cut, start, max_bytes) == oracle.digest(t_cut, start, max_bytes)

    @rule(p=st.integers(0, 1), back=_cut_back, start=st.integers(0, 3), max_bytes=st.sampled_from([None, 20, 60]),
          limit=st.integers(-1, 400), near=_near, newest=_newest, share=_share)
    def answer(self, p: int, back: int, start: int, max_bytes: int | None, limit: int, near: Near | None,
               newest: int, share: Share | None) -> None:
        """Answer the other pair's digest (the array log's: the same as its oracle's, by digest),
        with and without flow control."""
        t_cut = self._tick(back) * self.dt
        tick0, lo, hi, bitmaps, _ = self.pairs[1 - p][0].digest(t_cut, start, max_bytes)
        new, oracle = self.pairs[p]
        args = (tick0, lo, hi, bitmaps, t_cut, limit, near)
        assert (list(new.missing(*args, newest=newest, share=share))
                == list(oracle.missing(*args, newest=newest, share=share)))

    @rule(p=st.integers(0, 1), tick0=st.integers(-8, 600), lo=st.integers(0, 9), hi=st.sampled_from([2, 9, ORIGIN_MAX]),
          bitmaps=st.lists(st.tuples(_origin, st.binary(max_size=200)), max_size=4), back=_cut_back,
          limit=st.integers(-1, 400), near=_near)
    def answer_anything(self, p: int, tick0: int, lo: int, hi: int, bitmaps: list[tuple[int, bytes]], back: int,
                        limit: int, near: Near | None) -> None:
        """Answer a digest no log would send (any window, range and bytes; origins repeated)."""
        new, oracle = self.pairs[p]
        args = (max(self.now - tick0, -8), lo, hi, tuple(bitmaps), self._tick(back) * self.dt, limit, near)
        assert list(new.missing(*args)) == list(oracle.missing(*args))

    @rule(p=st.integers(0, 1), near=_near)
    def merge(self, p: int, near: Near | None) -> None:
        (new, oracle), (other, other_oracle) = self.pairs[p], self.pairs[1 - p]
        assert new.merge(other, near) == oracle.merge(other_oracle, near)

    @invariant()
    def same_scans(self) -> None:
        for new, oracle in getattr(self, "pairs", ()):
            assert new.count == oracle.count
            assert list(new.scans()) == list(oracle.scans())


ArrayLogAgainstOracle.TestCase.settings = settings(max_examples=examples(150), stateful_step_count=40, deadline=None)
TestArrayLogAgainstOracle = ArrayLogAgainstOracle.TestCase


def test_the_ring_grows_to_hold_ticks_however_far_apart():
    """Ticks far apart (a late join's first scans, a scan from far ahead) never share a column:
    every distance up to a few rings, as the oracle lists them."""
    for gap in range(0, 3000, 8):
        for late in (0, 7):
            new, oracle = ScanLog(DT, 100.0), OracleScanLog(DT, 100.0)
            for log in (new, oracle):
                for k in (3, 3 + gap, 3 + gap + late, gap // 2):
                    log.add(*_scan(1, k))
            assert list(new.scans()) == list(oracle.scans())
            assert new.digest(float(3 + gap + late)) == oracle.digest(float(3 + gap + late))


@pytest.mark.slow
def test_a_run_with_every_fault_keeps_its_scan_logs_and_event_log_with_the_oracle():
    """``Simulation(tick_plane=False)`` gives every actor the oracle's log, ``True`` the array
    log; over demo-all-faults (every fault kind: liars, spoofers, restarts, joins, corruption,
    partitions...) the two runs end with the same scans in every UAV's log and the same event log."""
    runs = {}
    for plane in (True, False):
        with Simulation("demo-all-faults", tick_plane=plane) as sim:
            sim.run()
            runs[plane] = (sim.metrics_dict()["event_log_sha256"],
                           {uid: list(a.scans.scans()) for uid, a in sim.actors.items()},
                           {type(a.scans) for a in sim.actors.values()})
    assert runs[True][2] == {ScanLog} and runs[False][2] == {OracleScanLog}
    assert sum(len(s) for s in runs[True][1].values()) > 1000
    assert runs[True][:2] == runs[False][:2]


# --- flow control (issue 36, M2: [radio] sync_resend_cap and sync_split) ------------------------


@given(origins=st.lists(st.integers(0, 2**31 - 1), min_size=1, max_size=20), tick=st.integers(0, 2**40),
       key=st.integers(0, 2**64 - 1))
def test_the_share_hash_of_arrays_is_the_share_hash_of_each(origins, tick, key):
    ticks = [tick + 3 * i for i in range(len(origins))]
    got = share_hashes(np.array(origins, np.int64), np.array(ticks, np.int64), key).tolist()
    assert got == [share_hash(o, k, key) for o, k in zip(origins, ticks)]


def test_the_two_answerers_shares_split_what_is_missing_and_the_cap_keeps_the_latest():
    """The two slots' answers are disjoint and together are the whole answer, about half each;
    a cap keeps the latest scans (ties to the lower origin), listed by origin then tick."""
    log = _log([_scan(o, k) for o in (1, 2, 5) for k in range(0, 200)])
    args = (0, 0, ORIGIN_MAX, (), 300.0, 10_000)
    whole = {(o, flat[i]) for o, flat in log.missing(*args) for i in range(0, len(flat), 4)}
    parts = [{(o, flat[i]) for o, flat in log.missing(*args, share=(slot, 2, 12345)) for i in range(0, len(flat), 4)}
             for slot in (0, 1)]
    assert parts[0] | parts[1] == whole and not parts[0] & parts[1]
    assert 0.4 < len(parts[0]) / len(whole) < 0.6
    capped = list(log.missing(*args, newest=7))
    assert [(o, flat[::4]) for o, flat in capped] == [(1, [197.0, 198.0, 199.0]), (2, [198.0, 199.0]), (5, [198.0, 199.0])]
    assert list(log.missing(*args, newest=10_000)) == list(log.missing(*args))  # a cap above the count: no change
