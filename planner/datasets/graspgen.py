"""GraspGen JSON: one file per (object, hand), in GraspGen's dataset layout.

GraspGen trains one model per gripper, on a folder of grasp JSONs keyed by
their ``object.file``; GraspDataGen, its official data generator, writes one
such folder per gripper. This export does the same, with the export folder
DIR as GraspGen's object root::

    DIR/meshes/{object}.obj                        the mesh, in metres (object.file)
    DIR/grasp_data/{hand}/{object}.json            grasp_root_dir of the hand
    DIR/grasp_data/{hand}/map_uuid_to_path.json    object.file -> JSON file name
    DIR/splits/{hand}/train.txt, valid.txt         object keys (object.file), one per line

So object keys are unique per (object, hand): the hands of one object share
the mesh file and never share a folder. Each file holds the content of the
ACRONYM export (see :mod:`planner.datasets.acronym`)::

    {"object": {"file", "scale", "name", "source", "source_scale", "mesh_sha256", "mass", "friction",
                "density", "volume", "com", "inertia", "up", "p_hold_outside"},
     "gripper": {"type", "configuration", "configuration_joints", "joint_names", "export_frame"},
     "grasps": {"transforms": [N x 4 x 4], "object_in_gripper": [N booleans], "label_source": str,
                "label_from": [N str: file_label, p_hold_trial, trial, p_hold or force_closure],
                "object_motion_during_closing_linear": [N], ..., "epsilon": [N], ...}}

``object.file`` is ``meshes/{object}.obj`` (relative to DIR) and
``object.scale`` 1. ``object_in_gripper`` and ``force_closure`` are JSON
booleans: GraspGen selects the positives with ``transforms[mask]`` and the
negatives with ``~mask``, which only a boolean array reads as a mask (0/1
integers would pick rows 0 and 1 over and over). Every other per-grasp HDF5
dataset becomes a list named by its last path component; ``contacts`` are
decoded into lists of ``{point, normal, link}``; NaN and infinity become ``null``.

GraspGen loads ``map_uuid_to_path.json`` when the grasp folder has one and
then never looks at the files, so a stale one hides objects silently:
:func:`finish` rewrites it after every export from the JSON files in the
folder (ours and any others), and rewrites the splits from the same list:
an object goes to ``valid.txt`` when the first 8 hex digits of the sha256 of
its name, as a fraction of 16**8, fall below :data:`VALID_FRACTION` (a split
that does not change as objects are added), unless that would leave
``train.txt`` empty.

Streaming: rows arrive in batches but the layout is one list per field, so
each field's list is spooled to its own temporary file and the files are
concatenated into the JSON document at the end (memory stays one batch).
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import shutil
from collections.abc import Iterable, Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import IO

import numpy as np

from planner import assets
from planner.datasets import registry
from planner.datasets.acronym import gripper_configuration, joint_names, per_grasp
from planner.datasets.labels import file_source
from planner.datasets.meshes import ExportedObject
from planner.record.grasp import Grasp
from planner.specs.hands import HandSpec

log = logging.getLogger(__name__)

SUFFIX = ".json"
GRASP_DATA, SPLITS, MAPPING = "grasp_data", "splits", "map_uuid_to_path.json"
#: Per-grasp lists written as JSON booleans.
BOOLEANS = ("object_in_gripper", "force_closure")
#: Share of the objects in the valid split (GraspDataGen's default).
VALID_FRACTION = 0.2
#: Every file this writer makes starts like this, with the object block.
HEAD = '{"object": '
#: Characters read to find the object block (it is about 1 kB).
HEAD_CHARS = 1 << 16


def relative_path(stem: str, hand: str) -> str:
    """Where the file of (object, hand) goes in the export folder."""
    return f"{GRASP_DATA}/{hand}/{stem}{SUFFIX}"


def write(path: Path, info: ExportedObject, hand: HandSpec, batches: Iterable[list[Grasp]]) -> int:
    """Write the file (atomically); returns the number of grasps."""
    total = 0
    sources: set[str] = set()
    spool = path.with_name(f".{path.name}.spool")  # one name per file: a rerun clears what a kill -9 left
    shutil.rmtree(spool, ignore_errors=True)
    spool.mkdir()
    with ExitStack() as stack:
        stack.callback(shutil.rmtree, spool, ignore_errors=True)  # after the parts below are closed
        lists: dict[str, IO[str]] = {}
        for batch in batches:
            columns = per_grasp(batch, hand, info.label)
            sources.update(columns["qualities/label_from"])
            for key, values in columns.items():
                name = key.rsplit("/", 1)[-1]
                if name not in lists:
                    lists[name] = stack.enter_context(open(Path(spool) / f"{len(lists)}.part", "w+", encoding="utf-8"))
                _spool(lists[name], name, values, first=total == 0)
            total += len(batch)
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "w", encoding="utf-8") as out:
            out.write(HEAD + json.dumps(_object(info)) + ', "gripper": ' + json.dumps(_gripper(hand)))
            out.write(', "grasps": {"label_source": ' + json.dumps(file_source(sources)))
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
        if array is not None and name in BOOLEANS:
            array = array.astype(bool)
        if array is None:
            items = values
        else:  # the NaN scan is cheap; rewriting nested lists is not
            items = _nulls(array.tolist()) if array.dtype.kind == "f" and not np.isfinite(array).all() \
                else array.tolist()
        text = json.dumps(items, allow_nan=False)[1:-1]
    if text:
        part.write(text if first else ", " + text)  # json.dumps' own separator: batching leaves no trace


def _nulls(values: list) -> list:
    """NaN and infinity (a margin where no finger touches) -> None, at any
    depth (JSON has neither)."""
    if values and isinstance(values[0], list):
        return [_nulls(v) for v in values]
    return [None if isinstance(v, float) and not math.isfinite(v) else v for v in values]


def _object(info: ExportedObject) -> dict:
    row = info.row
    scalars = {k: getattr(row, k) for k in ("mass", "friction", "density", "volume")}
    return {"file": info.file, "scale": info.scale, "name": row.name, "source": row.source,
            "source_scale": row.scale, "mesh_sha256": row.mesh_sha256, **_nulls_dict(scalars),
            "com": _nulls(row.com.tolist()), "inertia": _nulls(row.inertia.tolist()), "up": row.up,
            "p_hold_outside": info.outside_text}


def _nulls_dict(values: dict[str, float]) -> dict[str, float | None]:
    return {k: None if math.isnan(v) else float(v) for k, v in values.items()}


def _gripper(hand: HandSpec) -> dict:
    names, configuration = gripper_configuration(hand)
    return {"type": hand.name, "configuration": configuration.tolist(), "configuration_joints": names,
            "joint_names": joint_names(hand), "export_frame": hand.export_frame.tolist()}


# -- the folder index ------------------------------------------------------------------
def finish(out_dir: Path, hands: Sequence[str]) -> None:
    """Rewrite each hand's ``map_uuid_to_path.json`` and splits from the JSON
    files its grasp folder holds now."""
    for hand in hands:
        folder = out_dir / GRASP_DATA / hand
        if not folder.is_dir():
            continue
        objects = index(folder)
        mapping = {key: file for key, (file, _) in objects.items()}
        assets.atomic_write(folder / MAPPING, (json.dumps(mapping, indent=2, sort_keys=True) + "\n").encode())
        splits = out_dir / SPLITS / hand
        splits.mkdir(parents=True, exist_ok=True)
        for name, keys in split({key: name for key, (_, name) in objects.items()}).items():
            assets.atomic_write(splits / f"{name}.txt", "".join(f"{k}\n" for k in keys).encode())


def index(folder: Path) -> dict[str, tuple[str, str]]:
    """object.file -> (JSON file name, object name) of every grasp JSON in
    ``folder``, as GraspGen's scan would key them (files it cannot read, or
    without ``object.file``, are skipped, as GraspGen skips them)."""
    out: dict[str, tuple[str, str]] = {}
    for path in sorted(folder.glob(f"*{SUFFIX}")):
        if path.name == MAPPING:
            continue
        block = _object_block(path)
        key = block.get("file")
        if not isinstance(key, str):
            log.warning("%s: no object.file; GraspGen skips it", path)
            continue
        if key in out:
            log.warning("%s and %s both hold object '%s'; GraspGen reads one of them", out[key][0], path.name, key)
        out[key] = (path.name, str(block.get("name", key)))
    return out


def _object_block(path: Path) -> dict:
    """The ``object`` block of a grasp JSON ({} if unreadable). This writer's
    files start with it, so only their head is parsed."""
    with open(path, encoding="utf-8", errors="replace") as fh:
        head = fh.read(HEAD_CHARS)
    data: object = None
    if head.startswith(HEAD):
        try:
            data = {"object": json.JSONDecoder().raw_decode(head, len(HEAD))[0]}
        except json.JSONDecodeError:
            pass
    if data is None:
        try:
            with open(path, encoding="utf-8") as fh:
                data = json.load(fh)
        except (json.JSONDecodeError, UnicodeDecodeError):
            return {}
    block = data.get("object") if isinstance(data, dict) else None
    return block if isinstance(block, dict) else {}


def split(names: dict[str, str]) -> dict[str, list[str]]:
    """``{"train": keys, "valid": keys}`` of object keys -> object names (see
    the module docstring for the rule)."""
    valid = sorted(k for k, name in names.items() if _fraction(name) < VALID_FRACTION)
    if len(valid) == len(names):
        valid = []
    return {"train": sorted(set(names) - set(valid)), "valid": valid}


def _fraction(name: str) -> float:
    return int(hashlib.sha256(name.encode()).hexdigest()[:8], 16) / 16 ** 8


registry.register("graspgen", registry.PairWriter(relative_path, write, finish=finish))
