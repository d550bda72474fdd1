"""An animation of a finished run, rebuilt from its folder (``events.msgpack`` + ``scenario.json``).

Each frame shows, at one simulated time:

* the ground-truth scan map as a heat map: cells scanned so far by anyone, coloured by how
  fresh the scan is (``exp(-tau * age)``, the map certainty of eq. 8); never-scanned cells
  white. It is rebuilt incrementally from the ``pose`` events and each type's detection radius
  (:class:`swarm.viz.replay.CoverageRaster`);
* UAVs (one colour each, one marker per type: :func:`swarm.viz.style.type_marker`), their
  trails, detection circles, wrecks;
* targets: unknown (hollow), found, watched (by a UAV in surveillance mode);
* the no-fly zones (circles and polygons: filled, influence dotted), the area polygon (outside
  shaded) and the base (swarm.viz.hazards);
* radio links of the range graph between flying UAVs: working (grey), losing more than half
  of their copies in the last frame interval (orange, from ``rx`` / ``lost`` events), cut by an
  active partition (red dashed); a crashed UAV has no links from its crash on;
* a clock, running coverage / targets found / UAVs flying, the faults currently active, and
  fault events (schedule changes from the ``start`` header, crash and join events) flashed as
  they fire: a banner of the recent ones with their times (``t=200 s: B2 crashed``, newest
  first, those of the last :data:`FLASH_MAX_S` simulated seconds), a red border, rings at
  the UAV.

Frame ``k`` shows time ``k * speed / fps`` (``speed``: simulated seconds per second of video),
so a run of ``D`` seconds gives ``floor(D * fps / speed) + 1`` frames. Saved through
matplotlib's animation writers: ``FFMpegWriter`` for ``.mp4`` (needs ``ffmpeg`` on PATH) and
``PillowWriter`` for ``.gif``. Artists are created once and updated in place (``FuncAnimation``
with ``blit=True``). Library code never prints: progress goes to an optional callback.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
from matplotlib import colormaps
from matplotlib.animation import FFMpegWriter, FuncAnimation, PillowWriter
from matplotlib.artist import Artist
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import EllipseCollection, LineCollection
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from PIL import Image

from comms.messages import MODE_SURVEIL
from swarm.errors import SwarmError
from swarm.outputs import atomic_path
from swarm.viz.hazards import draw_hazards, hazards_of
from swarm.viz.replay import (
    CoverageRaster,
    Replay,
    check_run_dir,
    fault_events,
    fault_label,
    load_run,
)
from swarm.viz.style import (
    CRASH_MARKER,
    TARGET_FOUND_COLOUR,
    km_axes,
    line_width,
    many_uavs,
    natural_key,
    type_markers,
    uav_colours,
)

DEFAULT_FPS = 10
DEFAULT_SPEED = 60.0  # simulated seconds per second of video: a 2000 s run -> 33 s clip
DEFAULT_TRAIL_S = 300.0
DEFAULT_DPI = 80
FLASH_VIDEO_S = 2.0  # how long (video seconds) a fault event stays flashed ...
FLASH_MAX_S = 60.0  # ... but at most this many simulated seconds (and at least two frames)
BANNER_LINES = 3  # the newest events shown in the banner
LOSSY_FRACTION = 0.5
_TRAIL_POINTS = 120  # at most this many points per trail (decimated)


class AnimateError(SwarmError, ValueError):
    """The animation cannot be made as asked (bad option, missing encoder)."""


def banner_text(events: list[tuple[float, str, str, int]], lines: int = BANNER_LINES) -> str:
    """The newest ``lines`` of ``events`` (``(t, text, kind, uid)`` in time order), newest first,
    each with its time: ``t=200 s: B2 crashed``."""
    return "\n".join(f"t={t:.0f} s: {text}" for t, text, _kind, _uid in events[-lines:][::-1])


def ffmpeg_available() -> bool:
    return FFMpegWriter.isAvailable()


def frame_times(duration: float, speed: float, fps: float) -> np.ndarray:
    """Simulated time of each frame: ``k * speed / fps`` for every ``k`` up to ``duration``."""
    step = speed / fps
    n = int(math.floor(duration / step + 1e-9)) + 1
    return np.arange(n) * step


def default_animation_path(run_dir: str | Path) -> Path:
    """``RUN_DIR/animation.mp4`` when ffmpeg is available, else ``RUN_DIR/animation.gif``."""
    return Path(run_dir) / ("animation.mp4" if ffmpeg_available() else "animation.gif")


class _BlitGifWriter(PillowWriter):
    """PillowWriter that takes each frame from the scene's blitted canvas (see
    :meth:`_Scene.frame_rgba`) and palettises it at once (1 byte per pixel in memory instead of
    3, so a few hundred frames stay small; a GIF is palettised anyway)."""

    def __init__(self, scene: _Scene, fps: float):
        super().__init__(fps=fps)  # type: ignore[arg-type]  # the stubs say int; any positive fps works
        self.scene = scene

    def grab_frame(self, **savefig_kwargs: Any) -> None:
        w, h = self.scene.fig.canvas.get_width_height()
        im = Image.frombuffer("RGBA", (w, h), self.scene.frame_rgba(), "raw", "RGBA", 0, 1)  # type: ignore[arg-type]
        frame = im.convert("RGB").quantize(colors=255, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
        self._frames.append(frame)  # type: ignore[attr-defined]  # PillowWriter's own frame list


class _BlitMp4Writer(FFMpegWriter):
    """FFMpegWriter fed raw RGBA frames from the scene's blitted canvas."""

    def __init__(self, scene: _Scene, fps: float, **kwargs: Any):
        super().__init__(fps=fps, **kwargs)  # type: ignore[arg-type]  # as above
        self.scene = scene

    def grab_frame(self, **savefig_kwargs: Any) -> None:
        self._proc.stdin.write(bytes(self.scene.frame_rgba()))  # type: ignore[attr-defined]  # MovieWriter's pipe


class _Scene:
    """The figure and its artists; :meth:`update` moves everything to frame ``k``."""

    def __init__(self, rp: Replay, times: np.ndarray, fps: float, speed: float, trail_s: float, dpi: float):
        self.rp = rp
        self.times = times
        self.step = speed / fps
        self.flash_s = max(min(FLASH_VIDEO_S * speed, FLASH_MAX_S), 2 * self.step)
        self.trail_ticks = max(1, int(round(trail_s / rp.dt)))
        self.raster = CoverageRaster(rp)
        self.tau = rp.tau
        self.range = rp.radio_range
        self.radius = rp.detect_radius
        n = rp.n_uavs
        self.colours = uav_colours(rp.names)
        self.col = np.array([self.colours[nm] for nm in rp.names]).reshape(-1, 4)
        self.markers = type_markers(rp.types)
        self.many = many_uavs(n)
        self.lw = line_width(n, 1.2)
        self.events = fault_events(rp)
        self.crash_t = {uid: t for t, uid in rp.crashes}
        self.wreck = {uid: rp.last_position(uid, rp.tick_at(t)) for t, uid in rp.crashes}
        # Partitions as group-index arrays over UAV ids.
        index = {nm: u for u, nm in enumerate(rp.names)}
        self.partitions = []
        for f in rp.faults:
            if f.get("kind") == "partition":
                g = np.full(n, -1)
                for gi, group in enumerate(f.get("groups", [])):
                    for nm in group:
                        if nm in index:
                            g[index[nm]] = gi
                end = f.get("end_s")
                self.partitions.append((float(f.get("start_s", 0.0)), math.inf if end is None else float(end), g))
        self.windowed = [(float(f.get("start_s", 0.0)), math.inf if f.get("end_s") is None else float(f["end_s"]),
                          fault_label(f)) for f in rp.faults if f.get("kind") not in ("crash", "join")]
        self._build(dpi)

    # --- construction -----------------------------------------------------------------------
    def _build(self, dpi: float) -> None:
        rp = self.rp
        w, h, _c = rp.area
        fig = Figure(figsize=(10.0, 7.5), dpi=dpi)
        FigureCanvasAgg(fig)
        # No GUI here: Animation.save's per-frame draw_idle would re-render the whole figure for nothing
        # (frames come from frame_rgba).
        fig.canvas.draw_idle = lambda *a, **k: None  # type: ignore[method-assign]
        self.fig = fig
        self._background: Any = None  # the Agg canvas's saved region
        self._background_size: tuple[int, int] | None = None
        ax = fig.add_axes((0.07, 0.08, 0.62, 0.84))
        self.ax = ax
        km_axes(ax, w, h)
        ax.set_title(f"{rp.header.get('scenario', '?')} · {rp.header.get('planner', '?')} · "
                     f"seed {rp.header.get('seed', '?')}", fontsize=10)
        # A light slice of a sequential map: fresh scans stand out, UAV colours stay readable.
        cmap = ListedColormap(colormaps["PuBu"](np.linspace(0.08, 0.62, 256))).with_extremes(bad="white")
        img = np.full(self.raster.shape, np.nan, dtype=np.float32)
        self.image = ax.imshow(img, origin="lower", extent=(0, w, 0, h), cmap=cmap, vmin=0.0, vmax=1.0,
                               interpolation="nearest", zorder=0)
        cax = fig.add_axes((0.73, 0.09, 0.22, 0.022))
        cb = fig.colorbar(self.image, cax=cax, orientation="horizontal")
        cb.set_ticks([0, 0.5, 1.0])
        cb.ax.tick_params(labelsize=7)
        cb.set_label("scan freshness exp(\u2212\u03c4\u00b7age); white: never scanned", fontsize=7)
        # The no-fly zones, the area polygon and the base (swarm.viz.hazards): over the heat map.
        self.threat_patches, self.hazard_handles = draw_hazards(ax, hazards_of(rp.scenario, rp.threats))

        self.links_ok = LineCollection([], colors=[(0.35, 0.35, 0.35, 0.45)], linewidths=0.7 if not self.many else 0.3,
                                       zorder=2)
        self.links_lossy = LineCollection([], colors=["#ff8c00"], linewidths=1.2 if not self.many else 0.6, zorder=2)
        self.links_cut = LineCollection([], colors=["#d62728"], linewidths=1.4 if not self.many else 0.7,
                                        linestyles="--", zorder=2)
        for lc in (self.links_ok, self.links_lossy, self.links_cut):
            ax.add_collection(lc)
        self.trails = LineCollection([], linewidths=self.lw, zorder=3)
        ax.add_collection(self.trails)
        n = rp.n_uavs
        self.circles = EllipseCollection(np.zeros(n), np.zeros(n), np.zeros(n), units="xy",
                                         offsets=np.zeros((n, 2)), offset_transform=ax.transData,
                                         facecolors="none", edgecolors=self.col, linewidths=0.8, zorder=3)
        ax.add_collection(self.circles)
        size = 40 if not self.many else 16
        self.uav_scatters = {}
        for typ, marker in self.markers.items():
            self.uav_scatters[typ] = ax.scatter([], [], s=size, marker=marker, edgecolors="black",
                                                linewidths=0.5, zorder=5)
        self.type_ids = {typ: np.array([u for u, t in enumerate(rp.types) if t == typ], dtype=int)
                         for typ in self.markers}
        self.wrecks = ax.scatter([], [], s=size * 1.5, marker=CRASH_MARKER, c="black", edgecolors="white",
                                 linewidths=0.6, zorder=5)
        self.targets = ax.scatter([], [], s=70, marker="*", linewidths=0.8, zorder=6)
        self.rings = ax.scatter([], [], s=900, facecolors="none", linewidths=2.0, zorder=7)
        self.clock = ax.text(0.015, 0.985, "", transform=ax.transAxes, va="top", ha="left", fontsize=11,
                             family="monospace", zorder=8,
                             bbox=dict(boxstyle="round,pad=0.3", fc="white", ec="0.5", alpha=0.85))
        self.banner = ax.text(0.5, 0.06, "", transform=ax.transAxes, va="bottom", ha="center", fontsize=11,
                              color="white", weight="bold", zorder=9,
                              bbox=dict(boxstyle="round,pad=0.35", fc="#d62728", ec="none", alpha=0.9))
        self.border = Rectangle((0, 0), 1, 1, transform=ax.transAxes, fill=False, ec="#d62728", lw=5, zorder=9,
                                clip_on=False, visible=False)
        ax.add_patch(self.border)
        self.active = fig.text(0.71, 0.16, "", fontsize=7.5, va="bottom", ha="left", wrap=True)
        self._legend()

    def _legend(self) -> None:
        rp = self.rp
        handles: list[Artist] = []
        if self.many:
            for typ, marker in self.markers.items():
                count = int(np.count_nonzero(np.array(rp.types) == typ))
                handles.append(Line2D([], [], ls="", marker=marker, color="0.3", mec="black",
                                      label=f"type {typ} UAVs ({count})"))
        else:
            for u in sorted(range(rp.n_uavs), key=lambda u: natural_key(rp.names[u])):
                handles.append(Line2D([], [], ls="-", lw=self.lw, marker=self.markers[rp.types[u]],
                                      color=self.colours[rp.names[u]], mec="black",
                                      label=f"{rp.names[u]} ({rp.types[u]})"))
        handles += [
            Line2D([], [], ls="", marker=CRASH_MARKER, color="black", mec="white", label="crashed UAV"),
            Line2D([], [], ls="", marker="o", mfc="none", color="0.3", ms=9, label="detection radius"),
            Line2D([], [], ls="", marker="*", mfc="white", mec="0.3", ms=10, label="target, not found"),
            Line2D([], [], ls="", marker="*", mfc=TARGET_FOUND_COLOUR, mec="black", ms=10, label="target found"),
            Line2D([], [], ls="", marker="*", mfc="#2ca02c", mec="black", ms=12, label="target watched"),
            Line2D([], [], color="0.35", lw=1, label="radio link"),
            Line2D([], [], color="#ff8c00", lw=1.5, label=f"link losing >{LOSSY_FRACTION:.0%}"),
            Line2D([], [], color="#d62728", lw=1.5, ls="--", label="link cut (partition)"),
        ]
        handles += self.hazard_handles
        self.fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.71, 0.93), fontsize=7.5,
                        ncol=1 if len(handles) <= 24 else 2, frameon=False)

    # --- per frame --------------------------------------------------------------------------
    def artists(self) -> list[Any]:
        return [self.image, self.links_ok, self.links_lossy, self.links_cut, self.trails, self.circles,
                *self.uav_scatters.values(), self.wrecks, self.targets, self.rings, self.clock, self.banner,
                self.border, self.active]

    def init(self) -> list[Any]:
        return self.artists()

    def _drawn(self) -> list[Any]:
        """Every artist drawn per frame, bottom to top: the animated ones, plus the threats and
        the axes frame, which lie over or under the heat map and so cannot be background."""
        arts = self.artists() + self.threat_patches + list(self.ax.spines.values())
        return sorted(arts, key=lambda a: a.get_zorder())

    def frame_rgba(self) -> memoryview:
        """The current frame as RGBA bytes: the static background (axes, ticks, legend, colour
        bar: drawn once) restored, then only the changing artists drawn over it (blitting)."""
        canvas = cast(FigureCanvasAgg, self.fig.canvas)  # attached in _build
        size = canvas.get_width_height()
        if self._background is None or self._background_size != size:
            drawn = self._drawn()
            shown = [a.get_visible() for a in drawn]
            for a in drawn:
                a.set_visible(False)
            canvas.draw()  # type: ignore[no-untyped-call]  # (matplotlib's Agg canvas: unannotated)
            self._background = canvas.copy_from_bbox(self.fig.bbox)  # type: ignore[no-untyped-call]  # (as above)
            self._background_size = size
            for a, v in zip(drawn, shown):
                a.set_visible(v)
        canvas.restore_region(self._background)  # type: ignore[no-untyped-call]  # (as above)
        for a in self._drawn():
            self.fig.draw_artist(a)
        return canvas.buffer_rgba()  # type: ignore[no-untyped-call, no-any-return]  # (as above)

    def update(self, k: int) -> list[Any]:
        rp = self.rp
        t = float(self.times[k])
        i = rp.tick_at(t)
        n = rp.n_uavs

        ls = self.raster.advance(t)
        with np.errstate(invalid="ignore", over="ignore"):
            fresh = np.exp(-self.tau * (t - ls))  # -inf last_seen -> exp(-inf) = 0 ...
        fresh[ls == -np.inf] = np.nan  # ... but never-scanned cells are drawn white
        self.image.set_data(fresh)

        x, y = rp.x[i], rp.y[i]
        crashed = np.array([u in self.crash_t and self.crash_t[u] <= t + 1e-9 for u in range(n)], dtype=bool)
        flying = np.isfinite(x) & ~crashed  # a UAV that crashed during the tick shown is down
        pos = np.column_stack([np.nan_to_num(x), np.nan_to_num(y)])

        for typ, sc in self.uav_scatters.items():
            ids = self.type_ids[typ]
            ids = ids[flying[ids]]
            sc.set_offsets(pos[ids] if len(ids) else np.empty((0, 2)))
            sc.set_facecolor(self.col[ids] if len(ids) else np.empty((0, 4)))  # type: ignore[arg-type]  # RGBA rows
        wreck_ids = [u for u in np.flatnonzero(crashed).tolist() if self.wreck.get(u) is not None]
        self.wrecks.set_offsets(np.array([self.wreck[u] for u in wreck_ids]).reshape(-1, 2))

        d = np.where(flying, 2 * self.radius, 0.0)
        self.circles.set_offsets(pos)
        self.circles.set_widths(d)
        self.circles.set_heights(d)

        # Trails: the last trail_s seconds of every UAV that has flown, decimated.
        i0 = max(0, i - self.trail_ticks)
        stride = max(1, (i + 1 - i0) // _TRAIL_POINTS)
        segs, cols = [], []
        xs = rp.x[i0:i + 1:stride]
        ys = rp.y[i0:i + 1:stride]
        for u in range(n):
            ok = np.isfinite(xs[:, u])
            if np.count_nonzero(ok) >= 2:
                seg = np.column_stack([xs[ok, u], ys[ok, u]])
                if flying[u]:
                    seg = np.vstack([seg, pos[u]])
                segs.append(seg)
                cols.append(self.col[u])
        self.trails.set_segments(segs)
        self.trails.set_colors(cols if cols else [(0, 0, 0, 0)])

        self._links(t, flying, pos)
        self._targets(t, i, flying)
        coverage = self.raster.coverage()
        found = int(np.count_nonzero(rp.found_t <= t + 1e-9))
        self.clock.set_text(f"t = {t:6.0f} s  ({int(t // 60):d}:{int(t % 60):02d})\n"
                            f"coverage {coverage:.3f}\n"
                            f"targets  {found}/{rp.n_targets}\n"
                            f"flying   {int(flying.sum())}/{n}")
        self._faults(t, pos, flying)
        return self.artists()

    def _links(self, t: float, flying: np.ndarray, pos: np.ndarray) -> None:
        """Links between flying UAVs in range (a crashed UAV is not flying: no link to it)."""
        rp = self.rp
        n = rp.n_uavs
        alive = np.flatnonzero(flying)
        ok_segs = np.empty((0, 2, 2))
        lossy_segs = np.empty((0, 2, 2))
        cut_segs = np.empty((0, 2, 2))
        if len(alive) >= 2:
            ii, jj = np.triu_indices(len(alive), 1)
            a, b = alive[ii], alive[jj]
            dist = np.hypot(pos[a, 0] - pos[b, 0], pos[a, 1] - pos[b, 1])
            keep = dist <= self.range
            a, b = a[keep], b[keep]
            cut = np.zeros(len(a), dtype=bool)
            for start, end, g in self.partitions:
                if start <= t < end:
                    cut |= (g[a] >= 0) & (g[b] >= 0) & (g[a] != g[b])
            # Loss fraction per pair over the last frame interval.
            lo, hi = t - self.step, t
            key = np.minimum(a, b) * n + np.maximum(a, b)
            lossy = np.zeros(len(a), dtype=bool)
            if len(key):
                def counts(cols: dict[str, np.ndarray]) -> np.ndarray:
                    s0 = np.searchsorted(cols["t"], lo, side="right")
                    s1 = np.searchsorted(cols["t"], hi, side="right")
                    src, dst = cols["src"][s0:s1].astype(np.int64), cols["dst"][s0:s1].astype(np.int64)
                    kk = np.minimum(src, dst) * n + np.maximum(src, dst)
                    return np.bincount(kk, minlength=n * n)

                lost_c = counts(rp.lost)
                rx_c = counts(rp.rx)
                tot = lost_c[key] + rx_c[key]
                lossy = (tot > 0) & (lost_c[key] > LOSSY_FRACTION * np.maximum(tot, 1))
                lossy &= ~cut
            seg = np.stack([pos[a], pos[b]], axis=1)
            ok_segs = seg[~cut & ~lossy]
            lossy_segs = seg[lossy]
            cut_segs = seg[cut]
        # An (n, 2, 2) array is a sequence of segments; the stubs only name sequences.
        self.links_ok.set_segments(ok_segs)  # type: ignore[arg-type]
        self.links_lossy.set_segments(lossy_segs)  # type: ignore[arg-type]
        self.links_cut.set_segments(cut_segs)  # type: ignore[arg-type]

    def _targets(self, t: float, i: int, flying: np.ndarray) -> None:
        rp = self.rp
        tx, ty = rp.target_x[i], rp.target_y[i]
        exists = np.isfinite(tx)
        watched = set(rp.target[i][flying & (rp.mode[i] == MODE_SURVEIL)].tolist())
        ids = np.flatnonzero(exists)
        face = []
        for k in ids:
            if k in watched:
                face.append("#2ca02c")
            elif rp.found_t[k] <= t + 1e-9:
                face.append(TARGET_FOUND_COLOUR)
            else:
                face.append("white")
        self.targets.set_offsets(np.column_stack([tx[ids], ty[ids]]) if len(ids) else np.empty((0, 2)))
        self.targets.set_facecolor(face if face else "none")
        self.targets.set_edgecolor(["0.3" if f == "white" else "black" for f in face] if face else "none")
        self.targets.set_sizes([110 if f == "#2ca02c" else 70 for f in face] if face else [70])

    def _faults(self, t: float, pos: np.ndarray, flying: np.ndarray) -> None:
        recent = [note for note in self.events if note[0] <= t + 1e-9 and t - note[0] < self.flash_s]  # (t, text, kind, uid)
        if recent:
            age = t - recent[-1][0]
            alpha = 1.0 - 0.6 * age / self.flash_s
            self.banner.set_text(banner_text(recent, BANNER_LINES))
            self.banner.set_visible(True)
            patch = self.banner.get_bbox_patch()
            if patch is not None:
                patch.set_alpha(0.9 * alpha)
            self.border.set_visible(True)
            self.border.set_alpha(alpha)
        else:
            self.banner.set_text("")
            self.banner.set_visible(False)
            self.border.set_visible(False)
        ring_xy, ring_c = [], []
        for _t, _text, kind, uid in recent:
            if uid >= 0:
                where = self.wreck.get(uid) if kind == "crash" else (pos[uid] if flying[uid] else None)
                if where is not None:
                    ring_xy.append(where)
                    ring_c.append("#d62728" if kind == "crash" else "#2ca02c")
        self.rings.set_offsets(np.array(ring_xy, dtype=float).reshape(-1, 2))
        self.rings.set_edgecolor(ring_c if ring_c else "none")
        active = [label for start, end, label in self.windowed if start <= t < end]
        self.active.set_text(("faults active:\n  " + "\n  ".join(active)) if active else "")


@dataclass
class AnimationJob:
    """A checked request to animate a run (:func:`prepare_animation`); :meth:`render` makes it."""

    out_path: Path
    replay: Replay
    times: np.ndarray
    fps: float
    speed: float
    trail_s: float
    dpi: float

    @property
    def n_frames(self) -> int:
        return len(self.times)

    def make_animation(self) -> tuple[FuncAnimation, _Scene]:
        """The ``FuncAnimation`` (``blit=True``) and its scene, e.g. to show in a GUI or notebook."""
        scene = _Scene(self.replay, self.times, self.fps, self.speed, self.trail_s, self.dpi)
        anim = FuncAnimation(scene.fig, scene.update, frames=self.n_frames, init_func=scene.init, blit=True,
                             interval=1000.0 / self.fps, repeat=False, cache_frame_data=False)
        return anim, scene

    def render(self, progress: Callable[[int, int], None] | None = None) -> Path:
        """Write the file; ``progress(done, total)`` after each frame. Returns its path.

        ``Animation.save`` redraws the whole figure for every frame; our writers instead take
        each frame from :meth:`_Scene.frame_rgba`, which blits the changed artists over a
        background rendered once (axes, ticks, legend, colour bar).
        """
        anim, scene = self.make_animation()
        out_path = self.out_path
        writer: _BlitMp4Writer | _BlitGifWriter
        if out_path.suffix.lower() == ".mp4":
            writer = _BlitMp4Writer(scene, self.fps, codec="h264", extra_args=["-pix_fmt", "yuv420p"],
                                    metadata={"title": f"{self.replay.header.get('scenario', '')} replay"})
        else:
            writer = _BlitGifWriter(scene, self.fps)
        total = self.n_frames

        def on_frame(done: int, _total: int) -> None:
            if progress is not None:
                progress(done + 1, total)

        with atomic_path(out_path) as tmp:
            anim.save(str(tmp), writer=writer, dpi=self.dpi, progress_callback=on_frame)
        return out_path


def prepare_animation(run_dir: str | Path, out: str | Path | None = None, *, fps: float = DEFAULT_FPS,
                      speed: float = DEFAULT_SPEED, trail_s: float = DEFAULT_TRAIL_S,
                      dpi: float = DEFAULT_DPI) -> AnimationJob:
    """Check the options and read the run; raises :class:`AnimateError` / ``RunDirError``."""
    check_run_dir(run_dir)
    for name, value in (("--fps", fps), ("--speed", speed)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
            raise AnimateError(f"{name} must be a positive number, got {value!r}")
    if isinstance(trail_s, bool) or not isinstance(trail_s, (int, float)) or not trail_s >= 0:
        raise AnimateError(f"--trail must be a number >= 0 (seconds), got {trail_s!r}")
    out_path = Path(out) if out is not None else default_animation_path(run_dir)
    suffix = out_path.suffix.lower()
    if suffix not in (".mp4", ".gif"):
        raise AnimateError(f"{out_path}: unknown animation format {suffix or '(none)'!r}; use .mp4 or .gif")
    if suffix == ".mp4" and not ffmpeg_available():
        raise AnimateError(f"{out_path}: writing MP4 needs ffmpeg on PATH (not found); use a .gif name instead")
    if not out_path.parent.is_dir():
        raise AnimateError(f"{out_path.parent}: no such folder for the animation")
    rp = load_run(run_dir)
    if not np.isfinite(rp.x).any():
        raise AnimateError(f"{run_dir}: the event log has no UAV poses to animate")
    return AnimationJob(out_path, rp, frame_times(rp.duration, speed, fps), float(fps), float(speed),
                        float(trail_s), float(dpi))
