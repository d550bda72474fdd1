"""Figures of runs and sweeps, all drawn with matplotlib's object API (no global backend is
set, so a host program keeps its own): shared style (:mod:`.style`), a run folder read back
(:mod:`.replay`), the trajectories figure (:mod:`.plots`), animations (:mod:`.animate`) and
HTML reports (:mod:`.report`)."""

from swarm.viz.replay import Replay, RunDirError, load_run
from swarm.viz.report import ReportError, write_report, write_sweep_report

__all__ = ["Replay", "ReportError", "RunDirError", "load_run", "write_report", "write_sweep_report"]
