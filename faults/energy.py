"""Faults on a UAV's energy (issue 26): ``battery``, a sudden loss of the energy left at
``start_s`` and/or a faster drain over a window. Acts on a UAV whose type has an
``[endurance]`` budget (swarm.kernel.mission); on any other it does nothing and is not counted."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar, Literal

from faults.base import START, UAV, Draws, FaultHost, FaultKind
from faults.registry import register


@register
@dataclass(frozen=True, kw_only=True)
class Battery(FaultKind):
    """At ``start_s`` the UAV loses ``loss_frac`` of the energy it has left (a failed cell);
    from ``start_s`` to ``end_s`` (absent: the end of the run) it drains ``drain_factor`` times
    as fast (a cold or ageing pack). Counted once when it starts acting. The UAV's return to
    base judges the energy it has, so a loss or a faster drain sends it home early; one large
    enough, or a drain that outruns the reserve, loses it in flight (``energy_out``)."""

    uav: str = field(metadata=UAV)
    start_s: float = field(default=0.0, metadata=START)
    end_s: float = field(default=math.inf, metadata={"gt": 0, "note": "s, the faster drain's end; absent: the run's"})
    loss_frac: float = field(default=0.0, metadata={"ge": 0, "le": 1, "note": "of the energy left, lost at start_s"})
    drain_factor: float = field(default=1.0, metadata={"ge": 1, "le": 100, "note": "times the normal drain in the window"})
    kind: ClassVar[Literal["battery"]] = "battery"
    shrink_rank: ClassVar[int] = 190
    min_uavs: ClassVar[int] = 1

    @classmethod
    def generate(cls, d: Draws) -> Battery:
        """A loss of part of the energy left and/or a faster drain (nothing happens to a UAV
        without an [endurance] budget)."""
        start, end = d.draw(d.windows())
        loss = d.draw(d.st.sampled_from([0.0, 0.25, 0.5, 0.9]))
        factor = d.draw(d.st.sampled_from([1.0, 2.0, 5.0])) if loss else d.draw(d.st.sampled_from([2.0, 5.0]))
        return cls(uav=d.draw(d.names()), start_s=start, end_s=end, loss_frac=loss, drain_factor=factor)

    def span(self) -> tuple[float, float]:
        return (self.start_s, self.end_s)

    def install(self, host: FaultHost, index: int) -> None:
        uid = host.uid(self.uav)
        factor = self.drain_factor

        def start() -> None:
            battery = host.battery(uid)
            if battery is None or host.state(uid) == "crashed":
                return
            host.fired(self.kind)
            if self.loss_frac > 0.0:
                battery.lose(self.loss_frac)
            if factor != 1.0:
                battery.drain_factor *= factor
                if math.isfinite(self.end_s):
                    host.at(self.end_s, lambda: setattr(battery, "drain_factor", battery.drain_factor / factor))

        host.at(max(self.start_s, host.now), start)
