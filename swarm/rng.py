"""One tree of random streams per run, keyed by stable names.

Every consumer (a UAV's planner, a directed radio link, a target's motion, the random target
layout) gets its own ``numpy.random.Generator`` derived from the run's seed and a key such as
``("link", "B1", "B2")``. Keys are hashed with SHA-256 (not Python's ``hash``, which changes with
``PYTHONHASHSEED``), so a stream depends only on the seed and its key: adding a UAV does not
shift anyone else's draws, and the order in which streams are created does not matter.
"""

from __future__ import annotations

import hashlib

import numpy as np


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
