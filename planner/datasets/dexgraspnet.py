"""DexGraspNet ``.npy``: one file per (object, hand), in DexGraspNet's layout.

DexGraspNet keeps one result file per object, named by its *object code*
(``<result_path>/<code>.npy``), and loads the object's mesh from
``<data_root_path>/<code>/coacd/decomposed.obj`` (``ObjectModel``). The
export mirrors its ``data/`` folder, one result folder per hand, the object
code being the object's name::

    DIR/meshes/{object}.obj                       the mesh, in metres (mesh_file)
    DIR/dataset/{hand}/{object}.npy               result_path of the hand
    DIR/meshdata/{object}/coacd/decomposed.obj    the same mesh, where ObjectModel looks

``decomposed.obj`` is the planner's mesh itself (one piece), not a CoACD
decomposition, and no ``coacd.urdf`` is written (DexGraspNet's Isaac
validation, which needs it, simulates its Shadow hand only).

Each file is DexGraspNet's own format: a numpy object array (a list) of
dicts, saved with pickle, so it loads with ``numpy.load(path,
allow_pickle=True)``::

    {"scale": 1.0,                # turns the mesh file into metres (the file is in metres)
     "qpos": {"WRJTx", "WRJTy", "WRJTz": wrist (hand frame) translation [m], object frame,
              "WRJRx", "WRJRy", "WRJRz": wrist rotation as Euler angles [rad],
              joint_name: closed joint value [rad or m], ...},
     "qpos_open": the same wrist, joint_name: the preshape's open joint value (where closing
                  starts: the pre-grasp posture; DexGraspNet's own qpos_st is its optimiser's start, not this),
     "object_code": "{object}", "mesh_file": "meshes/{object}.obj" (relative to DIR),
     "epsilon", "score", "force_closure", "rank", "width", ..., "object_mass", ...: this project's
     extras (:data:`EXTRAS`, :data:`PHYSICS`, ``p_hold_outside``: where the object lies outside
     the labelled objects the hand's p_hold model was fitted on, '' inside)}

The Euler angles are ``Rotation.from_matrix(R).as_euler("xyz")`` of scipy:
lower-case "xyz" = *extrinsic* rotations about the fixed x, then y, then z
axes, i.e. R = Rz(c) @ Ry(b) @ Rx(a) for (a, b, c) = (WRJRx, WRJRy, WRJRz),
the same as transforms3d's ``euler2mat(a, b, c, "sxyz")`` that DexGraspNet
uses. The wrist is the hand frame (``root_link``), not the ACRONYM frame.
The joint names are this project's hands' (no hand here is DexGraspNet's
Shadow hand, whose ``robot0:FFJ3`` ... names its hand model hard-codes).

DexGraspNet files are per object by definition, so one (object, hand)'s list
is held in memory; rows are still read from the database in batches.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from planner.datasets import registry
from planner.datasets.acronym import joint_names
from planner.datasets.columns import grasp_columns, joint_matrix
from planner.datasets.meshes import ExportedObject
from planner.record.fields import record_fields
from planner.record.grasp import Grasp
from planner.specs.hands import HandSpec

SUFFIX = ".npy"
WRIST = ("WRJTx", "WRJTy", "WRJTz", "WRJRx", "WRJRy", "WRJRz")
#: Where DexGraspNet's ObjectModel finds an object's mesh (relative to DIR).
MESH_COPIES = ("meshdata/{stem}/coacd/decomposed.obj",)


#: This project's extras in every dict: every plain declared field of the record
#: (:mod:`planner.record.fields`; absent values as NaN, -1 or ''), and the object's
#: physical properties. Not carried: vectors and contacts (the wrist, qpos and
#: qpos_open hold the pose, the closed and the open joints), the database's ids.
EXTRAS = tuple(f.name for f in record_fields() if not f.shape and f.kind not in ("joints", "contacts")
               and f.name not in ("id", "unit_id", "object", "hand"))
BOOLEANS = tuple(f.name for f in record_fields() if f.kind == "bool" and "." not in f.attr)
PHYSICS = ("object_mass", "object_friction", "object_density", "object_up")


def relative_path(stem: str, hand: str) -> str:
    """Where the file of (object, hand) goes: named by the object code."""
    return f"dataset/{hand}/{stem}{SUFFIX}"


def wrist(pose: np.ndarray) -> np.ndarray:
    """(n, 6) translation [m] and extrinsic xyz Euler angles [rad] of (n, 4, 4) poses."""
    with warnings.catch_warnings():
        # at gimbal lock (|WRJRy| = pi/2, common for axis-aligned grasps) scipy
        # sets WRJRz = 0; the angles still give back the same rotation
        warnings.filterwarnings("ignore", "Gimbal lock", UserWarning)
        euler = Rotation.from_matrix(pose[:, :3, :3]).as_euler("xyz")
    return np.hstack([pose[:, :3, 3], euler])


def pose_from_qpos(qpos: dict[str, float]) -> np.ndarray:
    """(4, 4) hand pose from a qpos dict (the inverse of :func:`wrist`)."""
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_euler("xyz", [qpos[k] for k in WRIST[3:]]).as_matrix()
    pose[:3, 3] = [qpos[k] for k in WRIST[:3]]
    return pose


def write(path: Path, info: ExportedObject, hand: HandSpec, batches: Iterable[list[Grasp]]) -> int:
    """Write the file (atomically); returns the number of grasps."""
    names = joint_names(hand)
    keys = (*WRIST, *names)
    code = path.name[:-len(SUFFIX)]
    grasps: list[dict] = []
    physics = {**{name: getattr(info.row, name[len("object_"):]) for name in PHYSICS},
               "p_hold_outside": info.outside_text}
    for batch in batches:
        c = grasp_columns(batch)
        at = wrist(c["pose"])
        closed, opened = (_qposes(keys, at, joint_matrix(c[k], names)) for k in ("closed_joints", "open_joints"))
        extras = [c[name].astype(bool).tolist() if name in BOOLEANS else
                  c[name] if isinstance(c[name], list) else c[name].tolist() for name in EXTRAS]
        grasps += [{"scale": info.scale, "qpos": qpos, "qpos_open": qpos_open, "object_code": code,
                    "mesh_file": info.file, **physics, **dict(zip(EXTRAS, values))}
                   for qpos, qpos_open, *values in zip(closed, opened, *extras)]
    data = np.empty(len(grasps), dtype=object)
    data[:] = grasps
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        np.save(fh, data, allow_pickle=True)
    os.replace(tmp, path)
    return len(grasps)


def _qposes(keys: tuple[str, ...], at: np.ndarray, joints: np.ndarray) -> list[dict[str, float]]:
    """One qpos dict per row of wrists ``at`` (n, 6) and ``joints`` (n, j); a NaN joint (not stored) left out."""
    rows = np.hstack([at, joints]).tolist()
    if np.isnan(joints).any():
        return [{k: v for k, v in zip(keys, row) if v == v} for row in rows]
    return [dict(zip(keys, row)) for row in rows]


registry.register("dexgraspnet", registry.PairWriter(relative_path, write, mesh_copies=MESH_COPIES))
