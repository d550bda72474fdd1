"""``swarm_search_v1``, by its versioned name (the PettingZoo idiom)::

    from swarm.env import swarm_search_v1
    env = swarm_search_v1.parallel_env(scenario="paper-case1")

Importing this module pins the version: when a later version replaces it, the import fails
instead of silently giving different episodes (docs/env.md, "Versions")."""

from swarm.env.parallel import ENV_NAME, SwarmSearchEnv, parallel_env

__all__ = ["ENV_NAME", "SwarmSearchEnv", "parallel_env"]
