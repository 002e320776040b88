"""ACRONYM HDF5: one file ``{object}__{hand}.h5`` per (object, hand).

ACRONYM's published layout, readable by its own tools (``acronym_tools``)::

    gripper/type             str     hand name
    gripper/configuration    float64 (1,)  largest opening [m] (parallel jaw), else 0
    object/file              str     mesh path (the objects table's source)
    object/{scale,mass,friction,density,volume}  float64 scalars
    object/com               float64 (3,)   [m], scaled mesh frame
    object/inertia           float64 (3, 3) [kg m^2] about the COM
    grasps/transforms        float64 (N, 4, 4)  pose @ export_frame: gripper
                             frame (+z approach, fingers along x) in the scaled mesh frame
    grasps/qualities/flex/object_in_gripper  int64 (N,)  1 = success; attribute
                             ``label_source``: "simulation" (PyBullet trials),
                             "force_closure" (the flag), or "mixed"
    grasps/qualities/flex/object_motion_during_{closing,shaking}_{linear,angular}
                             float64 (N,) [m] / [rad], NaN when not simulated

This project's extras (a foreign reader ignores them): ``object/name``;
``grasps/qualities/{epsilon, volume, force_closure, reachability,
manipulability, score, rank, simulated_success (-1: not simulated),
robust_epsilon_mean, robust_epsilon_quantile}`` (NaN when absent);
``grasps/joint_names`` (J,), ``joints_closed`` / ``joints_open`` (N, J)
[rad or m]; ``width`` (N,) [m] (NaN: not a parallel jaw); ``preshape``,
``candidate``, ``seed``; ``contacts`` (N,) JSON text ``[{point, normal,
link}]`` in the object frame; ``approach_point``, ``approach_dir`` (N, 3),
``roll`` [rad], ``standoff`` [m]; ``poses_hand_frame`` (N, 4, 4) (the hand
frame in the object frame) and ``export_frame`` (4, 4) with transforms =
poses_hand_frame @ export_frame.

Datasets are chunked and resizable; each batch of rows is appended.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import h5py
import numpy as np

from planner.datasets import fields
from planner.datasets.batch import Batch, ObjectInfo
from planner.specs.hands import HandSpec

SUFFIX = ".h5"
#: Rows per HDF5 chunk: 1,024 transforms are 128 kB.
CHUNK_ROWS = 1024


def write(path: Path, info: ObjectInfo, hand: HandSpec, batches: Iterable[Batch]) -> int:
    """Write the file (atomically: a partial export never has the final name); returns N."""
    tmp = path.with_name(path.name + ".tmp")
    total = validated = 0
    with h5py.File(tmp, "w") as f:
        _header(f, info, hand)
        for batch in batches:
            for key, values in fields.per_grasp(batch, hand).items():
                _append(f, f"grasps/{key}", values, total)
            total += len(batch)
            validated += int(np.count_nonzero(batch.sim_success >= 0))
        f[f"grasps/{fields.FLEX}object_in_gripper"].attrs["label_source"] = fields.label_source(validated, total)
    os.replace(tmp, path)
    return total


def _header(f: h5py.File, info: ObjectInfo, hand: HandSpec) -> None:
    f["gripper/type"] = hand.name
    f["gripper/configuration"] = np.array([fields.max_opening(hand)], np.float64)
    f["object/file"] = info.file
    f["object/name"] = info.name
    for key in ("scale", "mass", "friction", "density", "volume"):
        f[f"object/{key}"] = np.float64(getattr(info, key))
    f["object/com"] = np.asarray(info.com, np.float64)
    f["object/inertia"] = np.asarray(info.inertia, np.float64)
    f["grasps/joint_names"] = np.array(fields.joint_names(hand), dtype=h5py.string_dtype())
    f["grasps/export_frame"] = np.asarray(hand.export_frame, np.float64)


def _append(f: h5py.File, key: str, values: np.ndarray | list[str], start: int) -> None:
    if isinstance(values, list):
        data = np.array(values, dtype=h5py.string_dtype())
    else:
        data = np.asarray(values)
        data = data.astype(np.int64 if data.dtype.kind in "iub" else np.float64, copy=False)
    if key not in f:
        f.create_dataset(key, shape=(0, *data.shape[1:]), maxshape=(None, *data.shape[1:]), dtype=data.dtype,
                         chunks=(CHUNK_ROWS, *data.shape[1:]))
    ds = f[key]
    ds.resize(start + len(data), axis=0)
    ds[start:] = data
