"""The scan log behind anti-entropy: digests name exactly what a peer lacks."""

from __future__ import annotations

from budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.maps.scanlog import ORIGIN_MAX, ScanLog

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
    """missing() (chunks skipped, taken or tested at once by their boxes and centres) lists
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
                if rnd.random() < 0.3:  # (mine learns more scans of this chunk later: fresh centres)
                    mine.add(origin, max(0, k - rnd.randint(1, 100)) * DT, x, y, 1500.0)
            if rnd.random() < 0.4:
                theirs.add(origin, k * DT, x, y, 1500.0)
    if forget:
        mine.forget_before(end * DT)
    t_cut = (end - rnd.randint(0, 5)) * DT
    tick0, lo, hi, bitmaps, _ = theirs.digest(t_cut)
    near = None if h is None else (rnd.uniform(0, 3e4), rnd.uniform(0, 3e4), h)
    for _ in range(2):  # (twice: the second time with the centres missing() kept)
        got = [(o, flat[i:i + 4]) for o, flat in mine.missing(tick0, lo, hi, bitmaps, t_cut, limit, near)
               for i in range(0, len(flat), 4)]
        have = {(o, round(s[0] / DT)) for o, s in theirs.scans()}
        want = [(o, list(s)) for o, s in mine.scans()
                if tick0 <= round(s[0] / DT) <= t_cut / DT and (o, round(s[0] / DT)) not in have
                and (near is None or (s[1] - near[0]) ** 2 + (s[2] - near[1]) ** 2 <= near[2] ** 2)][:limit]
        assert got == want
