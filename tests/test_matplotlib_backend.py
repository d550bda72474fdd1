"""The library draws on its own figures (``matplotlib.figure.Figure`` with an Agg canvas) and never
picks matplotlib's backend: a host program that embeds it keeps the backend it chose."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("swarm", "agents", "comms", "faults")

_HOST = textwrap.dedent("""
    import importlib, io, pkgutil
    import matplotlib
    matplotlib.use("svg")
    import swarm.experiments, swarm.viz
    names = [m.name for pkg in (swarm.viz, swarm.experiments)
             for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + ".")]
    for name in names:
        importlib.import_module(name)
    assert matplotlib.get_backend() == "svg", matplotlib.get_backend()

    # Drawing does not change it either, and leaves no figure with pyplot.
    from swarm.experiments.common import save_figure, subplots
    fig, ax = subplots(figsize=(2, 2))
    ax.plot([0, 1], [1, 0])
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    assert buf.getvalue()[:8] == b"\\x89PNG\\r\\n\\x1a\\n"
    import matplotlib.pyplot as plt
    assert plt.get_fignums() == [] and matplotlib.get_backend() == "svg"
    print(len(names))
""")


@pytest.mark.slow  # a subprocess importing every viz and experiments module
def test_importing_and_drawing_keeps_the_hosts_backend():
    out = subprocess.run([sys.executable, "-c", _HOST], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr
    assert int(out.stdout.strip()) >= 10  # style, plots, replay, animate, report, sweep, paper, ...


def test_no_library_module_sets_a_backend():
    offenders = [p.relative_to(ROOT).as_posix() for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))
                 if "matplotlib.use" in p.read_text(encoding="utf-8")]
    assert offenders == []
