"""One tree of random streams per run, keyed by stable names.

Every consumer (a UAV's planner, a directed radio link, a target's motion, the random target
layout) gets its own ``numpy.random.Generator`` derived from the run's seed and a key such as
``("link", "B1", "B2")``. Keys are hashed with SHA-256 (not Python's ``hash``, which changes with
``PYTHONHASHSEED``), so a stream depends only on the seed and its key: adding a UAV does not
shift anyone else's draws, and the order in which streams are created does not matter.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.random.bit_generator import ISeedSequence


class RngTree:
    def __init__(self, seed: int):
        if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        self.seed = seed

    @staticmethod
    def _spawn_key(key: tuple) -> tuple[int, ...]:
        digest = hashlib.sha256("\x1f".join(map(str, key)).encode()).digest()
        return tuple(int.from_bytes(digest[i : i + 4], "little") for i in range(0, 16, 4))

    def generator(self, *key: str | int) -> np.random.Generator:
        ss = np.random.SeedSequence(entropy=self.seed, spawn_key=self._spawn_key(key))
        return np.random.Generator(np.random.PCG64(ss))

    def generators(self, keys: Sequence[tuple[str | int, ...]]) -> list[np.random.Generator]:
        """``[self.generator(*key) for key in keys]``: the same streams, their seed words made
        together (:func:`stream_states`' algorithm): about 4 us a stream instead of 35 (a dense
        swarm makes tens of thousands of link streams in its first tick; issue 25)."""
        if not keys:
            return []
        sha = hashlib.sha256
        digests = b"".join([sha("\x1f".join(map(str, key)).encode()).digest() for key in keys])
        spawn = np.frombuffer(digests, dtype="<u4").reshape(len(keys), 8)[:, :4].astype(np.uint32)
        return [generator_from_state(words) for words in _seed_states(self.seed, spawn)]


# --- many streams' first draws at once (issue 25: a million targets build in seconds) -----------
#
# ``generator(*key)`` costs about 35 us (SHA-256, a SeedSequence, a PCG64), so a scenario with a
# million random targets spent most of its build making generators to take four uniforms from
# each. :func:`first_randoms` computes those first draws for many keys at once, with numpy, by
# the very algorithms numpy runs (SeedSequence's entropy mixing, PCG64's seeding and its XSL-RR
# output, ``Generator.random``'s 53-bit double): the same numbers bit for bit
# (tests/test_rng_vector.py checks them against the Generators). The stream itself is made only
# if something draws from it later (swarm.kernel.world.Targets: a moving target's motion noise).

_M32 = 0xFFFFFFFF
_INIT_A, _MULT_A, _INIT_B, _MULT_B = 0x43B0D7E5, 0x931E8875, 0x8B51F9DD, 0x58F38DED
_MIX_L, _MIX_R = 0xCA01F9DD, 0x4973F715
_POOL = 4
_PCG_MULT = (2549297995355413924, 4865540595714422341)  # PCG64's 128-bit multiplier (high, low)


def _entropy_words(n: int) -> list[int]:
    """An int's uint32 words, least significant first (SeedSequence's coercion)."""
    words = [n & _M32]
    n >>= 32
    while n > 0:
        words.append(n & _M32)
        n >>= 32
    return words


def _seed_states(seed: int, spawn_keys: np.ndarray) -> np.ndarray:
    """``SeedSequence(seed, spawn_key=k).generate_state(4, np.uint64)`` for each row ``k`` of
    ``spawn_keys`` (n, 4) uint32: an (n, 4) uint64 array."""
    u32 = np.uint32
    n = len(spawn_keys)
    run = _entropy_words(seed)
    if len(run) < _POOL:  # (a spawn key follows: the run entropy is padded to the pool size)
        run += [0] * (_POOL - len(run))
    words: list[np.ndarray | int] = [*run, *(spawn_keys[:, j] for j in range(spawn_keys.shape[1]))]
    hc = _INIT_A

    def hashmix(value: np.ndarray | int) -> np.ndarray:
        nonlocal hc
        v = np.asarray(value, dtype=u32) ^ u32(hc)
        hc = (hc * _MULT_A) & _M32
        v = v * u32(hc)
        return v ^ (v >> u32(16))

    def mix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        r: np.ndarray = u32(_MIX_L) * x - u32(_MIX_R) * y
        return r ^ (r >> u32(16))

    with np.errstate(over="ignore"):
        mixer = [np.broadcast_to(hashmix(words[i] if i < len(words) else 0), (n,)) for i in range(_POOL)]
        for i_src in range(_POOL):
            for i_dst in range(_POOL):
                if i_src != i_dst:
                    mixer[i_dst] = mix(mixer[i_dst], hashmix(mixer[i_src]))
        for i_src in range(_POOL, len(words)):
            for i_dst in range(_POOL):
                mixer[i_dst] = mix(mixer[i_dst], hashmix(words[i_src]))
        hc = _INIT_B
        out = np.empty((n, 8), dtype=u32)
        for i_dst in range(8):
            v = np.asarray(mixer[i_dst % _POOL], dtype=u32) ^ u32(hc)
            hc = (hc * _MULT_B) & _M32
            v = v * u32(hc)
            out[:, i_dst] = v ^ (v >> u32(16))
    return out.view("<u8").astype(np.uint64)  # (little-endian words, as numpy's view)


def _mulhi64(a: np.ndarray, b: np.ndarray | np.uint64) -> np.ndarray:
    """The high 64 bits of the 128-bit products ``a * b`` (uint64)."""
    m, s = np.uint64(_M32), np.uint64(32)
    al, ah, bl, bh = a & m, a >> s, b & m, b >> s
    lh, hl = al * bh, ah * bl
    mid = ((al * bl) >> s) + (lh & m) + (hl & m)
    return ah * bh + (lh >> s) + (hl >> s) + (mid >> s)


class _Pcg128:
    """PCG64 (numpy's, XSL-RR output) for many streams at once: 128-bit state as (hi, lo)."""

    def __init__(self, seed: np.ndarray, inc: np.ndarray):
        one = np.uint64(1)
        # pcg_setseq_128_srandom_r: state = 0; inc = initseq << 1 | 1; step; state += initstate; step
        self.inc_hi = (inc[:, 0] << one) | (inc[:, 1] >> np.uint64(63))
        self.inc_lo = (inc[:, 1] << one) | one
        self.hi = np.zeros(len(seed), np.uint64)
        self.lo = np.zeros(len(seed), np.uint64)
        with np.errstate(over="ignore"):
            self._step()
            lo = self.lo + seed[:, 1]
            self.hi = self.hi + seed[:, 0] + (lo < self.lo).astype(np.uint64)
            self.lo = lo
            self._step()

    def _step(self) -> None:
        mh, ml = np.uint64(_PCG_MULT[0]), np.uint64(_PCG_MULT[1])
        hi = _mulhi64(self.lo, ml) + self.hi * ml + self.lo * mh
        lo = self.lo * ml
        lo2 = lo + self.inc_lo
        self.hi = hi + self.inc_hi + (lo2 < lo).astype(np.uint64)
        self.lo = lo2

    def next_uint64(self) -> np.ndarray:
        with np.errstate(over="ignore"):
            self._step()
            x = self.hi ^ self.lo
            rot = self.hi >> np.uint64(58)
            return (x >> rot) | (x << ((np.uint64(64) - rot) & np.uint64(63)))


def stream_states(seed: int, prefix: tuple[str | int, ...], ids: range) -> np.ndarray:
    """The PCG64 seed words (``SeedSequence.generate_state(4, np.uint64)``) of the streams
    ``RngTree(seed).generator(*prefix, i)`` for every ``i`` of ``ids``: an (n, 4) uint64 array."""
    head = "".join(f"{p}\x1f" for p in prefix).encode()  # _spawn_key's "\x1f".join(map(str, key))
    sha = hashlib.sha256
    digests = b"".join([sha(head + b"%d" % i).digest() for i in ids])
    spawn = np.frombuffer(digests, dtype="<u4").reshape(len(ids), 8)[:, :4].astype(np.uint32)
    return _seed_states(seed, spawn)


def first_randoms(states: np.ndarray, k: int) -> np.ndarray:
    """The first ``k`` ``Generator.random()`` draws of each stream of ``states`` (rows of
    :func:`stream_states`), as an ``(n, k)`` float64 array, without making the generators."""
    pcg = _Pcg128(states[:, 0:2], states[:, 2:4])
    out = np.empty((len(states), k))
    for j in range(k):
        out[:, j] = (pcg.next_uint64() >> np.uint64(11)) * (1.0 / 9007199254740992.0)
    return out


class _Seeded(ISeedSequence):
    """A SeedSequence's output, computed beforehand (:func:`stream_states`): all PCG64 asks of it."""

    __slots__ = ("words",)

    def __init__(self, words: np.ndarray):
        self.words = words

    def generate_state(self, n_words: int, dtype: Any = np.uint32) -> np.ndarray:
        assert n_words == 4 and np.dtype(dtype) == np.uint64  # (PCG64's one request)
        return self.words


def generator_from_state(words: np.ndarray) -> np.random.Generator:
    """The generator :meth:`RngTree.generator` makes for the key whose :func:`stream_states` row
    is ``words``, the same stream (2 us instead of 35: no SHA-256 or SeedSequence)."""
    # (numpy's stubs name only SeedSequence; PCG64 takes any ISeedSequence)
    return np.random.Generator(np.random.PCG64(_Seeded(words)))  # type: ignore[arg-type]
