"""Which event loop drives a simulation, and the rules of driving it.

A simulation is bound to the first event loop that drives it: the host's running loop for
``await sim.run_until(t)``, or a private loop for the synchronous ``step()``/``run()``. Mixing
the two raises a clear :class:`~swarm.errors.APIMisuseError`; so does driving one that is closed
or failed. Library code never calls ``asyncio.run``.
"""

from __future__ import annotations

import asyncio
import gc
import time
from collections.abc import Callable, Coroutine
from typing import Any

from swarm.errors import APIMisuseError

# Allocations between two young-generation collections while a private loop runs (Python's
# default: 700).
_GC_THRESHOLD = 70_000

Advance = Callable[[], Coroutine[Any, Any, None]]


class LoopBinding:
    """A simulation's event loop (host or private), whether it is closed or failed, and the
    wall-clock seconds spent advancing it (the one wall-clock fact, for ``metrics.json``)."""

    def __init__(self) -> None:
        self.loop: asyncio.AbstractEventLoop | None = None
        self.own_loop = False
        self.closed = False
        self.failed: BaseException | None = None
        self.wall_seconds = 0.0

    def _check_usable(self) -> None:
        if self.closed:
            raise APIMisuseError("this Simulation is closed")
        if self.failed is not None:
            raise APIMisuseError(f"this Simulation failed earlier: {self.failed}")

    def check_host_loop(self) -> None:
        """The caller runs in the loop that drives (or will drive) it: the host's, not a private one."""
        self._check_usable()
        loop = asyncio.get_running_loop()
        if self.own_loop:
            raise APIMisuseError("this Simulation is driven with step()/run(); wait_until needs it driven by "
                                 "`await sim.run_until(t)` in your event loop (use call_at with step())")
        if self.loop is None:
            self.loop = loop
        elif self.loop is not loop:
            raise APIMisuseError("this Simulation is bound to another event loop; drive it from one loop only")

    async def in_host_loop(self, advance: Advance) -> None:
        """Run ``advance()`` in the caller's running event loop."""
        self._check_usable()
        loop = asyncio.get_running_loop()
        if self.loop is None:
            self.loop = loop
        elif self.loop is not loop:
            raise APIMisuseError("this Simulation is bound to another event loop (it was driven with "
                                 "step()/run() or from another loop); drive it from one loop only")
        start = time.perf_counter()
        try:
            await self._guarded(advance)
        finally:
            self.wall_seconds += time.perf_counter() - start

    def in_own_loop(self, advance: Advance) -> None:
        """Run ``advance()`` to completion on the simulation's private loop."""
        self._check_usable()
        try:
            asyncio.get_running_loop()
        except RuntimeError:
            pass
        else:
            raise APIMisuseError("step()/run() are synchronous and cannot run inside a running event loop; "
                                 "use `await sim.run_until(t)` there")
        if self.loop is None:
            self.loop = asyncio.new_event_loop()
            self.own_loop = True
        elif not self.own_loop:
            raise APIMisuseError("this Simulation is driven by a host event loop; use `await sim.run_until(t)`")
        start = time.perf_counter()
        # Python's cyclic garbage collector re-traverses the run's caches (decoded frames, disks,
        # scan logs: tens of thousands of small objects) every few hundred allocations and finds
        # next to nothing: the run's garbage is freed by reference counting. Collecting 1/100 as
        # often saves about 4% of a paper-fig11 run. Only here, where nothing else runs until we
        # return, and restored after: the threshold belongs to the whole process.
        thresholds = gc.get_threshold()
        if thresholds[0] > 0:
            gc.set_threshold(max(thresholds[0], _GC_THRESHOLD), *thresholds[1:])
        try:
            self.loop.run_until_complete(self._guarded(advance))
        finally:
            gc.set_threshold(*thresholds)
            self.wall_seconds += time.perf_counter() - start

    async def _guarded(self, advance: Advance) -> None:
        try:
            await advance()
        except BaseException as exc:
            self.failed = exc  # (nothing drives a simulation that failed half-way through a tick)
            raise

    def close(self, tasks: list[asyncio.Task[Any]]) -> None:
        """Mark it closed; on a private loop, let the cancelled ``tasks`` finish and close it."""
        if self.closed:
            return
        self.closed = True
        if self.own_loop and self.loop is not None:
            if tasks:
                self.loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))
            self.loop.close()

    def can_close_in_finaliser(self) -> bool:
        """Whether a finaliser may close it: only a private loop that is neither running nor
        closed can be driven to finish the cancellations; in a host loop (run_until) the owner
        must close() or use ``with``: a finaliser cannot wait for that loop."""
        if self.closed:
            return False
        return not (self.own_loop and self.loop is not None and (self.loop.is_running() or self.loop.is_closed()))
