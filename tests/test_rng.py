"""swarm.kernel.rng.RngTree: one random stream per (seed, key), and nothing else shared.

A stream depends only on the run's seed and its key (hashed with SHA-256): not on which other
streams exist or the order they were made in, not on PYTHONHASHSEED, and drawing from it leaves
numpy's and Python's global random state alone.
"""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys

import numpy as np
import pytest

import swarm.kernel.rng
from swarm.kernel.rng import RngTree

KEYS = [("link", "B1", "B2"), ("link", "B2", "B1"), ("planner", "A1"), ("target", 3), ("targets",)]


def _draws(tree: RngTree, *key, n: int = 8) -> list[float]:
    return tree.generator(*key).random(n).tolist()


def test_same_seed_and_key_give_the_same_stream():
    a, b = RngTree(7), RngTree(7)
    for key in KEYS:
        assert _draws(a, *key) == _draws(b, *key)
    # ...and asking the same tree twice starts the stream again (a generator is not shared).
    assert _draws(a, "planner", "A1") == _draws(a, "planner", "A1")


def test_different_keys_give_different_streams():
    tree = RngTree(7)
    streams = [_draws(tree, *key) for key in KEYS]
    assert len({tuple(s) for s in streams}) == len(KEYS)
    # A directed link is not its reverse, and one key is not a prefix of a longer one.
    assert _draws(tree, "link", "B1", "B2") != _draws(tree, "link", "B2", "B1")
    assert _draws(tree, "target") != _draws(tree, "target", 0)


def test_different_seeds_give_different_streams():
    assert _draws(RngTree(1), "planner", "A1") != _draws(RngTree(2), "planner", "A1")
    assert _draws(RngTree(0), "planner", "A1") != _draws(RngTree(2**40), "planner", "A1")


def test_a_stream_does_not_depend_on_the_other_streams_or_their_order():
    forward, backward = RngTree(3), RngTree(3)
    got_f = {key: _draws(forward, *key) for key in KEYS}
    got_b = {key: _draws(backward, *key) for key in reversed(KEYS)}
    assert got_f == got_b
    # Adding a stream (a new UAV's planner) and drawing a lot from it shifts nobody else.
    crowded = RngTree(3)
    crowded.generator("planner", "NEW").random(10_000)
    assert {key: _draws(crowded, *key) for key in KEYS} == got_f


def test_keys_of_ints_and_their_strings_name_the_same_stream():
    """Keys are joined as text: ("target", 3) and ("target", "3") are one stream. Pinned so a
    change of the key encoding (which would change every run's draws) is seen."""
    tree = RngTree(5)
    assert _draws(tree, "target", 3) == _draws(tree, "target", "3")


def test_a_stream_is_pinned():
    """The key's spawn words and the first draws of one stream. If these change, every run's
    event log changes (tests/test_regression.py's pinned hashes with them): on purpose only."""
    assert RngTree._spawn_key(("link", "B1", "B2")) == (527665264, 652792569, 3119531032, 2128273818)
    draws = RngTree(1).generator("link", "B1", "B2").integers(0, 2**32, 4).tolist()
    assert draws == [3029546130, 4142725294, 2912928584, 1655555430]


# The child loads swarm/kernel/rng.py by path: importing the swarm package would cost a second a process.
_DRAW_IN_A_PROCESS = (
    "import importlib.util, json, sys\n"
    "spec = importlib.util.spec_from_file_location('rng', sys.argv[1])\n"
    "rng = importlib.util.module_from_spec(spec)\n"
    "spec.loader.exec_module(rng)\n"
    "tree = rng.RngTree(11)\n"
    "keys = [('link', 'B1', 'B2'), ('planner', 'A1'), ('target', 3)]\n"
    "print(json.dumps({repr(k): tree.generator(*k).random(4).tolist() for k in keys}))\n"
    "print(json.dumps([hash('B1') == hash('B1'), hash('B1')]))\n"
)


def _draws_in_a_process(hashseed: str) -> tuple[dict, int]:
    env = {**os.environ, "PYTHONHASHSEED": hashseed}
    out = subprocess.run([sys.executable, "-c", _DRAW_IN_A_PROCESS, swarm.kernel.rng.__file__], env=env,
                         capture_output=True, text=True, timeout=120, check=True)
    draws, (_, str_hash) = (json.loads(line) for line in out.stdout.splitlines())
    return draws, str_hash


def test_streams_do_not_depend_on_pythonhashseed():
    draws_0, hash_0 = _draws_in_a_process("0")
    draws_1, hash_1 = _draws_in_a_process("4242")
    assert hash_0 != hash_1, "the two processes did hash strings differently (else this test proves nothing)"
    assert draws_0 == draws_1
    # ...and they are this process's draws too.
    here = RngTree(11)
    assert draws_0 == {repr(k): here.generator(*k).random(4).tolist()
                       for k in [("link", "B1", "B2"), ("planner", "A1"), ("target", 3)]}


def test_drawing_leaves_the_global_random_states_alone():
    np.random.seed(123)
    random.seed(123)
    np_before = np.random.get_state()
    py_before = random.getstate()
    tree = RngTree(9)
    for key in KEYS:
        g = tree.generator(*key)
        g.random(100)
        g.integers(0, 10, 100)
        g.normal(size=100)
    np_after = np.random.get_state()
    assert np_before[0] == np_after[0] and np.array_equal(np_before[1], np_after[1]) and np_before[2:] == np_after[2:]
    assert random.getstate() == py_before


def test_the_global_random_states_do_not_change_the_streams():
    np.random.seed(1)
    random.seed(1)
    a = _draws(RngTree(4), "planner", "A1")
    np.random.seed(2)
    np.random.random(1000)
    random.seed(2)
    assert _draws(RngTree(4), "planner", "A1") == a


@pytest.mark.parametrize("seed", [-1, 1.5, "1", True, None])
def test_seed_must_be_a_non_negative_int(seed):
    with pytest.raises(ValueError, match="non-negative integer"):
        RngTree(seed)


def test_large_seeds_are_accepted():
    assert len(_draws(RngTree(2**64 + 1), "planner", "A1")) == 8


@pytest.mark.parametrize("seed", [0, 3, 2**33 + 1])
def test_generators_made_together_are_the_streams_of_generator(seed):
    """RngTree.generators (seed words of many streams at once: issue 25) gives each key's stream."""
    tree = RngTree(seed)
    keys = [("link", "B1", f"A{i}") for i in range(40)] + [("target", 7), ("uav", "A1", 2)]
    assert tree.generators([]) == []
    for g, key in zip(tree.generators(keys), keys):
        assert g.random(6).tolist() == tree.generator(*key).random(6).tolist()
        assert g.standard_normal(3).tolist() == _draws_normal(tree, *key)


def _draws_normal(tree: RngTree, *key) -> list[float]:
    g = tree.generator(*key)
    g.random(6)
    return g.standard_normal(3).tolist()
