"""Reading a finished run back from its folder: the event log as per-tick, per-UAV arrays.

:func:`load_run` reads ``events.msgpack`` (required), ``scenario.json`` (required: area, UAV
types, threats, radio range), and ``metrics.json`` / ``timeseries.csv`` when present, into a
:class:`Replay`. Poses become ``(ticks, uavs)`` arrays (NaN / -1 where a UAV did not fly that
tick), targets ``(ticks, targets)`` arrays; rare events (found, mode, crash, join, handover,
faults) stay as small lists, radio events (rx, lost) as column arrays.

:class:`CoverageRaster` rebuilds the ground-truth "last scanned" map from the poses and each
UAV type's detection radius, vectorised over many poses at once; it reproduces the simulator's
cell rule exactly (a cell is scanned when its centre lies inside the detection circle), so its
coverage equals ``metrics.json``'s.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgpack
import numpy as np

from comms.messages import MODE_NAMES, MODE_SEARCH, MODE_SURVEIL
from comms.radio import LogDistance
from swarm.events import MODE_CODES, read_columns
from swarm.outputs import RunDirError, check_run_dir, read_json, read_run_dir

__all__ = [
    "CoverageRaster",
    "Replay",
    "RunDirError",
    "Threat",
    "check_run_dir",
    "fault_events",
    "fault_label",
    "first_seen_map",
    "load_run",
    "replay_from_bytes",
    "stamp_poses",
]


# The kinds a replay reads.
_REPLAYED = ("start", "pose", "target", "rx", "lost", "found", "crash", "join", "handover", "violation", "host",
             "landed", "launched")


@dataclass(frozen=True)
class Threat:
    x: float
    y: float
    radius: float
    d_max: float


@dataclass
class Replay:
    """A run rebuilt from its event log (see the module docstring)."""

    header: dict[str, Any]
    scenario: dict[str, Any]
    dt: float
    duration: float  # simulated seconds covered by the run
    names: list[str]  # index = UAV id
    types: list[str]
    x: np.ndarray  # (ticks, uavs) metres, NaN when not flying
    y: np.ndarray
    theta: np.ndarray
    mode: np.ndarray  # (ticks, uavs) int8: -1 not flying, 0 search, 1 surveil
    target: np.ndarray  # (ticks, uavs) int32: watched target id or -1
    target_x: np.ndarray  # (ticks, targets), NaN before a target exists
    target_y: np.ndarray
    found_t: np.ndarray  # (targets,) time first detected, inf if never
    found_by: dict[int, int]
    crashes: list[tuple[float, int]]  # (t, uid)
    joins: list[tuple[float, int]]  # (t, uid)
    handovers: list[tuple[float, int, int, int]]  # (t, target, from uid, to uid)
    violations: list[tuple[float, str, int, int]]
    rx: dict[str, np.ndarray]  # columns t, src, dst, accepted
    lost: dict[str, np.ndarray]  # columns t, src, dst, cause (index into lost_causes)
    lost_causes: list[str]
    metrics: dict[str, Any] | None = None
    timeseries: dict[str, list[Any]] | None = None  # column name -> values (numbers or mode strings)
    faults: list[dict[str, Any]] = field(default_factory=list)  # the start header's schedule, then faults a host added
    # (issue 33, [endurance]) when each UAV landed at its base and launched again: (t, uid)
    landings: list[tuple[float, int]] = field(default_factory=list)
    launches: list[tuple[float, int]] = field(default_factory=list)

    # --- geometry from the scenario ---------------------------------------------------------
    @property
    def n_ticks(self) -> int:
        return int(self.x.shape[0])

    @property
    def n_uavs(self) -> int:
        return len(self.names)

    @property
    def n_targets(self) -> int:
        return int(self.target_x.shape[1])

    @property
    def times(self) -> np.ndarray:
        return np.arange(self.n_ticks) * self.dt

    @property
    def area(self) -> tuple[float, float, float]:
        """(width_m, height_m, cell_m)."""
        a = self.scenario.get("area", {})
        return float(a.get("width_m", 50_000.0)), float(a.get("height_m", 50_000.0)), float(a.get("cell_m", 100.0))

    @property
    def detect_radius(self) -> np.ndarray:
        """(uavs,) detection radius of each UAV's type, metres."""
        types = self.scenario.get("uav_types", {})
        return np.array([float(types.get(t, {}).get("detect_radius_m", 0.0)) for t in self.types])

    @property
    def radio_range(self) -> float:
        """How far links reach (``RadioSettings.range_limit_m``): the log-distance model's link
        budget caps ``range_m``."""
        radio = self.scenario.get("radio", {})
        r = math.inf if radio.get("range_m") is None else float(radio["range_m"])
        if radio.get("model") == "log_distance":
            r = min(r, LogDistance(**(radio.get("log_distance") or {})).range_m)
        return r

    @property
    def tau(self) -> float:
        """Memory factor of the uncertainty map (the scenario's ``effective_tau``)."""
        m = self.scenario.get("map", {})
        if m.get("tau") is not None:
            return float(m["tau"])
        radius = float(np.max(self.detect_radius)) if self.n_uavs else 2000.0
        return float(m.get("prior_target_speed", 10.0)) / max(radius, 1.0)

    @property
    def threats(self) -> list[Threat]:
        out = []
        for th in self.scenario.get("threats", []):
            r = float(th["radius_m"])
            infl = th.get("influence_m")
            out.append(Threat(float(th["x_m"]), float(th["y_m"]), r, float(infl) if infl is not None else r + 3000.0))
        return out

    def tick_at(self, t: float) -> int:
        """Index of the last tick at or before ``t`` (clipped to the run)."""
        return int(min(max(math.floor(t / self.dt + 1e-9), 0), self.n_ticks - 1))

    def last_position(self, uid: int, i: int) -> tuple[float, float] | None:
        """Where UAV ``uid`` last was at or before tick ``i`` (a wreck's position)."""
        col = self.x[: i + 1, uid]
        idx = np.flatnonzero(np.isfinite(col))
        if len(idx) == 0:
            return None
        j = idx[-1]
        return float(self.x[j, uid]), float(self.y[j, uid])

    def mode_seconds(self) -> dict[str, dict[str, float]]:
        """Per UAV: seconds in search, in surveillance, and not flying (pending or down)."""
        out = {}
        for u, name in enumerate(self.names):
            m = self.mode[:, u]
            out[name] = {
                MODE_NAMES[MODE_SEARCH]: float(np.count_nonzero(m == MODE_SEARCH)) * self.dt,
                MODE_NAMES[MODE_SURVEIL]: float(np.count_nonzero(m == MODE_SURVEIL)) * self.dt,
                "not flying": float(np.count_nonzero(m < 0)) * self.dt,
            }
        return out


def _read_timeseries(path: Path) -> dict[str, list[Any]]:
    cols: dict[str, list[Any]] = {}
    with path.open(newline="") as fh:
        for row in csv.DictReader(fh):
            for k, v in row.items():
                try:
                    val: object = float(v)
                except (TypeError, ValueError):
                    val = v
                cols.setdefault(k, []).append(val)
    return cols


def load_run(run_dir: str | Path) -> Replay:
    """Read a run folder written by ``swarm run --out DIR`` (see the module docstring)."""
    run = read_run_dir(run_dir)
    d = run.path
    metrics = read_json(d / "metrics.json") if (d / "metrics.json").is_file() else None
    ts = d / "timeseries.csv"
    timeseries = _read_timeseries(ts) if ts.is_file() else None
    try:
        rp = replay_from_bytes(run.events, run.scenario)
    except (ValueError, msgpack.UnpackException, KeyError, IndexError, TypeError) as exc:
        raise RunDirError(f"{d / 'events.msgpack'}: not a readable event log ({type(exc).__name__}: {exc})") from None
    rp.metrics = metrics
    rp.timeseries = timeseries
    if metrics and metrics.get("sim_seconds"):
        rp.duration = float(metrics["sim_seconds"])
    return rp


def replay_from_bytes(data: bytes, scenario: dict[str, Any]) -> Replay:
    """Build a :class:`Replay` from an event log's bytes and the scenario dict that ran."""
    cols = read_columns(data, _REPLAYED)
    starts = cols["start"]["header"]
    header: dict[str, Any] = starts[0] if starts else {}
    pose, tgt, rx, lost = cols["pose"], cols["target"], cols["rx"], cols["lost"]
    found: dict[int, tuple[float, int]] = {}
    for t, m, u in zip(cols["found"]["t"], cols["found"]["target"], cols["found"]["uav"]):
        found.setdefault(int(m), (float(t), int(u)))
    j = cols["join"]
    joins = [(float(t), int(u)) for t, u in zip(j["t"], j["uav"])]
    join_names = {int(u): name for u, name in zip(j["uav"], j["uav_name"])}
    c = cols["crash"]
    crashes = [(float(t), int(u)) for t, u in zip(c["t"], c["uav"])]
    landings = [(float(t), int(u)) for t, u in zip(cols["landed"]["t"], cols["landed"]["uav"])]
    launches = [(float(t), int(u)) for t, u in zip(cols["launched"]["t"], cols["launched"]["uav"])]
    h = cols["handover"]
    handovers = [(float(t), int(m), int(a), int(b)) for t, m, a, b in zip(h["t"], h["target"], h["from_uav"], h["to_uav"])]
    v = cols["violation"]
    violations = [(float(t), str(k), int(a), int(b)) for t, k, a, b in zip(v["t"], v["invariant"], v["uav"], v["other"])]
    t_max = max((float(max(col["t"])) for col in cols.values() if col["t"]), default=0.0)
    dt = float(header.get("dt", scenario.get("dt_s", 1.0)))

    names: dict[int, str] = {}
    types: dict[int, str] = {}
    for uid, name, typ in header.get("uavs", []):
        names[int(uid)] = name
        types[int(uid)] = typ
    spec_type = {u.get("name"): u.get("type") for u in scenario.get("uavs", [])}
    # (issue 34) What a host added while it ran: its UAVs' types, its faults (shown like scheduled ones).
    hosted = [(c, a) for c, a in zip(cols["host"]["change"], cols["host"]["args"])]
    spec_type.update({a["name"]: a["type"] for c, a in hosted if c == "add_uav"})
    added_faults = [dict(a["fault"]) for c, a in hosted if c == "add_fault"]
    for uid, name in join_names.items():
        names.setdefault(uid, name)
        types.setdefault(uid, spec_type.get(name, "?"))
    pose_uav = np.asarray(pose["uav"], dtype=np.int64)
    n_u = max([len(names)] + [int(pose_uav.max()) + 1 if len(pose_uav) else 0])
    for uid in range(n_u):
        names.setdefault(uid, f"U{uid}")
        types.setdefault(uid, "?")
    tg_id = np.asarray(tgt["target"], dtype=np.int64)
    n_tg = max(int(header.get("targets", 0)), int(tg_id.max()) + 1 if len(tg_id) else 0,
               max(found, default=-1) + 1)
    n_t = int(round(t_max / dt)) + 1

    x = np.full((n_t, n_u), np.nan)
    y = np.full((n_t, n_u), np.nan)
    theta = np.full((n_t, n_u), np.nan)
    mode = np.full((n_t, n_u), -1, dtype=np.int8)
    target = np.full((n_t, n_u), -1, dtype=np.int32)
    if len(pose_uav):
        ti = np.rint(np.asarray(pose["t"], dtype=float) / dt).astype(np.int64)
        x[ti, pose_uav] = pose["x"]
        y[ti, pose_uav] = pose["y"]
        theta[ti, pose_uav] = pose["theta"]
        mode[ti, pose_uav] = [MODE_CODES[m] for m in pose["mode"]]
        target[ti, pose_uav] = pose["target"]
    tx = np.full((n_t, n_tg), np.nan)
    ty = np.full((n_t, n_tg), np.nan)
    if len(tg_id):
        ti = np.rint(np.asarray(tgt["t"], dtype=float) / dt).astype(np.int64)
        tx[ti, tg_id] = tgt["x"]
        ty[ti, tg_id] = tgt["y"]
    found_t = np.full(n_tg, np.inf)
    for k, (t, _u) in found.items():
        found_t[k] = t

    def columns(source: dict[str, list[Any]], names_: tuple[str, ...], dtypes: tuple[Any, ...]) -> dict[str, np.ndarray]:
        out = {n: np.asarray(source[n], dtype=dt_) for n, dt_ in zip(names_, dtypes)}
        order = np.argsort(out["t"], kind="stable")
        return {n: a[order] for n, a in out.items()}

    causes: dict[str, int] = {}
    lost_cause = [causes.setdefault(cause, len(causes)) for cause in lost["cause"]]

    return Replay(
        header=header,
        scenario=scenario,
        dt=dt,
        duration=n_t * dt,
        names=[names[u] for u in range(n_u)],
        types=[types[u] for u in range(n_u)],
        x=x, y=y, theta=theta, mode=mode, target=target,
        target_x=tx, target_y=ty,
        found_t=found_t,
        found_by={k: u for k, (_t, u) in found.items()},
        crashes=crashes,
        joins=joins,
        handovers=handovers,
        landings=landings,
        launches=launches,
        violations=violations,
        rx=columns(rx, ("t", "src", "dst", "accepted"), (float, np.int32, np.int32, bool)),
        lost=columns({**lost, "cause": lost_cause}, ("t", "src", "dst", "cause"), (float, np.int32, np.int32, np.int16)),
        lost_causes=list(causes),
        faults=list(header.get("faults", [])) + added_faults,
    )


def fault_label(f: dict[str, Any]) -> str:
    """A short human label for one fault of the schedule (a ``start`` header entry)."""
    kind = f.get("kind", "?")
    if kind == "partition":
        label = "partition " + " | ".join(",".join(g) for g in f.get("groups", []))
        return label + (" (one-way)" if f.get("one_way") else "")
    if kind in ("drop", "duplicate", "corrupt"):
        label = f"{kind} {f.get('rate', 0):.0%}"
    elif kind == "burst":
        label = "burst loss"
    elif kind == "delay":
        label = f"delay +{f.get('extra_s', 0):g} s"
    else:
        label = kind
    if f.get("uavs"):
        label += " on " + ",".join(f["uavs"])
    if f.get("links"):
        label += " on " + ",".join(f"{a}\u2192{b}" for a, b in f["links"])
    return label


def fault_events(rp: Replay) -> list[tuple[float, str, str, int]]:
    """Every fault-related change, in time order: ``(t, text, kind, uid or -1)``.

    Windowed faults (drop, burst, delay, duplicate, corrupt, partition) from the ``start``
    header's schedule and the faults a host added (``host`` events) (start and end), crashes
    and late joins from their events.
    """
    out: list[tuple[float, str, str, int]] = []
    for f in rp.faults:
        kind = f.get("kind")
        if kind in ("crash", "join"):
            continue
        label = fault_label(f)
        out.append((float(f.get("start_s", 0.0)), label + (" begins" if kind == "partition" else " starts"),
                    str(kind), -1))
        end = f.get("end_s")
        if end is not None and end <= rp.duration:
            out.append((float(end), "partition healed" if kind == "partition" else label + " ends", f"{kind}-end", -1))
    for t, uid in rp.crashes:
        out.append((t, f"{rp.names[uid]} crashed", "crash", uid))
    for t, uid in rp.joins:
        if t > 0:
            out.append((t, f"{rp.names[uid]} joined", "join", uid))
    out.sort(key=lambda notice: notice[0])
    return out


class CoverageRaster:
    """The ground-truth scan map rebuilt from poses, stamped in time order.

    ``last_seen[row, col]`` is the time a cell was last inside some UAV's detection circle
    (``-inf``: never). :meth:`advance` stamps every tick up to a time; stamping is vectorised
    over all poses of the step (one index array per detection radius).
    """

    def __init__(self, replay: Replay):
        self.rp = replay
        self.width, self.height, self.cell = replay.area
        self.nx = int(round(self.width / self.cell))
        self.ny = int(round(self.height / self.cell))
        self.last_seen = np.full((self.ny, self.nx), -np.inf, dtype=np.float32)
        self._next_tick = 0
        radius = replay.detect_radius
        self._groups = [(float(r), np.flatnonzero(radius == r)) for r in np.unique(radius) if r > 0]

    @property
    def shape(self) -> tuple[int, int]:
        return (self.ny, self.nx)

    def coverage(self) -> float:
        return float(np.count_nonzero(self.last_seen > -np.inf)) / (self.nx * self.ny)

    def advance(self, t: float) -> np.ndarray:
        """Stamp every tick at or before ``t`` not stamped yet; returns ``last_seen``.

        Going back in time (an animation restarting) rebuilds from the start."""
        end = self.rp.tick_at(t) + 1 if t >= 0 else 0
        if end < self._next_tick:
            self.last_seen.fill(-np.inf)
            self._next_tick = 0
        if end > self._next_tick:
            stamp_poses(self.last_seen, self.rp, self._next_tick, end, self.cell, np.maximum, self._groups)
            self._next_tick = end
        return self.last_seen


def first_seen_map(replay: Replay) -> np.ndarray:
    """(ny, nx) float32: when each cell was first scanned (``inf``: never)."""
    w, h, c = replay.area
    out = np.full((int(round(h / c)), int(round(w / c))), np.inf, dtype=np.float32)
    radius = replay.detect_radius
    groups = [(float(r), np.flatnonzero(radius == r)) for r in np.unique(radius) if r > 0]
    stamp_poses(out, replay, 0, replay.n_ticks, c, np.minimum, groups)
    return out


def stamp_poses(grid_map: np.ndarray, rp: Replay, i0: int, i1: int, cell: float, op: np.ufunc,
                groups: list[tuple[float, np.ndarray]], chunk: int = 128) -> None:
    """Apply ``op`` (np.maximum / np.minimum) of each pose's time to the cells it scans, for
    ticks ``i0 <= i < i1``. Same rule as :meth:`agents.maps.grid.Grid.disk`: cell centres within
    the radius, cells outside the grid ignored."""
    ny, nx = grid_map.shape
    flat_map = grid_map.reshape(-1)
    times = (np.arange(i0, i1) * rp.dt)
    for radius, uids in groups:
        xs = rp.x[i0:i1][:, uids]
        ys = rp.y[i0:i1][:, uids]
        ts = np.broadcast_to(times[:, None], xs.shape)
        ok = np.isfinite(xs)
        xs, ys, ts = xs[ok], ys[ok], ts[ok]
        if len(xs) == 0:
            continue
        k = int(math.ceil(radius / cell)) + 1
        off = np.arange(-k, k + 1)
        r2 = radius * radius
        for s in range(0, len(xs), chunk):
            px, py, pt = xs[s:s + chunk], ys[s:s + chunk], ts[s:s + chunk]
            ix = np.floor(px / cell).astype(np.int64)[:, None] + off[None, :]  # (p, K)
            iy = np.floor(py / cell).astype(np.int64)[:, None] + off[None, :]
            dx = (ix + 0.5) * cell - px[:, None]
            dy = (iy + 0.5) * cell - py[:, None]
            inside = (dy[:, :, None] ** 2 + dx[:, None, :] ** 2) <= r2  # (p, Ky, Kx)
            inside &= ((ix >= 0) & (ix < nx))[:, None, :]
            inside &= ((iy >= 0) & (iy < ny))[:, :, None]
            p_idx, ky, kx = np.nonzero(inside)
            flat = iy[p_idx, ky] * nx + ix[p_idx, kx]
            op.at(flat_map, flat, pt[p_idx].astype(flat_map.dtype))
