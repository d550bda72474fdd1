"""Figures a researcher can read at a glance: the run's trajectories.png (found and never-found
targets apart, crashed UAVs marked, the coverage shading in the legend), UAV type markers that
do not change from run to run, and numbers written in readable units."""

from __future__ import annotations

import io
import zlib
from pathlib import Path

import pytest
from matplotlib.lines import Line2D
from PIL import Image

from swarm.kernel.simulation import Simulation
from swarm.viz.plots import crashed_uavs, found_targets, trajectories_figure, trajectories_plot
from swarm.viz.style import (
    CRASH_MARKER,
    TARGET_FOUND_COLOUR,
    THIN_SEP,
    TYPE_MARKERS,
    format_metric,
    metric_kind,
    metric_unit,
    type_marker,
    type_markers,
)

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def crashed_result():
    """faults-small for its whole 300 s: B2 crashes at 200 s; 2 of its 3 targets are found."""
    with Simulation(DATA / "faults-small.toml") as sim:
        return sim.run()


@pytest.fixture(scope="module")
def early_result():
    """faults-small stopped at 150 s, before B2's crash."""
    with Simulation(DATA / "faults-small.toml", duration_s=150.0) as sim:
        return sim.run()


def _legend_labels(fig) -> list[str]:
    return [t.get_text() for t in fig.axes[0].get_legend().get_texts()]


def _end_markers(fig) -> list[Line2D]:
    """The single-point markers drawn on the axes (UAV ends, target ends)."""
    return [ln for ln in fig.axes[0].get_lines() if len(ln.get_xdata()) == 1]


def test_trajectories_tell_found_from_never_found_targets(crashed_result):
    m = crashed_result.metrics
    found = found_targets(crashed_result)
    assert found is not None and len(found) == m["targets_found"]
    k, total = m["targets_found"], m["targets_total"]
    assert 0 < k < total  # the test needs both kinds
    fig = trajectories_plot(crashed_result)
    labels = _legend_labels(fig)
    assert f"target found ({k})" in labels and f"target not found ({total - k})" in labels
    stars = [ln for ln in _end_markers(fig) if ln.get_marker() == "*"]
    assert len(stars) == total
    filled = [ln for ln in stars if ln.get_markerfacecolor() == TARGET_FOUND_COLOUR]
    assert len(filled) == k  # found ones filled, the others not
    assert "scanned at least once" in labels


def test_trajectories_mark_crashed_uavs(crashed_result, early_result):
    assert crashed_uavs(crashed_result) == {"B2"}
    fig = trajectories_plot(crashed_result)
    labels = _legend_labels(fig)
    assert "crashed (1)" in labels and "B2 (B), crashed" in labels and "B1 (B)" in labels
    crosses = [ln for ln in _end_markers(fig) if ln.get_marker() == CRASH_MARKER]
    assert len(crosses) == 1
    b2 = crashed_result.paths["B2"]
    assert (crosses[0].get_xdata()[0], crosses[0].get_ydata()[0]) == (b2[-1, 1] / 1000, b2[-1, 2] / 1000)
    # Every other UAV ends with its type's marker.
    ends = {ln.get_marker() for ln in _end_markers(fig)} - {"*", CRASH_MARKER}
    assert ends == {type_marker("A"), type_marker("B")}
    # Before the crash: no cross, no "crashed" in the legend.
    early = trajectories_plot(early_result)
    assert not any("crashed" in label for label in _legend_labels(early))
    assert not [ln for ln in _end_markers(early) if ln.get_marker() == CRASH_MARKER]


def test_trajectories_figure_writes_a_png(crashed_result, tmp_path):
    buf = io.BytesIO()
    trajectories_figure(crashed_result, buf)
    with Image.open(io.BytesIO(buf.getvalue())) as im:
        assert im.format == "PNG" and im.size[0] >= 700
    trajectories_figure(crashed_result, tmp_path / "t.png")
    assert (tmp_path / "t.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_type_markers_depend_on_the_type_name_only():
    # A type keeps its marker whatever other types fly in the run (it used to be the sorted
    # position among the types present: B was "^" next to C and "o" next to A).
    assert type_markers(["B", "C"])["B"] == type_markers(["A", "B"])["B"] == type_marker("B") == "o"
    assert type_markers(["A", "B", "C"])["A"] == type_markers(["A"])["A"] == "^"
    assert type_markers(["C", "Z"])["C"] == type_markers(["A", "C"])["C"] == type_marker("C")
    # By CRC-32, not hash(): the same in every process whatever PYTHONHASHSEED.
    assert type_marker("C") == TYPE_MARKERS[zlib.crc32(b"C") % len(TYPE_MARKERS)]
    others = {type_marker(f"T{i}") for i in range(50)}
    assert others <= set(TYPE_MARKERS) and len(others) > 3
    assert not others & {"^", "o", "x", "X", "*"}  # never A's, B's, a crash cross or a target star


def test_metric_units():
    assert format_metric("radio.bytes_sent", 4_121_000) == "4.12 MB"
    assert format_metric("radio.bytes_sent", 18_639.5) == "18.6 kB"
    assert format_metric("radio.bytes_sent", 532) == "532 B"
    assert format_metric("radio.bytes_sent", 2.5e9) == "2.50 GB"
    assert format_metric("radio.bytes_sent", 999_700) == "1.00 MB"  # not "1000 kB"
    assert format_metric("coverage", 0.74) == "0.740"
    assert format_metric("certainty", 0.12345) == "0.123"
    assert format_metric("surveillance_ratio_mean", 0.5) == "0.500"
    assert format_metric("radio.sent", 4_121_000) == f"4{THIN_SEP}121{THIN_SEP}000"
    assert format_metric("targets_found", 10.0) == "10"
    assert format_metric("targets_found", 2.25) == "2.25"
    assert format_metric("violations.separation", 0.0) == "0"  # "separation" is no ratio
    assert format_metric("sim_seconds", 2000.0) == f"2{THIN_SEP}000 s"
    assert format_metric("latency_s", 3.25) == "3.25 s"
    assert format_metric("coverage", 0.0123, signed=True) == "+0.012"
    assert format_metric("coverage", -0.0001, signed=True) == "0.000"  # no "-0.000"
    assert format_metric("coverage", float("nan")) == "–"
    assert [metric_kind(n) for n in ("radio.bytes_sent", "coverage", "handover_latency_s", "radio.dropped")] == \
        ["bytes", "fraction", "seconds", "count"]
    # One unit for a column: chosen from its largest value, shared by the smaller ones.
    unit = metric_unit("radio.bytes_sent", 4.1e6)
    assert (unit.suffix, unit.number(3.34e5), unit.format(4_121_000)) == ("MB", "0.33", "4.12 MB")
    counts = metric_unit("radio.sent", 322.0)
    assert (counts.number(322.4), counts.number(14.4), counts.number(2.0)) == ("322", "14", "2")


@pytest.fixture(scope="module")
def geo_run(tmp_path_factory):
    """A short geographic run with a no-fly polygon, a threat circle and a base (issue 33)."""
    pytest.importorskip("shapely")
    from test_geo import geo_doc

    from swarm.outputs import write_run
    from swarm.scenario import parse_scenario

    doc = geo_doc(duration_s=30.0, threats=[{"x_m": 15000.0, "y_m": 4000.0, "radius_m": 800.0}],
                  endurance={"lon": 10.05, "lat": 54.05, "types": {"B": {"capacity_wh": 5000.0},
                                                                    "A": {"capacity_wh": 5000.0}}})
    with Simulation(parse_scenario(doc, "geo.toml")) as sim:
        result = sim.run()
    out = tmp_path_factory.mktemp("geo") / "run"
    write_run(result, out, figures=False)
    return result, out


def test_hazards_are_drawn_in_every_map(geo_run):
    """Issue 33: the area polygon, the no-fly polygons (and circles) and the base in
    trajectories.png, the report's trajectories and the animation."""
    from swarm.viz.animate import _Scene
    from swarm.viz.replay import load_run
    from swarm.viz.report.run_figures import fig_trajectories

    result, out = geo_run
    expected = {"outside the area polygon", "no-fly polygon (2)", "threat (1)", "base"}
    assert expected <= set(_legend_labels(trajectories_plot(result)))
    rp = load_run(out)
    assert expected <= {t.get_text() for leg in fig_trajectories(rp).legends for t in leg.get_texts()}
    import numpy as np

    scene = _Scene(rp, np.array([0.0]), fps=10.0, speed=60.0, trail_s=60.0, dpi=50.0)
    assert expected <= {t.get_text() for leg in scene.fig.legends for t in leg.get_texts()}
    # the base square and the outside of the polygon are drawn, over the heat map
    assert any(getattr(a, "get_marker", lambda: None)() == "s" for a in scene.threat_patches)
    assert all(a.get_zorder() > scene.image.get_zorder() for a in scene.threat_patches)


def test_zones_geojson_has_the_base(geo_run):
    import json

    _result, out = geo_run
    zones = json.loads((out / "zones.geojson").read_text())["features"]
    roles = [f["properties"]["role"] for f in zones]
    assert roles.count("base") == 1 and roles.count("no_fly") == 2 and roles.count("threat") == 1
    base = next(f for f in zones if f["properties"]["role"] == "base")
    assert base["geometry"]["type"] == "Point" and base["geometry"]["coordinates"] == pytest.approx([10.05, 54.05])
    assert base["properties"]["land_radius_m"] == 500.0
