"""UAV types as data (Table 1 of the paper): a third type needs a table row, not a class."""

from __future__ import annotations

import math
from dataclasses import dataclass

GRAVITY = 9.81


@dataclass(frozen=True, slots=True)
class UavType:
    name: str
    speed_min: float
    speed_max: float
    accel_max: float
    bank_max_rad: float
    detect_radius: float
    w_t: float  # target attraction weight (eq. 22)
    w_r: float  # competing repulsion weight (eq. 23)
    influence_radius: float  # D: how far a target pulls this type (eq. 22)

    def turn_rate_max(self, v: float) -> float:
        """Largest |omega| at speed v: v/|omega| >= r_min = v^2/(g tan(phi))."""
        return GRAVITY * math.tan(self.bank_max_rad) / max(v, 1e-6)

    def r_min(self, v: float) -> float:
        return v * v / (GRAVITY * math.tan(self.bank_max_rad))
