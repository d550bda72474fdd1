"""The ``swarm`` command line: run, validate and list scenarios (and sweep, export, report...).

Only this module prints and exits. A user mistake (bad scenario, unknown name, bad option)
prints one ``error:`` line and exits with status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import asyncio
import shlex
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from swarm.errors import SwarmError, UsageError

if TYPE_CHECKING:
    from concurrent.futures import Executor

    from rich.console import Console
    from rich.progress import Progress, TaskID
    from rich.table import Table

    from swarm.experiments.resilience.runs import ResilienceReport
    from swarm.experiments.sweep import RunSpec
    from swarm.kernel.results import RunResult
    from swarm.kernel.simulation import Simulation
    from swarm.scenario import Scenario

EXIT_USAGE = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as a shell reports a command stopped by Ctrl-C


class _Parser(argparse.ArgumentParser):
    """argparse with one grammar for every subcommand: no abbreviations (``--seed`` is never
    taken for ``--seeds``), and a "did you mean" for a mistyped option."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        # One line, like every other mistake the command reports (argparse would add its usage).
        self.exit(EXIT_USAGE, f"error: {self.prog}: {message} (see `{self.prog} --help`)\n")

    def _check_value(self, action: argparse.Action, value: Any) -> None:
        # An invalid choice (a subcommand, an experiment, an axis) names the closest valid one.
        import difflib

        choices = action.choices
        if choices is not None and value not in choices:
            names = [str(c) for c in choices]
            close = difflib.get_close_matches(str(value), names, n=1)
            hint = f"did you mean {close[0]!r}? " if close else ""
            raise argparse.ArgumentError(action, f"invalid choice: {value!r} ({hint}choose from {', '.join(names)})")
        return super()._check_value(action, value)

    def unknown_options(self, extras: list[str]) -> None:
        """Exit with one usage error for arguments this (sub)command does not take, naming the
        closest option it does take."""
        import difflib

        message = f"unrecognized arguments: {' '.join(extras)}"
        options = [o for a in self._actions for o in a.option_strings]
        first = next((e for e in extras if e.startswith("-")), None)
        if first is not None:
            close = difflib.get_close_matches(first.split("=")[0], options, n=1)
            if close:
                message += f" (did you mean {close[0]}?)"
        self.error(message)


def parse_seeds(text: str) -> list[int]:
    """``--seeds``: ``N`` (seeds 0..N-1), ``A-B`` (A to B, both included) or ``a,b,c``."""
    text = text.strip()
    try:
        if "," in text:
            seeds = [int(part) for part in text.split(",") if part.strip()]
        elif "-" in text.lstrip("-"):
            first, _, last = text.partition("-")
            seeds = list(range(int(first), int(last) + 1))
        else:
            seeds = list(range(int(text)))
    except ValueError:
        raise argparse.ArgumentTypeError(f"found {text!r}; expected N (seeds 0..N-1), A-B or a,b,c") from None
    if not seeds or any(seed < 0 for seed in seeds):
        raise argparse.ArgumentTypeError(f"found {text!r}; expected at least one seed, none negative")
    return seeds


def _version() -> str:
    from swarm import __version__

    return __version__


def _print_json(data: Any) -> None:
    import json

    print(json.dumps(data, indent=2, allow_nan=False, default=str))


def _console(stderr: bool = False) -> Console:
    from rich.console import Console

    # Piped into a file or another program, rich would cut tables to 80 columns: give it room.
    stream = sys.stderr if stderr else sys.stdout
    width = None if stream.isatty() else 200
    return Console(stderr=stderr, highlight=False, width=width)


def _warn(source: str, scenario: Scenario, duration_s: float | None = None) -> list[str]:
    """Print a ``warning:`` line on stderr for each value that runs but looks unintended
    (:mod:`swarm.scenario.warnings`); return them."""
    from swarm.scenario import scenario_warnings

    warnings = scenario_warnings(scenario, duration_s)
    for w in warnings:
        print(f"warning: {source}: {w}", file=sys.stderr)
    return warnings


# `swarm validate` prints at most this many problems of one scenario, then how many more.
VALIDATE_MAX_PROBLEMS = 20


def _cmd_validate(args: argparse.Namespace) -> int:
    from swarm.errors import ScenarioError
    from swarm.kernel.memory import MemoryLimitError, check_memory
    from swarm.scenario import load_scenario

    if args.memory_limit is not None and not args.memory_limit > 0:
        raise UsageError(f"--memory-limit {args.memory_limit:g}: expected a positive number of GB")
    reports = []
    for ref in args.scenario:
        try:
            sc = load_scenario(ref, allow_planner_imports=args.allow_planner_imports)
        except ScenarioError as err:
            reports.append({"scenario": ref, "ok": False, "problems": [str(e) for e in err.all]})
            continue
        try:  # the same guard as `swarm run` (swarm.kernel.memory)
            estimate = check_memory(sc, args.memory_limit)
        except MemoryLimitError as err:
            reports.append({"scenario": ref, "ok": False, "problems": [f"{ref}: {err}"]})
            continue
        types = sorted({u.type for u in sc.uavs})
        reports.append({"scenario": ref, "ok": True, "name": sc.name, "uavs": len(sc.uavs), "types": types,
                        "targets": len(sc.targets.placed) + sc.targets.count,
                        "no_fly_zones": len(sc.threats) + len(sc.no_fly), "threats": len(sc.threats),
                        "no_fly_polygons": len(sc.no_fly), "faults": len(sc.faults), "duration_s": sc.duration_s,
                        "memory_estimate_bytes": estimate.total, "warnings": _warn(ref, sc)})
    if args.json:
        _print_json(reports)
    for r in reports:
        if r["ok"] and not args.json:
            print(f"ok: {r['scenario']}: scenario '{r['name']}', {r['uavs']} UAVs ({', '.join(r['types'])}), "
                  f"{r['targets']} targets, {_zone_words(r['threats'], r['no_fly_polygons'])}, {r['faults']} faults, "
                  f"{r['duration_s']:g} s")
        elif not r["ok"]:
            problems = r["problems"]
            for problem in problems[:VALIDATE_MAX_PROBLEMS]:
                print(f"error: {problem}", file=sys.stderr)
            if len(problems) > VALIDATE_MAX_PROBLEMS:
                print(f"error: {r['scenario']}: ... and {len(problems) - VALIDATE_MAX_PROBLEMS} more problems "
                      f"(the first {VALIDATE_MAX_PROBLEMS} are shown; --json lists them all)", file=sys.stderr)
    return EXIT_USAGE if any(not r["ok"] for r in reports) else 0


def _zone_words(circles: int, polygons: int) -> str:
    """"3 no-fly zones (2 threat circles, 1 polygon)": every hazard a scenario keeps UAVs out of."""
    total = circles + polygons
    parts = [f"{n} {word}{'' if n == 1 else 's'}" for n, word in ((circles, "threat circle"), (polygons, "polygon")) if n]
    detail = f" ({', '.join(parts)})" if circles and polygons else (f" ({parts[0].split(' ', 1)[1]})" if total else "")
    return f"{total} no-fly zone{'' if total == 1 else 's'}{detail}"


def _cmd_list(args: argparse.Namespace) -> int:
    from swarm.scenario import builtin_scenarios, load_scenario

    if args.planners:
        from agents.planners import BUILTIN, available_planners

        planners = available_planners()
        width = max(map(len, planners), default=0)
        for name, where in planners.items():
            origin = "built-in" if name in BUILTIN else "entry point"
            print(f"{name:{width}s}  {origin:11s}  {where}")
        return 0
    names = builtin_scenarios()
    width = max(map(len, names), default=0)
    for name in names:
        sc = load_scenario(name)
        print(f"{name:{width}s}  {sc.description}")
    return 0


def _progress(*, quiet: bool, transient: bool = False, count: bool = False) -> Progress:
    """The one progress display of every long command, on stderr: description, bar, an
    optional done/total count, a ``note`` field the command updates, elapsed and remaining."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    columns = [TextColumn("[bold]{task.description}"), BarColumn()]
    if count:
        columns.append(MofNCompleteColumn())
    columns += [TextColumn("{task.fields[note]}"), TimeElapsedColumn(), TimeRemainingColumn()]
    return Progress(*columns, console=_console(stderr=True), transient=transient, disable=quiet)


def _per_target(values: dict[str, Any], fmt: Callable[[Any], str]) -> str:
    """``0: 7 s, 1: –`` (a dash: never), target by target."""
    return ", ".join(f"{k}: {'–' if v is None else fmt(v)}" for k, v in sorted(values.items(), key=lambda kv: int(kv[0])))


def _watch_rows(metrics: dict[str, Any]) -> list[tuple[str, str]]:
    """The detection and watch rows of the summary (docs/outputs.md)."""
    if "time_to_first_detection_s" not in metrics:
        return []
    share = metrics["uav_time_share"]
    return [
        ("first detection (s, per target)", _per_target(metrics["time_to_first_detection_s"], lambda v: f"{v:g}")),
        (f"to slow watcher (s; {', '.join(metrics['slow_types'])})",
         _per_target(metrics["time_to_slow_watcher_s"], lambda v: f"{v:g}")),
        ("watched share (per found target)", _per_target(metrics["watched_share"], lambda v: f"{v:.3f}") or "none found"),
        ("watch gaps, longest (per found target)",
         _per_target(metrics.get("watch_continuity", {}), lambda c: f"{c['gaps']} ({c['longest_gap_s']:g} s)")
         or "none found"),
        ("UAV time watching / searching", f"{share['watching']:.3f} / {share['searching']:.3f}"),
    ]


def _summary_table(metrics: dict[str, Any], out_dir: Path | None) -> Table:
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
        *_watch_rows(metrics),
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


def _cmd_view(args: argparse.Namespace) -> int:
    """(issue 26) Open a recording in the rerun viewer where a display exists; otherwise say how."""
    import os
    import shutil
    import subprocess

    target = Path(args.rundir)
    rrds = [target] if target.suffix == ".rrd" and target.is_file() else sorted(target.glob("*.rrd"))
    if not rrds:
        raise UsageError(f"{target}: no rerun recording (.rrd) there; write one with "
                         f"`swarm run SCENARIO --out {target} --rerun {target / 'run.rrd'}`")
    import importlib.util

    if importlib.util.find_spec("rerun") is None:
        raise UsageError("the rerun viewer is not installed: pip install 'uav-swarm-sim[view]'")
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) and sys.platform.startswith("linux"):
        print(f"no display here: copy {rrds[0]} to a machine with one and run `rerun {rrds[0].name}` there "
              f"(pip install rerun-sdk), or open it in the web viewer at https://app.rerun.io (drag and drop)")
        return 0
    viewer = shutil.which("rerun")
    return subprocess.call([viewer, str(rrds[0])] if viewer else [sys.executable, "-m", "rerun", str(rrds[0])])


def _cmd_run(args: argparse.Namespace) -> int:
    from swarm.kernel.simulation import Simulation
    from swarm.outputs import write_run
    from swarm.scenario import load_scenario, parse_assignment

    if args.duration is not None and not args.duration > 0:
        raise UsageError(f"--duration {args.duration:g}: expected a positive number of seconds")
    if args.memory_limit is not None and not args.memory_limit > 0:
        raise UsageError(f"--memory-limit {args.memory_limit:g}: expected a positive number of GB")
    sets = dict(parse_assignment(s) for s in args.set)
    if args.planner is not None and "planner.name" in sets:
        raise UsageError(f"--planner {args.planner} and --set planner.name={sets['planner.name']}: give the planner "
                         f"once, with --planner")
    # The planner first (typed by the user: allowed, and the file's own planner is then never
    # imported), so --set planner.options.KEY are the options of the planner that runs.
    # --set and --duration go into the document before it is judged, together: a setting that
    # only makes sense beside another one (--set planner.surveillance=false for a search-only
    # --planner; --set dt_s=1e-5 for a --duration 1 run) is judged as the user means it.
    if args.duration is not None and "duration_s" in sets and sets["duration_s"] != args.duration:
        raise UsageError(f"--duration {args.duration:g} and --set duration_s={sets['duration_s']}: give the duration once")
    sc = load_scenario(args.scenario, planner=args.planner, allow_planner_imports=args.allow_planner_imports,
                       overrides=sets, run_duration_s=args.duration)
    own_duration = sc.duration_s  # the scenario's end, before --duration
    if args.duration is not None:  # (the loader judged it as run for --duration: not judged again)
        sc = sc.model_copy(update={"duration_s": args.duration})
    sim = Simulation(sc, seed=args.seed, memory_limit_gb=args.memory_limit)
    if args.duration is None:
        _warn(args.scenario, sim.scenario)
    else:  # the scenario as written, run for --duration (what the shortened run leaves out)
        _warn(args.scenario, sim.scenario.model_copy(update={"duration_s": own_duration}), args.duration)
    with sim, _progress(quiet=args.quiet or args.json, transient=True) as progress:
        task = progress.add_task(f"{sim.scenario.name} ({sim.scenario.planner.name})", total=sim.n_ticks,
                                 note="t=0 s")

        def on_progress(now: float, end: float) -> None:
            progress.update(task, completed=round(now / sim.dt), note=f"t={now:.0f}/{end:.0f} s")

        if args.mavlink is None and args.pace is None:
            result = sim.run(progress=on_progress)
        else:  # (issue 34) a host loop: the MAVLink bridge and/or the pacer wait for each tick
            result = asyncio.run(_hosted(sim, args.mavlink, args.pace, on_progress))
    out_dir = Path(args.out) if args.out else None
    if out_dir is not None:
        from swarm.viz.plots import trajectories_png

        write_run(result, out_dir, sim.scenario.to_dict(), figure=None if args.no_figures else trajectories_png)
    if args.rerun is not None:  # (issue 26: a recording for the rerun viewer, extra `view`)
        from swarm.viz.rerun_view import record

        record(result.events, sim.scenario.to_dict(), args.rerun)
    if args.json:
        _print_json(result.metrics)
    elif not args.quiet:
        _console().print(_summary_table(result.metrics, out_dir))
    return 0


async def _hosted(sim: Simulation, mavlink: str | None, pace_factor: float | None,
                  progress: Callable[[float, float], None]) -> RunResult:
    """Run ``sim`` to its end in this loop beside the MAVLink bridge and the pacer."""
    from swarm.mavlink import MavlinkBridge, pace

    t_end = sim.n_ticks * sim.dt
    tasks = []
    if pace_factor is not None:
        if not pace_factor > 0:
            raise UsageError(f"--pace {pace_factor:g}: expected a positive number (simulated seconds per second)")
        tasks.append(pace(sim, pace_factor, t_end))
    bridge = MavlinkBridge(sim, mavlink) if mavlink is not None else None
    if bridge is not None:
        tasks.append(bridge.run(t_end))
    try:
        await asyncio.gather(sim.run_until(t_end, progress), *tasks)
    finally:
        if bridge is not None:
            bridge.close()
    return sim.result()


def _cmd_rerun(args: argparse.Namespace) -> int:
    """Re-run a run folder and compare event-log hashes: 0 equal, 1 different, 2 cannot re-run."""
    from contextlib import ExitStack

    from swarm.reproduce import rerun

    quiet = args.quiet or args.json
    with ExitStack() as stack:
        shown: list[Any] = []  # the bar, made at the first tick (a folder that cannot be re-run shows none)

        def on_progress(now: float, end: float) -> None:
            if not shown:
                bar = stack.enter_context(_progress(quiet=quiet, transient=True))
                shown[:] = [bar, bar.add_task(f"re-running {args.rundir}", total=end, note="")]
            bar, task = shown
            bar.update(task, completed=now, total=end, note=f"t={now:.0f}/{end:.0f} s")

        res = rerun(args.rundir, args.out, allow_planner_imports=args.allow_planner_imports,
                    figures=not args.no_figures, progress=on_progress)
    if args.json:
        _print_json({"equal": res.equal, "original_sha256": res.original_sha256, "sha256": res.sha256,
                     "out": str(res.out), "first_difference_s": res.first_difference_s,
                     "versions_then": res.versions_then, "versions_now": res.versions_now,
                     "version_differences": res.version_differences})
    else:
        print(f"original  {res.original_sha256}  {res.folder}")
        print(f"re-run    {res.sha256}  {res.out}")
        if res.equal:
            print("equal: the re-run reproduces the folder's event log")
        else:
            print(f"DIFFERENT: the first tick whose events differ is t = {res.first_difference_s:g} s")
        changed = res.version_differences
        if changed:
            print("versions differ: " + "; ".join(changed))
        elif not res.equal:
            print("versions: the same as the original's (" + ", ".join(f"{k} {v}" for k, v in res.versions_now.items()) + ")")
    return 0 if res.equal else 1


def _parse_grid(assignments: list[str]) -> dict[str, list[Any]]:
    from swarm.experiments.sweep import split_values
    from swarm.scenario import parse_assignment

    grid: dict[str, list[Any]] = {}
    for text in assignments:
        key, sep, values = text.partition("=")
        if not sep or not key.strip() or not values.strip():
            raise UsageError(f"--set {text!r}: expected KEY=VALUE[,VALUE...], e.g. radio.loss_base=0,0.3")
        grid[key.strip()] = [parse_assignment(f"{key.strip()}={v}")[1] for v in split_values(values)]
    return grid


def _dask_executor(args: argparse.Namespace) -> tuple[Executor | None, Any]:
    """``(executor, client)`` for ``--scheduler ADDRESS``, or ``(None, None)`` for a local pool."""
    if not args.scheduler:
        return None, None
    from distributed import Client

    try:
        client = Client(args.scheduler, timeout=args.connect_timeout)  # type: ignore[no-untyped-call]  # (distributed: unannotated)
    except OSError as exc:
        raise UsageError(f"--scheduler {args.scheduler}: cannot reach a Dask scheduler there ({exc})") from exc
    return client.get_executor(), client  # type: ignore[no-untyped-call]  # (distributed: unannotated)


def _cmd_sweep(args: argparse.Namespace) -> int:
    from agents.planners import PlannerError, resolve_planner
    from swarm.experiments.sweep import SweepInterrupted, check_baseline, graceful_interrupts, plan_runs, run_sweep
    from swarm.scenario import load_scenario

    planners = [p.strip() for p in args.planner.split(",") if p.strip()]
    if not planners:
        raise UsageError(f"--planner {args.planner!r}: expected a comma-separated list of planners")
    for name in planners:
        try:
            resolve_planner(name)
        except PlannerError as exc:
            raise UsageError(f"--planner {args.planner!r}: {exc}") from None
    check_baseline(planners, args.baseline)
    sc = load_scenario(args.scenario, planner=planners[0], allow_planner_imports=args.allow_planner_imports)
    runs = plan_runs(sc, seeds=args.seeds, planners=planners, grid=_parse_grid(args.set), duration_s=args.duration,
                     figures=args.figures, allow_planner_imports=args.allow_planner_imports)
    executor, client = _dask_executor(args)

    def on_first_interrupt() -> None:
        print("interrupted: starting no new run, finishing the runs in progress (Ctrl-C again to stop at once)",
              file=sys.stderr)

    try:
        with graceful_interrupts(on_first_interrupt) as stop, \
                _progress(quiet=args.quiet or args.json, count=True) as progress:
            task = progress.add_task("sweep", total=len(runs), note="")

            def on_progress(done: int, total: int, spec: RunSpec, status: str) -> None:
                progress.update(task, completed=done, note=f"{status}: {spec.label}")

            result = run_sweep(runs, args.out, executor=executor, workers=args.workers, progress=on_progress,
                               stop=stop, baseline=args.baseline)
    except SweepInterrupted as exc:
        r = exc.result
        how = ("stopped after the runs in progress finished" if exc.graceful
               else "stopped at once; the runs in progress were abandoned")
        print(f"interrupted: {how}. {r.summary.get('runs_finished', 0)} of {r.total} runs are finished and kept in "
              f"{args.out} ({r.ran} ran now); run the same command again to resume: "
              f"swarm {shlex.join(args.argv)}", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        if client is not None:
            client.close()
    _warn(args.scenario, sc, args.duration)  # after the sweep: its errors come first, as one line
    summary = result.summary
    from swarm.viz.report import write_sweep_report

    report = write_sweep_report(args.out, summary)
    if args.json:
        _print_json(summary)
    elif not args.quiet:
        _console().print(_sweep_table(summary))
        if summary.get("setting_comparisons"):
            _console().print(_equivalence_table(summary))
    print(f"report: {report}", file=sys.stderr)
    print(f"{result.total} runs: {result.skipped} already finished, {result.ran} ran, "
          f"{len(result.failed)} failed; summary in {Path(args.out) / 'summary.json'}", file=sys.stderr)
    for f in result.failed:
        print(f"failed: {f['run']}: {f['error']} (see {Path(args.out) / f['folder'] / 'error.json'})", file=sys.stderr)
    return 1 if result.failed else 0


def _sweep_table(summary: dict[str, Any]) -> Table:
    from rich.table import Table

    shown = ["coverage", "certainty", "targets_found", "surveillance_ratio_mean", "handovers_fast_to_slow"]
    t = Table(title="sweep summary (mean [95% interval])", caption=summary.get("interval"))
    t.add_column("planner")
    t.add_column("settings")
    t.add_column("runs", justify="right")
    for m in shown:
        t.add_column(m, justify="right")
    for g in summary["groups"]:
        cells = []
        for m in shown:
            d = g["metrics"].get(m)
            cells.append(f"{d['mean']:.3f} [{d['ci95'][0]:.3f}, {d['ci95'][1]:.3f}]" if d else "-")
        t.add_row(g["planner"], ", ".join(f"{k}={v}" for k, v in g["settings"].items()) or "-",
                  str(g["runs"]), *cells)
    return t


def _cmd_compare(args: argparse.Namespace) -> int:
    """Two sweep folders run by run: 0 equivalent, 1 not (2: cannot compare)."""
    from swarm.experiments.equivalence import compare_folders

    c = compare_folders(args.old, args.new)
    if args.json:
        _print_json(c.as_dict())
    else:
        rows = [{"planner": g["planner"], "label": f"{g['settings']} ({g['identical']} identical)",
                 "paired_seeds": g["paired_seeds"], "equivalence": g["equivalence"]} for g in c.groups]
        _console().print(_equivalence_table({"setting_comparisons": rows}, title="new - old, paired by run"))
    print(f"{c.paired} runs in both ({c.identical} with the same event log), {c.only_old} only in {c.old}, "
          f"{c.only_new} only in {c.new}: {'equivalent' if c.equivalent else 'NOT equivalent'}", file=sys.stderr)
    return 0 if c.equivalent else 1


def _equivalence_table(summary: dict[str, Any], title: str = "new - old, paired by seed") -> Table:
    """Each ``--set`` axis's later values against its first, paired by seed, with the verdict
    of :mod:`swarm.experiments.equivalence` (the margins are in the column titles)."""
    from rich.table import Table

    from swarm.experiments.equivalence import MARGINS

    t = Table(title=f"{title} (mean [95% interval]); equivalent when every interval is within its margin")
    for col in ("planner", "setting", "seeds"):
        t.add_column(col)
    for name, margin in MARGINS.items():
        t.add_column(f"{name} ({margin.text()})", justify="right")
    t.add_column("equivalent")
    for c in summary["setting_comparisons"]:
        cells = []
        for name in MARGINS:
            e = c["equivalence"].get(name)
            cells.append(f"{e['mean']:+.3f} [{e['ci95'][0]:+.3f}, {e['ci95'][1]:+.3f}]{'' if e['equivalent'] else ' (out)'}"
                         if e else "-")
        verdicts = [e["equivalent"] for e in c["equivalence"].values()]
        t.add_row(c["planner"], c.get("label") or f"{c['key']}: {c['old']} -> {c['new']}", str(c["paired_seeds"]), *cells,
                  ("yes" if all(verdicts) else "no") if verdicts else "-")
    return t


@contextmanager
def _experiment_runner(args: argparse.Namespace,
                       ) -> Iterator[tuple[Executor | None, Callable[[str, str, float, float, str], None]]]:
    """``(executor, on_progress)`` for the multi-sweep commands (paper, resilience): the Dask
    executor of ``--scheduler`` (closed on exit) or None, and a progress callback
    ``(key, description, done, total, info)`` drawing one rich bar per key."""
    executor, client = _dask_executor(args)
    try:
        with _progress(quiet=args.quiet, count=True) as progress:
            tasks: dict[str, TaskID] = {}

            def on_progress(key: str, desc: str, done: float, total: float, info: str) -> None:
                if key not in tasks:
                    tasks[key] = progress.add_task(desc, total=total, note=info)
                progress.update(tasks[key], completed=done, total=total, note=info)

            yield executor, on_progress
    finally:
        if client is not None:
            client.close()


def _cmd_paper(args: argparse.Namespace) -> int:
    from swarm.experiments.paper import run_paper

    with _experiment_runner(args) as (executor, on_progress):
        report = run_paper(args.experiment, args.out, seeds=args.seeds, duration_s=args.duration,
                           executor=executor, workers=args.workers, progress=on_progress)
    failed = []
    for rep in report.experiments:
        for folder, res in rep.sweeps:
            print(f"{rep.name}: {folder}: {res.total} runs: {res.skipped} already finished, {res.ran} ran, "
                  f"{len(res.failed)} failed", file=sys.stderr)
        for folder, kept in rep.single:
            print(f"{rep.name}: {folder}: {'already finished, kept' if kept else 'ran'}", file=sys.stderr)
        for fig in rep.figures:
            print(f"{rep.name}: figure {fig}", file=sys.stderr)
        failed += rep.failed
    if not args.quiet:
        from rich.table import Table

        t = Table(title="paper (quoted) vs ours (measured)", show_lines=False)
        for col in ("experiment", "quantity", "paper (quoted)", "ours (measured)"):
            t.add_column(col, overflow="fold")
        for r in report.rows:
            t.add_row(r["experiment"], r["quantity"], r["paper_quoted"], r["ours_measured"])
        _console().print(t)
    print(f"table: {report.table_md} and {report.table_csv}", file=sys.stderr)
    for f in failed:
        print(f"failed: {f['run']}: {f['error']}", file=sys.stderr)
    return 1 if failed else 0


def _cmd_resilience(args: argparse.Namespace) -> int:
    from swarm.experiments.resilience import parse_values, run_resilience

    if args.duration is not None and not args.duration > 0:
        raise UsageError(f"--duration {args.duration:g}: expected a positive number of seconds")
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers {args.workers}: expected a whole number >= 1")
    values = None
    if args.values is not None:
        if args.axis == "all":
            raise UsageError("--values needs one axis, not all")
        values = parse_values(args.axis, args.values)
    with _experiment_runner(args) as (executor, on_progress):
        report = run_resilience(args.axis, args.out, values=values, scenario=args.scenario, seeds=args.seeds,
                                duration_s=args.duration, crash_at_s=args.crash_at, burst_loss=args.burst_loss,
                                executor=executor, workers=args.workers, progress=on_progress)
    failed = []
    for rep in report.axes:
        res = rep.sweep
        print(f"{rep.axis}: {rep.out_dir}: {res.total} runs: {res.skipped} already finished, {res.ran} ran, "
              f"{len(res.failed)} failed", file=sys.stderr)
        for fig in rep.figures:
            print(f"{rep.axis}: figure {fig}", file=sys.stderr)
        t = rep.results.get("target")
        if t and t.get("available"):
            k = t["dacmp"]["kept_coverage"]
            print(f"{rep.axis}: DACMP keeps {k['mean']:.3f} [{k['ci95'][0]:.3f}, {k['ci95'][1]:.3f}] of its loss-free "
                  f"coverage at {t['loss']:g} loss (target >= {t['kept_at_least']:g}: "
                  f"{'met' if t['met'] else 'not met'})", file=sys.stderr)
        failed += [f for f in res.failed]
    if not args.quiet:
        _console().print(_resilience_table(report))
    print(f"table: {report.table_md} and {report.table_csv}", file=sys.stderr)
    for f in failed:
        print(f"failed: {f['run']}: {f['error']}", file=sys.stderr)
    return 1 if failed else 0


def _resilience_table(report: ResilienceReport) -> Table:
    from rich.table import Table

    t = Table(title="resilience (mean [95% interval] over seeds)")
    for col in ("axis", "value", "coverage DACMP", "coverage greedy", "targets DACMP", "targets greedy"):
        t.add_column(col, justify="right" if col != "axis" else "left")

    def cell(d: dict[str, Any] | None, digits: int) -> str:
        return f"{d['mean']:.{digits}f} [{d['ci95'][0]:.{digits}f}, {d['ci95'][1]:.{digits}f}]" if d else "-"

    for rep in report.axes:
        for pt in rep.results["points"]:
            pl = pt["planners"]
            t.add_row(rep.axis, pt["label"], cell(pl["dacmp"]["coverage"], 3), cell(pl["greedy"]["coverage"], 3),
                      cell(pl["dacmp"]["targets_found"], 2), cell(pl["greedy"]["targets_found"], 2))
    return t


def _cmd_bench(args: argparse.Namespace) -> int:
    from swarm.experiments.bench import CASES
    from swarm.experiments.bench import main as bench_main

    unknown = [c for c in args.case if c not in {k.name for k in CASES}]
    if unknown:
        raise SwarmError(f"unknown bench case(s) {unknown}; known: {', '.join(k.name for k in CASES)}")
    if args.examples is not None:
        if args.examples < 1:
            raise UsageError(f"--examples {args.examples}: expected a whole number >= 1")
        from swarm.experiments.examples import main as examples_main

        return examples_main(args.examples)
    if args.against is not None:
        from swarm.experiments.against import main as against_main

        return against_main(args.against, pairs=args.pairs, quick=args.quick, only=args.case or None)
    return bench_main(quick=args.quick, only=args.case or None, as_array=args.json, components=args.components)


def _cmd_animate(args: argparse.Namespace) -> int:
    from swarm.viz.animate import prepare_animation

    job = prepare_animation(args.rundir, args.out, fps=args.fps, speed=args.speed, trail_s=args.trail)
    with _progress(quiet=args.quiet, transient=True, count=True) as progress:
        task = progress.add_task(f"rendering {job.out_path.name}", total=job.n_frames, note="frames")

        def on_frame(done: int, total: int) -> None:
            progress.update(task, completed=done)

        path = job.render(progress=on_frame)
    if not args.quiet:
        print(f"wrote {path}")
    from swarm.viz.report import refresh_report

    report = refresh_report(args.rundir, path)
    if report is not None and not args.quiet:
        print(f"updated {report} (it now embeds {path.name})")
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from swarm.viz.report import find_animation, write_report

    path = write_report(args.rundir, args.out, animation=args.animation)
    if not args.quiet:
        print(f"wrote {path}")
        if args.animation is None and find_animation(args.rundir) is None:
            then = (f"adds it to {path}" if args.out is None
                    else f"then run `swarm report` again to add it to {path}")
            print(f"no animation in {args.rundir}: `swarm animate {args.rundir}` makes one and {then}", file=sys.stderr)
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from swarm.export import export_parquet

    result = export_parquet(args.folder, args.out)
    if not args.quiet:
        what = f"{result.runs} runs" if result.runs > 1 else "1 run"
        print(f"wrote {len(result.rows)} Parquet tables of {what} to {result.out}")
        for name, n in result.rows.items():
            print(f"  {name}.parquet  {n:,} rows")
    return 0


def _add_executor_args(parser: argparse.ArgumentParser, scheduler_help: str) -> None:
    """``--workers K`` or ``--scheduler ADDRESS`` (see :func:`_dask_executor`)."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, help="local worker processes (default: CPU count)")
    where.add_argument("--scheduler", default=None, metavar="ADDRESS", help=scheduler_help)
    parser.add_argument("--connect-timeout", type=float, default=10.0, help=argparse.SUPPRESS)


def _add_allow_arg(parser: argparse.ArgumentParser) -> None:
    """``--allow-planner-imports``: the opt-in for module:Class planners named by files
    (swarm.scenario.trust; the environment variable SWARM_ALLOW_PLANNER_IMPORTS=1 does the same)."""
    parser.add_argument("--allow-planner-imports", action="store_true",
                        help="import a planner given as module:Class inside a scenario file or a --set value (runs "
                             "that module's code; off by default: only planners you type with --planner, built-in "
                             "and entry-point names are imported); same as SWARM_ALLOW_PLANNER_IMPORTS=1")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="swarm", description="Deterministic multi-UAV search and surveillance simulator (DACMP).")
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = p.add_subparsers(dest="command", required=True)
    p.set_defaults(subparsers=sub.choices)

    r = sub.add_parser("run", help="run one scenario and write its outputs")
    r.add_argument("scenario", help="built-in name (see `swarm list`) or path to a .toml file")
    r.add_argument("--seed", type=int, default=None, help="random seed (default: the scenario's)")
    r.add_argument("--planner", default=None, metavar="NAME",
                   help="planner: a built-in name (swarm list --planners), package.module:Class, or an entry-point "
                        "name (default: the scenario's)")
    r.add_argument("--duration", type=float, default=None, help="simulated seconds (default: the scenario's)")
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario setting, e.g. --set radio.loss_base=0.3 (repeatable)")
    r.add_argument("--out", default=None, help="output folder (metrics.json, timeseries.csv, events.msgpack, trajectories.png)")
    r.add_argument("--no-figures", action="store_true", help="skip trajectories.png")
    r.add_argument("--rerun", default=None, metavar="FILE.rrd",
                   help="also record the run for the rerun viewer (extra `view`); `swarm view` opens it")
    r.add_argument("--mavlink", default=None, metavar="URL",
                   help="each UAV a MAVLink system on this pymavlink connection, e.g. udpout:127.0.0.1:14550 "
                        "(extra `mavlink`; docs/embedding.md#mavlink)")
    r.add_argument("--pace", type=float, default=None, metavar="FACTOR",
                   help="simulated seconds per wall-clock second (1.0: real time; default: as fast as it runs)")
    r.add_argument("--memory-limit", type=float, default=None, metavar="GB",
                   help="refuse a scenario estimated to need more (default: SWARM_MEMORY_LIMIT_GB, else half of "
                        "this machine's memory)")
    r.add_argument("--quiet", action="store_true", help="no progress bar or summary table")
    r.add_argument("--json", action="store_true", help="print the metrics as JSON on stdout instead of the table")
    _add_allow_arg(r)
    r.set_defaults(func=_cmd_run)

    v = sub.add_parser("validate", help="check scenario files without running them")
    v.add_argument("scenario", nargs="+", help="built-in names or .toml files; every problem of each is reported")
    v.add_argument("--json", action="store_true", help="print one JSON record per scenario on stdout")
    v.add_argument("--memory-limit", type=float, default=None, metavar="GB",
                   help="refuse a scenario estimated to need more, as `swarm run` does (default: SWARM_MEMORY_LIMIT_GB, "
                        "else half of this machine's memory)")
    _add_allow_arg(v)
    v.set_defaults(func=_cmd_validate)

    rr = sub.add_parser("rerun", help="re-run a run folder and compare event-log hashes (exit 0 equal, 1 different)")
    rr.add_argument("rundir", help="a run folder (`swarm run --out DIR`, a sweep's runs/PLANNER/SETTINGS/seed-NNN, ...)")
    rr.add_argument("--out", default=None, metavar="DIR", help="folder for the new run (default: a new temporary folder)")
    rr.add_argument("--no-figures", action="store_true", help="skip trajectories.png")
    rr.add_argument("--quiet", action="store_true", help="no progress bar")
    rr.add_argument("--json", action="store_true", help="print the comparison as JSON on stdout")
    _add_allow_arg(rr)
    rr.set_defaults(func=_cmd_rerun)

    cm = sub.add_parser("compare", help="pair two sweep folders' runs by planner, settings and seed (before and after "
                                        "a change): equivalent? (exit 0 yes, 1 no)")
    cm.add_argument("old", help="the sweep folder of the old code or model (swarm sweep --out, or swarm paper's --out)")
    cm.add_argument("new", help="the sweep folder of the new one, run with the same planners, settings and seeds")
    cm.add_argument("--json", action="store_true", help="print the comparison as JSON instead of the table")
    cm.set_defaults(func=_cmd_compare)
    b = sub.add_parser("bench", help="run the benchmark cases, one JSON line each")
    b.add_argument("--quick", action="store_true", help="only the quick cases")
    b.add_argument("--case", action="append", default=[], help="run only this case (repeatable)")
    b.add_argument("--json", action="store_true", help="print one JSON array at the end instead of a line per case")
    b.add_argument("--components", action="store_true",
                   help="also the CPU time per UAV-tick of each component of the tick (receive, outbox, anti-entropy, "
                        "geometry, radio, observer, world, actors, planning): in each line, and as a table on stderr")
    b.add_argument("--against", metavar="REFERENCE", default=None,
                   help="run each case alternately with this yardstick (../shared/bench/reference_limit.py), each in "
                        "its own process, and print the ratios of their rates (a JSON line per case, a table on stderr)")
    b.add_argument("--pairs", type=int, default=3, help="with --against: how many (case, reference) pairs (default 3)")
    b.add_argument("--examples", type=int, default=None, metavar="N",
                   help="instead of the cases: N property-test-sized runs in this process (paper-case1, 300 s, "
                        "seeds 1..N after a warm-up) and the examples per CPU-minute (one JSON line)")
    b.set_defaults(func=_cmd_bench)

    sw = sub.add_parser("sweep", help="run planners x settings x seeds and summarise (process pool or Dask)")
    sw.add_argument("scenario", help="built-in name or path to a .toml file")
    sw.add_argument("--seeds", type=parse_seeds, default=parse_seeds("30"), metavar="N|A-B|a,b,c",
                    help="seeds: N (0..N-1), A-B or a,b,c (default 30: seeds 0-29)")
    sw.add_argument("--planner", default="dacmp,greedy", help="comma-separated planners (default dacmp,greedy)")
    sw.add_argument("--baseline", default=None, metavar="PLANNER",
                    help="the planner the others are compared with, seed by seed (default: the first of --planner)")
    sw.add_argument("--set", action="append", default=[], metavar="KEY=V1,V2",
                    help="sweep a scenario setting over values, e.g. --set radio.loss_base=0,0.3 (repeatable)")
    sw.add_argument("--duration", type=float, default=None, help="simulated seconds (default: the scenario's)")
    _add_executor_args(sw, "submit to a running Dask scheduler, e.g. tcp://10.0.0.5:8786")
    sw.add_argument("--figures", action="store_true", help="write trajectories.png for every run")
    sw.add_argument("--out", required=True, help="sweep folder (runs/, summary.json, summary.csv)")
    sw.add_argument("--quiet", action="store_true", help="no progress bar or table")
    sw.add_argument("--json", action="store_true", help="print summary.json's content on stdout instead of the table")
    _add_allow_arg(sw)
    sw.set_defaults(func=_cmd_sweep)

    pa = sub.add_parser("paper", help="reproduce the paper's experiments (section 4): figures and a table")
    pa.add_argument("experiment", choices=["fig11", "case1", "case2", "case3", "all"],
                    help="fig11 (DACMP vs greedy over seeds, beside the reference planners), case1 (handover), "
                         "case2 (threats, task loads), "
                         "case3 (late joiner vs case2 over seeds), or all of them")
    pa.add_argument("--seeds", type=parse_seeds, default=None, metavar="N|A-B|a,b,c",
                    help="seeds: N (0..N-1), A-B or a,b,c (default: 30 for fig11, 10 for case3; "
                         "case2: a single run unless given; "
                         "all: case2 gets case3's count)")
    pa.add_argument("--duration", type=float, default=None,
                    help="simulated seconds per run (default: each scenario's; shorter for quick trials)")
    _add_executor_args(pa, "submit the multi-seed runs to a running Dask scheduler, e.g. tcp://10.0.0.5:8786")
    pa.add_argument("--out", default="results/paper", help="output folder (default results/paper)")
    pa.add_argument("--quiet", action="store_true", help="no progress bars or table")
    pa.set_defaults(func=_cmd_paper)

    from swarm.experiments.resilience.axes import AXES  # (the axes' records: names and help from one place)

    rs = sub.add_parser("resilience", help="coverage and targets found along each degradation axis: "
                                           + ", ".join(AXES))
    rs.add_argument("axis", choices=[*AXES, "all"],
                    help=", ".join(a.summary for a in AXES.values()) + ", or all of them")
    # An option, not a positional: it has a default (a required scenario is positional).
    rs.add_argument("--scenario", default="paper-fig11", help="built-in name or .toml file (default paper-fig11)")
    rs.add_argument("--seeds", type=parse_seeds, default=parse_seeds("10"), metavar="N|A-B|a,b,c",
                    help="seeds per planner and value: N (0..N-1), A-B or a,b,c (default 10: seeds 0-9)")
    rs.add_argument("--values", default=None, metavar="V1,V2,...",
                    help="values of one axis instead of its defaults: loss rates, burst lengths in frames, "
                         "ranges in km (inf = unlimited), numbers of UAVs (crash, restart, liar), seconds (pause, "
                         "skew), probabilities (detect), km (jammer)")
    rs.add_argument("--duration", type=float, default=None, help="simulated seconds per run (default: the scenario's)")
    rs.add_argument("--crash-at", type=float, default=300.0, metavar="S",
                    help="when the crash, restart and pause axes' faults happen (default 300 s)")
    rs.add_argument("--burst-loss", type=float, default=0.3, metavar="RATE",
                    help="mean loss rate of the burst axis (default 0.3)")
    _add_executor_args(rs, "submit the runs to a running Dask scheduler, e.g. tcp://10.0.0.5:8786")
    rs.add_argument("--out", default="results/resilience", help="output folder (default results/resilience)")
    rs.add_argument("--quiet", action="store_true", help="no progress bars or table")
    rs.set_defaults(func=_cmd_resilience)

    ls = sub.add_parser("list", help="list the built-in scenarios (or, with --planners, the planners)")
    ls.add_argument("--planners", action="store_true",
                    help="list the planners a name can choose (built-in and registered under swarm.planners)")
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

    vw = sub.add_parser("view", help="open a run's rerun recording (RUNDIR/*.rrd) in the rerun viewer")
    vw.add_argument("rundir", help="a run folder holding a recording (`swarm run --out DIR --rerun DIR/run.rrd`), or an .rrd")
    vw.set_defaults(func=_cmd_view)

    rep = sub.add_parser("report", help="write a self-contained HTML report of a run folder")
    rep.add_argument("rundir", help="a run folder written by `swarm run --out DIR`")
    rep.add_argument("--out", default=None, metavar="FILE", help="HTML file (default: RUNDIR/report.html)")
    rep.add_argument("--animation", default=None, metavar="FILE",
                     help="animation to embed (default: RUNDIR/animation.mp4 or .gif if present)")
    rep.add_argument("--quiet", action="store_true", help="do not print the path written")
    rep.set_defaults(func=_cmd_report)

    ex = sub.add_parser("export", help="write a run or sweep folder's events, time series and paths as Parquet tables")
    ex.add_argument("folder", help="a run folder (`swarm run --out`) or a sweep folder (`swarm sweep --out`)")
    ex.add_argument("--format", choices=["parquet"], default="parquet",
                    help="parquet: one table per event kind, timeseries and paths (needs the parquet extra)")
    ex.add_argument("--out", default=None, metavar="DIR", help="output folder (default: FOLDER/parquet)")
    ex.add_argument("--quiet", action="store_true", help="do not print the tables written")
    ex.set_defaults(func=_cmd_export)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args, extras = parser.parse_known_args(argv)
        if extras:
            args.subparsers[args.command].unknown_options(extras)
    except SystemExit as exc:  # argparse has printed the usage and its error line (or --help)
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    args.argv = argv  # what the user typed (a stopped sweep says how to resume it)
    try:
        code: int = args.func(args)
        return code
    except SwarmError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
