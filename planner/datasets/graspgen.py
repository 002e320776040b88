"""GraspGen JSON: one file ``{object}__{hand}.json`` per (object, hand).

The content of the ACRONYM export (see :mod:`planner.datasets.acronym`) as
GraspGen lays it out::

    {"object": {"file", "name", "scale", "mass", "friction", "density", "volume", "com", "inertia"},
     "gripper": {"type", "configuration", "joint_names", "export_frame"},
     "grasps": {"transforms": [N x 4 x 4], "object_in_gripper": [N], "label_source": str,
                "object_motion_during_closing_linear": [N], ..., "epsilon": [N], ...}}

Every per-grasp HDF5 dataset becomes a list named by its last path
component; ``contacts`` are decoded into lists of ``{point, normal, link}``;
NaN becomes ``null``.

Streaming: rows arrive in batches but the layout is one list per field, so
each field's list is spooled to its own temporary file and the files are
concatenated into the JSON document at the end (memory stays one batch).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from collections.abc import Iterable
from contextlib import ExitStack
from pathlib import Path
from typing import IO

import numpy as np

from planner.datasets.acronym import joint_names, label_source, max_opening, per_grasp, validated_count
from planner.db.store import ObjectRow
from planner.grasp import Grasp
from planner.specs.hands import HandSpec

SUFFIX = ".json"


def write(path: Path, info: ObjectRow, hand: HandSpec, batches: Iterable[list[Grasp]]) -> int:
    """Write the file (atomically); returns the number of grasps."""
    total = validated = 0
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=".graspgen-") as spool, ExitStack() as stack:
        lists: dict[str, IO[str]] = {}
        for batch in batches:
            for key, values in per_grasp(batch, hand).items():
                name = key.rsplit("/", 1)[-1]
                if name not in lists:
                    lists[name] = stack.enter_context(open(Path(spool) / f"{len(lists)}.part", "w+", encoding="utf-8"))
                _spool(lists[name], name, values, first=total == 0)
            total += len(batch)
            validated += validated_count(batch)
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "w", encoding="utf-8") as out:
            out.write('{"object": ' + json.dumps(_object(info)) + ', "gripper": ' + json.dumps(_gripper(hand)))
            out.write(', "grasps": {"label_source": ' + json.dumps(label_source(validated, total)))
            for name, part in lists.items():
                out.write(f', "{name}": [')
                part.seek(0)
                shutil.copyfileobj(part, out)
                out.write("]")
            out.write("}}\n")
    os.replace(tmp, path)
    return total


def _spool(part: IO[str], name: str, values: np.ndarray | list[str], first: bool) -> None:
    if name == "contacts":
        text = ", ".join(values)  # type: ignore[arg-type]  # already JSON
    else:
        array = None if isinstance(values, list) else np.asarray(values)
        if array is None:
            items = values
        else:  # the NaN scan is cheap; rewriting nested lists is not
            items = _nulls(array.tolist()) if array.dtype.kind == "f" and np.isnan(array).any() else array.tolist()
        text = json.dumps(items, allow_nan=False)[1:-1]
    if text:
        part.write(text if first else ", " + text)  # json.dumps' own separator: batching leaves no trace


def _nulls(values: list) -> list:
    """NaN -> None, at any depth (JSON has no NaN)."""
    if values and isinstance(values[0], list):
        return [_nulls(v) for v in values]
    return [None if isinstance(v, float) and math.isnan(v) else v for v in values]


def _object(info: ObjectRow) -> dict:
    scalars = {k: getattr(info, k) for k in ("scale", "mass", "friction", "density", "volume")}
    return {"file": info.source, "name": info.name, **_nulls_dict(scalars), "com": _nulls(info.com.tolist()),
            "inertia": _nulls(info.inertia.tolist())}


def _nulls_dict(values: dict[str, float]) -> dict[str, float | None]:
    return {k: None if math.isnan(v) else float(v) for k, v in values.items()}


def _gripper(hand: HandSpec) -> dict:
    return {"type": hand.name, "configuration": [max_opening(hand)], "joint_names": joint_names(hand),
            "export_frame": hand.export_frame.tolist()}
