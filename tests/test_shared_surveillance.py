"""Every planner either surveils or says it does not (issue 22, point 4).

Greedy and the reference planners declare ``surveils = "shared"``: with ``planner.surveillance
= true`` they watch targets through the one shared surveillance and handover logic (DACMP's
decision, agents.planners.surveillance); with it off they are exactly the search planners they
were (tests/test_regression.py pins greedy's hash). A planner that declares ``surveils = False``
is refused with one ``error:`` line when surveillance is on: ``swarm validate``, ``swarm run``
and, for a sweep over several planners, at its start.
"""

from __future__ import annotations

import json
import textwrap

import pytest

from agents.planners import GreedyPlanner
from agents.planners.surveillance import SharedSurveillance
from swarm import Simulation
from swarm.cli import main
from swarm.testing.invariants import check_events, default_checkers, handover_checkers

SEARCHERS = ("greedy", "lawnmower", "formation", "levy")


@pytest.mark.parametrize("planner", SEARCHERS)
def test_search_planners_watch_and_hand_over_by_the_shared_rules(planner):
    """paper-case1 (600 s): each search planner's UAVs watch both targets, B1 hands target 0
    over to the slow A1, and the assignment and safety checkers find nothing."""
    with Simulation("paper-case1", planner=planner) as sim:
        r = sim.run()
        assert all(isinstance(a.planner, SharedSurveillance) for a in sim.actors.values())
        scenario = sim.scenario
    m = r.metrics
    assert m["surveillance_ratio_mean"] > 0.5 and min(m["watched_share"].values()) > 0.5
    assert m["handovers_fast_to_slow"] == 1 and m["handover_list"][0]["to"] == "A1"
    assert check_events(r.events, scenario, handover_checkers() + default_checkers()) == []


def test_search_only_runs_are_the_bare_search_planner():
    """paper-fig11 is search only: no wrapper, so its runs are greedy's as before."""
    with Simulation("paper-fig11", planner="greedy", duration_s=20.0) as sim:
        assert not sim.scenario.planner.surveillance
        assert all(type(a.planner) is GreedyPlanner for a in sim.actors.values())
        m = sim.run().metrics
    assert m["uav_time_share"]["watching"] == 0.0 and m["watched_share"] == {}


@pytest.fixture
def plugins(tmp_path, monkeypatch):
    """A module ``plug`` on sys.path with a search-only planner, a shared one and a bad one."""
    (tmp_path / "plug.py").write_text(textwrap.dedent("""
        from agents.planners.greedy import GreedyPlanner

        class SearchOnly(GreedyPlanner):
            surveils = False

        class Shared(GreedyPlanner):
            surveils = "shared"

        class Bad(GreedyPlanner):
            surveils = "sometimes"
    """))
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def _one_error(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


def test_a_search_only_planner_is_refused_under_surveillance_by_run_and_validate(plugins, capsys):
    assert main(["run", "paper-case1", "--planner", "plug:SearchOnly", "--duration", "5", "--quiet"]) == 2
    line = _one_error(capsys)
    assert "planner.surveillance" in line and "surveils = False" in line and "planner.surveillance=false" in line
    doc = plugins / "mine.toml"
    doc.write_text(textwrap.dedent("""
        duration_s = 5.0
        [[uavs]]
        type = "B"
        x_m = 1000.0
        y_m = 1000.0
        [planner]
        name = "plug:SearchOnly"
    """))
    assert main(["validate", str(doc)]) == 2  # a file may not import code: refused before anything else
    assert "--allow-planner-imports" in _one_error(capsys)
    assert main(["validate", "--allow-planner-imports", str(doc)]) == 2
    assert "planner.surveillance" in _one_error(capsys)
    # With surveillance off it runs (and is search only).
    assert main(["run", "paper-case1", "--planner", "plug:SearchOnly", "--set", "planner.surveillance=false",
                 "--duration", "5", "--quiet"]) == 0
    doc.write_text(doc.read_text() + "surveillance = false\n")
    assert main(["validate", "--allow-planner-imports", str(doc)]) == 0


def test_a_sweep_with_a_search_only_planner_is_refused_at_its_start(plugins, capsys, tmp_path):
    out = tmp_path / "sweep"
    args = ["sweep", "paper-case1", "--planner", "greedy,plug:SearchOnly", "--seeds", "1", "--duration", "5",
            "--out", str(out), "--quiet"]
    assert main(args) == 2
    assert "plug:SearchOnly" in _one_error(capsys)
    assert not (out / "runs").exists()  # nothing ran


def test_a_user_planner_can_use_the_shared_logic_and_a_wrong_declaration_is_one_error(plugins, capsys):
    with Simulation("paper-case1", planner="plug:Shared", duration_s=60.0) as sim:
        assert isinstance(sim.actors[0].planner, SharedSurveillance)
        m = sim.run().metrics
    assert m["uav_time_share"]["watching"] > 0
    assert main(["run", "paper-case1", "--planner", "plug:Bad", "--duration", "5", "--quiet"]) == 2
    assert "surveils = 'sometimes'" in _one_error(capsys)


def test_metrics_json_and_summary_show_the_detection_and_watch_measures(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "paper-case1", "--planner", "greedy", "--duration", "120", "--out", str(out),
                 "--no-figures"]) == 0
    text = capsys.readouterr().out
    for row in ("first detection", "to slow watcher", "watched share", "UAV time watching / searching"):
        assert row in text
    m = json.loads((out / "metrics.json").read_text())
    assert set(m["time_to_first_detection_s"]) == {"0", "1"} and m["slow_types"] == ["A"]
    assert set(m["per_uav"]["B1"]["time_share"]) == {"watching", "searching"}
    from swarm.viz.report import write_report

    html = write_report(out).read_text()
    section = html[html.index('<h2 id="watch">'):]
    first = m["time_to_first_detection_s"]["0"]
    assert "to slow watcher" in section and f"<td>0</td><td>{first:g} s</td>" in section
    share = m["uav_time_share"]
    assert f"<td>swarm</td><td></td><td>{share['watching']:.3f}</td><td>{share['searching']:.3f}</td>" in section
