"""Pinned event-log hashes of a small scenario.

These change only when behaviour is meant to change (a model or planner change, a new event
field). When one must change, update it in the same commit and say why in the message; a speed
optimisation must leave them as they are.

History:
- initial values (simulator core + DACMP planner).
- link faults now act in a fixed kind order (drop before corrupt; the small scenario lists
  corrupt first) and corruption flips distinct bytes; DACMP's global guide breaks near-ties
  towards the heading instead of always south-west. Both intended behaviour changes.
- targets' turn rate is mean-reverting (they travel instead of circling on the spot): changes
  every run with targets (greedy too). DACMP: pyramid layers read at the nearest coarse centre,
  eq. 19 over layers 1..L, guide from 4 x 4 sub-area means with ties drawn from the UAV's own
  stream, particles kept within 2.5 R_s. All intended behaviour changes.
- Case 2 work (DACMP only; greedy unchanged): a UAV in surveillance mode of a target within
  one planning step of it counts as being at the target in other UAVs' eq. 23 (same-type
  exclusion, eq. 27, held only by chance before), the nearer of two same-type claimants keeps
  it, a watcher keeps its target while its term dominates there and circles it (vector-field
  loiter) instead of overflying it, stale tracks stop attracting, and the collision-avoidance
  turn goes away from the other UAV instead of always right. Intended behaviour changes.
- anti-entropy (agents.maps.scanlog): beacons carry a scan digest every 5 s and UAVs resend scans a
  neighbour lacks (unicast, about two answerers, 600 s window), so lost, partitioned and
  pre-join scans reach every map; heard scans with absurd centres or radii are ignored. Frames
  and maps change: intended.
- (batched planning and the faster guide sums left these hashes unchanged, as they must.)
- DACMP's global guide takes the most uncertain neighbouring sub-area (exact ties only, as the
  paper says; a 2% near-tie tolerance before): unchanged here (no near-tie in these 60 s), the
  paper-fig11 event logs change.
- DACMP surveillance for Case 2 (eq. 23 once per UAV, a watcher only in its own target's scope,
  the farther same-type claimant yields, the declared target is the strongest pull, watchers
  feel threats at 0.15 k_rep): unchanged here (one target, seen at 20 s; no watcher in a threat field),
  paper-case2/3 logs change; paper-fig11's (search only) do not.
- Assignment rules (docs/modelling.md): a searching UAV competes (eq. 23) only for targets no UAV
  watches (a fast searcher passing within D of a watched target kept a slow UAV from taking it
  over); the keep rule judges the watched target by its own term; a target last seen inside a
  no-fly zone is kept. The dacmp hash changes (a searcher near the watched target here); greedy's
  does not; paper-fig11's (search only) do not.
- greedy and the reference planners surveil with planner.surveillance = true, through the shared
  surveillance logic (agents.planners.surveillance). This scenario leaves surveillance on (the
  default), so greedy's pinned run is now taken with surveillance off: the same hash as before
  (greedy ignored the flag), as a search-only greedy must keep. "greedy-surveillance" pins the
  new behaviour (intended); measured after the assignment-rule changes above, which the shared
  logic inherits.
- Detect and avoid (issue 22, point 3: collision avoidance takes the true poses of the UAVs
  within uav_types.X.daa_range_m instead of the radio's one-tick-old ones), the threat guard no
  longer overriding collision avoidance, and a conflict also when two UAVs are closer than
  2 d_min at the lookahead's end: unchanged here (no two UAVs of this scenario ever come close
  enough for collision avoidance to act). The paper-fig11 logs of greedy and DACMP change (UAVs
  do meet there: greedy seed 0 first differs at t = 543 s by the conflict rule, at 545 s by
  detect and avoid alone), the lawnmower's do not; see docs/paper.md for the statistics.
- DACMP's mode rule compares a target's own term with f_S, not the sum f_t over targets (with a
  10 km D another UAV's claim on a nearby target kept a slow UAV from taking a target over):
  the dacmp pin and paper-case2 (seeds 0-19, 4000 s) are unchanged; the shared logic's
  "greedy-surveillance" pin changes (it tries each target as the waypoint).
"""

from __future__ import annotations

import pytest

from swarm import Simulation
from swarm.scenario import apply_overrides, load_scenario

PINNED = {
    "greedy": "28ac6a09c44b534c028ac764ff241b191238cf8874c828dda12d1a4c75244b20",  # surveillance off
    "greedy-surveillance": "c1e9934c49c2f8e14676975ea79a316f9ad86f3762b9e9cb8b0e07cf8f41be13",
    "dacmp": "e7ad249893753fce4fb2a1b8e95edc22c268e46d0afb5c62cb8827c84259cc26",
}


@pytest.mark.parametrize("case", sorted(PINNED))
def test_pinned_hash(case, small_scenario_path):
    planner, _, surveillance = case.partition("-")
    scenario = load_scenario(small_scenario_path)
    if planner == "greedy":  # greedy's pin is search only; the shared surveillance logic has its own
        scenario = apply_overrides(scenario, {"planner.surveillance": surveillance == "surveillance"})
    with Simulation(scenario, duration_s=60.0, planner=planner) as sim:
        assert sim.run().metrics["event_log_sha256"] == PINNED[case]
