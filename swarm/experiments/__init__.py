"""Experiments built on the simulation: sweeps over seeds, planners and settings on any
executor (:mod:`.sweep`), the paper's section 4 (:mod:`.paper`), resilience axes
(:mod:`.resilience`), speed and memory cases (:mod:`.bench`), and what they share
(:mod:`.common`)."""

from typing import Any

# Imported when first used (PEP 562): `import swarm.experiments.resilience.axes` (the command
# line's help) must not load the paper's figures or the sweeps.
_LAZY = {"run_paper": "paper", "run_resilience": "resilience", "RunSpec": "sweep", "SweepResult": "sweep",
         "run_sweep": "sweep", "sweep": "sweep"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"swarm.experiments.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = ["RunSpec", "SweepResult", "run_paper", "run_resilience", "run_sweep", "sweep"]
