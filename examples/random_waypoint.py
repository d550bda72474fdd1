"""An example planner: fly to the least recently scanned of a few random points within reach.

    PYTHONPATH=examples swarm run paper-case1 --planner random_waypoint:RandomWaypoint
    # options, in the scenario: [planner.options] tries = 16, reach_factor = 2.0
"""

import math

import numpy as np

from agents.planners import Plan, PlanView


class RandomWaypoint:
    name = "random-waypoint"

    def __init__(self, tries: int = 8, reach_factor: float = 3.0):
        if tries < 1 or not reach_factor > 0:
            raise ValueError("tries must be >= 1 and reach_factor > 0")
        self.tries, self.reach_factor = tries, reach_factor

    def plan(self, view: PlanView) -> Plan:
        g = view.grid
        reach = self.reach_factor * view.kind.detect_radius
        # Points ahead of the UAV (it cannot turn on the spot), drawn from its own stream.
        heading = view.theta + view.rng.uniform(-math.pi / 2, math.pi / 2, self.tries)
        xs = np.clip(view.x + reach * np.cos(heading), 0.0, g.width_m * (1 - 1e-9))
        ys = np.clip(view.y + reach * np.sin(heading), 0.0, g.height_m * (1 - 1e-9))
        ix, iy = g.cells_of(xs, ys)
        best = int(np.argmax(view.umap.q_at(ix, iy, view.t)))  # q = 1: never seen, 0: just seen
        return Plan(float(xs[best]), float(ys[best]))
