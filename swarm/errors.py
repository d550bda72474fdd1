"""One root exception for everything the simulator raises on purpose, and its kinds.

* user mistakes subclass both :class:`SwarmError` and the matching built-in so that
  ``except ValueError`` keeps working: :class:`ScenarioError` (a bad scenario document),
  :class:`UsageError` (a public call got an argument it cannot use);
* :class:`APIMisuseError`: the API was called in a state where it cannot work (a closed
  simulation, another event loop, ``step()`` past the end); the fix is in the caller's code;
* :class:`SimulationError`: the run itself failed (an actor or its planner raised); the
  original exception is its ``__cause__``;
* elsewhere: :class:`comms.codec.FrameError` (a frame a receiver rejects),
  :class:`agents.planners.PlannerError`, and the run-folder errors of :mod:`swarm.viz`.

:class:`SwarmError` itself is defined in :mod:`comms.errors`, the bottom of the import
graph, so the lower packages can subclass it without a cycle.
"""

from __future__ import annotations

from comms.errors import SwarmError

__all__ = ["APIMisuseError", "BadStateError", "NotControlledError", "NotGeographicError", "ScenarioError",
           "SimulationError", "SwarmError", "TimeInPastError", "UnknownUavError", "UsageError"]


class ScenarioError(SwarmError, ValueError):
    """A scenario document is wrong.

    ``str(err)`` is one readable line naming the file, the key path, what was found and what
    was expected. The parts are also attributes so tests and tools can check them.
    """

    def __init__(self, source: str, key: str, found: str, expected: str, hint: str = ""):
        self.source = source
        self.key = key
        self.found = found
        self.expected = expected
        self.hint = hint
        where = f"{source}: " if source else ""
        at = f"{key}: " if key else ""
        message = f"{where}{at}found {found}; expected {expected}"
        if hint:
            message += f" ({hint})"
        super().__init__(message)
        # Every problem found in the same document, in document order (this one first); the
        # loader fills it in when validation finds several (``swarm validate`` lists them all).
        self.all: list[ScenarioError] = [self]


class SimulationError(SwarmError, RuntimeError):
    """The simulation cannot go on: an actor (or its planner) raised. Internal, not a misuse."""


class APIMisuseError(SwarmError, RuntimeError):
    """A public method was called in a state where it cannot work (closed simulation, another
    event loop, a synchronous call inside a running loop, stepping past the end)."""


class UsageError(SwarmError, ValueError):
    """A call into the public API received an argument it cannot use."""


# --- the embedding API's bad inputs (docs/embedding.md): one kind each, all UsageErrors ---


class UnknownUavError(UsageError):
    """No UAV has the name a call gave."""


class TimeInPastError(UsageError):
    """A time before the simulation's present (the tick boundary where a change would take effect)."""


class NotControlledError(UsageError):
    """``set_state`` on a UAV the host has not taken control of (``take_control``)."""


class BadStateError(UsageError):
    """A pose or speed given for a body that is not finite (or a speed outside its type's range)."""


class NotGeographicError(UsageError):
    """Longitude/latitude given to a scenario in metres (one without ``[geo]``)."""
