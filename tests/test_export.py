"""``swarm export FOLDER --format parquet``: a run folder and a sweep folder as Parquet tables,
read back with pandas and DuckDB and compared with the event log, the time series and the
paths; a missing pyarrow and a folder that is neither a run nor a sweep are one error line."""

from __future__ import annotations

import csv
import json
import math
import sys
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

duckdb = pytest.importorskip("duckdb")
pd = pytest.importorskip("pandas")
pq = pytest.importorskip("pyarrow.parquet")

from faults.schedule import Pause, Restart  # noqa: E402
from swarm.cli import main  # noqa: E402
from swarm.events import KINDS, read_events  # noqa: E402
from swarm.experiments.sweep import sweep  # noqa: E402
from swarm.export import export_parquet  # noqa: E402
from swarm.kernel.simulation import Simulation  # noqa: E402
from swarm.outputs import write_run  # noqa: E402
from swarm.scenario import load_scenario  # noqa: E402
from tests.conftest import DATA  # noqa: E402

TABLES = [*KINDS, "timeseries", "paths"]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """faults-small for 150 s (a partition, corruption, drops, a late joiner) with a pause and
    a restart: most kinds of events, written by write_run as `swarm run --out` does; and a UAV
    added from Python (A9, inside the threat: violations), which the log's start header does
    not list."""
    out = tmp_path_factory.mktemp("export") / "run"
    with Simulation(load_scenario(DATA / "faults-small.toml"), duration_s=150.0) as sim:
        sim.add_fault(Pause(uav="B1", start_s=20.0, end_s=40.0))
        sim.add_fault(Restart(uav="A1", at_s=60.0, downtime_s=5.0))
        sim.add_uav("A", 6000.0, 6000.0, name="A9", join_s=50.0)
        write_run(sim.run(), out, sim.scenario.to_dict(), figures=False)
    return out


@pytest.fixture(scope="module")
def exported(run_dir) -> Path:
    assert main(["export", str(run_dir), "--format", "parquet", "--quiet"]) == 0
    return run_dir / "parquet"


def _frame_rows(df) -> list[dict]:
    return [{k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in row.items()}
            for row in df.to_dict("records")]


def _as_python(value):
    """A value read back by pandas as the record holds it: a map comes back as a list of
    (key, value) pairs, a list as a numpy array."""
    if isinstance(value, list) and all(isinstance(pair, tuple) for pair in value):
        return {k: _as_python(v) for k, v in value}
    if hasattr(value, "tolist"):
        return value.tolist()
    return value


def test_a_run_exports_every_table_with_the_event_logs_rows_and_values(run_dir, exported):
    assert sorted(p.name for p in exported.glob("*.parquet")) == sorted(f"{t}.parquet" for t in [*TABLES, "run"])
    records = list(read_events((run_dir / "events.msgpack").read_bytes()))
    by_kind = Counter(e.kind for e in records)
    assert {"pose", "rx", "lost", "pause", "resume", "restart", "crash", "join", "found"} <= set(by_kind)
    for kind, spec in KINDS.items():
        df = pd.read_parquet(exported / f"{kind}.parquet")
        # (the UAV type columns beside the ids: test_every_uav_id_has_its_type_beside_it)
        assert [c for c in df.columns if not c.endswith("_type")] == ["seq", *(f.name for f in spec.fields)]
        assert len(df) == by_kind[kind], kind
        want = [(i, e) for i, e in enumerate(records) if e.kind == kind]
        assert df["seq"].tolist() == [i for i, _ in want]
        for f in spec.fields:
            got = [_as_python(v) for v in df[f.name].tolist()]
            if f.py_type is str:  # (pandas' string columns read a null as NaN)
                got = [None if isinstance(v, float) and math.isnan(v) else v for v in got]
            expected = [getattr(e, f.name) for _, e in want]
            if f.name in ("header", "args"):  # (tables: JSON text)
                expected = [json.loads(json.dumps(h)) for h in expected]
                got = [json.loads(v) for v in got]
            assert got == expected, (kind, f.name)


def _types_by_name(run_dir: Path) -> dict[str, str]:
    """Each UAV's type as the run's metrics.json says (every UAV the run had)."""
    return {name: u["type"] for name, u in json.loads((run_dir / "metrics.json").read_text())["per_uav"].items()}


def test_every_uav_id_has_its_type_beside_it(run_dir, exported):
    types = _types_by_name(run_dir)
    assert types["A9"] == "A" and "A9" not in {n for _, n, _t in next(iter(
        read_events((run_dir / "events.msgpack").read_bytes()))).header["uavs"]}  # added from Python
    expected = {"pose": ["uav_type"], "rx": ["src_type", "dst_type"], "handover": ["from_type", "to_type"],
                "crash": ["uav_type"], "join": ["uav_type"], "violation": ["uav_type", "other_type"]}
    checked = 0
    for kind, spec in KINDS.items():
        df = pd.read_parquet(exported / f"{kind}.parquet")
        columns = list(df.columns)
        ids = [f.name for f in spec.fields if f.role == "uav"]
        type_columns = [c for c in columns if c.endswith("_type")]
        assert len(type_columns) >= len(ids), kind  # one per UAV id (a violation's other party too)
        if kind in expected:
            assert type_columns == expected[kind], kind
        for column in type_columns:
            name = columns[columns.index(column) - 1]  # right after the name column
            assert name.endswith("_name") and name[:-5] == column[:-5], (kind, column)
            assert str(pq.read_schema(exported / f"{kind}.parquet").field(column).type) == "string"
            for uav, uav_type in zip(df[name], df[column]):
                assert (None if pd.isna(uav_type) else uav_type) == (types[uav] if isinstance(uav, str) else None), \
                    (kind, column, uav)
                checked += isinstance(uav, str)
    assert checked > 1000
    pose = pd.read_parquet(exported / "pose.parquet")
    assert set(pose[pose["uav_name"] == "A9"]["uav_type"]) == {"A"}  # from metrics.json: not in the header
    paths = pd.read_parquet(exported / "paths.parquet")
    assert list(paths.columns) == ["object", "id", "name", "uav_type", "t", "x", "y"]  # no lon/lat: in metres only
    uav = paths[paths["object"] == "uav"]
    assert [types[n] for n in uav["name"]] == uav["uav_type"].tolist()
    assert paths[paths["object"] == "target"]["uav_type"].isna().all()


def test_the_run_table_and_every_tables_metadata_say_the_scenario_and_tick(run_dir, exported):
    header = next(iter(read_events((run_dir / "events.msgpack").read_bytes()))).header
    metrics = json.loads((run_dir / "metrics.json").read_text())
    run = pd.read_parquet(exported / "run.parquet")
    assert _frame_rows(run) == [{
        "scenario": "faults-small", "planner": metrics["planner"], "seed": 7, "dt_s": header["dt"],
        "sim_seconds": 150.0, "event_log_sha256": metrics["event_log_sha256"], "crs": None}]
    assert pq.read_schema(exported / "run.parquet").field("dt_s").metadata[b"unit"] == b"s"
    for table in TABLES + ["run"]:
        meta = pq.read_schema(exported / f"{table}.parquet").metadata
        assert (meta[b"scenario"], float(meta[b"dt_s"])) == (b"faults-small", header["dt"]), table
    got = duckdb.sql(f"select scenario, dt_s from '{exported / 'run.parquet'}'").fetchall()
    assert got == [("faults-small", header["dt"])]


def test_a_geographic_run_has_lon_and_lat_beside_x_and_y(tmp_path):
    """geo-coast, 60 s: lon/lat of every pose, target and path point, checked against the
    run's own GeoJSON (written by swarm.geo.geojson, rounded to 1e-7 degrees)."""
    out = tmp_path / "geo"
    with Simulation(load_scenario("geo-coast"), duration_s=60.0) as sim:
        write_run(sim.run(), out, sim.scenario.to_dict(), figures=False)
    assert main(["export", str(out), "--format", "parquet", "--quiet"]) == 0
    tracks = {f["properties"]["name"]: f["geometry"]["coordinates"]
              for f in json.loads((out / "paths.geojson").read_text())["features"]}
    pose = pd.read_parquet(out / "parquet" / "pose.parquet")
    assert list(pose.columns[:7]) == ["seq", "t", "uav", "x", "y", "lon", "lat"]
    assert len(pose) > 100 and 10.0 < pose["lon"].min() < pose["lon"].max() < 11.0
    for name, rows in pose.groupby("uav_name"):
        assert np.abs(rows[["lon", "lat"]].to_numpy() - np.array(tracks[name])).max() <= 1e-7
    target = pd.read_parquet(out / "parquet" / "target.parquet")
    target_tracks = [f["geometry"]["coordinates"] for f in json.loads((out / "targets.geojson").read_text())["features"]]
    for k, rows in target.groupby("target"):
        assert np.abs(rows[["lon", "lat"]].to_numpy() - np.array(target_tracks[k])).max() <= 1e-7
    paths = pd.read_parquet(out / "parquet" / "paths.parquet")
    assert list(paths.columns) == ["object", "id", "name", "uav_type", "t", "x", "y", "lon", "lat"]
    assert paths["lon"].notna().all() and len(paths) == len(pose) + len(target)
    schema = pq.read_schema(out / "parquet" / "pose.parquet")
    assert schema.field("lon").metadata[b"unit"] == b"deg" and schema.metadata[b"scenario"] == b"geo-coast"
    run = pd.read_parquet(out / "parquet" / "run.parquet")
    assert run["crs"].tolist() == ["EPSG:4326"]


def test_the_columns_are_typed_from_the_schema(exported):
    schema = pq.read_schema(exported / "pose.parquet")
    assert {n: str(schema.field(n).type) for n in ("t", "uav", "x", "mode", "target", "uav_name")} == {
        "t": "double", "uav": "int64", "x": "double", "mode": "string", "target": "int64", "uav_name": "string"}
    assert schema.field("x").metadata[b"unit"] == b"m" and schema.field("theta").metadata[b"unit"] == b"rad"
    assert str(pq.read_schema(exported / "rx.parquet").field("accepted").type) == "bool"


def test_duckdb_reads_the_tables_and_joins_them(run_dir, exported):
    records = list(read_events((run_dir / "events.msgpack").read_bytes()))
    poses = Counter(e.uav_name for e in records if e.kind == "pose")
    got = duckdb.sql(f"select uav_name, count(*) from '{exported / 'pose.parquet'}' group by uav_name").fetchall()
    assert dict(got) == poses
    # The order across tables: every pause comes before its UAV's poses that tick (seq).
    first = duckdb.sql(f"""
        select p.t, min(q.seq) > p.seq from '{exported / 'pause.parquet'}' p
        join '{exported / 'pose.parquet'}' q on q.t = p.t and q.uav = p.uav group by p.t, p.seq""").fetchall()
    assert first and all(later for _, later in first)
    lost = duckdb.sql(f"select cause, count(*) from '{exported / 'lost.parquet'}' group by cause").fetchall()
    assert dict(lost) == Counter(e.cause for e in records if e.kind == "lost")


def test_the_time_series_and_paths_are_there_too(run_dir, exported):
    with (run_dir / "timeseries.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    ts = pd.read_parquet(exported / "timeseries.parquet")
    assert list(ts.columns) == list(rows[0]) and len(ts) == len(rows)
    assert ts["alive"].dtype.kind == "i" and ts["coverage"].dtype.kind == "f"
    assert ts["coverage"].tolist() == [float(r["coverage"]) for r in rows]
    assert ts["mode_B1"].tolist() == [r["mode_B1"] for r in rows]
    paths = pd.read_parquet(exported / "paths.parquet")
    records = list(read_events((run_dir / "events.msgpack").read_bytes(), {"pose", "target"}))
    assert len(paths) == len(records)
    uav = paths[paths["object"] == "uav"]
    assert list(zip(uav["name"], uav["t"], uav["x"], uav["y"])) == [
        (e.uav_name, e.t, e.x, e.y) for e in records if e.kind == "pose"]
    assert paths[paths["object"] == "target"]["name"].isna().all()


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("export") / "sweep"
    with ThreadPoolExecutor(2) as ex:
        res = sweep(load_scenario(DATA / "faults-small.toml"), out, seeds=2, planners=["greedy"], duration_s=30.0,
                    grid={"radio.range_m": [5000.0, math.inf], "recording.level": ["frames", "summary"]}, executor=ex)
    assert res.ran == 8 and not res.failed
    return out


def test_a_sweep_exports_one_table_per_kind_over_its_runs_with_the_swept_values(sweep_dir, tmp_path, capsys):
    assert main(["export", str(sweep_dir), "--out", str(tmp_path / "pq")]) == 0
    assert "8 runs" in capsys.readouterr().out
    runs = sorted(sweep_dir.glob("runs/*/*/seed-*/metrics.json"))
    assert len(runs) == 8
    for kind in ("pose", "rx", "radio", "join"):
        df = pd.read_parquet(tmp_path / "pq" / f"{kind}.parquet")
        assert list(df.columns[:5]) == ["run", "planner", "seed", "radio.range_m", "recording.level"]
        assert str(df["radio.range_m"].dtype) == "float64" and set(df["radio.range_m"]) <= {5000.0, math.inf}
        total = 0
        for metrics_path in runs:
            m = json.loads(metrics_path.read_text())
            folder = metrics_path.parent.relative_to(sweep_dir).as_posix()
            mine = df[df["run"] == folder]
            records = [e for e in read_events((metrics_path.parent / "events.msgpack").read_bytes()) if e.kind == kind]
            assert len(mine) == len(records), (kind, folder)
            total += len(records)
            if records:
                assert set(mine["planner"]) == {m["planner"]} and set(mine["seed"]) == {m["seed"]}
                assert set(mine["recording.level"]) == {m["settings"]["recording.level"]}
                for f in KINDS[kind].fields:  # (radio's lost: a map of cause to [copies, bytes])
                    assert [_as_python(v) for v in mine[f.name]] == [getattr(e, f.name) for e in records], f.name
        assert len(df) == total
    # Radio summaries only where the runs recorded them; frame copies only in the others.
    levels = duckdb.sql(f"""select "recording.level", count(*) from '{tmp_path / 'pq' / 'radio.parquet'}'
                            group by all""").fetchall()
    assert {level for level, n in levels if n} == {"summary"}
    rx = duckdb.sql(f"""select distinct "recording.level" from '{tmp_path / 'pq' / 'rx.parquet'}'""").fetchall()
    assert rx == [("frames",)]
    ts = pd.read_parquet(tmp_path / "pq" / "timeseries.parquet")
    assert set(ts["seed"]) == {0, 1} and len(set(ts["run"])) == 8
    # The run table: one row per run, its labels first; the shared scenario and tick as metadata.
    run = pd.read_parquet(tmp_path / "pq" / "run.parquet")
    assert list(run.columns) == ["run", "planner", "seed", "radio.range_m", "recording.level", "scenario", "dt_s",
                                 "sim_seconds", "event_log_sha256", "crs"]
    assert sorted(run["run"]) == sorted(p.parent.relative_to(sweep_dir).as_posix() for p in runs)
    for metrics_path in runs:
        m = json.loads(metrics_path.read_text())
        row = run[run["run"] == metrics_path.parent.relative_to(sweep_dir).as_posix()].iloc[0]
        assert (row["seed"], row["event_log_sha256"], row["sim_seconds"]) == (m["seed"], m["event_log_sha256"], 30.0)
    assert set(run["scenario"]) == {"faults-small"}
    assert pq.read_schema(tmp_path / "pq" / "pose.parquet").metadata[b"scenario"] == b"faults-small"


def test_a_sweep_of_the_tick_keeps_dt_s_in_the_run_table_only(tmp_path):
    out = tmp_path / "sweep"
    with ThreadPoolExecutor(2) as ex:
        res = sweep(load_scenario(DATA / "faults-small.toml"), out, seeds=1, planners=["greedy"], duration_s=10.0,
                    grid={"dt_s": [0.5, 1.0]}, executor=ex)
    assert res.ran == 2 and not res.failed
    export_parquet(out, tmp_path / "pq")
    run = pd.read_parquet(tmp_path / "pq" / "run.parquet")
    assert sorted(run["dt_s"]) == [0.5, 1.0] and "setting:dt_s" in run.columns  # the swept key, renamed
    meta = pq.read_schema(tmp_path / "pq" / "pose.parquet").metadata
    assert b"dt_s" not in meta and meta[b"scenario"] == b"faults-small"
    ticks = duckdb.sql(f"""select r.dt_s, count(distinct p.t) from '{tmp_path / 'pq' / 'pose.parquet'}' p
                           join '{tmp_path / 'pq' / 'run.parquet'}' r using (run) group by all order by 1""").fetchall()
    assert ticks == [(0.5, 20), (1.0, 10)]


def test_without_pyarrow_one_error_line_names_the_extra(run_dir, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    assert main(["export", str(run_dir), "--out", str(tmp_path / "pq")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "pip install 'uav-swarm-sim[parquet]'" in err[0]


@pytest.mark.parametrize("make", ["empty", "missing", "sweep_unfinished"])
def test_a_folder_that_is_no_run_nor_sweep_is_one_error_line(tmp_path, capsys, make):
    folder = tmp_path / "folder"
    if make != "missing":
        folder.mkdir()
    if make == "sweep_unfinished":
        (folder / "sweep.json").write_text('{"runs": {}}')
    assert main(["export", str(folder), "--format", "parquet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and str(folder) in err[0]


def test_export_parquet_returns_what_it_wrote(run_dir, tmp_path):
    result = export_parquet(run_dir, tmp_path / "again")
    assert result.runs == 1 and set(result.rows) == {*TABLES, "run"}
    assert all(p.is_file() for p in result.paths().values())
    assert result.rows["pose"] == len(pd.read_parquet(result.paths()["pose"]))
