"""The kernel: the modules that make up a tick, and nothing else.

:class:`~swarm.kernel.simulation.Simulation` builds the parts below from a scenario and runs one
tick at time ``t`` as these phases, in this order (the one list of them; each phase is a call into
the part that owns it):

0. **boundary**: the host's changes at boundary ``t`` (:mod:`~swarm.kernel.host`, logged and
   replayed by :mod:`~swarm.kernel.hostlog`), then the faults, joins and frame deliveries due by
   ``t``, in the clock's priorities (:mod:`~swarm.kernel.clock`);
1. **start**: the tick's fault windows (:mod:`~swarm.kernel.faulting`);
2. **mission**: wind, energy, relief on station, landings and launches
   (:mod:`~swarm.kernel.mission`, the way home :mod:`~swarm.kernel.homeway`; without ``[wind]``
   or ``[endurance]`` the do-nothing phase of :mod:`~swarm.kernel.mission_phase`); then the
   live UAVs' actor tasks are started (:mod:`~swarm.kernel.fleet`);
3. **sense**: what each live UAV senses in the ground truth (:mod:`~swarm.kernel.world`), after
   the tick faults and with its energy reading;
4. **wake**: every live actor runs its step, and the tick waits for all of them
   (:mod:`~swarm.kernel.fleet`); with the tick plane (``Simulation(tick_plane=True)``, the
   default) the inboxes of the actors about to be woken are merged for them first, in UAV-id
   order (:mod:`~swarm.kernel.receiving`);
5. **observe**: the ground truth into the metrics (:mod:`~swarm.kernel.metrics`), the event log
   (:mod:`~swarm.kernel.recorder`) and the paths (:mod:`~swarm.kernel.observer`);
6. **transmit**: the frames through the radio and the fault injector, their deliveries put on the
   clock (:mod:`~swarm.kernel.transmission`);
7. **integrate**: the UAVs fly their commands for ``dt`` and the targets move
   (:mod:`~swarm.kernel.world`);
8. **end**: the time series sampled when due, the log flushed, the next tick scheduled.

The other parts: :mod:`~swarm.kernel.assembly` (the scenario a run is given, judged once, and
every part built from it in dependency order), :mod:`~swarm.kernel.build` (the pieces made from a
scenario),
:mod:`~swarm.kernel.rng` (one random stream per stable key), :mod:`~swarm.kernel.memory` (a run
too big for the machine refused before anything is allocated), :mod:`~swarm.kernel.driving` (which
event loop drives a run), :mod:`~swarm.kernel.snapshot` (a run at one instant) and
:mod:`~swarm.kernel.results` (a run's metrics and results).

Beside the kernel, in :mod:`swarm`: the event schema :mod:`swarm.events` (the kernel writes it, the
readers of a log use it without the kernel), the errors, and the faces built on the kernel (the
CLI, the run files of :mod:`swarm.outputs`, export, rerun, MAVLink). The public names are
importable from :mod:`swarm` (``from swarm import Simulation``).
"""
