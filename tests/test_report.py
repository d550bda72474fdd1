"""`swarm report` and the sweep report: self-contained HTML that a real browser renders.

The browser test uses Debian's Chromium (``/usr/bin/chromium``). The session fixture installs
it with ``apt-get install -y -q chromium`` when it is missing and we are root; it skips (with
the reason) only when that is impossible.
"""

from __future__ import annotations

import base64
import io
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from swarm.cli import main
from swarm.viz.report import write_report, write_sweep_report

DATA = Path(__file__).parent / "data"
CHROMIUM = "/usr/bin/chromium"


# --- fixtures ---------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def reported_run(tmp_path_factory):
    """faults-small (300 s: partition, late join, crash, drops), its GIF animation and its report.
    Seconds to build: the tests that use it are marked ``slow`` (test_sweep_report is quick)."""
    out = tmp_path_factory.mktemp("report") / "run"
    assert main(["run", str(DATA / "faults-small.toml"), "--out", str(out), "--quiet"]) == 0
    assert main(["animate", str(out), "--out", str(out / "animation.gif"), "--fps", "5", "--speed", "60",
                 "--quiet"]) == 0
    assert main(["report", str(out), "--quiet"]) == 0
    return out


@pytest.fixture(scope="session")
def chromium() -> str:
    """Path of a headless-capable Chromium, installed from Debian's packages when missing."""
    if os.path.exists(CHROMIUM):
        return CHROMIUM
    if not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("apt-get") is None:
        pytest.skip("chromium is missing and cannot be installed here (needs root and apt-get); "
                    "install Debian's `chromium` package to run the browser test")
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}

    def install() -> subprocess.CompletedProcess:
        return subprocess.run(["apt-get", "install", "-y", "-q", "chromium"], capture_output=True, text=True,
                              env=env, timeout=1200)

    r = install()
    if r.returncode != 0:  # stale package lists: refresh once and retry
        subprocess.run(["apt-get", "update", "-q"], capture_output=True, text=True, env=env, timeout=600)
        r = install()
    if r.returncode != 0 or not os.path.exists(CHROMIUM):
        tail = (r.stderr or r.stdout).strip().splitlines()[-3:]
        pytest.skip(f"could not install chromium with apt-get: {' | '.join(tail)}")
    return CHROMIUM


def _chromium(binary: str, tmp: Path, *args: str) -> subprocess.CompletedProcess:
    profile = tmp / "chromium-profile"  # own profile: parallel test runs do not share a lock
    return subprocess.run([binary, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                           f"--user-data-dir={profile}", *args], capture_output=True, text=True, timeout=180)


# --- what the HTML references -----------------------------------------------------------------

def _references(text: str) -> list[str]:
    """Every src / href / poster attribute value and CSS url(...) in a page."""
    attrs = re.findall(r"""\b(?:src|href|poster|srcset|action|data)\s*=\s*["']([^"']*)["']""", text, flags=re.I)
    urls = re.findall(r"url\(\s*['\"]?([^'\")]*)", text, flags=re.I)
    return attrs + urls


def _assert_self_contained(text: str) -> None:
    for ref in _references(text):
        assert ref.startswith("data:") or ref.startswith("#"), f"external reference {ref[:80]!r}"
    # Outside the embedded data: base64 may spell anything ("//cDn" turned up in a PNG once).
    lowered = re.sub(r"data:[a-z/+.-]+;base64,[A-Za-z0-9+/=]+", "data:", text).lower()
    for bad in ("http://", "https://", "//cdn", "<script", "<link", "@import", "<iframe"):
        assert bad not in lowered, f"report contains {bad!r}"


@pytest.mark.slow  # the reported_run fixture
def test_run_report_is_self_contained(reported_run):
    html = (reported_run / "report.html").read_text()
    assert len(html) > 50_000
    _assert_self_contained(html)
    pngs = re.findall(r'src="data:image/png;base64,([^"]+)"', html)
    assert len(pngs) >= 6  # trajectories, coverage, targets, task load, radio, fault timeline
    for b64 in pngs:
        with Image.open(io.BytesIO(base64.b64decode(b64))) as im:
            assert im.format == "PNG" and im.size[0] >= 500
    gif = re.findall(r'src="data:image/gif;base64,([^"]+)"', html)
    assert len(gif) == 1, "the animation is embedded"
    assert base64.b64decode(gif[0]) == (reported_run / "animation.gif").read_bytes()


@pytest.mark.slow  # the reported_run fixture
def test_run_report_content(reported_run):
    html = (reported_run / "report.html").read_text()
    for text in ("faults-small", "greedy", "coverage", "certainty", "task load per UAV".split()[0],
                 "B2 crashed", "A2 joined", "partition B1 | B2,A1 begins", "partition healed", "drop 30% starts",
                 "event log SHA-256", "B1", "A2"):
        assert text in html, text
    import json

    m = json.loads((reported_run / "metrics.json").read_text())
    assert f"{m['coverage']:.4f}" in html and m["event_log_sha256"] in html
    causes = m["radio"]["dropped_by_cause"]
    assert causes and all(cause in html for cause in causes)  # every cause of lost frames is listed


@pytest.mark.slow  # renders the report again, and a `python -m swarm` subprocess
def test_report_without_animation_and_errors(reported_run, tmp_path, capsys):
    out = tmp_path / "plain.html"
    path = write_report(reported_run, out, animation=None)
    assert path == out  # found the folder's animation.gif by itself
    assert "data:image/gif" in out.read_text()
    bare = tmp_path / "bare"
    bare.mkdir()
    for name in ("events.msgpack", "scenario.json", "timeseries.csv"):
        shutil.copy(reported_run / name, bare / name)
    assert main(["report", str(bare)]) == 2
    assert "metrics.json: missing" in capsys.readouterr().err
    (bare / "events.msgpack").unlink()
    r = subprocess.run([sys.executable, "-m", "swarm", "report", str(bare)], capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "events.msgpack: missing" in r.stderr


@pytest.mark.slow  # renders the report twice and an animation
def test_animate_after_report_puts_the_animation_in_it(reported_run, tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    for name in ("events.msgpack", "scenario.json", "timeseries.csv", "metrics.json"):
        shutil.copy(reported_run / name, run / name)
    assert main(["report", str(run)]) == 0
    out = capsys.readouterr()
    html = (run / "report.html").read_text()
    assert "data:image/gif" not in html and "No animation" in html and "swarm animate" in html
    assert f"no animation in {run}" in out.err and "swarm animate" in out.err  # said on the terminal too
    assert main(["animate", str(run), "--out", str(run / "animation.gif"), "--fps", "2", "--speed", "120"]) == 0
    out = capsys.readouterr()
    assert f"updated {run / 'report.html'}" in out.out
    gif = re.findall(r'src="data:image/gif;base64,([^"]+)"', (run / "report.html").read_text())
    assert len(gif) == 1 and base64.b64decode(gif[0]) == (run / "animation.gif").read_bytes()
    # A folder without a report gets none from `animate`.
    (run / "report.html").unlink()
    assert main(["animate", str(run), "--out", str(run / "animation.gif"), "--fps", "2", "--speed", "120",
                 "--quiet"]) == 0
    assert not (run / "report.html").exists()


def test_radio_row_writes_one_loss_when_it_does_not_vary():
    from swarm.viz.report.run_report import _radio_words

    assert "loss 0.1," in _radio_words({"loss_base": 0.1, "loss_at_range": 0.1}, 5000.0)
    assert "loss 0.1," in _radio_words({"loss_base": 0.1}, None)
    words = _radio_words({"loss_base": 0.1, "loss_at_range": 0.3}, 5000.0)
    assert "0.1-0.1" not in words and "loss 0.1 near, 0.3 at the range limit" in words


def test_handover_rows_split_latency_into_overlap_and_gap():
    from swarm.viz.report import handover_rows

    base = {"target": 2, "from": "B3", "to": "A4", "from_type": "B", "to_type": "A"}
    # The owner let go at 120 s, the newcomer arrived at 152 s: logged at 152 s, latency -32 s.
    gap, overlap = handover_rows([{**base, "t": 152.0, "latency_s": -32.0}, {**base, "t": 45.0, "latency_s": 15.0}])
    assert gap == ("152 s", 2, "B3 (B)", "A4 (A)", "120 s", "152 s", "0 s", "32 s")
    # The newcomer arrived at 30 s, the owner let go at 45 s: both held it for 15 s.
    assert overlap == ("45 s", 2, "B3 (B)", "A4 (A)", "45 s", "30 s", "15 s", "0 s")


def test_violations_are_listed_with_who_when_and_which():
    from types import SimpleNamespace

    from swarm.viz.report.run_report import _violation_section, violation_episodes

    rp = SimpleNamespace(
        names=["A1", "A2", "B1"], dt=1.0, scenario={"safety": {"min_separation_m": 100.0}},
        # separation A1-B1 for 3 ticks, again later; A2 inside threat 0 once
        violations=[(10.0, "separation", 0, 2), (11.0, "separation", 0, 2), (12.0, "separation", 0, 2),
                    (11.0, "threat", 1, 0), (40.0, "separation", 0, 2)],
        metrics={"violations": {"separation": 4, "threat": 1, "dynamics": 2},
                 "dynamics_violations_by_uav": {"A2": {"count": 2, "first_s": 5.0, "last_s": 50.0}}})
    eps = violation_episodes(rp)
    assert [(e["invariant"], e["who"], e["start_s"], e["end_s"], e["ticks"]) for e in eps] == [
        ("dynamics", "A2", 5.0, 50.0, 2),
        ("separation", "A1 and B1", 10.0, 12.0, 3),
        ("threat", "A2 in threat 0", 11.0, 11.0, 1),
        ("separation", "A1 and B1", 40.0, 40.0, 1),
    ]
    sec = _violation_section(rp)
    assert sec["any"] and sec["unlisted"] == "" and sec["totals"] == "separation 4, threat 1, dynamics 2"
    assert sec["rows"][1] == ("separation", "A1 and B1", "10 s", "12 s", 3)
    assert dict(sec["meanings"])["separation"].endswith("(100 m in this run)")
    # A run folder from before dynamics were listed per UAV: the count it cannot place is named.
    del rp.metrics["dynamics_violations_by_uav"]
    assert _violation_section(rp)["unlisted"] == "2 dynamics"


@pytest.mark.slow  # a 400 s run with every fault kind
def test_run_report_lists_the_runs_violations(tmp_path):
    import json

    # A head-on pair that hears nothing (every frame dropped) and has no detect-and-avoid sensor:
    # they fly into each other (demo-all-faults no longer does, with the sensor).
    doc = tmp_path / "head-on.toml"
    doc.write_text('name = "head-on"\nseed = 16\nduration_s = 60.0\n[area]\nwidth_m = 9000.0\nheight_m = 5000.0\n'
                   '[planner]\nname = "greedy"\n'
                   '[[uavs]]\nname = "B1"\ntype = "B"\nx_m = 8500.0\ny_m = 2500.0\nheading_deg = 180.0\n'
                   '[[uavs]]\nname = "A1"\ntype = "A"\nx_m = 4500.0\ny_m = 2500.0\nheading_deg = 0.0\n'
                   '[[faults]]\nkind = "drop"\nrate = 1.0\n')
    out = tmp_path / "demo"
    assert main(["run", str(doc), "--set", "uav_types.A.daa_range_m=0", "--set", "uav_types.B.daa_range_m=0",
                 "--out", str(out), "--quiet", "--no-figures"]) == 0
    assert main(["report", str(out), "--quiet"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["violations"]["separation"] > 0  # what makes this run worth reporting on
    html = (out / "report.html").read_text()
    section = html.split('id="violations"')[1].split('id="uavs"')[0]
    rows = re.findall(r"<tr><td>separation</td><td>(\w+) and (\w+)</td><td>([\d.]+) s</td><td>([\d.]+) s</td>"
                      r"<td>(\d+)</td></tr>", section)
    assert rows and sum(int(r[4]) for r in rows) == m["violations"]["separation"]
    assert all(a in m["per_uav"] and b in m["per_uav"] and float(t0) <= float(t1) for a, b, t0, t1, _n in rows)


def _sweep_summary() -> dict:
    def stat(mean, sd, half):
        return {"mean": mean, "sd": sd, "ci95": [mean - half, mean + half]}

    groups = []
    for planner, base in (("greedy", 0.70), ("dacmp", 0.74)):
        for loss in (0.0, 0.3):
            groups.append({
                "planner": planner,
                "settings": {"radio.loss_base": loss},
                "runs": 4,
                "metrics": {
                    "coverage": stat(base - loss / 10, 0.02, 0.03),
                    "targets_found": stat(10 + 2 * (planner == "dacmp") - 3 * loss, 1.1, 1.7),
                    "surveillance_ratio_mean": stat(0.5 - loss / 3, 0.05, 0.08),
                },
            })
    groups[-1]["metrics"]["surveillance_ratio_mean"] = {"mean": 0.41, "sd": None, "ci95": None}  # one run only
    return {"scenario": "paper-fig11", "seeds": [1, 2, 3, 4], "varying": ["planner", "radio.loss_base"],
            "groups": groups}


def test_sweep_report(tmp_path):
    summary = _sweep_summary()
    out = write_sweep_report(tmp_path, summary, tmp_path / "sweep.html")
    html = out.read_text()
    _assert_self_contained(html)
    assert "paper-fig11" in html and "radio.loss_base=0.3" in html and "greedy" in html and "dacmp" in html
    assert "0.740 ± 0.020 [0.710, 0.770]" in html  # mean ± sd [95% interval], a fraction with 3 decimals
    assert html.count("<tr>") >= 1 + 4  # header + one row per group
    pngs = re.findall(r'src="data:image/png;base64,([^"]+)"', html)
    assert len(pngs) == 1
    with Image.open(io.BytesIO(base64.b64decode(pngs[0]))) as im:
        assert im.size[0] >= 800 and len(im.convert("RGB").getcolors(1 << 20)) > 50
    # Default output path, and a summary with no groups still gives a page.
    assert write_sweep_report(tmp_path, {"groups": []}).name == "report.html"


def test_sweep_report_says_how_intervals_are_bounded(tmp_path):
    summary = _two_planner_summary()
    summary["interval"] = "Student-t 95% interval of the mean over seeds, clipped to the range the metric can take"
    summary["groups"][0]["metrics"]["coverage"] = {"n": 2, "mean": 0.9, "sd": 0.05, "ci95": [0.45, 1.0],
                                                   "bounds": [0.0, 1.0]}
    html = write_sweep_report(tmp_path, summary, tmp_path / "sweep.html").read_text()
    assert "clipped to the range the metric can take" in html.split('id="summary"')[1]
    assert "<td>interval</td>" not in html  # a note under the table, not a setting
    assert re.search(r'title="interval clipped at 1.000, the end of the metric&#39;s range">0.900 ± 0.050 '
                     r'\[0.450, 1.000\]</td>', html)
    assert html.count("interval clipped") == 1  # the other cells' intervals were not clipped


def _stat(mean, sd=0.0, half=0.0):
    return {"n": 4, "mean": mean, "sd": sd, "ci95": [mean - half, mean + half]}


def _two_planner_summary() -> dict:
    """dacmp and greedy at one setting; three metrics vary, two are the same in every group."""
    groups = []
    for planner, cov, sent, mb in (("dacmp", 0.74, 1234.0, 4.121e6), ("greedy", 0.69, 987.0, 3.2e6)):
        groups.append({"planner": planner, "settings": {"radio.loss_base": 0.3}, "runs": 4, "metrics": {
            "coverage": _stat(cov, 0.02, 0.03),
            "radio.sent": _stat(sent, 40.0, 60.0),
            "radio.bytes_sent": _stat(mb, 3.34e5, 5.3e5),
            "violations.threat": _stat(0.0),  # zero everywhere
            "handovers": _stat(3.0),  # constant, not zero
        }})
    # summarize() writes "other - first": greedy - dacmp, with the sweep's first planner (dacmp) the baseline.
    comparisons = [{"settings": {"radio.loss_base": 0.3}, "planner": "greedy", "baseline": "dacmp", "paired_seeds": 4,
                    "difference": {"coverage": _stat(-0.05, 0.01, 0.01), "radio.sent": _stat(-247.0, 30.0, 300.0),
                                   "radio.bytes_sent": _stat(-9.21e5, 1e5, 2e5), "violations.threat": _stat(0.0),
                                   "handovers": _stat(0.0)}}]
    return {"scenario": "paper-fig11", "seeds": [1, 2, 3, 4], "groups": groups, "comparisons": comparisons}


def test_sweep_report_leaves_out_metrics_that_never_differ(tmp_path, monkeypatch):
    from swarm.viz.report import sweep_report as report

    drawn = []
    real = report.fig_sweep
    monkeypatch.setattr(report, "fig_sweep", lambda groups, metrics: drawn.append(list(metrics)) or real(groups, metrics))
    summary = _two_planner_summary()
    assert report.constant_metrics(summary["groups"]) == {"violations.threat": 0.0, "handovers": 3.0}
    html = write_sweep_report(tmp_path, summary, tmp_path / "sweep.html").read_text()
    assert drawn == [["coverage", "radio.sent", "radio.bytes_sent"]]  # one panel each, none for the others
    heads = re.findall(r"<th>([^<]*)</th>", html.split('id="differences"')[0])
    assert "violations.threat" not in heads and "handovers" not in heads and "coverage" in heads
    assert "Not shown, the same in every group: violations.threat = 0; handovers = 3." in html
    # A single group: only all-zero metrics are left out (nothing to compare with, but a 0 is noise).
    one = {"groups": summary["groups"][:1]}
    assert report.constant_metrics(one["groups"]) == {"violations.threat": 0.0}


def test_sweep_report_numbers_in_units(tmp_path):
    html = write_sweep_report(tmp_path, _two_planner_summary(), tmp_path / "sweep.html").read_text()
    nb = "\u202f"  # thin (narrow no-break) thousands separator
    assert "<th>radio.bytes_sent (MB)</th>" in html
    assert "4.12 ± 0.33 [3.59, 4.65]" in html  # 4.121e+06 ± 3.34e+05 bytes
    assert f"1{nb}234 ± 40 [1{nb}174, 1{nb}294]" in html  # a count
    assert "e+0" not in html.split("<body>")[1].split("data:image")[0]


def test_sweep_report_paired_differences_are_first_minus_second(tmp_path):
    from swarm.viz.report import paired_differences

    summary = _two_planner_summary()
    d = paired_differences(summary["comparisons"][0])
    assert (d["first"], d["second"]) == ("dacmp", "greedy")
    assert d["difference"]["coverage"]["mean"] == pytest.approx(0.05)
    assert d["difference"]["coverage"]["ci95"] == pytest.approx([0.04, 0.06])
    html = write_sweep_report(tmp_path, summary, tmp_path / "sweep.html").read_text()
    section = html.split('id="differences"')[1]
    assert "<h3>dacmp \u2212 greedy</h3>" in section
    # dacmp covers more: positive, and marked better (its interval leaves out zero).
    assert re.search(r'<td class="num better"[^>]*>\+0\.050 \[\+0\.040, \+0\.060\]</td>', section)
    assert "<td>radio.bytes_sent (kB)</td>" in section  # bytes in kB, the unit in the row's name
    assert ">+921 [+721, +1\u202f121]</td>" in section
    assert "violations.threat" not in section
    # The summary's own order on request.
    html = write_sweep_report(tmp_path, summary, tmp_path / "sweep2.html", first_minus_second=False).read_text()
    section = html.split('id="differences"')[1]
    assert "<h3>greedy \u2212 dacmp</h3>" in section and "-0.050 [-0.060, -0.040]" in section
    assert 'class="num worse"' in section


def test_sweep_report_escapes_what_it_shows(tmp_path):
    summary = {"scenario": "<script>alert(1)</script>", "groups": [
        {"planner": "<b>x</b>", "settings": {"a": "<i>"}, "runs": 1, "metrics": {"coverage": _stat(0.5, 0.1, 0.1)}}]}
    html = write_sweep_report(tmp_path, summary, tmp_path / "e.html").read_text()
    _assert_self_contained(html)
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html and "&lt;b&gt;x&lt;/b&gt;" in html and "<i>" not in html


def test_report_templates_are_package_data():
    """The templates ship with the package (a non-editable install finds them) and jinja2 is a
    declared dependency."""
    import importlib.resources
    import tomllib

    root = Path(__file__).resolve().parent.parent
    project = tomllib.loads((root / "pyproject.toml").read_text())
    assert any(d.replace(" ", "").startswith("jinja2>=") for d in project["project"]["dependencies"])
    patterns = project["tool"]["setuptools"]["package-data"]["swarm.viz"]
    templates = importlib.resources.files("swarm.viz") / "templates"
    names = sorted(p.name for p in templates.iterdir() if p.is_file())
    assert {"base.html.j2", "run_report.html.j2", "sweep_report.html.j2"} <= set(names)
    import fnmatch

    assert all(any(fnmatch.fnmatch(f"templates/{n}", pat) for pat in patterns) for n in names)


# --- in a real browser ------------------------------------------------------------------------

def _distinct_colours(png: Path, top: int = 200) -> tuple[int, float]:
    """Distinct RGB colours below the page header, and the share of saturated (coloured) pixels."""
    with Image.open(png) as im:
        rgb = np.asarray(im.convert("RGB"))[top:]
    flat = rgb.reshape(-1, 3)
    distinct = len(np.unique(flat[:, 0].astype(np.int64) << 16 | flat[:, 1].astype(np.int64) << 8 | flat[:, 2]))
    saturated = float(np.mean(flat.max(axis=1).astype(int) - flat.min(axis=1) > 40))
    return distinct, saturated


@pytest.mark.slow  # three Chromium runs
def test_report_renders_in_headless_chromium(reported_run, chromium, tmp_path):
    """What this proves: Chromium, offline (file://, no network needed since nothing is external),
    decodes every embedded figure at its full pixel size, and the screenshot of the top of the page
    is a rendered figure page — thousands of distinct colours and plenty of coloured pixels —
    unlike the same page with its image data broken (the negative control), which shows only
    text and boxes."""
    report = reported_run / "report.html"
    html = report.read_text()

    # 1. Every <img> decoded by the browser, at the PNG/GIF's own size.
    probe = tmp_path / "probe.html"
    js = ('<script>window.addEventListener("load",function(){var o=[];document.querySelectorAll("img")'
          '.forEach(function(i){o.push(i.naturalWidth+"x"+i.naturalHeight)});var p=document.createElement("pre");'
          'p.id="img-sizes";p.textContent=o.join(" ");document.body.appendChild(p);});</script>')
    probe.write_text(html.replace("</body>", js + "</body>"))
    r = _chromium(chromium, tmp_path, "--dump-dom", probe.as_uri())
    found = re.search(r'<pre id="img-sizes">([^<]*)</pre>', r.stdout)
    assert found, f"chromium did not load the page: {r.stderr[-500:]}"
    sizes = found.group(1).split()
    expected = []
    for _kind, b64 in re.findall(r'src="data:image/(png|gif);base64,([^"]+)"', html):
        with Image.open(io.BytesIO(base64.b64decode(b64))) as im:
            expected.append(f"{im.size[0]}x{im.size[1]}")
    assert sizes == expected and len(sizes) >= 7

    # 2. The screenshot shows figures.
    shot = tmp_path / "report.png"
    r = _chromium(chromium, tmp_path, f"--screenshot={shot}", "--window-size=1200,2000", report.as_uri())
    assert shot.is_file(), r.stderr[-500:]
    with Image.open(shot) as im:
        assert im.size == (1200, 2000)
        assert np.asarray(im.convert("L")).std() > 20  # not blank
    distinct, saturated = _distinct_colours(shot)

    broken = tmp_path / "broken.html"
    broken.write_text(re.sub(r"base64,[^\"]+", "base64,AAAA", html))
    broken_shot = tmp_path / "broken.png"
    _chromium(chromium, tmp_path, f"--screenshot={broken_shot}", "--window-size=1200,2000", broken.as_uri())
    b_distinct, b_saturated = _distinct_colours(broken_shot)

    # Measured here: ~6500 colours / 2% coloured pixels for the report, ~750 / 0.03% when broken.
    assert distinct > 3000 and saturated > 0.005, (distinct, saturated)
    assert distinct > 4 * b_distinct and saturated > 10 * b_saturated, (distinct, b_distinct, saturated, b_saturated)


@pytest.mark.slow  # a Chromium run
def test_wide_sweep_table_scrolls_inside_the_page(chromium, tmp_path):
    """Issue 23: a sweep with many differing metrics made the summary table run off a 1300 px page.
    In Chromium at that width the page itself is no wider than the window, while the table's box
    is narrower than the table: it scrolls sideways on its own."""
    metrics = [f"radio.metric_{i}" for i in range(14)] + ["coverage", "certainty"]
    groups = [{"planner": planner, "settings": {"radio.loss_base": loss, "radio.range_m": 8000.0 + loss},
               "runs": 3, "metrics": {m: _stat(1000.0 * (k + 1) + 37.0 * j, 12.0, 30.0) for k, m in enumerate(metrics)}}
              for j, (planner, loss) in enumerate((("dacmp", 0.0), ("dacmp", 0.3), ("greedy", 0.0), ("greedy", 0.3)))]
    html = write_sweep_report(tmp_path, {"scenario": "wide", "groups": groups}, tmp_path / "wide.html").read_text()
    js = ('<script>window.addEventListener("load",function(){var s=document.querySelector(".scroll");'
          'var p=document.createElement("pre");p.id="widths";p.textContent=[document.documentElement.scrollWidth,'
          'window.innerWidth,s.scrollWidth,s.clientWidth].join(" ");document.body.appendChild(p);});</script>')
    probe = tmp_path / "probe.html"
    probe.write_text(html.replace("</body>", js + "</body>"))
    r = _chromium(chromium, tmp_path, "--window-size=1300,900", "--dump-dom", probe.as_uri())
    found = re.search(r'<pre id="widths">([^<]*)</pre>', r.stdout)
    assert found, f"chromium did not load the page: {r.stderr[-500:]}"
    page, window, table, box = map(int, found.group(1).split())
    assert page <= window, (page, window)
    assert table > box + 200, (table, box)  # the table is much wider than its box, which scrolls
