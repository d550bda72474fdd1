"""Experiments built on the simulation: sweeps over seeds, planners and settings on any
executor (:mod:`.sweep`), the paper's section 4 (:mod:`.paper`), resilience axes
(:mod:`.resilience`), speed and memory cases (:mod:`.bench`), and what they share
(:mod:`.common`)."""

from swarm.experiments.paper import run_paper
from swarm.experiments.resilience import run_resilience
from swarm.experiments.sweep import RunSpec, SweepResult, run_sweep, sweep

__all__ = ["RunSpec", "SweepResult", "run_paper", "run_resilience", "run_sweep", "sweep"]
