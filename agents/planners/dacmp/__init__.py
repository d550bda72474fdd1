"""DACMP (the paper's planner): the planner itself, the Gaussian pyramid of the uncertainty map
it reads (:mod:`.pyramid`, computed once per tick for maps that share storage:
:mod:`.pyramid_reuse`), and the Dubins paths its PSO scores (:mod:`.dubins`)."""

from agents.planners.dacmp.planner import DacmpPlanner

__all__ = ["DacmpPlanner"]
