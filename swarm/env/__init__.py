"""Reinforcement-learning environments on the simulator (needs the ``rl`` extra:
``pip install 'uav-swarm-sim[rl]'``; ``import swarm`` never needs it).

* :func:`parallel_env`: the PettingZoo parallel environment ``swarm_search_v1``
  (:mod:`swarm.env.parallel`; also as :mod:`swarm.env.swarm_search_v1`). docs/env.md.
"""

try:
    import gymnasium as _gymnasium  # noqa: F401
    import pettingzoo as _pettingzoo  # noqa: F401
except ImportError as _exc:  # pragma: no cover - exercised only without the extra
    raise ImportError(
        f"swarm.env needs the rl extra (PettingZoo and Gymnasium): pip install 'uav-swarm-sim[rl]' ({_exc})"
    ) from _exc

from swarm.env import swarm_search_v1
from swarm.env.parallel import ENV_NAME, ExternalPlanner, RewardWeights, SwarmSearchEnv, parallel_env

# Every environment by its versioned name.
ENVS = {ENV_NAME: parallel_env}

__all__ = ["ENVS", "ENV_NAME", "ExternalPlanner", "RewardWeights", "SwarmSearchEnv", "parallel_env", "swarm_search_v1"]
