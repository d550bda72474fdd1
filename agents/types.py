"""UAV types as data (Table 1 of the paper): a third type needs a table row, not a class."""

from __future__ import annotations

import math
from dataclasses import dataclass

GRAVITY = 9.81

# Range of a UAV's detect-and-avoid sensor (``[uav_types.X] daa_range_m``) unless its type says
# otherwise. Collision avoidance (agents.apf) looks ``planner.apf.lookahead_s`` = 15 s ahead, and
# the fastest closing speed between Table 1's types is two type B head-on, 2 x 90 m/s: a conflict
# it would act on starts at most 15 x 180 = 2700 m away. 3000 m adds 300 m (more than one tick of
# closing at 180 m/s) so that such a UAV is sensed before the lookahead reaches it.
DAA_RANGE_M = 3000.0


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
    # Detect-and-avoid sensor range (m): other UAVs within it are sensed (ground truth) for
    # collision avoidance instead of taken from the radio; 0 = no such sensor.
    daa_range: float = DAA_RANGE_M

    def turn_rate_max(self, v: float) -> float:
        """Largest |omega| at speed v: v/|omega| >= r_min = v^2/(g tan(phi))."""
        return GRAVITY * math.tan(self.bank_max_rad) / max(v, 1e-6)

    def r_min(self, v: float) -> float:
        return v * v / (GRAVITY * math.tan(self.bank_max_rad))
