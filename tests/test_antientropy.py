"""Anti-entropy answers under flow control (issue 36, M2): ``[radio] sync_resend_cap`` and
``sync_split``, at the actor's side (:class:`agents.antientropy.AntiEntropy`)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from agents.antientropy import ANSWERERS, AntiEntropy, answer_slot, answers
from agents.knowledge import Peer
from agents.maps.scanlog import ORIGIN_MAX, ScanLog
from comms.messages import ScanDigest
from comms.settings import RadioSettings

T = 300.0
DIGEST = ScanDigest(99, T - 2.0, 0, 0, ORIGIN_MAX, ())  # UAV 99 knows no scan at all


def _log() -> ScanLog:
    log = ScanLog(1.0)
    for origin in (1, 2, 5):
        for k in range(200):
            log.add(origin, float(k), 100.0 * origin + k, 7.0 * k, 1500.0)
    return log


def _peers(n: int) -> dict[int, Peer]:
    return {u: Peer(u, x=0.0, y=0.0, t_pose=T) for u in range(100, 100 + n)}


def _resent(uid: int, n: int, **radio: object) -> int:
    """How many scans UAV ``uid`` (hearing ``n`` neighbours) sends in answer to DIGEST."""
    counters = SimpleNamespace(digests_sent=0, digest_bytes=0, scans_resent=0, resent_bytes=0)
    ae = AntiEntropy(uid, RadioSettings(**radio), _log())  # type: ignore[arg-type]
    ae.answer([DIGEST], T, _peers(n), 5.0, lambda t, msgs: b"f" * len(msgs), counters)
    return counters.scans_resent


def _answerer(slot: int, n: int) -> int:
    return next(u for u in range(10_000) if answer_slot(u, DIGEST, n) == slot)


def test_slots_are_who_answers():
    n = 7
    slots = [answer_slot(u, DIGEST, n) for u in range(2000)]
    assert set(slots) == {None, *range(ANSWERERS)}
    assert [s is not None for s in slots] == [answers(u, DIGEST, n) for u in range(2000)]
    assert 0.2 < sum(s is not None for s in slots) / 2000 < 0.37  # about 2 / n
    assert {answer_slot(u, DIGEST, ANSWERERS) for u in range(50)} == {-1}  # few neighbours: all answer, all of it


@pytest.mark.parametrize("cap", [1, 37, 250])
def test_the_cap_bounds_an_answer(cap):
    uid = _answerer(0, 7)
    assert _resent(uid, 7) == 600  # today's model: everything the digest lacks
    assert _resent(uid, 7, sync_resend_cap=cap) == cap
    assert _resent(uid, 7, sync_resend_cap=cap, sync_max_records=cap // 2) == cap // 2  # the older limit still holds


def test_the_two_slots_split_an_answer_and_a_lone_answerer_sends_it_all():
    shares = [_resent(_answerer(slot, 7), 7, sync_split=True) for slot in (0, 1)]
    assert sum(shares) == 600 and min(shares) > 250
    assert _resent(_answerer(-1, 2), 2, sync_split=True) == 600
    capped = [_resent(_answerer(slot, 7), 7, sync_split=True, sync_resend_cap=100) for slot in (0, 1)]
    assert capped == [100, 100]
