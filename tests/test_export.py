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

import pytest

duckdb = pytest.importorskip("duckdb")
pd = pytest.importorskip("pandas")
pq = pytest.importorskip("pyarrow.parquet")

from faults.schedule import Pause, Restart  # noqa: E402
from swarm.cli import main  # noqa: E402
from swarm.events import KINDS, read_events  # noqa: E402
from swarm.experiments.sweep import sweep  # noqa: E402
from swarm.export import export_parquet  # noqa: E402
from swarm.outputs import write_run  # noqa: E402
from swarm.scenario import load_scenario  # noqa: E402
from swarm.simulation import Simulation  # noqa: E402
from tests.conftest import DATA  # noqa: E402

TABLES = [*KINDS, "timeseries", "paths"]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """faults-small for 150 s (a partition, corruption, drops, a late joiner) with a pause and
    a restart: most kinds of events, written by write_run as `swarm run --out` does."""
    out = tmp_path_factory.mktemp("export") / "run"
    with Simulation(load_scenario(DATA / "faults-small.toml"), duration_s=150.0) as sim:
        sim.add_fault(Pause(uav="B1", start_s=20.0, end_s=40.0))
        sim.add_fault(Restart(uav="A1", at_s=60.0, downtime_s=5.0))
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
    assert sorted(p.name for p in exported.glob("*.parquet")) == sorted(f"{t}.parquet" for t in TABLES)
    records = list(read_events((run_dir / "events.msgpack").read_bytes()))
    by_kind = Counter(e.kind for e in records)
    assert {"pose", "rx", "lost", "pause", "resume", "restart", "crash", "join", "found"} <= set(by_kind)
    for kind, spec in KINDS.items():
        df = pd.read_parquet(exported / f"{kind}.parquet")
        assert list(df.columns) == ["seq", *(f.name for f in spec.fields)]
        assert len(df) == by_kind[kind], kind
        want = [(i, e) for i, e in enumerate(records) if e.kind == kind]
        assert df["seq"].tolist() == [i for i, _ in want]
        for f in spec.fields:
            got = [_as_python(v) for v in df[f.name].tolist()]
            expected = [getattr(e, f.name) for _, e in want]
            if f.name in ("header", "args"):  # (tables: JSON text)
                expected = [json.loads(json.dumps(h)) for h in expected]
                got = [json.loads(v) for v in got]
            assert got == expected, (kind, f.name)


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
    assert result.runs == 1 and set(result.rows) == set(TABLES)
    assert all(p.is_file() for p in result.paths().values())
    assert result.rows["pose"] == len(pd.read_parquet(result.paths()["pose"]))
