"""Pinned event-log hashes of a small scenario.

These change only when behaviour is meant to change (a model or planner change, a new event
field). When one must change, update it in the same commit and say why in the message; a speed
optimisation must leave them as they are.

History:
- initial values (simulator core + DACMP planner).
"""

from __future__ import annotations

import pytest

from swarm import Simulation

PINNED = {
    "greedy": "38d5cf138e6b3fd8fc853660a33c6363197e6e79817a10550b14d313ec565d73",
    "dacmp": "76805ec4b8d18681e344673f2aa194d45c2da50723f33b354e42ffdb6d16b5dd",
}


@pytest.mark.parametrize("planner", sorted(PINNED))
def test_pinned_hash(planner, small_scenario_path):
    with Simulation(small_scenario_path, duration_s=60.0, planner=planner) as sim:
        assert sim.run().metrics["event_log_sha256"] == PINNED[planner]
