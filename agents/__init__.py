"""One UAV and what it thinks with: the asyncio actor, its knowledge (tracks, threats, peers),
its map (:mod:`agents.maps`), its planner (:mod:`agents.planners`, the public planner API), the
local planner (APF) and the kinematics. Never imports :mod:`swarm`: a UAV sees only its
sensor readings and its inbox."""

from agents.actor import ActorOutput, UavActor
from agents.apf import ApfSettings
from agents.inputs import ActorSettings, SensorReading
from agents.knowledge import Knowledge, KnownThreat, Peer, Track
from agents.types import UavType
from comms.errors import SwarmError

__all__ = [
    "ActorOutput",
    "ActorSettings",
    "ApfSettings",
    "Knowledge",
    "KnownThreat",
    "Peer",
    "SensorReading",
    "SwarmError",
    "Track",
    "UavActor",
    "UavType",
]
