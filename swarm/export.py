"""Columnar export: a run folder's (or a whole sweep's) event log, time series and paths as
Parquet tables with named, typed columns (``swarm export FOLDER --format parquet``).

Needs pyarrow, the ``parquet`` extra (``pip install 'uav-swarm-sim[parquet]'``); the simulator
itself never does. The tables, in ``--out`` (default ``FOLDER/parquet``):

* ``<kind>.parquet``, one per event kind of :data:`swarm.events.KINDS` (every kind, empty when
  the log has none): ``seq`` (the event's position in the log, 0 for ``start``: the order
  across tables, within a tick too), then the kind's record fields, their Arrow types made from
  the schema's annotations (``float`` float64, ``int`` int64, ``bool``, ``str`` string, a
  table of counts a map, the ``start`` header JSON text) and their units in each column's
  metadata (``unit``); beside every UAV id its UAV's type (``uav_type``, ``src_type``...:
  :func:`_type_columns`);
* ``timeseries.parquet``: ``timeseries.csv`` with typed columns (integers, floats, mode names);
* ``paths.parquet``: ``object`` (``uav`` or ``target``), ``id``, ``name`` (a UAV's),
  ``uav_type``, ``t``, ``x``, ``y``: the UAV and target positions of the ``pose`` and
  ``target`` events, in one table for plotting;
* ``run.parquet``: one row per run, :data:`RUN_COLUMNS` (scenario, planner, seed, ``dt_s``...).

For a geographic run every table with ``x`` and ``y`` has ``lon`` and ``lat`` after them
(WGS84 degrees, the run's own frame: :func:`swarm.geo.geojson.run_frame`). Every table's
metadata has ``scenario`` and ``dt_s`` where all runs exported share them.

A sweep folder (``swarm sweep --out``) gives the same tables over all its finished runs, each
row with its run's ``run`` (the run folder, from the sweep folder), ``planner``, ``seed`` and
every swept setting (a column named by its key, typed from its values) in front.

One table per kind rather than one long table with a kind column: each kind has its own
fields, so its columns are typed and never null (a long table would be a sparse union: a
``pose`` row has nothing in ``cause``, an ``rx`` nothing in ``theta``, and ``target`` or
``mode`` would need one type for every kind), and a query reads only the kind it wants. ``seq``
joins them back into log order when that matters.
"""

from __future__ import annotations

import contextlib
import csv
import importlib
import json
import math
import os
import typing
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from swarm.errors import SwarmError
from swarm.events import KINDS, NAME, UAV, FieldSpec, KindSpec, read_columns
from swarm.outputs import RunDirError, atomic_path, check_run_dir, read_json

__all__ = ["ExportResult", "MissingExtraError", "export_parquet", "find_runs"]

EXTRA_HINT = "pip install 'uav-swarm-sim[parquet]'"
TABLES_BESIDE_EVENTS = ("timeseries", "paths")  # (and "run", one row per run)


class MissingExtraError(SwarmError, ImportError):
    """An optional dependency the call needs is not installed (the message names the extra)."""


def _pyarrow() -> tuple[Any, Any]:
    """``pyarrow`` and ``pyarrow.parquet``, or :class:`MissingExtraError` naming the extra."""
    try:
        return importlib.import_module("pyarrow"), importlib.import_module("pyarrow.parquet")
    except ImportError as exc:
        raise MissingExtraError(f"swarm export --format parquet needs pyarrow ({exc}): {EXTRA_HINT}") from None


@dataclass(frozen=True)
class RunInfo:
    """One run folder to export, and what a sweep says of it (empty for a lone run)."""

    path: Path
    label: dict[str, Any] = field(default_factory=dict)  # run, planner, seed, swept settings


@dataclass
class ExportResult:
    """What :func:`export_parquet` wrote: the folder, the runs, and each table's rows."""

    out: Path
    runs: int
    rows: dict[str, int]  # table name -> rows

    def paths(self) -> dict[str, Path]:
        return {name: self.out / f"{name}.parquet" for name in self.rows}


def find_runs(folder: str | os.PathLike[str]) -> tuple[list[RunInfo], bool]:
    """The run folders to export and whether ``folder`` is a sweep: a run folder is one run; a
    sweep folder (``sweep.json``) is its finished runs (``runs/PLANNER/SETTINGS/seed-NNN`` with
    ``metrics.json``), each labelled with its planner, seed and swept settings.
    :class:`~swarm.outputs.RunDirError` for a folder that is neither, or a sweep with no
    finished run."""
    d = Path(folder)
    if not d.is_dir():
        raise RunDirError(f"{d}: no such folder (expected a run folder or a sweep folder)")
    if (d / "sweep.json").is_file():
        runs = []
        for metrics_path in sorted(d.glob("runs/*/*/seed-*/metrics.json")):
            run_dir = metrics_path.parent
            check_run_dir(run_dir)
            m = read_json(metrics_path)
            label = {"run": run_dir.relative_to(d).as_posix(), "planner": m.get("planner"), "seed": m.get("seed"),
                     **{str(k): v for k, v in (m.get("settings") or {}).items()}}
            runs.append(RunInfo(run_dir, label))
        if not runs:
            raise RunDirError(f"{d} is a sweep folder with no finished run yet (no runs/*/*/seed-*/metrics.json): "
                              f"run its `swarm sweep` command to finish it")
        return runs, True
    if not (d / "events.msgpack").is_file():
        raise RunDirError(f"{d}: neither a run folder (no events.msgpack; `swarm run SCENARIO --out DIR` writes one) "
                          f"nor a sweep folder (no sweep.json; `swarm sweep ... --out DIR`)")
    return [RunInfo(check_run_dir(d))], False


# --- column types -----------------------------------------------------------------------------------


def _arrow_type(pa: Any, annotation: Any) -> Any:
    """The Arrow type of a schema annotation (``str``, ``list[int]``, ``dict[str, list[int]]``...);
    ``None`` for a free-form table (``dict[str, Any]``: written as JSON text)."""
    simple = {float: pa.float64(), int: pa.int64(), bool: pa.bool_(), str: pa.string()}
    if annotation in simple:
        return simple[annotation]
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is list:
        inner = _arrow_type(pa, args[0])
        return None if inner is None else pa.list_(inner)
    if origin is dict and args and args[0] is str:
        inner = _arrow_type(pa, args[1])
        return None if inner is None else pa.map_(pa.string(), inner)
    return None


def _field(pa: Any, f: FieldSpec) -> Any:
    arrow = _arrow_type(pa, f.annotation)
    meta = {k: v for k, v in (("unit", f.unit), ("label", f.meta.label), ("role", f.role if f.role != "value" else ""))
            if v}
    if arrow is None:
        arrow, meta = pa.string(), {**meta, "encoding": "json"}
    return pa.field(f.name, arrow, nullable=f.nullable, metadata=meta or None)


def _column(pa: Any, f: FieldSpec, values: Sequence[Any]) -> Any:
    arrow = _arrow_type(pa, f.annotation)
    if arrow is None:
        from swarm.experiments.sweep import strict_json

        return pa.array([json.dumps(strict_json(v)) for v in values], pa.string())
    if pa.types.is_map(arrow):
        values = [list(v.items()) for v in values]
    return pa.array(values, arrow)


def _label_types(pa: Any, runs: Sequence[RunInfo]) -> list[tuple[str, Any]]:
    """The label columns of a sweep (run, planner, seed, then each swept setting by key), each
    typed from its values over all runs."""
    keys = list(dict.fromkeys(k for r in runs for k in r.label))
    return [(k, _label_type(pa, [r.label.get(k) for r in runs])) for k in keys]


_NONFINITE = {"inf": math.inf, "-inf": -math.inf, "nan": math.nan}  # strict JSON's spelling (sweep.py)


def _label_type(pa: Any, values: Sequence[Any]) -> Any:
    """The Arrow type of a column of JSON values: bool, int64, float64 (numbers, "inf", "-inf"
    and "nan" among them as strict JSON writes them), string, or else string holding JSON text
    (arrays, tables, mixtures; :func:`_label_columns` converts)."""
    present = [v for v in values if v is not None]
    if present and all(isinstance(v, bool) for v in present):
        return pa.bool_()
    numbers = [v for v in present if isinstance(v, (int, float)) and not isinstance(v, bool)]
    if present and len(numbers) == len(present) and all(isinstance(v, int) for v in numbers):
        return pa.int64()
    if numbers and all(v in numbers or (isinstance(v, str) and v in _NONFINITE) for v in present):
        return pa.float64()
    return pa.string()


def _label_columns(pa: Any, labels: Sequence[tuple[str, Any]], run: RunInfo, n: int) -> list[Any]:
    out = []
    for key, arrow in labels:
        v = run.label.get(key)
        if pa.types.is_floating(arrow) and isinstance(v, str):
            v = _NONFINITE[v]
        elif pa.types.is_string(arrow) and v is not None and not isinstance(v, str):
            v = json.dumps(v)
        out.append(pa.array([v] * n, arrow))
    return out


def _label_names(labels: Sequence[tuple[str, Any]], taken: Iterable[str]) -> list[str]:
    """Column names of the labels: the key, or ``setting:KEY`` where a key is also a column of
    the tables (a setting named ``t`` or ``x``)."""
    taken = set(taken)
    fixed = {"run", "planner", "seed"}
    return [k if k in fixed or k not in taken else f"setting:{k}" for k, _ in labels]


# --- the tables ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RunFacts:
    """What the tables of one run add to its events: each UAV's type, the geographic frame
    (None for a run in metres only), and the ``run`` table's row."""

    types: dict[int, str]  # UAV id -> type name
    frame: Any  # swarm.geo.frame.GeoFrame | None
    row: dict[str, Any]  # scenario, planner, seed, dt_s, sim_seconds, event_log_sha256, crs


RUN_COLUMNS = ("scenario", "planner", "seed", "dt_s", "sim_seconds", "event_log_sha256", "crs")


def run_facts(run_dir: Path, columns: Mapping[str, Mapping[str, list[Any]]]) -> RunFacts:
    """A run's :class:`RunFacts`, from its event log's columns (the ``start`` header: scenario,
    seed, planner, dt, the UAVs it began with and their types; ``join`` and ``restart``: the
    names of UAVs added later), ``metrics.json`` (those UAVs' types, how long it ran, its log's
    hash) and ``scenario.json`` (its ``[geo]`` frame)."""
    from swarm.geo.geojson import run_frame

    headers = columns["start"]["header"]
    header: Mapping[str, Any] = headers[0] if headers else {}
    metrics = read_json(run_dir / "metrics.json") if (run_dir / "metrics.json").is_file() else {}
    scenario = read_json(run_dir / "scenario.json")
    by_name = {str(name): str(u["type"]) for name, u in (metrics.get("per_uav") or {}).items()
               if isinstance(u, Mapping) and u.get("type") is not None}
    types = {int(uid): str(kind) for uid, _name, kind, *_ in header.get("uavs", [])}
    for kind in ("join", "restart"):
        for uid, name in zip(columns[kind]["uav"], columns[kind]["uav_name"]):
            if uid not in types and name in by_name:
                types[uid] = by_name[name]
    try:
        frame = run_frame(scenario)
    except Exception as exc:  # (a damaged [geo] table: a pyproj or key error)
        raise RunDirError(f"{run_dir / 'scenario.json'}: its [geo] table gives no map frame ({exc})") from None
    row = {"scenario": header.get("scenario"), "planner": header.get("planner"), "seed": header.get("seed"),
           "dt_s": header.get("dt"), "sim_seconds": metrics.get("sim_seconds"),
           "event_log_sha256": metrics.get("event_log_sha256"), "crs": frame.crs if frame is not None else None}
    return RunFacts(types, frame, row)


def _type_columns(spec: KindSpec) -> list[tuple[str, str, tuple[str, str] | None, str]]:
    """``(column, id field, condition, after)`` of each UAV type column of a kind: one per UAV
    id (``uav`` -> ``uav_type``, ``from_uav`` -> ``from_type`` as its ``from_name``, ``src`` ->
    ``src_type``; a violation's ``other`` -> ``other_type``, only where it is a UAV), placed
    after the id's name column (or the id where it has none)."""
    names = {f.meta.of: f for f in spec.fields if f.role == NAME}
    wire_names = {f.name for f in spec.fields if f.role != NAME}
    out: list[tuple[str, str, tuple[str, str] | None, str]] = []
    for f in spec.fields:
        if f.role == UAV:
            derived = names.get(f.name)
            name = derived.name if derived is not None else (f"{f.name}_name" if f"{f.name}_name" in wire_names
                                                              else None)
            stem = name[: -len("_name")] if name is not None and name.endswith("_name") else f.name
            out.append((f"{stem}_type", f.name, None, name or f.name))
    for of, f in names.items():
        if of is not None and not any(c[1] == of for c in out):  # (an id that is a UAV's only sometimes)
            out.append((f"{f.name[: -len('_name')]}_type", of, f.meta.when, f.name))
    return out


_TYPE_META = {"label": "UAV type"}
_LON_META = {"unit": "deg", "label": "WGS84 longitude"}
_LAT_META = {"unit": "deg", "label": "WGS84 latitude"}


def _layout(names: Sequence[str], types: Sequence[tuple[str, str, tuple[str, str] | None, str]],
            geo: bool) -> list[tuple[str, Any]]:
    """The columns of a table in order: ``(name, how)`` with ``how`` ``None`` (a column of its
    own), a type column's ``(id field, condition)``, or ``"lon"`` / ``"lat"`` (after ``y``
    when the export has a geographic run)."""
    after: dict[str, list[tuple[str, Any]]] = {}
    for column, of, when, follows in types:
        after.setdefault(follows, []).append((column, (of, when)))
    if geo and "x" in names and "y" in names:
        after.setdefault("y", []).extend([("lon", "lon"), ("lat", "lat")])
    out: list[tuple[str, Any]] = []
    for n in names:
        out.append((n, None))
        out.extend(after.get(n, []))
    return out


def _added_field(pa: Any, name: str, how: Any) -> Any:
    if how in ("lon", "lat"):
        return pa.field(name, pa.float64(), metadata=_LON_META if how == "lon" else _LAT_META)
    return pa.field(name, pa.string(), metadata=_TYPE_META)


def _added_column(pa: Any, how: Any, columns: Mapping[str, Sequence[Any]], facts: RunFacts) -> Any:
    """A type column (from the ids) or a lon/lat column (from ``x`` and ``y``) of one run."""
    if how in ("lon", "lat"):
        n = len(columns["x"])
        if facts.frame is None or not n:
            return pa.array([None] * n, pa.float64())
        lon, lat = facts.frame.to_lonlat(list(columns["x"]), list(columns["y"]))
        return pa.array(lon if how == "lon" else lat, pa.float64())
    of, when = how
    ids = columns[of]
    ok = [True] * len(ids) if when is None else [c == when[1] for c in columns[when[0]]]
    return pa.array([facts.types.get(int(u)) if keep and u is not None else None for u, keep in zip(ids, ok)],
                    pa.string())


def _event_layout(spec: KindSpec, geo: bool) -> list[tuple[str, Any]]:
    return _layout(["seq", *(f.name for f in spec.fields)], _type_columns(spec), geo)


def _event_schema(pa: Any, spec: KindSpec, geo: bool) -> Any:
    fields = {f.name: f for f in spec.fields}
    return pa.schema([pa.field("seq", pa.int64(), nullable=False) if name == "seq"
                      else _field(pa, fields[name]) if how is None else _added_field(pa, name, how)
                      for name, how in _event_layout(spec, geo)],
                     metadata={"kind": spec.kind, "doc": spec.doc})


def _timeseries(pa: Any, path: Path) -> Any | None:
    if not path.is_file():
        return None
    with path.open(newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        return None
    header, body = rows[0], rows[1:]
    columns = {}
    for i, name in enumerate(header):
        raw = [r[i] if i < len(r) else None for r in body]
        columns[name] = _typed_text(pa, raw)
    return pa.table(columns)


def _typed_text(pa: Any, raw: Sequence[str | None]) -> Any:
    """A CSV column as integers, else floats, else text."""
    for kind, convert in ((pa.int64(), int), (pa.float64(), float)):
        try:
            return pa.array([None if v in (None, "") else convert(v) for v in raw], kind)
        except ValueError:
            continue
    return pa.array(list(raw), pa.string())


def _paths(pa: Any, columns: Mapping[str, Mapping[str, list[Any]]], facts: RunFacts, geo: bool) -> Any:
    pose, target = columns["pose"], columns["target"]
    n_u, n_t = len(pose["t"]), len(target["t"])
    joined = {"object": ["uav"] * n_u + ["target"] * n_t, "id": list(pose["uav"]) + list(target["target"]),
              "name": list(pose["uav_name"]) + [None] * n_t, "t": list(pose["t"]) + list(target["t"]),
              "x": list(pose["x"]) + list(target["x"]), "y": list(pose["y"]) + list(target["y"])}
    kinds = {"object": pa.string(), "id": pa.int64(), "name": pa.string(), "t": pa.float64(), "x": pa.float64(),
             "y": pa.float64()}
    arrays, fields = [], []
    for name, how in _layout(list(joined), [("uav_type", "id", ("object", "uav"), "name")], geo):
        if how is None:
            arrays.append(pa.array(joined[name], kinds[name]))
            fields.append(pa.field(name, kinds[name]))
        else:
            arrays.append(_added_column(pa, how, joined, facts))
            fields.append(_added_field(pa, name, how))
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields))


def _run_table(pa: Any, facts: Sequence[RunFacts], labels: Sequence[tuple[str, Any]], names: Sequence[str],
               runs: Sequence[RunInfo]) -> Any:
    """One row per run: its sweep labels (a sweep), then :data:`RUN_COLUMNS` (planner and seed
    once)."""
    kinds = {"scenario": pa.string(), "planner": pa.string(), "seed": pa.int64(), "dt_s": pa.float64(),
             "sim_seconds": pa.float64(), "event_log_sha256": pa.string(), "crs": pa.string()}
    units = {"dt_s": "s", "sim_seconds": "s"}
    per_run = [_label_columns(pa, labels, r, 1) for r in runs]
    label_cols = [pa.concat_arrays([cols[i] for cols in per_run]) for i in range(len(labels))]
    own = [c for c in RUN_COLUMNS if c not in names]
    fields = [*(pa.field(n, t) for n, (_k, t) in zip(names, labels)),
              *(pa.field(c, kinds[c], metadata={"unit": units[c]} if c in units else None) for c in own)]
    arrays = [*label_cols, *(pa.array([f.row[c] for f in facts], kinds[c]) for c in own)]
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields))


def _shared_metadata(facts: Sequence[RunFacts]) -> dict[str, str]:
    """Every table's metadata: ``scenario`` and ``dt_s`` where all runs share them (a sweep of
    ``dt_s`` has one per run: the ``run`` table)."""
    out = {}
    for key in ("scenario", "dt_s"):
        values = {json.dumps(f.row[key]) for f in facts}
        if len(values) == 1 and facts[0].row[key] is not None:
            out[key] = str(facts[0].row[key])
    return out


def export_parquet(folder: str | os.PathLike[str], out: str | os.PathLike[str] | None = None) -> ExportResult:
    """Write the Parquet tables of a run folder or a sweep folder (see the module docstring)
    into ``out`` (default ``FOLDER/parquet``); each file is replaced whole (written beside, then
    renamed). :class:`MissingExtraError` without pyarrow, :class:`~swarm.outputs.RunDirError`
    for a folder that is neither a run nor a sweep."""
    runs, sweep = find_runs(folder)
    pa, pq = _pyarrow()
    # What each run adds (types, frame, its row of the run table) first, from the few events
    # that say it; then one run's whole log at a time.
    facts = [run_facts(run.path, _read_columns(run, ("start", "join", "restart"))) for run in runs]
    geo = any(f.frame is not None for f in facts)
    shared = _shared_metadata(facts)
    out_dir = Path(out) if out is not None else Path(folder) / "parquet"
    out_dir.mkdir(parents=True, exist_ok=True)
    labels = _label_types(pa, runs) if sweep else []
    taken = {"seq", *(f.name for spec in KINDS.values() for f in spec.fields), "object", "id", "name", "x", "y",
             "lon", "lat", *(c for spec in KINDS.values() for c, *_ in _type_columns(spec)), *RUN_COLUMNS}
    names = _label_names(labels, taken)
    label_fields = [pa.field(n, t) for n, (_k, t) in zip(names, labels)]
    rows = {k: 0 for k in (*KINDS, *TABLES_BESIDE_EVENTS, "run")}
    layouts = {kind: _event_layout(spec, geo) for kind, spec in KINDS.items()}
    schemas = {kind: _event_schema(pa, spec, geo) for kind, spec in KINDS.items()}
    schemas = {k: pa.schema([*label_fields, *s], metadata={**s.metadata, **{k.encode(): v.encode()
                                                                           for k, v in shared.items()}})
               for k, s in schemas.items()}
    extra: dict[str, list[Any]] = {name: [] for name in TABLES_BESIDE_EVENTS}
    with contextlib.ExitStack() as stack:
        writers = {}
        for kind, schema in schemas.items():
            # Written beside, renamed into place when every run is in (atomic_path).
            writers[kind] = pq.ParquetWriter(stack.enter_context(atomic_path(out_dir / f"{kind}.parquet")), schema)
            stack.callback(writers[kind].close)
        for run, fact in zip(runs, facts):
            columns = _read_columns(run)
            for kind, spec in KINDS.items():
                n = len(columns[kind]["seq"])
                if not n:
                    continue
                fields = {f.name: f for f in spec.fields}
                arrays = [*_label_columns(pa, labels, run, n)]
                for name, how in layouts[kind]:
                    if name == "seq":
                        arrays.append(pa.array(columns[kind]["seq"], pa.int64()))
                    elif how is None:
                        arrays.append(_column(pa, fields[name], columns[kind][name]))
                    else:
                        arrays.append(_added_column(pa, how, columns[kind], fact))
                writers[kind].write_table(pa.Table.from_arrays(arrays, schema=schemas[kind]))
                rows[kind] += n
            for name, table in (("timeseries", _timeseries(pa, run.path / "timeseries.csv")),
                                ("paths", _paths(pa, columns, fact, geo))):
                if table is None:
                    continue
                for i, (label_name, col) in enumerate(zip(names, _label_columns(pa, labels, run, table.num_rows))):
                    table = table.add_column(i, label_name, col)
                extra[name].append(table)
    for name, tables in extra.items():
        if not tables:
            del rows[name]  # (no timeseries.csv in any run)
            continue
        table = pa.concat_tables(tables, promote_options="permissive")
        rows[name] = table.num_rows
        _write_table(pq, table, out_dir / f"{name}.parquet", shared)
    run_table = _run_table(pa, facts, labels, names, runs)
    rows["run"] = run_table.num_rows
    _write_table(pq, run_table, out_dir / "run.parquet", shared)
    return ExportResult(out_dir, len(runs), rows)


def _read_columns(run: RunInfo, kinds: Sequence[str] | None = None) -> dict[str, dict[str, list[Any]]]:
    try:
        return read_columns((run.path / "events.msgpack").read_bytes(), kinds, positions=True)
    except ValueError as exc:  # (EventLogError, a truncated file)
        raise RunDirError(f"{run.path / 'events.msgpack'}: not a readable event log ({exc})") from None


def _write_table(pq: Any, table: Any, path: Path, metadata: Mapping[str, str]) -> None:
    table = table.replace_schema_metadata({**(table.schema.metadata or {}),
                                           **{k.encode(): v.encode() for k, v in metadata.items()}})
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)
