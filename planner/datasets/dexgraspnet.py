"""DexGraspNet ``.npy``: one file ``{object}__{hand}.npy`` per (object, hand).

DexGraspNet's own format: a numpy object array (a list) of dicts, saved
with pickle, so it loads with ``numpy.load(path, allow_pickle=True)``::

    {"scale": float,              # object/scale: the mesh scale the grasp refers to
     "qpos": {"WRJTx", "WRJTy", "WRJTz": wrist (hand frame) translation [m], object frame,
              "WRJRx", "WRJRy", "WRJRz": wrist rotation as Euler angles [rad],
              joint_name: closed joint value [rad or m], ...},
     "epsilon", "score", "force_closure", "rank", "width": this project's extras}

The Euler angles are ``Rotation.from_matrix(R).as_euler("xyz")`` of scipy:
lower-case "xyz" = *extrinsic* rotations about the fixed x, then y, then z
axes, i.e. R = Rz(c) @ Ry(b) @ Rx(a) for (a, b, c) = (WRJRx, WRJRy, WRJRz),
the same as transforms3d's ``euler2mat(a, b, c, "sxyz")`` that DexGraspNet
uses. The wrist is the hand frame (``root_link``), not the ACRONYM frame.

DexGraspNet files are per object by definition, so one (object, hand)'s list
is held in memory; rows are still read from the database in batches.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from planner.datasets.acronym import joint_names
from planner.datasets.columns import grasp_columns, joint_matrix
from planner.db.store import ObjectRow
from planner.grasp import Grasp
from planner.specs.hands import HandSpec

SUFFIX = ".npy"
WRIST = ("WRJTx", "WRJTy", "WRJTz", "WRJRx", "WRJRy", "WRJRz")


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


def write(path: Path, info: ObjectRow, hand: HandSpec, batches: Iterable[list[Grasp]]) -> int:
    """Write the file (atomically); returns the number of grasps."""
    names = joint_names(hand)
    scale = float(info.scale)
    grasps: list[dict] = []
    for batch in batches:
        c = grasp_columns(batch)
        base = wrist(c["pose"]).tolist()
        joints = joint_matrix(c["closed_joints"], names).tolist()
        for i in range(len(batch)):
            qpos = dict(zip(WRIST, base[i]))
            qpos.update((k, v) for k, v in zip(names, joints[i]) if not math.isnan(v))  # NaN: not stored
            grasps.append({"scale": scale, "qpos": qpos, "epsilon": float(c["epsilon"][i]),
                           "score": float(c["score"][i]), "force_closure": bool(c["force_closure"][i]),
                           "rank": int(c["rank"][i]), "width": float(c["width"][i])})
    data = np.empty(len(grasps), dtype=object)
    data[:] = grasps
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        np.save(fh, data, allow_pickle=True)
    os.replace(tmp, path)
    return len(grasps)
