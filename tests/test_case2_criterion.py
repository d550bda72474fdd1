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


@pytest.mark.slow  # 20 runs of 4000 s on a pool of 2 processes: about 4-6 minutes on 2 idle cores
@pytest.mark.xfail(strict=True, reason=(
    "measured 17 of 20 (2026-12-07, issue 33; 16 of 20 before it, 5 of 20 under the earlier 2000 s criterion). No "
    "violation on any seed; every takeover in time, none released before its relief had the target in sight. The "
    "three failing seeds: one target never found in 4000 s, each time one that keeps to the area's edge (target 2 "
    "along the south edge, seed 0; target 1 along the north edge, seed 12: no UAV within 2.1 km of it all run); a "
    "target that left its no-fly zone twice while its keeper, patrolling the boundary, was on the far side, and "
    "was not seen again (seed 11: 260 m beyond the keeper's sight on its next pass)."))
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
