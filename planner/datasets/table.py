"""Flat tables: ``grasps.parquet`` / ``grasps.csv``, one row per grasp.

Every column of the ``grasps`` table, flat (JSON vectors expanded, joints
and contacts kept as JSON text), with the grasp's validation and robust
rows and its object's properties. Rows come per (object, hand) in rank
order. Empty / null means absent (not computed, not validated). Parquet is
written with an explicit schema (each field's metadata holds its ``unit``
and ``description``: :func:`field_metadata`), one row group per database batch; CSV by
the ``csv`` module with a header row, floats written in full precision.
``object_file`` names the object's mesh in the export folder,
``meshes/{object}.obj``, in metres (:mod:`planner.datasets.meshes`).

The columns are the declared fields (:func:`planner.record.fields.record_fields`),
vectors expanded (``pose_00`` ... ``pose_33``), ``id`` as ``grasp_id`` and
the robust epsilon as ``robust_epsilon_*``, then the object's
``object_mass``, ``object_friction``, ``object_density``, ``object_up``, ``object_scale`` and
``object_file``; :data:`COLUMNS_DOC` is the table of them the README shows.
ACRONYM's gripper frame is ``pose`` times the hand's export frame.
"""

from __future__ import annotations

import csv
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from planner.datasets import registry
from planner.datasets.columns import Stream, grasp_columns
from planner.datasets.labels import labels as dataset_labels
from planner.record.fields import GROUPS, Field, by_name, record_fields
from planner.record.grasp import Grasp

_AXES = ("x", "y", "z")
#: Flat names renamed in the table.
RENAMED = {"id": "grasp_id", "robust_mean": "robust_epsilon_mean", "robust_quantile": "robust_epsilon_quantile"}
#: The object's declared fields the table repeats on every row.
OBJECT_FIELDS = ("object_mass", "object_friction", "object_density", "object_up")
#: Columns of the export, not of the database: (name, arrow type, meaning).
EXPORT_COLUMNS = (("object_scale", "float64", "scale that turns `object_file` into metres: 1 (the mesh file is in "
                   "metres)"),
                  ("object_file", "string", "the object's mesh, `meshes/{object}.obj`, relative to the export folder"),
                  ("label", "int64", "success label as `--label` chooses: 1 holds, 0 drops (see `label_from`)"),
                  ("label_from", "string", "where the label came from: `file_label` (the label of the file the "
                   "grasp was imported from), `p_hold_trial` (p_hold updated by the trial's verdict, >= 0.5), `trial` (the dynamic trial: MuJoCo's, else PyBullet's), `p_hold` "
                   "(p_hold >= 0.5) or `force_closure` (a closure flag, not a success label)"),
                  ("p_hold_outside", "string", "where the object lies outside the labelled objects the hand's "
                   "p_hold model was fitted on (`density 1,322 kg/m^3 (labels: 150-157 kg/m^3); friction 0.5 "
                   "(labels: 1)`); empty inside: there p_hold, and a label from it, is an extrapolation"))


def _suffixes(shape: tuple[int, ...]) -> list[tuple[str, tuple[int, ...]]]:
    """Column suffixes of a vector field and the index of each."""
    if shape == (3,):
        return [(f"_{a}", (i,)) for i, a in enumerate(_AXES)]
    if len(shape) == 1:
        return [(f"_{i}", (i,)) for i in range(shape[0])]
    return [(f"_{i}{j}", (i, j)) for i in range(shape[0]) for j in range(shape[1])]


def _spec() -> list[tuple[str, str, str, tuple[int, ...], Field | None]]:
    """(column, arrow type, source field of :func:`grasp_columns`, index, declaration)."""
    out: list[tuple[str, str, str, tuple[int, ...], Field | None]] = []
    for f in record_fields():
        name = RENAMED.get(f.name, f.name)
        for suffix, index in _suffixes(f.shape) if f.shape else [("", ())]:
            out.append((name + suffix, f.dtype, f.name, index, f))
    out += [(name, by_name(name).dtype, "", (), by_name(name)) for name in OBJECT_FIELDS]
    return out + [(name, kind, "", (), None) for name, kind, _ in EXPORT_COLUMNS]


_SPEC = _spec()
COLUMNS = [name for name, *_ in _SPEC]
#: Columns that may be null: NaN (floats) or -1 (integers) in the grasp columns.
NULLABLE = {name for name, _, _, _, f in _SPEC
            if f is not None and f.dtype != "string"
            and (f.nullable or f.attr.partition(".")[0] in GROUPS)}


def _doc_rows() -> list[str]:
    rows, done = [], set()
    for name, kind, _, _, f in _SPEC:
        if f is None or f.name in done:
            continue
        done.add(f.name)
        names = [c for c, *_, g in _SPEC if g is f]
        meaning = (f"[{f.unit}] " if f.unit else "") + f.doc
        rows.append(f"| {', '.join(f'`{c}`' for c in names)} | {kind}{', null' if name in NULLABLE else ''} | "
                    f"{meaning} |")
    return rows + [f"| `{name}` | {kind} | {meaning} |" for name, kind, meaning in EXPORT_COLUMNS]


#: The column table, for the README.
COLUMNS_DOC = "\n".join(["| column | type | meaning |", "| --- | --- | --- |", *_doc_rows()]) + "\n"


def columns(stream: Stream, batch: list[Grasp]) -> dict[str, np.ndarray | list]:
    """One batch as flat columns (numpy arrays or lists of str)."""
    n, info = len(batch), stream.info
    constants = {"object_mass": info.row.mass, "object_friction": info.row.friction,
                 "object_density": info.row.density, "object_up": info.row.up, "object_scale": info.scale,
                 "object_file": info.file,
                 "p_hold_outside": info.outside_text}
    grasps = grasp_columns(batch)
    label, label_from = dataset_labels(grasps, info.label)
    labelled = {"label": label, "label_from": label_from}
    out: dict[str, np.ndarray | list] = {}
    for name, _, source, index, _ in _SPEC:
        if name in labelled:
            out[name] = labelled[name]
            continue
        if not source:
            out[name] = [constants[name]] * n
            continue
        values = grasps[source]
        out[name] = values[(slice(None), *index)] if index else values  # type: ignore[call-overload]
    return out


def _nulls(name: str, values: np.ndarray) -> np.ndarray | None:
    if name not in NULLABLE:
        return None
    return np.isnan(values) if values.dtype.kind == "f" else values < 0


def field_metadata(column: str) -> dict[str, str]:
    """A Parquet column's field metadata: its ``unit`` ('' for none: m, rad, g, kg ...) and ``description``,
    as the README's column table gives them (``pyarrow.parquet.read_schema(path).field(column).metadata``)."""
    f = _FIELDS[column]
    if f is None:
        return {"unit": "", "description": _EXPORT_MEANINGS[column]}
    index = _INDEX[column]
    if f.shape == (4, 4) and not (index[1] == 3 and index[0] < 3):  # a pose: only its translation is in [m]
        return {"unit": "", "description": f.doc}
    return {"unit": f.unit, "description": f.doc}


_FIELDS = {name: f for name, _, _, _, f in _SPEC}
_INDEX = {name: index for name, _, _, index, _ in _SPEC}
_EXPORT_MEANINGS = {name: meaning for name, _, meaning in EXPORT_COLUMNS}


def write_parquet(path: Path, streams: Iterable[Stream]) -> int:
    import pyarrow as pa
    import pyarrow.parquet as pq

    schema = pa.schema([pa.field(name, getattr(pa, kind)(), metadata=field_metadata(name))
                        for name, kind, *_ in _SPEC])
    total = 0
    with pq.ParquetWriter(path, schema) as writer:
        for stream in streams:
            for batch in stream.batches:
                arrays = [pa.array(v, type=schema.field(k).type, mask=_nulls(k, v) if isinstance(v, np.ndarray)
                                   else None) for k, v in columns(stream, batch).items()]
                writer.write_table(pa.Table.from_arrays(arrays, schema=schema))
                total += len(batch)
    return total


def write_csv(path: Path, streams: Iterable[Stream]) -> int:
    total = 0
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(COLUMNS)
        for stream in streams:
            for batch in stream.batches:
                cols = []
                for name, values in columns(stream, batch).items():
                    if isinstance(values, np.ndarray):
                        mask = _nulls(name, values)
                        values = values.tolist()
                        if mask is not None and mask.any():
                            values = [None if m else v for v, m in zip(values, mask.tolist())]
                    cols.append(values)
                writer.writerows(zip(*cols))
                total += len(batch)
    return total


#: Cells ``pandas.read_csv`` reads as missing by default (its ``STR_NA_VALUES``), and the booleans it
#: (and ``polars.read_csv``) turns into True / False.
PANDAS_MISSING = frozenset({"", "#N/A", "#N/A N/A", "#NA", "-1.#IND", "-1.#QNAN", "-NaN", "-nan", "1.#IND",
                            "1.#QNAN", "<NA>", "N/A", "NA", "NULL", "NaN", "None", "n/a", "nan", "null"})
CSV_BOOLEANS = frozenset({"true", "false"})


def misread_name(name: str) -> bool:
    """Whether a reader that infers each CSV column's type from its text
    (``pandas.read_csv``, ``polars.read_csv``, ``pyarrow.csv.read_csv``) may not give ``name`` back as
    that text: a number ('001' reads as 1, '1e3' as 1000.0), a boolean or
    one of pandas' missing-value markers ('NA', 'null')."""
    if name in PANDAS_MISSING or name.strip().lower() in CSV_BOOLEANS:
        return True
    try:
        float(name)
    except ValueError:
        return False
    return "_" not in name  # Python's float() reads '1_000'; the CSV readers keep it as text


def csv_notes(pairs: Sequence[tuple[str, str]]) -> list[str]:
    """A note for every text column of names whose values a type-inferring reader turns into numbers or
    missing values (the object names of a folder of ``000.obj``, ``001.obj``, ...)."""
    notes = []
    for column, index in (("object", 0), ("hand", 1)):
        bad = sorted({p[index] for p in pairs if misread_name(p[index])})
        if bad:
            notes.append(f"{column} names {', '.join(repr(n) for n in bad)} look like numbers or missing values: "
                         f"pandas.read_csv, polars.read_csv and pyarrow.csv.read_csv infer each column's type from "
                         f"its text and may read them as such, silently; read grasps.csv with pd.read_csv(path, "
                         f"dtype={{'{column}': str}}, "
                         f"keep_default_na=False, na_values=['']) or pl.read_csv(path, "
                         f"schema_overrides={{'{column}': pl.String}}), or export --format parquet, which keeps "
                         f"every column's type")
    return notes


registry.register("parquet", registry.TableWriter("grasps.parquet", write_parquet))
registry.register("csv", registry.TableWriter("grasps.csv", write_csv, csv_notes))
