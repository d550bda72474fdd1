"""DACMP (the paper's planner): the planner itself and its settings (:mod:`.settings`), the
Gaussian pyramid of the uncertainty map it reads (:mod:`.pyramid`; kept up to date per map,
recomputed only where the map changed: :mod:`.maintained`), and the Dubins paths its PSO
scores (:mod:`.dubins`)."""

from agents.planners.dacmp.planner import DacmpPlanner
from agents.planners.dacmp.settings import DacmpSettings

__all__ = ["DacmpPlanner", "DacmpSettings"]
