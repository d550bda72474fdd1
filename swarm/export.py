"""Columnar export: a run folder's (or a whole sweep's) event log, time series and paths as
Parquet tables with named, typed columns (``swarm export FOLDER --format parquet``).

Needs pyarrow, the ``parquet`` extra (``pip install 'uav-swarm-sim[parquet]'``); the simulator
itself never does. The tables, in ``--out`` (default ``FOLDER/parquet``):

* ``<kind>.parquet``, one per event kind of :data:`swarm.events.KINDS` (every kind, empty when
  the log has none): ``seq`` (the event's position in the log, 0 for ``start``: the order
  across tables, within a tick too), then the kind's record fields, their Arrow types made from
  the schema's annotations (``float`` float64, ``int`` int64, ``bool``, ``str`` string, a
  table of counts a map, the ``start`` header JSON text) and their units in each column's
  metadata (``unit``);
* ``timeseries.parquet``: ``timeseries.csv`` with typed columns (integers, floats, mode names);
* ``paths.parquet``: ``object`` (``uav`` or ``target``), ``id``, ``name`` (a UAV's), ``t``,
  ``x``, ``y``: the UAV and target positions of the ``pose`` and ``target`` events, in one
  table for plotting.

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
from swarm.events import KINDS, FieldSpec, KindSpec, read_columns
from swarm.outputs import RunDirError, atomic_path, check_run_dir, read_json

__all__ = ["ExportResult", "MissingExtraError", "export_parquet", "find_runs"]

EXTRA_HINT = "pip install 'uav-swarm-sim[parquet]'"
TABLES_BESIDE_EVENTS = ("timeseries", "paths")


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


def _event_schema(pa: Any, spec: KindSpec) -> Any:
    return pa.schema([pa.field("seq", pa.int64(), nullable=False), *(_field(pa, f) for f in spec.fields)],
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


def _paths(pa: Any, columns: Mapping[str, Mapping[str, list[Any]]]) -> Any:
    pose, target = columns["pose"], columns["target"]
    n_u, n_t = len(pose["t"]), len(target["t"])
    return pa.table({
        "object": pa.array(["uav"] * n_u + ["target"] * n_t, pa.string()),
        "id": pa.array(list(pose["uav"]) + list(target["target"]), pa.int64()),
        "name": pa.array(list(pose["uav_name"]) + [None] * n_t, pa.string()),
        "t": pa.array(list(pose["t"]) + list(target["t"]), pa.float64()),
        "x": pa.array(list(pose["x"]) + list(target["x"]), pa.float64()),
        "y": pa.array(list(pose["y"]) + list(target["y"]), pa.float64()),
    })


def export_parquet(folder: str | os.PathLike[str], out: str | os.PathLike[str] | None = None) -> ExportResult:
    """Write the Parquet tables of a run folder or a sweep folder (see the module docstring)
    into ``out`` (default ``FOLDER/parquet``); each file is replaced whole (written beside, then
    renamed). :class:`MissingExtraError` without pyarrow, :class:`~swarm.outputs.RunDirError`
    for a folder that is neither a run nor a sweep."""
    runs, sweep = find_runs(folder)
    pa, pq = _pyarrow()
    out_dir = Path(out) if out is not None else Path(folder) / "parquet"
    out_dir.mkdir(parents=True, exist_ok=True)
    labels = _label_types(pa, runs) if sweep else []
    taken = {"seq", *(f.name for spec in KINDS.values() for f in spec.fields), "object", "id", "name", "x", "y"}
    names = _label_names(labels, taken)
    label_fields = [pa.field(n, t) for n, (_k, t) in zip(names, labels)]
    rows = {k: 0 for k in (*KINDS, *TABLES_BESIDE_EVENTS)}
    schemas = {kind: _event_schema(pa, spec) for kind, spec in KINDS.items()}
    schemas = {k: pa.schema([*label_fields, *s], metadata=s.metadata) for k, s in schemas.items()}
    extra: dict[str, list[Any]] = {name: [] for name in TABLES_BESIDE_EVENTS}
    with contextlib.ExitStack() as stack:
        writers = {}
        for kind, schema in schemas.items():
            # Written beside, renamed into place when every run is in (atomic_path).
            writers[kind] = pq.ParquetWriter(stack.enter_context(atomic_path(out_dir / f"{kind}.parquet")), schema)
            stack.callback(writers[kind].close)
        for run in runs:
            try:
                columns = read_columns((run.path / "events.msgpack").read_bytes(), positions=True)
            except ValueError as exc:  # (EventLogError, a truncated file)
                raise RunDirError(f"{run.path / 'events.msgpack'}: not a readable event log ({exc})") from None
            for kind, spec in KINDS.items():
                n = len(columns[kind]["seq"])
                if not n:
                    continue
                arrays = [*_label_columns(pa, labels, run, n), pa.array(columns[kind]["seq"], pa.int64()),
                          *(_column(pa, f, columns[kind][f.name]) for f in spec.fields)]
                writers[kind].write_table(pa.Table.from_arrays(arrays, schema=schemas[kind]))
                rows[kind] += n
            for name, table in (("timeseries", _timeseries(pa, run.path / "timeseries.csv")),
                                ("paths", _paths(pa, columns))):
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
        with atomic_path(out_dir / f"{name}.parquet") as tmp:
            pq.write_table(table, tmp)
    return ExportResult(out_dir, len(runs), rows)
