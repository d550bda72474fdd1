"""One root exception for everything the simulator raises on purpose.

User mistakes (a bad scenario, a wrong call) subclass both :class:`SwarmError` and the
matching built-in (``ValueError``/``TypeError``) so ``except ValueError`` keeps working.
Internal failures (an actor crashed with a bug) are :class:`SimulationError`.
"""

from __future__ import annotations


class SwarmError(Exception):
    """Root of every exception the simulator raises deliberately."""


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


class SimulationError(SwarmError, RuntimeError):
    """The simulation cannot go on (an actor raised, or the API was used in a wrong state)."""


class UsageError(SwarmError, ValueError):
    """A call into the public API received an argument it cannot use."""
