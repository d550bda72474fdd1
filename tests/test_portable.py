"""Portable artifacts (issue 32): nothing a run, a sweep or their reports and exports write
holds an absolute path of the machine they ran on, so a folder can be sent elsewhere as it is."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from swarm.cli import main
from swarm.experiments.sweep import sweep
from swarm.scenario import load_scenario
from swarm.scenario.builtin import __file__ as _builtin
from swarm.viz.report import write_sweep_report

BUILTIN = Path(_builtin).parent


def _holding(folder: Path, needles: list[bytes]) -> dict[str, list[str]]:
    """Every file under ``folder`` (text or not: the bytes as written) that holds one of ``needles``."""
    found: dict[str, list[str]] = {}
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        data = path.read_bytes()
        hits = [n.decode() for n in needles if n in data]
        if hits:
            found[path.relative_to(folder).as_posix()] = hits
    return found


@pytest.mark.slow  # a geographic run, its report, animation and export, and a small sweep with its report
def test_nothing_written_holds_the_absolute_path_of_where_it_ran(tmp_path, seed1_fails, capsys):
    here = tmp_path / "work"
    (here / "in").mkdir(parents=True)
    toml = here / "in" / "coast.toml"  # a scenario file given by its absolute path
    shutil.copy(BUILTIN / "geo-coast.toml", toml)
    run = here / "run"
    args = ["run", str(toml), "--duration", "60", "--out", str(run), "--quiet"]
    if importlib.util.find_spec("rerun") is not None:
        args += ["--rerun", str(run / "run.rrd")]
    assert main(args) == 0
    assert main(["report", str(run)]) == 0
    assert main(["animate", str(run), "--out", str(run / "animation.gif"), "--fps", "2", "--speed", "60",
                 "--quiet"]) == 0
    assert main(["export", str(run), "--format", "parquet", "--quiet"]) == 0
    written = {p.name for p in run.rglob("*")}
    assert {"metrics.json", "scenario.json", "events.msgpack", "timeseries.csv", "trajectories.png", "report.html",
            "animation.gif", "paths.geojson", "zones.geojson", "pose.parquet", "run.parquet"} <= written
    # A sweep (one run fails: its error.json and traceback), its report and its export.
    sw = here / "sweep"
    with ThreadPoolExecutor(2) as ex:
        res = sweep(load_scenario("paper-case1"), sw, seeds=2, planners=["greedy"], duration_s=10.0, executor=ex)
    assert res.ran == 2 and len(res.failed) == 1
    assert seed1_fails in (sw / res.failed[0]["folder"] / "error.json").read_text()
    write_sweep_report(sw, res.summary)
    assert main(["export", str(sw), "--format", "parquet", "--quiet"]) == 0
    capsys.readouterr()

    needles = sorted({str(here).encode(), os.path.realpath(here).encode()})
    assert _holding(here, needles) == {}
    # ... nor where the simulator itself is installed (the traceback of error.json names
    # files from their import root: swarm/..., not /.../site-packages/swarm/...).
    package = str(Path(__file__).resolve().parents[1]).encode()
    error = json.loads((sw / res.failed[0]["folder"] / "error.json").read_text())
    assert 'File "swarm/' in error["traceback"] and package.decode() not in error["traceback"]
    assert _holding(here, [package]) == {}
