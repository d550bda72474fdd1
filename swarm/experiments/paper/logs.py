"""Reading a run's results back: time series, finished sweeps, and :class:`RunLog` (one run's
events as columns)."""

from __future__ import annotations

import csv
import json
import math
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np

from comms.messages import MODE_SURVEIL
from swarm.events import MODE_CODES, Handover, Mode, read_columns, records
from swarm.experiments.sweep import run_folder
from swarm.outputs import read_json, read_run_dir
from swarm.scenario import load_scenario

# --- reading results ---------------------------------------------------------------------------

def copy_file(src: Path, dst: Path) -> Path:
    shutil.copyfile(src, dst)
    return dst


def read_timeseries(folder: Path) -> dict[str, np.ndarray]:
    """``timeseries.csv`` as arrays: numeric columns as float, ``mode_*`` as strings."""
    with open(folder / "timeseries.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    cols: dict[str, np.ndarray] = {}
    for k in (rows[0].keys() if rows else ()):
        vals = [r[k] for r in rows]
        cols[k] = np.array(vals) if k.startswith("mode_") else np.array([float(v) for v in vals])
    return cols


def finished_runs(sweep_dir: Path, planner: str, seeds: Sequence[int]) -> list[dict[str, Any]]:
    """Finished runs of one planner: ``{"seed", "folder", "metrics", "ts"}`` each, in seed order."""
    out = []
    for s in seeds:
        folder = sweep_dir / run_folder(planner, (), s)
        if (folder / "metrics.json").is_file() and (folder / "timeseries.csv").is_file():
            out.append({"seed": int(s), "folder": folder, "metrics": json.loads((folder / "metrics.json").read_text()),
                        "ts": read_timeseries(folder)})
    return out


def join_time(sweep_dir: Path, seeds: Sequence[int]) -> tuple[float | None, str | None]:
    """The first late joiner of paper-case3: (join time, UAV name), from a run's scenario.json."""
    uavs = None
    for s in seeds:
        p = sweep_dir / "runs" / "dacmp" / "default" / f"seed-{int(s):03d}" / "scenario.json"
        if p.is_file():
            uavs = json.loads(p.read_text())["uavs"]
            break
    if uavs is None:
        uavs = load_scenario("paper-case3").to_dict()["uavs"]
    joins = sorted((float(u["join_s"]), u["name"]) for u in uavs if u.get("join_s"))
    return joins[0] if joins else (None, None)


def stack(runs: Sequence[dict[str, Any]], column: str) -> tuple[np.ndarray, np.ndarray]:
    """``(t, values[n_runs, n_t])`` on the time grid the runs share (their shortest)."""
    n = min(len(r["ts"]["t"]) for r in runs)
    t = runs[0]["ts"]["t"][:n]
    return t, np.vstack([r["ts"][column][:n] for r in runs])


def mean_curve(runs: Sequence[dict[str, Any]], column: str) -> tuple[np.ndarray, np.ndarray]:
    t, v = stack(runs, column)
    return t, v.mean(axis=0)


def band(values: np.ndarray) -> dict[str, np.ndarray]:
    """Per time point: mean, Student-t 95% interval of the mean, min and max over runs."""
    from scipy import stats

    n = values.shape[0]
    mean = values.mean(axis=0)
    if n > 1:
        half = stats.t.ppf(0.975, n - 1) * values.std(axis=0, ddof=1) / math.sqrt(n)
    else:
        half = np.zeros_like(mean)
    return {"mean": mean, "lo": mean - half, "hi": mean + half, "min": values.min(axis=0), "max": values.max(axis=0)}


def stays_above_from(t: np.ndarray, a: np.ndarray, b: np.ndarray, after: float | None) -> float | None:
    """First sample time (>= ``after``) from which ``a > b`` at every later sample, or None."""
    above = a > b
    start = None
    for i in range(len(t) - 1, -1, -1):
        if not above[i]:
            break
        start = float(t[i])
    if start is None:
        return None
    return max(start, after) if after is not None and start < after else start


def _split_rows(rows: np.ndarray, keys: Sequence[int]) -> dict[int, np.ndarray]:
    """``rows`` grouped by ``keys`` (one per row), each group in log order, the groups in the
    order their keys first appear."""
    k = np.asarray(keys, dtype=np.int64)
    order = np.argsort(k, kind="stable")
    bounds = np.flatnonzero(np.diff(k[order])) + 1
    groups = {int(k[idx[0]]): rows[idx] for idx in np.split(order, bounds) if len(idx)}
    return {key: groups[key] for key in dict.fromkeys(k.tolist())}


@dataclass
class RunLog:
    """What the figures and the table need from one run folder's event log."""

    names: dict[int, str]
    types: dict[int, str]
    type_specs: dict[str, dict[str, Any]]
    end_t: float
    dt: float
    poses: dict[int, np.ndarray]      # uid -> rows (t, x, y, mode, target)
    targets: dict[int, np.ndarray]    # target id -> rows (t, x, y)
    modes: list[Mode]                 # on every change of a UAV's mode or target
    handovers: list[Handover]
    found: dict[int, tuple[Any, ...]]           # target -> (t, uid)
    joins: dict[int, float]
    crashes: dict[int, float]
    metrics: dict[str, Any]
    threats: list[dict[str, Any]]

    @classmethod
    def load(cls, folder: Path) -> RunLog:
        run = read_run_dir(folder)
        metrics = read_json(run.path / "metrics.json")
        scenario = run.scenario
        cols = read_columns(run.events, ("start", "pose", "target", "mode", "handover", "found", "join", "crash"))
        header = cols["start"]["header"][0] if cols["start"]["header"] else {}
        dt = float(header.get("dt", scenario.get("dt_s", 1.0)))
        names: dict[int, str] = {}
        types: dict[int, str] = {}
        for uid, name, typ in header.get("uavs", []):
            names[uid] = name
            types[uid] = typ
        j = cols["join"]
        joins = dict(zip(j["uav"], j["t"]))
        names.update(zip(j["uav"], j["uav_name"]))
        crashes: dict[int, float] = {}
        for t, uid in zip(cols["crash"]["t"], cols["crash"]["uav"]):
            crashes.setdefault(uid, t)
        found: dict[int, tuple[Any, ...]] = {}
        for t, m, uid in zip(cols["found"]["t"], cols["found"]["target"], cols["found"]["uav"]):
            found.setdefault(m, (t, uid))
        p = cols["pose"]
        pose_rows = np.column_stack([np.asarray(p["t"], dtype=np.float64), np.asarray(p["x"], dtype=np.float64),
                                     np.asarray(p["y"], dtype=np.float64),
                                     np.asarray([MODE_CODES[m] for m in p["mode"]], dtype=np.float64),
                                     np.asarray(p["target"], dtype=np.float64)]).reshape(-1, 5)
        g = cols["target"]
        target_rows = np.column_stack([np.asarray(g[k], dtype=np.float64) for k in ("t", "x", "y")]).reshape(-1, 3)
        poses = _split_rows(pose_rows, p["uav"])
        targets = _split_rows(target_rows, g["target"])
        modes = cast("list[Mode]", records("mode", cols["mode"]))
        handovers = cast("list[Handover]", records("handover", cols["handover"]))
        for uid, name in names.items():  # UAVs added during the run: type from the scenario
            if uid not in types:
                types[uid] = next((u["type"] for u in scenario["uavs"] if u["name"] == name), "?")
        return cls(
            names=names, types=types, type_specs=scenario["uav_types"], end_t=float(metrics["sim_seconds"]), dt=dt,
            poses=poses, targets=targets,
            modes=modes, handovers=handovers, found=found, joins=joins, crashes=crashes, metrics=metrics,
            threats=scenario.get("threats", []),
        )

    def speed_max(self, uid: int) -> float:
        return float(self.type_specs.get(self.types.get(uid, "?"), {}).get("speed_max", math.nan))

    def is_slow(self, uid: int) -> bool:
        speeds = {float(s["speed_max"]) for s in self.type_specs.values()}
        return len(speeds) > 1 and self.speed_max(uid) == min(speeds)

    def uid(self, name: str) -> int | None:
        return next((u for u, n in self.names.items() if n == name), None)

    def target_at(self, m: int, t: np.ndarray) -> np.ndarray:
        """Target ``m``'s (x, y) at times ``t`` (its rows are logged every tick)."""
        rows = self.targets[m]
        i = np.clip(np.searchsorted(rows[:, 0], t), 0, len(rows) - 1)
        return rows[i, 1:3]

    def watchers_at_end(self) -> dict[int, list[tuple[str, bool]]]:
        """Target -> ``(UAV, in range)`` for every UAV that, at the last logged tick, is in
        surveillance mode assigned to it; ``in range``: the target is inside that UAV's
        detection radius at that tick (a fast UAV circling a moving target can be just outside)."""
        out: dict[int, list[tuple[str, bool]]] = {m: [] for m in self.targets}
        if not self.poses:
            return out
        t_last = max(p[-1, 0] for p in self.poses.values())
        for uid in sorted(self.poses, key=lambda u: self.names.get(u, "")):
            p = self.poses[uid]
            if p[-1, 0] != t_last or int(p[-1, 3]) != MODE_SURVEIL or int(p[-1, 4]) < 0:
                continue
            m = int(p[-1, 4])
            if m not in self.targets:
                continue
            tx, ty = self.target_at(m, np.array([t_last]))[0]
            r = float(self.type_specs.get(self.types[uid], {}).get("detect_radius_m", math.inf))
            out[m].append((self.names[uid], bool(math.hypot(p[-1, 1] - tx, p[-1, 2] - ty) <= r)))
        return out

    def surveil_seconds(self, uid: int, m: int) -> float:
        p = self.poses.get(uid)
        if p is None:
            return 0.0
        return float(np.count_nonzero((p[:, 3] == MODE_SURVEIL) & (p[:, 4] == m))) * self.dt

    def mode_segments(self, uid: int) -> list[tuple[float, float, str, int]]:
        """(start, end, mode, target) with mode in search / surveil / pending / down."""
        segs = []
        start = self.joins.get(uid, 0.0)
        if start > 0:
            segs.append((0.0, start, "pending", -1))
        end = self.crashes.get(uid, self.end_t)
        changes = [e for e in self.modes if e.uav == uid]
        for i, e in enumerate(changes):
            t_next = changes[i + 1].t if i + 1 < len(changes) else end
            if t_next > e.t:
                segs.append((e.t, min(t_next, end), e.mode, e.target))
        if uid in self.crashes:
            segs.append((end, self.end_t, "down", -1))
        return segs
