"""The ``swarm`` command line: run, validate and list scenarios.

Only this module prints and exits. A user mistake (bad scenario, unknown name, bad option)
prints one ``error:`` line and exits with status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from swarm.errors import SwarmError

EXIT_USAGE = 2


def _console(stderr: bool = False):
    from rich.console import Console

    return Console(stderr=stderr, highlight=False)


def _cmd_validate(args) -> int:
    from swarm.scenario import load_scenario

    for ref in args.scenario:
        sc = load_scenario(ref)
        types = sorted({u.type for u in sc.uavs})
        print(f"ok: {ref}: scenario '{sc.name}', {len(sc.uavs)} UAVs ({', '.join(types)}), "
              f"{len(sc.targets.placed) + sc.targets.count} targets, {len(sc.threats)} threats, "
              f"{len(sc.faults)} faults, {sc.duration_s:g} s")
    return 0


def _cmd_list(args) -> int:
    from swarm.scenario import builtin_scenarios, load_scenario

    for name in builtin_scenarios():
        sc = load_scenario(name)
        print(f"{name:14s} {sc.description}")
    return 0


def _summary_table(metrics: dict, out_dir: Path | None):
    from rich.table import Table

    t = Table(title=f"{metrics['scenario']} · planner {metrics['planner']} · seed {metrics['seed']}", show_header=True)
    t.add_column("metric")
    t.add_column("value", justify="right")
    r = metrics["radio"]
    rows = [
        ("simulated / wall", f"{metrics['sim_seconds']:g} s / {metrics['wall_seconds']:.2f} s"),
        ("coverage", f"{metrics['coverage']:.3f}"),
        ("certainty", f"{metrics['certainty']:.3f}"),
        ("targets found", f"{metrics['targets_found']} / {metrics['targets_total']}"),
        ("surveillance ratio (mean)", f"{metrics['surveillance_ratio_mean']:.3f}"),
        ("handovers (fast->slow)", f"{metrics['handovers']} ({metrics['handovers_fast_to_slow']})"),
        ("radio sent/delivered", f"{r['sent']} / {r['delivered']}"),
        ("radio dropped/rejected", f"{r['dropped']} / {r['rejected']}"),
        ("violations sep/threat/dyn", "{separation} / {threat} / {dynamics}".format(**metrics["violations"])),
        ("faults applied", ", ".join(f"{k}={v}" for k, v in metrics["faults_applied"].items()) or "none"),
        ("event log sha256", metrics["event_log_sha256"][:16] + "…"),
    ]
    if out_dir is not None:
        rows.append(("outputs", str(out_dir)))
    for k, v in rows:
        t.add_row(k, v)
    return t


def _cmd_run(args) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from swarm.outputs import write_run
    from swarm.scenario import apply_overrides, load_scenario, parse_assignment
    from swarm.simulation import Simulation

    sc = load_scenario(args.scenario)
    if args.set:
        sc = apply_overrides(sc, dict(parse_assignment(s) for s in args.set))
    sim = Simulation(sc, seed=args.seed, planner=args.planner, duration_s=args.duration)
    err = _console(stderr=True)
    with sim, Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.fields[sim]}"),
        TimeElapsedColumn(), TimeRemainingColumn(), console=err, transient=True, disable=args.quiet,
    ) as progress:
        task = progress.add_task(f"{sim.scenario.name} ({sim.scenario.planner.name})", total=sim.n_ticks,
                                 sim="t=0 s")

        def on_progress(now: float, end: float) -> None:
            progress.update(task, completed=round(now / sim.dt), sim=f"t={now:.0f}/{end:.0f} s")

        result = sim.run(progress=on_progress)
    out_dir = Path(args.out) if args.out else None
    if out_dir is not None:
        write_run(result, out_dir, sim.scenario.to_dict(), figures=not args.no_figures)
    if not args.quiet:
        _console().print(_summary_table(result.metrics, out_dir))
    return 0


def _cmd_bench(args) -> int:
    from swarm.bench import CASES, main as bench_main

    unknown = [c for c in args.case if c not in {k.name for k in CASES}]
    if unknown:
        raise SwarmError(f"unknown bench case(s) {unknown}; known: {', '.join(k.name for k in CASES)}")
    return bench_main(quick=args.quick, only=args.case or None)


def _cmd_animate(args) -> int:
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from swarm.animate import prepare_animation

    job = prepare_animation(args.rundir, args.out, fps=args.fps, speed=args.speed, trail_s=args.trail)
    err = _console(stderr=True)
    with Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(), TextColumn("frames"),
        TimeElapsedColumn(), TimeRemainingColumn(), console=err, transient=True, disable=args.quiet,
    ) as progress:
        task = progress.add_task(f"rendering {job.out_path.name}", total=job.n_frames)

        def on_frame(done: int, total: int) -> None:
            progress.update(task, completed=done)

        path = job.render(progress=on_frame)
    if not args.quiet:
        print(f"wrote {path}")
    return 0


def _cmd_report(args) -> int:
    from swarm.report import write_report

    path = write_report(args.rundir, args.out, animation=args.animation)
    if not args.quiet:
        print(f"wrote {path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="swarm", description="Deterministic multi-UAV search and surveillance simulator (DACMP).")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="run one scenario and write its outputs")
    r.add_argument("scenario", help="built-in name (see `swarm list`) or path to a .toml file")
    r.add_argument("--seed", type=int, default=None, help="random seed (default: the scenario's)")
    r.add_argument("--planner", choices=["greedy", "dacmp"], default=None, help="planner (default: the scenario's)")
    r.add_argument("--duration", type=float, default=None, help="simulated seconds (default: the scenario's)")
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario setting, e.g. --set radio.loss_base=0.3 (repeatable)")
    r.add_argument("--out", default=None, help="output folder (metrics.json, timeseries.csv, events.msgpack, trajectories.png)")
    r.add_argument("--no-figures", action="store_true", help="skip trajectories.png")
    r.add_argument("--quiet", action="store_true", help="no progress bar or summary table")
    r.set_defaults(func=_cmd_run)

    v = sub.add_parser("validate", help="check scenario files without running them")
    v.add_argument("scenario", nargs="+")
    v.set_defaults(func=_cmd_validate)

    b = sub.add_parser("bench", help="run the benchmark cases, one JSON line each")
    b.add_argument("--quick", action="store_true", help="only the quick cases")
    b.add_argument("--case", action="append", default=[], help="run only this case (repeatable)")
    b.set_defaults(func=_cmd_bench)

    ls = sub.add_parser("list", help="list the built-in scenarios")
    ls.set_defaults(func=_cmd_list)

    an = sub.add_parser("animate", help="render a run folder's animation (MP4 with ffmpeg, else GIF)")
    an.add_argument("rundir", help="a run folder written by `swarm run --out DIR`")
    an.add_argument("--out", default=None, metavar="FILE",
                    help=".mp4 or .gif (default: RUNDIR/animation.mp4 if ffmpeg is installed, else RUNDIR/animation.gif)")
    an.add_argument("--fps", type=float, default=10.0, help="frames per second of video (default 10)")
    an.add_argument("--speed", type=float, default=60.0,
                    help="simulated seconds per second of video (default 60: a 2000 s run gives a 33 s clip)")
    an.add_argument("--trail", type=float, default=300.0, metavar="SECONDS", help="trail length (default 300 s)")
    an.add_argument("--quiet", action="store_true", help="no progress bar")
    an.set_defaults(func=_cmd_animate)

    rep = sub.add_parser("report", help="write a self-contained HTML report of a run folder")
    rep.add_argument("rundir", help="a run folder written by `swarm run --out DIR`")
    rep.add_argument("--out", default=None, metavar="FILE", help="HTML file (default: RUNDIR/report.html)")
    rep.add_argument("--animation", default=None, metavar="FILE",
                     help="animation to embed (default: RUNDIR/animation.mp4 or .gif if present)")
    rep.add_argument("--quiet", action="store_true", help="do not print the path written")
    rep.set_defaults(func=_cmd_report)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except SwarmError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
