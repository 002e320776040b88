"""Flat tables: ``grasps.parquet`` / ``grasps.csv``, one row per grasp.

Every column of the ``grasps`` table, flat (JSON vectors expanded, joints
and contacts kept as JSON text), with the grasp's validation and robust
rows and its object's properties. Rows come per (object, hand) in rank
order. Empty / null means absent (not computed, not validated). Parquet is
written with an explicit schema, one row group per database batch; CSV by
the ``csv`` module with a header row, floats written in full precision.
``object_file`` names the object's mesh in the export folder,
``meshes/{object}.obj``, in metres (:mod:`planner.datasets.meshes`).

| column | type | meaning |
| --- | --- | --- |
| `object` | string | object name (key of the `objects` table) |
| `hand` | string | hand name |
| `grasp_id` | int64 | `grasps.id` in the exported database |
| `unit_id` | int64 | the unit of work that produced the grasp |
| `preshape` | string | preshape name |
| `candidate` | int64 | candidate number in the unit's enumeration (to replay it) |
| `seed` | int64 | the unit's seed |
| `approach_point_x`, `approach_point_y`, `approach_point_z` | float64 | [m] where the approach ray meets the object, object frame |
| `approach_dir_x`, `approach_dir_y`, `approach_dir_z` | float64 | unit approach direction, object frame |
| `roll` | float64 | [rad] roll of the hand about the approach direction |
| `standoff` | float64 | [m] back-off after first contact, before closing |
| `pose_00`, `pose_01`, `pose_02`, `pose_03`, `pose_10`, `pose_11`, `pose_12`, `pose_13`, `pose_20`, `pose_21`, `pose_22`, `pose_23`, `pose_30`, `pose_31`, `pose_32`, `pose_33` | float64 | grasp pose, row-major 4x4: the hand frame (`root_link`) in the object frame, metres; ACRONYM's gripper frame is this times the hand's export frame |
| `width` | float64, null | [m] distance between the fingers (parallel jaws) |
| `open_joints` | string | JSON `{joint: value}` of the preshape [rad or m] |
| `closed_joints` | string | JSON `{joint: value}` of the closed hand [rad or m] |
| `contacts` | string | JSON `[{point, normal, link}]`, object frame, normals into the object |
| `n_contacts` | int64 | number of contacts |
| `links_touching` | int64 | number of hand links touching the object |
| `epsilon` | float64 | Ferrari-Canny L1 epsilon (0 unless force-closure) |
| `volume` | float64 | volume of the grasp wrench space (0 unless generated with `--volume`) |
| `force_closure` | int64 | 1 if force-closure, else 0 |
| `resist_worst` | float64, null | [g] weight resistance, worst of 14 gravity directions (object frame) |
| `resist_mean` | float64, null | [g] weight resistance, mean over the 14 directions |
| `open_margin` | float64, null | [m] smallest travel a touching finger has left towards its open limit |
| `close_margin` | float64, null | [m] smallest travel a touching finger has left towards its closing stop |
| `push` | float64, null | smallest cosine between a finger region's contact normal and its closing motion |
| `feasibility` | string | feasibility reasons, comma-separated ('' = feasible) |
| `settled_epsilon` | float64, null | Ferrari-Canny epsilon of the contacts after a dynamic closing (hands with `settle`) |
| `reachability` | float64, null | fraction of sampled table placements an arm reaches |
| `manipulability` | float64, null | best arm manipulability over the reachable placements |
| `score` | float64 | ranking score (`meta.ranking` says how) |
| `p_hold` | float64, null | calibrated probability that the grasp holds (the hand's `grasp calibrate` model, or the shipped one) |
| `rank` | int64, null | 1 = best grasp of its (object, hand) |
| `validation_success` | int64, null | 1 if the object stayed in the hand in the PyBullet trial |
| `validation_fingers_in_contact` | int64, null | fingers touching the object after shaking |
| `validation_closing_linear` | float64, null | [m] object motion during closing |
| `validation_closing_angular` | float64, null | [rad] object rotation during closing |
| `validation_shaking_linear` | float64, null | [m] object motion during shaking |
| `validation_shaking_angular` | float64, null | [rad] object rotation during shaking |
| `robust_epsilon_mean` | float64, null | robust epsilon: mean over pose / friction noise samples |
| `robust_epsilon_quantile` | float64, null | robust epsilon: low quantile over the samples |
| `robust_samples` | int64, null | noise samples behind the robust values |
| `object_mass` | float64 | [kg] |
| `object_friction` | float64 | friction coefficient used for the quality |
| `object_scale` | float64 | scale that turns `object_file` into metres: 1 (the mesh file is in metres) |
| `object_file` | string | the object's mesh, `meshes/{object}.obj`, relative to the export folder |
"""

from __future__ import annotations

import csv
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from planner.datasets.columns import Stream, grasp_columns
from planner.grasp import Grasp

#: The column table above, for the README.
COLUMNS_DOC = __doc__[__doc__.index("| column |"):].strip() + "\n"

_AXES = ("x", "y", "z")
#: (column, arrow type name, source: a column of :func:`grasp_columns`, optionally with an index)
_SPEC: list[tuple[str, str, str]] = [
    ("object", "string", ""), ("hand", "string", ""), ("grasp_id", "int64", "id"),
    ("unit_id", "int64", "unit_id"), ("preshape", "string", "preshape"), ("candidate", "int64", "candidate"),
    ("seed", "int64", "seed"),
    *((f"approach_point_{a}", "float64", f"approach_point:{i}") for i, a in enumerate(_AXES)),
    *((f"approach_dir_{a}", "float64", f"approach_dir:{i}") for i, a in enumerate(_AXES)),
    ("roll", "float64", "roll"), ("standoff", "float64", "standoff"),
    *((f"pose_{i}{j}", "float64", f"pose:{i}:{j}") for i in range(4) for j in range(4)),
    ("width", "float64", "width"), ("open_joints", "string", "open_joints"),
    ("closed_joints", "string", "closed_joints"), ("contacts", "string", "contacts"),
    ("n_contacts", "int64", "n_contacts"), ("links_touching", "int64", "links_touching"),
    ("epsilon", "float64", "epsilon"), ("volume", "float64", "volume"),
    ("force_closure", "int64", "force_closure"),
    *((name, "float64", name) for name in ("resist_worst", "resist_mean", "open_margin", "close_margin", "push")),
    ("feasibility", "string", "feasibility"), ("settled_epsilon", "float64", "settled_epsilon"),
    ("reachability", "float64", "reachability"),
    ("manipulability", "float64", "manipulability"), ("score", "float64", "score"),
    ("p_hold", "float64", "p_hold"), ("rank", "int64", "rank"),
    ("validation_success", "int64", "validation_success"),
    ("validation_fingers_in_contact", "int64", "validation_fingers_in_contact"),
    *((f"validation_{s}_{k}", "float64", f"validation_{s}_{k}") for s in ("closing", "shaking")
      for k in ("linear", "angular")),
    ("robust_epsilon_mean", "float64", "robust_mean"), ("robust_epsilon_quantile", "float64", "robust_quantile"),
    ("robust_samples", "int64", "robust_samples"),
    ("object_mass", "float64", ""), ("object_friction", "float64", ""), ("object_scale", "float64", ""),
    ("object_file", "string", ""),
]
COLUMNS = [name for name, _, _ in _SPEC]
#: Columns that may be null: NaN (floats) or -1 (integers) in the grasp columns.
NULLABLE = {"width", "reachability", "manipulability", "rank", "resist_worst", "resist_mean", "open_margin",
            "close_margin", "push", "settled_epsilon", "p_hold", *(c for c in COLUMNS if c.startswith(
    ("validation_", "robust_")))}


def columns(stream: Stream, batch: list[Grasp]) -> dict[str, np.ndarray | list]:
    """One batch as flat columns (numpy arrays or lists of str)."""
    n, info = len(batch), stream.info
    constants = {"object": info.name, "hand": stream.hand, "object_mass": info.row.mass,
                 "object_friction": info.row.friction, "object_scale": info.scale, "object_file": info.file}
    grasps = grasp_columns(batch)
    out: dict[str, np.ndarray | list] = {}
    for name, _, source in _SPEC:
        if not source:
            out[name] = [constants[name]] * n
            continue
        field, *index = source.split(":")
        values = grasps[field]
        out[name] = values[(slice(None), *map(int, index))] if index else values  # type: ignore[call-overload]
    return out


def _nulls(name: str, values: np.ndarray) -> np.ndarray | None:
    if name not in NULLABLE:
        return None
    return np.isnan(values) if values.dtype.kind == "f" else values < 0


def write_parquet(path: Path, streams: Iterable[Stream]) -> int:
    import pyarrow as pa
    import pyarrow.parquet as pq

    schema = pa.schema([(name, getattr(pa, kind)()) for name, kind, _ in _SPEC])
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
