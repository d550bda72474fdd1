"""The root of every exception the simulator raises on purpose, :class:`SwarmError`.

It lives here, in the package every other one builds on (``comms`` imports nothing of ours),
so that ``comms``, ``faults``, ``agents`` and ``swarm`` can all subclass it without an import
cycle. Users import it from :mod:`swarm.errors` (or ``swarm``), which re-exports it with the
simulator's own subclasses.
"""

from __future__ import annotations

__all__ = ["SwarmError"]


class SwarmError(Exception):
    """Root of every exception the simulator raises deliberately."""
