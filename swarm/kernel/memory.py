"""How much memory a scenario will need, estimated before anything is allocated.

A mistyped ``area.cell_m`` (1 m instead of 100 m) turns a 50 km square into 2.5e9 cells: the
run would allocate tens of GB and be killed by the kernel without a word. The simulation
therefore estimates its memory from the scenario and refuses, with one error naming the
settings that drive it, above a limit (by default half of this machine's physical memory; set
``SWARM_MEMORY_LIMIT_GB``, ``swarm run --memory-limit GB`` or ``Simulation(memory_limit_gb=...)``).

The estimate is an upper bound of the big arrays, not of Python's overhead:

* the ground truth: one dense float32 last-seen map of every cell, and (on large grids) one
  float32 buffer of q for certainty (eq. 8): 8 bytes a cell;
* the UAVs' own maps: shared storage on dense grids (up to 2**20 cells: one base plus a little
  per UAV; a dense map each when a knowledge horizon keeps them apart:
  :func:`agents.maps.mapgroup.maps_share`); on larger grids, 64 x 64-cell float32 tiles allocated where a map was written: a
  UAV's own swath over the run plus the swaths of the UAVs it can hear (within radio range),
  at most the whole grid, rounded up to whole tiles;
* DACMP's maintained pyramids (:mod:`agents.planners.dacmp.maintained`), one per UAV map:
  float32 ``E`` and levels 1..L, dense on dense grids (4 + 4/3 bytes a cell per UAV), else
  levels only (``E`` is read from the map), in tiles near what the map has seen: at most
  :data:`PYRAMID_PER_MAP_BYTE` bytes per byte of the UAV's map tiles (measured: 0.38 on
  bench-100), plus the particles' windows of one batch
  (every UAV's levels within ``ring_max_factor`` detection radii of it, float32);
* per UAV, a mailbox of the frames of one tick (one from each UAV it hears, at most
  ``radio.mailbox_capacity``, of a typical size);
* what the run records of every target every tick (issue 25: a million targets are a million
  ``target`` events a tick): its event (about 40 bytes of the in-memory log, and as much again
  in the result's copy of it), its position in the observer's per-tick array (16 bytes) and in
  the result's paths (24 bytes); likewise a
  UAV's ``pose`` event and path row (counted at 160 bytes: Python floats).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from agents.maps.mapgroup import maps_share
from agents.maps.umap import DEFAULT_TILE as _TILE
from agents.maps.umap import DENSE_MAX_CELLS as _DENSE_MAX_CELLS
from swarm.errors import SwarmError
from swarm.scenario import Scenario

__all__ = ["MemoryEstimate", "MemoryLimitError", "check_memory", "default_limit_bytes", "estimate_memory", "format_bytes"]

_GB = 1024**3
_TYPICAL_FRAME_BYTES = 512  # a beacon (hello, intent, a few scans) is 150-400 bytes
# Bytes of a tiled map's maintained DACMP pyramid per byte of the map's tiles: its levels (E is
# not stored), a third of the map's cells or more (their tiles reach one cell past the seen
# ones). Counted generously (bench-100 measures 0.38 after 200 s).
PYRAMID_PER_MAP_BYTE = 0.75
# Recorded per target and per UAV each tick (see the module docstring): a target's event in the
# log (36-40 bytes of msgpack, twice: the log and the result's copy of its bytes), its position
# in the observer's array and in the result's paths (measured: 121 bytes a target-tick of peak
# RSS with 10^5 targets over paper-case1's 600 s).
_TARGET_TICK_BYTES = 128
_UAV_TICK_BYTES = 160


class MemoryLimitError(SwarmError, MemoryError):
    """A scenario would need more memory than the limit allows."""


@dataclass(frozen=True)
class MemoryEstimate:
    cells: int
    parts: dict[str, float]  # bytes by what needs them

    @property
    def total(self) -> float:
        return sum(self.parts.values())


def estimate_memory(sc: Scenario) -> MemoryEstimate:
    """An upper bound of the run's big arrays, in bytes, by part (see the module docstring)."""
    nx = math.ceil(sc.area.width_m / sc.area.cell_m)
    ny = math.ceil(sc.area.height_m / sc.area.cell_m)
    cells = nx * ny
    n = len(sc.uavs)
    parts: dict[str, float] = {"ground truth (8 B a cell)": 8.0 * cells}
    if maps_share(cells, sc.area.width_m, sc.area.height_m, sc.radio.horizon_m):
        # MapGroup: one shared base; members differ by a few scans each (counted generously).
        parts["UAV maps (shared storage)"] = 4.0 * cells * (1 + 0.05 * n)
    elif cells <= _DENSE_MAX_CELLS:
        parts["UAV maps (dense, one each)"] = 4.0 * cells * n
    else:
        area = sc.area.width_m * sc.area.height_m
        range_m = sc.radio.range_limit_m
        heard_share = 1.0 if not math.isfinite(range_m) else min(1.0, math.pi * range_m**2 / area)
        tile_cells = _TILE * _TILE
        tiles_total = math.ceil(nx / _TILE) * math.ceil(ny / _TILE)
        total = 0.0
        for u in sc.uavs:
            t = sc.uav_types[u.type]
            flown = max(0.0, sc.duration_s - (u.join_s or 0.0))
            swath_m2 = 2 * t.detect_radius_m * t.speed_max * flown + math.pi * t.detect_radius_m**2
            # a band of swath 2 R_s touches tiles on a band (2 R_s + one tile) wide
            band_factor = (2 * t.detect_radius_m + _TILE * sc.area.cell_m) / (2 * t.detect_radius_m)
            own_tiles = swath_m2 * band_factor / (sc.area.cell_m**2 * tile_cells)
            heard = 1.0 + (n - 1) * heard_share
            total += min(float(tiles_total), own_tiles * heard) * tile_cells * 4.0
        parts["UAV maps (tiles)"] = total
    if sc.planner.name == "dacmp":
        if cells <= _DENSE_MAX_CELLS:
            parts["DACMP pyramids (dense, 16/3 B a cell per UAV)"] = n * cells * 16.0 / 3.0
        else:
            parts["DACMP pyramids (tiles)"] = PYRAMID_PER_MAP_BYTE * parts["UAV maps (tiles)"]
        # Every UAV replans at t = 0, in one batch: its levels in a window of side 2 r_max + a
        # margin (level l: that over 2**l cells a side, at least a few cells).
        ring = float(sc.planner.dacmp.ring_max_factor)
        window = 0.0
        for u in sc.uavs:
            side = 2 * ring * sc.uav_types[u.type].detect_radius_m / sc.area.cell_m + 4
            window += sum(4.0 * (side / 2**l + 3) ** 2 for l in range(1, sc.map.levels + 1))
        parts["DACMP particle windows of one batch"] = window
    # Mailboxes are drained every tick: at most a frame from each other UAV, of a typical size.
    parts["mailboxes"] = float(n * min(sc.radio.mailbox_capacity, n) * _TYPICAL_FRAME_BYTES)
    ticks = math.ceil(sc.duration_s / sc.dt_s) if sc.dt_s > 0 else 0
    targets = len(sc.targets.placed) + sc.targets.count
    if targets:
        parts[f"target events and paths ({_TARGET_TICK_BYTES} B a target a tick)"] = float(
            _TARGET_TICK_BYTES * targets * ticks)
    parts[f"UAV events and paths ({_UAV_TICK_BYTES} B a UAV a tick)"] = float(_UAV_TICK_BYTES * n * ticks)
    return MemoryEstimate(cells, parts)


def format_bytes(n: float) -> str:
    """A size for a person: ``512 B``, ``10.2 MB``, ``1.5 GB``, ``3.2e+285 TB`` (binary units,
    1 KB = 1024 B; three significant digits)."""
    if not math.isfinite(n):
        return f"{n} B"
    for unit in ("B", "KB", "MB", "GB"):
        if abs(n) < 1024:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} TB" if abs(n) < 1e4 else f"{n:.2e} TB"


def _physical_memory() -> int | None:
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # not POSIX
        return None


def default_limit_bytes() -> float:
    """``SWARM_MEMORY_LIMIT_GB`` if set, else half of the physical memory (16 GB if unknown)."""
    env = os.environ.get("SWARM_MEMORY_LIMIT_GB")
    if env:
        try:
            value = float(env)
        except ValueError:
            raise MemoryLimitError(f"SWARM_MEMORY_LIMIT_GB={env!r}: expected a number of GB") from None
        if not value > 0:
            raise MemoryLimitError(f"SWARM_MEMORY_LIMIT_GB={env!r}: expected a positive number of GB")
        return value * _GB
    physical = _physical_memory()
    return physical / 2 if physical else 16.0 * _GB


def check_memory(sc: Scenario, limit_gb: float | None = None) -> MemoryEstimate:
    """The estimate, or :class:`MemoryLimitError` if it is above the limit."""
    est = estimate_memory(sc)
    limit = default_limit_bytes() if limit_gb is None else limit_gb * _GB
    if est.total > limit:
        biggest = ", ".join(f"{name} {format_bytes(b)}" for name, b in sorted(est.parts.items(), key=lambda p: -p[1])[:3])
        cells = f"{est.cells:,}" if est.cells < 10**12 else f"{float(est.cells):.3g}"
        raise MemoryLimitError(
            f"scenario {sc.name!r} would need about {format_bytes(est.total)} ({biggest}), above the limit of "
            f"{format_bytes(limit)}: it has {cells} cells (area.width_m {sc.area.width_m:g} x area.height_m "
            f"{sc.area.height_m:g} at area.cell_m {sc.area.cell_m:g}), {len(sc.uavs)} UAVs and "
            f"{len(sc.targets.placed) + sc.targets.count:,} targets (targets.count) over duration_s "
            f"{sc.duration_s:g}; use a larger area.cell_m or a smaller area, fewer targets or UAVs or a shorter "
            f"duration_s, or raise the limit (--memory-limit GB, SWARM_MEMORY_LIMIT_GB)")
    return est
