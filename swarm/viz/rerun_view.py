"""A run recorded for the rerun viewer (issue 26, item 6; extra ``view``: ``rerun-sdk``).

:func:`record` writes an ``.rrd`` recording of a finished run, rebuilt from its event log and
scenario (:func:`swarm.viz.replay.replay_from_bytes`), on one timeline ``sim_time``
(simulated seconds; nothing of the wall clock): entities

* ``world/uavs`` (points, one per flying UAV: label = name, colour by type) and
  ``world/detection`` (the same points with their detection radius: the discs), every tick;
* ``world/paths`` (each UAV's track so far), ``world/targets`` (points) and
  ``world/radio`` (the links that delivered a frame that tick), every ``every_s``;
* ``world/zones`` (static: circular threats as polygons, no-fly polygons, the area polygon);
* ``world/coverage`` (an image: the swarm's union of scanned cells, grey = seen), every
  ``coverage_every_s``;
* ``events`` (text, one row per ``found``, ``handover``, ``release``, ``crash``, ``join``,
  ``restart``, ``rtb``, ``landed``, ``launched``, ``energy_out``, ``violation`` event) and
  ``faults`` (text: each fault window's start and end).

Coordinates are the run's local metres (x east, y north), the viewer's 2-D space; a
geographic run's lon/lat are in its GeoJSON files. ``swarm view RUN_FOLDER`` opens
``RUN_FOLDER/run.rrd`` (or the one ``--rerun`` wrote there).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["EVENT_KINDS", "record"]

# The events written to the ``events`` text log.
EVENT_KINDS = ("found", "handover", "release", "crash", "join", "restart", "rtb", "landed", "launched", "energy_out",
               "violation")
_TYPE_COLOURS = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189)]


def _rr() -> Any:
    try:
        import rerun as rr
    except ImportError:  # pragma: no cover (the extra is installed where this is called)
        from swarm.errors import UsageError

        raise UsageError("--rerun needs the rerun SDK: pip install 'uav-swarm-sim[view]'") from None
    return rr


def record(events: bytes, scenario: Mapping[str, Any], path: str | Path, *, every_s: float = 5.0,
           coverage_every_s: float = 30.0) -> Path:
    """Write the run (its event log ``events`` and ``scenario`` as ``scenario.json`` holds it)
    to the rerun recording ``path``; returns the path."""
    from swarm.events import read_events
    from swarm.viz.replay import CoverageRaster, replay_from_bytes

    rr = _rr()
    rp = replay_from_bytes(events, dict(scenario))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream("uav-swarm-sim", recording_id=f"{scenario.get('name', 'run')}-{scenario.get('seed', 0)}")
    rec.save(str(path))
    types = sorted(set(rp.types))
    colour = [_TYPE_COLOURS[types.index(t) % len(_TYPE_COLOURS)] for t in rp.types]
    radius = rp.detect_radius
    w, h, cell = rp.area
    rec.log("world/zones", _zones(rr, scenario), static=True)
    rec.log("world/area", rr.Boxes2D(mins=[[0.0, 0.0]], sizes=[[w, h]], labels=["area"]), static=True)
    every = max(1, round(every_s / rp.dt))
    cov_every = max(1, round(coverage_every_s / rp.dt))
    raster = CoverageRaster(rp)
    rx_t = rp.rx.get("t", np.zeros(0))
    rx_src, rx_dst = rp.rx.get("src", np.zeros(0, int)), rp.rx.get("dst", np.zeros(0, int))
    rx_ok = rp.rx.get("accepted", np.ones(len(rx_t), bool))
    ticks = rp.times
    for i, t in enumerate(ticks.tolist()):
        rec.set_time("sim_time", duration=t)
        flying = np.flatnonzero(np.isfinite(rp.x[i]))
        pos = np.column_stack([rp.x[i, flying], rp.y[i, flying]])
        rec.log("world/uavs", rr.Points2D(pos, labels=[rp.names[k] for k in flying],
                                          colors=[colour[k] for k in flying], radii=150.0))
        rec.log("world/detection", rr.Points2D(pos, radii=radius[flying], colors=[(*colour[k], 40) for k in flying]))
        if i % every == 0:
            strips = [np.column_stack([rp.x[: i + 1, k], rp.y[: i + 1, k]])[np.isfinite(rp.x[: i + 1, k])]
                      for k in range(rp.n_uavs)]
            rec.log("world/paths", rr.LineStrips2D([s for s in strips if len(s) > 1] or [[[0.0, 0.0], [0.0, 0.0]]],
                                                   colors=[colour[k] for k, s in enumerate(strips) if len(s) > 1] or None))
            tx, ty = rp.target_x[i], rp.target_y[i]
            live = np.flatnonzero(np.isfinite(tx))
            rec.log("world/targets", rr.Points2D(np.column_stack([tx[live], ty[live]]), labels=[f"T{k}" for k in live],
                                                 colors=[(0, 0, 0)] * len(live), radii=200.0))
            sel = (np.abs(rx_t - t) < 1e-9) & rx_ok
            pairs = sorted({(int(a), int(b)) for a, b in zip(rx_src[sel], rx_dst[sel]) if a >= 0})
            segs = [[[rp.x[i, a], rp.y[i, a]], [rp.x[i, b], rp.y[i, b]]] for a, b in pairs
                    if math.isfinite(rp.x[i, a]) and math.isfinite(rp.x[i, b])]
            rec.log("world/radio", rr.LineStrips2D(segs or [[[0.0, 0.0], [0.0, 0.0]]], radii=20.0))
        if i % cov_every == 0 or i == len(ticks) - 1:
            seen = raster.advance(t) > -np.inf
            img = np.where(seen, 180, 255).astype(np.uint8)[::-1]  # north up
            rec.log("world/coverage", rr.Image(img))
    for e in read_events(events):
        if e.kind in EVENT_KINDS:
            rec.set_time("sim_time", duration=float(e.t))
            fields = {f.name: getattr(e, f.name) for f in dataclasses.fields(e) if f.name != "t"}
            text = f"{e.kind} " + " ".join(f"{k}={v}" for k, v in fields.items())
            level = "WARN" if e.kind in ("crash", "violation", "energy_out") else "INFO"
            rec.log("events", rr.TextLog(text, level=level))
    for f in rp.faults:
        start = float(f.get("start_s", f.get("at_s", 0.0)) or 0.0)
        end = f.get("end_s")
        rec.set_time("sim_time", duration=start)
        rec.log("faults", rr.TextLog(f"{f.get('kind')} starts: {f}", level="WARN"))
        if end is not None and math.isfinite(float(end)):
            rec.set_time("sim_time", duration=float(end))
            rec.log("faults", rr.TextLog(f"{f.get('kind')} ends", level="INFO"))
    rec.flush()
    del rec
    return path


def _zones(rr: Any, scenario: Mapping[str, Any]) -> Any:
    strips: list[Any] = []
    for th in scenario.get("threats") or []:
        a = np.linspace(0.0, 2.0 * math.pi, 73)
        strips.append(np.column_stack([th["x_m"] + th["radius_m"] * np.cos(a), th["y_m"] + th["radius_m"] * np.sin(a)]))
    if scenario.get("geo") or scenario.get("no_fly"):
        from swarm.geo.geojson import run_frame

        frame = run_frame(scenario)
        if frame is not None:
            strips.append(np.asarray(frame.area))
        for z in scenario.get("no_fly") or []:
            ring = np.asarray(z["polygon"], dtype=float)
            strips.append(frame.ring_to_local(ring) if frame is not None else ring)
    return rr.LineStrips2D(strips or [[[0.0, 0.0], [0.0, 0.0]]], colors=[(200, 0, 0)] * max(1, len(strips)))


def entity_rows(path: str | Path) -> dict[str, int]:
    """Rows per entity path of a recording, read back with rerun's own reader (tests, ``swarm view``)."""
    import rerun.chunk as chunk

    rows: dict[str, int] = {}
    for c in chunk.RrdReader(str(path)).store().stream().to_chunks():
        if not c.is_static or c.entity_path.startswith("/world"):
            rows[c.entity_path] = rows.get(c.entity_path, 0) + c.num_rows
    return rows
