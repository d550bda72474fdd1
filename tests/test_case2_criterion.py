"""Case 2 across seeds, judged as DACMP-SPEC "Reproduction targets" says: ``swarm sweep
paper-case2 --seeds 20 --planner dacmp --duration 4000`` meets the criterion
(:func:`swarm.experiments.paper.case2_conditions`) on at least 18 of seeds 0-19. One slow test
that prints the per-seed table; a module of its own so that its 20 runs go beside
``test_paper_cases.py``'s (which runs whole on one worker: it shares runs between its tests).
"""

from __future__ import annotations

import pytest

from swarm import load_scenario

CASE2_SWEEP_SEEDS = 20  # seeds 0..19
CASE2_MIN_HOLDING = 18  # DACMP-SPEC "Reproduction targets"


def case2_table(per_seed: list[dict]) -> str:
    """The per-seed table of the Case 2 criterion (what the slow test prints)."""
    from swarm.experiments.paper import CASE2_CONDITIONS

    head = (f"{'seed':>4} {'found':>5} {'f->s':>4} {'opp':>3} {'sep':>3} {'thr':>3}  "
            + " ".join(f"{k:>9}" for k in CASE2_CONDITIONS))
    rows = [head] + [f"{m['seed']:>4} {m['targets_found']:>5} {m['handovers_fast_to_slow']:>4} "
                     f"{m['handover_opportunities']:>3} {m['separation_violations']:>3} {m['threat_violations']:>3}  "
                     + " ".join(f"{'yes' if m['conditions'][k] else 'NO':>9}" for k in CASE2_CONDITIONS)
                     + "".join(f"\n       {v}" for v in m["handover_rule_violations"])
                     for m in per_seed]
    return "\n".join(rows)


def _zone_log(target_xy: tuple[float, float], uav_xy: tuple[float, float], seen_at: float = 100.0):
    """A two-tick RunLog: one type-A UAV (detection radius 1.5 km) watching target 0, a 3 km
    zone at the origin; the UAV had the target in sight at ``seen_at`` (the first tick)."""
    import numpy as np

    from swarm.experiments.paper import RunLog

    (tx, ty), (x, y) = target_xy, uav_xy
    return RunLog(
        names={0: "A1"}, types={0: "A"}, type_specs={"A": {"detect_radius_m": 1500.0, "speed_max": 50.0}},
        end_t=200.0, dt=1.0,
        poses={0: np.array([[seen_at, tx + 100.0, ty, 1.0, 0.0], [200.0, x, y, 1.0, 0.0]])},
        targets={0: np.array([[seen_at, tx, ty], [200.0, tx, ty]])},
        modes=[], handovers=[], found={0: (seen_at, 0)}, joins={}, crashes={}, metrics={},
        threats=[{"x_m": 0.0, "y_m": 0.0, "radius_m": 3000.0}])


def test_held_at_zone_edge_reads_the_spec_for_a_patrolling_keeper():
    """DACMP-SPEC: a target deeper in a no-fly zone than its watcher can see from outside is held
    by a UAV that keeps it and stays at that zone's edge (docs/paper.md says why "anywhere round
    it": the keeper patrols the boundary). Each clause can fail on its own."""
    from swarm.experiments.paper import held_at_zone_edge

    # 2 km deep; the keeper on the far side, 0.9 km off the edge (sees 0.6 km in): held.
    assert held_at_zone_edge(_zone_log((1000.0, 0.0), (-3900.0, 0.0)), 0, "A1")
    # ... but not from 2 x 1.5 km + 1 m off the edge (not at the edge),
    assert not held_at_zone_edge(_zone_log((1000.0, 0.0), (-6001.0, 0.0)), 0, "A1")
    # ... nor when the target is only 0.5 km deep: from 0.9 km off the edge the keeper would see
    # it from the nearest point of its line (the spec's exception is for deeper targets),
    assert not held_at_zone_edge(_zone_log((2500.0, 0.0), (-3900.0, 0.0)), 0, "A1")
    # ... nor when the target is outside the zone (it came out; nobody holds it),
    assert not held_at_zone_edge(_zone_log((3500.0, 0.0), (-3900.0, 0.0)), 0, "A1")
    # ... nor for a UAV by another zone's edge or inside it.
    assert not held_at_zone_edge(_zone_log((1000.0, 0.0), (-2000.0, 0.0)), 0, "A1")


@pytest.mark.slow  # 20 runs of 4000 s on a pool of 2 processes: about 4-6 minutes on 2 idle cores
@pytest.mark.xfail(strict=True, reason=(
    "measured 17 of 20 (2026-12-07, issue 33; 16 of 20 before it, 5 of 20 under the earlier 2000 s criterion). No "
    "violation on any seed; every takeover in time, none released before its relief had the target in sight. The "
    "three failing seeds (docs/paper.md, 'Case 1 to 3 as tests', per-seed table): a target never found in 4000 s, "
    "each time one that keeps to the area's edge, the band searched least (target 2 by the south edge, seed 0; "
    "target 1 in the north-west, seed 12; no UAV within 2.1 km of it all run); a target that came out of its "
    "no-fly zone at up to 20 m/s while its one keeper was on the far side of its 493 s lap, and was not seen again "
    "(seed 11: 259 m beyond the keeper's sight on its next pass)."))
def test_case2_holds_on_at_least_18_of_20_seeds(tmp_path):
    """DACMP-SPEC "Reproduction targets": ``swarm sweep paper-case2 --seeds 20 --planner dacmp
    --duration 4000`` meets Case 2's criterion (swarm.experiments.paper.case2_conditions: all six
    found; each watched by one UAV at the end, or kept from a no-fly zone's edge; every
    handover opportunity taken and released within 60 s, at least four fast -> slow handovers
    where four were offered; released fast UAVs search or watch a free target; no violation)
    on at least 18 of seeds 0-19. Prints the per-seed table."""
    from swarm.experiments.common import executor_for
    from swarm.experiments.paper import CASE2_JUDGE_S, RunLog, case2_measures
    from swarm.experiments.sweep import plan_runs, run_sweep

    runs = plan_runs(load_scenario("paper-case2"), seeds=range(CASE2_SWEEP_SEEDS), planners=["dacmp"],
                     duration_s=CASE2_JUDGE_S)
    with executor_for(None, 2) as ex:
        res = run_sweep(runs, tmp_path, executor=ex)
    assert not res.failed
    per_seed = [case2_measures(RunLog.load(tmp_path / spec.folder), tmp_path / spec.folder) for spec in runs]
    table = case2_table(per_seed)
    print(table)
    holding = sum(1 for m in per_seed if m["conditions"]["all"])
    assert holding >= CASE2_MIN_HOLDING, f"Case 2 holds on {holding} of {CASE2_SWEEP_SEEDS}:\n{table}"
