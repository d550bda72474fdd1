"""`swarm animate`: the animation rebuilt from a run folder, and the event-log replay under it."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from swarm.cli import main
from swarm.viz.animate import (
    DEFAULT_FPS,
    DEFAULT_SPEED,
    FLASH_MAX_S,
    AnimateError,
    banner_text,
    ffmpeg_available,
    frame_times,
    prepare_animation,
)
from swarm.viz.replay import CoverageRaster, RunDirError, fault_events, first_seen_map, load_run
from swarm.viz.style import many_uavs, type_markers, uav_colours

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """faults-small for its whole 300 s: partition 50-150 s, A2 joins at 100 s, B2 crashes at 200 s."""
    out = tmp_path_factory.mktemp("anim") / "run"
    assert main(["run", str(DATA / "faults-small.toml"), "--out", str(out), "--quiet", "--no-figures"]) == 0
    return out


def test_frame_times_follow_speed_and_fps():
    # Default: a 2000 s paper run gives a 33 s clip at 10 fps (frames every 6 simulated seconds).
    t = frame_times(2000.0, DEFAULT_SPEED, DEFAULT_FPS)
    assert len(t) == 334 and t[0] == 0.0 and t[-1] == pytest.approx(1998.0)
    assert 20 <= len(t) / DEFAULT_FPS <= 40
    assert len(frame_times(300.0, 60.0, 5.0)) == 26  # floor(300 * 5 / 60) + 1
    assert len(frame_times(300.0, 30.0, 10.0)) == 101


def test_replay_rebuilds_ground_truth_exactly(run_dir):
    rp = load_run(run_dir)
    m = json.loads((run_dir / "metrics.json").read_text())
    # Coverage raster from poses + detection radii == the simulator's own coverage metric.
    assert float(np.isfinite(first_seen_map(rp)).mean()) == m["coverage"]
    raster = CoverageRaster(rp)
    raster.advance(rp.duration)
    assert raster.coverage() == m["coverage"]
    # Mode seconds from pose events == the simulator's per-UAV accounting.
    secs = rp.mode_seconds()
    for name, per in m["per_uav"].items():
        assert secs[name]["search"] == per["mode_seconds"]["search"]
        assert secs[name]["surveil"] == per["mode_seconds"]["surveil"]
    assert rp.names == ["B1", "B2", "A1", "A2"] and rp.types == ["B", "B", "A", "A"]
    assert [(t, rp.names[u]) for t, u in rp.crashes] == [(200.0, "B2")]
    texts = [text for _t, text, _k, _u in fault_events(rp)]
    assert "partition B1 | B2,A1 begins" in texts and "partition healed" in texts
    assert "B2 crashed" in texts and "A2 joined" in texts and "drop 30% starts" in texts


def test_coverage_raster_is_monotone_in_time(run_dir):
    rp = load_run(run_dir)
    raster = CoverageRaster(rp)
    seen = [raster.advance(t).copy() for t in (0.0, 50.0, 120.0, 299.0)]
    cover = [np.isfinite(s).sum() for s in seen]
    assert cover == sorted(cover) and cover[0] > 0
    assert float(seen[-1].max()) == 299.0


@pytest.mark.slow  # renders and encodes 26 frames; single frames are checked below
def test_gif_has_the_expected_frames(run_dir, tmp_path):
    out = tmp_path / "anim.gif"
    fps, speed = 5, 60
    assert main(["animate", str(run_dir), "--out", str(out), "--fps", str(fps), "--speed", str(speed), "--quiet"]) == 0
    assert out.stat().st_size > 10_000
    expected = math.floor(300.0 * fps / speed) + 1
    with Image.open(out) as im:
        assert im.format == "GIF"
        assert im.n_frames == expected == 26
        assert im.size == (800, 600)
        assert im.info["duration"] == 1000 // fps
    assert not list(tmp_path.glob("*.part*")), "temporary file left behind"


def test_frames_show_partition_crash_and_join(run_dir, tmp_path):
    """The artists of single frames carry the fault story of faults-small."""
    job = prepare_animation(run_dir, tmp_path / "a.gif", fps=10, speed=10)  # one frame per second
    anim, scene = job.make_animation()
    scene.init()

    def at(t):
        scene.update(int(t))
        return scene

    s = at(30)  # before the partition: all links fine, no banner
    assert len(s.links_cut.get_segments()) == 0 and len(s.links_ok.get_segments()) > 0
    assert not s.banner.get_visible()
    s = at(60)  # partition B1 | B2,A1: B1's links cut
    assert len(s.links_cut.get_segments()) >= 1 and "partition" in s.active.get_text()
    s = at(101)  # A2 just joined: flashed, with the time it joined
    assert s.banner.get_visible() and "t=100 s: A2 joined" in s.banner.get_text()
    assert len(s.uav_scatters["A"].get_offsets()) == 2
    s = at(201)  # B2 crashed: flashed, wreck drawn, one UAV fewer
    assert "t=200 s: B2 crashed" in s.banner.get_text() and len(s.wrecks.get_offsets()) == 1
    assert len(s.uav_scatters["B"].get_offsets()) == 1
    assert "flying   3/4" in s.clock.get_text()
    s = at(290)  # long after: banner gone, drop still active
    assert not s.banner.get_visible() and "drop 30%" in s.active.get_text()
    rgba = np.asarray(s.frame_rgba())
    assert rgba.shape == (600, 800, 4) and len(np.unique(rgba.reshape(-1, 4), axis=0)) > 100
    del anim


def test_banner_shows_each_event_with_its_time_and_only_recent_ones(run_dir, tmp_path):
    """Default speed (60 simulated s per video second, a frame every 6 s): the banner lists the
    events of the last FLASH_MAX_S simulated seconds, newest first, each with its time."""
    job = prepare_animation(run_dir, tmp_path / "a.gif", fps=10, speed=60)
    anim, scene = job.make_animation()
    scene.init()
    assert scene.flash_s == FLASH_MAX_S == 60.0
    scene.update(19)  # t = 114 s: A2 joined and corrupt ended at 100 s; the partition began 64 s ago
    text = scene.banner.get_text()
    assert text.splitlines()[0].startswith("t=100 s: ") and "t=100 s: A2 joined" in text
    assert "t=100 s: corrupt 10% ends" in text and "partition" not in text
    scene.update(26)  # t = 156 s: the partition healed at 150 s; the join (56 s ago) is still recent
    assert scene.banner.get_text().splitlines()[0] == "t=150 s: partition healed"
    scene.update(28)  # t = 168 s: the join is 68 s old: no longer in the banner
    assert "A2 joined" not in scene.banner.get_text() and "t=150 s: partition healed" in scene.banner.get_text()
    scene.update(40)  # t = 240 s: the crash at 200 s was 40 s ago, nothing since
    assert scene.banner.get_text() == "t=200 s: B2 crashed" and scene.banner.get_visible()
    scene.update(45)  # t = 270 s: nothing in the last 60 s
    assert not scene.banner.get_visible() and scene.banner.get_text() == ""
    events = [(12.0, "x crashed", "crash", 0), (312.4, "B2 crashed", "crash", 1)]
    assert banner_text(events) == "t=312 s: B2 crashed\nt=12 s: x crashed"
    assert banner_text(events, lines=1) == "t=312 s: B2 crashed"
    del anim


def test_no_links_to_a_crashed_uav_after_its_crash(run_dir, tmp_path):
    """B2 crashes at 200 s. With unlimited range every pair of flying UAVs is linked; from the
    crash on, no link (working, lossy or cut) ends at B2's wreck or anywhere near it."""
    job = prepare_animation(run_dir, tmp_path / "a.gif", fps=10, speed=10)  # a frame per second
    anim, scene = job.make_animation()
    scene.init()
    scene.range = math.inf
    b2 = scene.rp.names.index("B2")
    wreck = np.array(scene.wreck[b2])

    def ends_at_b2() -> int:
        segs = [seg for lc in (scene.links_ok, scene.links_lossy, scene.links_cut) for seg in lc.get_segments()]
        return sum(any(np.hypot(*(np.asarray(p) - wreck)) < 1.0 for p in seg) for seg in segs)

    scene.update(199)  # the last tick B2 flies, at the place it crashes: it has links
    assert ends_at_b2() >= 1
    for t in (200, 201, 205, 210, 230, 299):
        scene.update(t)
        assert ends_at_b2() == 0, f"t={t}: a link is drawn to the crashed B2"
        n_flying = 3  # B1, A1, A2: every pair linked
        assert sum(len(lc.get_segments()) for lc in (scene.links_ok, scene.links_lossy, scene.links_cut)) == \
            n_flying * (n_flying - 1) // 2
    del anim


def test_style_scales_to_100_uavs():
    names = [f"U{i}" for i in range(100)]
    colours = uav_colours(names)
    assert len(set(colours.values())) == 100
    assert many_uavs(100) and not many_uavs(12)
    assert uav_colours(["B2", "B1"])["B1"] != uav_colours(["B2", "B1"])["B2"]
    assert len(set(type_markers(["A", "B", "C"]).values())) == 3


def _swarm(*args):
    return subprocess.run([sys.executable, "-m", "swarm", *args], capture_output=True, text=True)


@pytest.mark.slow  # whole runs or a subprocess: the full run has it, the quick loop need not
def test_errors_are_one_line_exit_2(run_dir, tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    r = _swarm("animate", str(empty))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "events.msgpack" in lines[0] and "missing" in lines[0]
    assert main(["animate", str(run_dir), "--out", str(tmp_path / "x.avi")]) == 2
    assert main(["animate", str(run_dir), "--fps", "0"]) == 2
    assert main(["animate", str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err
    assert "'.avi'" in err and "--fps must be a positive number" in err and "no such run folder" in err
    with pytest.raises(RunDirError):
        load_run(tmp_path / "nowhere")
    if not ffmpeg_available():
        with pytest.raises(AnimateError, match="ffmpeg"):
            prepare_animation(run_dir, tmp_path / "x.mp4")


@pytest.mark.skipif(not ffmpeg_available(), reason="ffmpeg not on PATH: MP4 output not available here")
def test_mp4_when_ffmpeg_is_present(run_dir, tmp_path):
    out = tmp_path / "anim.mp4"
    assert main(["animate", str(run_dir), "--out", str(out), "--fps", "5", "--speed", "60", "--quiet"]) == 0
    data = out.read_bytes()
    assert len(data) > 1000 and data[4:8] == b"ftyp"
