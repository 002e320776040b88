"""ACRONYM HDF5: one file ``DIR/{object}__{hand}.h5`` per (object, hand),
written and read back.

ACRONYM's published layout, readable by its own tools (``acronym_tools``:
``load_grasps(file)``, ``load_mesh(file, mesh_root_dir=DIR)``)::

    gripper/type             str     hand name
    gripper/configuration    float64 (D,)  the open hand, see below ([0.04] for the Panda)
    object/file              str     "meshes/{object}.obj", relative to DIR (the mesh in metres)
    object/scale             float64 1.0: what turns object/file into metres
    object/{mass,friction,density,volume}  float64 scalars
    object/com               float64 (3,)   [m], object frame
    object/inertia           float64 (3, 3) [kg m^2] about the COM
    grasps/transforms        float64 (N, 4, 4)  pose @ export_frame: gripper
                             frame (+z approach, fingers along x) in the object frame
    grasps/qualities/flex/object_in_gripper  int64 (N,)  1 = success; attribute
                             ``label_source``: "simulation" (PyBullet trials),
                             "force_closure" (the flag), or "mixed"
    grasps/qualities/flex/object_motion_during_{closing,shaking}_{linear,angular}
                             float64 (N,) [m] / [rad], NaN when not simulated

``load_mesh`` joins ``object/file`` to ``mesh_root_dir``, loads it with
trimesh and applies ``object/scale``: with ``mesh_root_dir=DIR`` that is the
planner's checked mesh in the object frame, wherever DIR was copied (see
:mod:`planner.datasets.meshes`).

``gripper/configuration`` follows ACRONYM's Panda files, which store
``[0.04]``: the Panda's one driven finger joint (``panda_finger_joint1``; the
other finger mimics it) fully open, i.e. one finger's travel from the centre
line, half the 0.08 m opening. For every hand it is the open hand in the same
terms: the driven (non-mimic) finger joints, in the hand's joint order (named
by the extra ``gripper/configuration_joints``), at their values in the hand's
widest preshape (:func:`widest_preshape`, the one ``grasp import`` closes
foreign poses from), in joint units:

| hand | `gripper/configuration_joints` | `gripper/configuration` | meaning |
| --- | --- | --- | --- |
| panda | `panda_finger_joint1` | `[0.04]` | [m] one finger's travel from the centre line, fully open: half the 0.08 m opening (ACRONYM's own value); `panda_finger_joint2` mimics it |
| pr2 | `left_gripper_joint`, `right_gripper_joint` | `[0.548, 0.548]` | [rad] each finger's hinge fully open (preshape `wide`) |
| barrett | `bh_j11_joint`, `bh_j12_joint`, `bh_j22_joint`, `bh_j32_joint` | `[0.0, 0.0, 0.0, 0.0]` | [rad] spread 0 (fingers 1 and 2 side by side, facing finger 3) and the three proximal flexions straight (preshape `wrap`); finger 2's spread and the distal joints mimic these |
| allegro | `index_abd`, `index_mcp`, `index_pip`, `index_dip`, `middle_abd`, `middle_mcp`, `middle_pip`, `middle_dip`, `ring_abd`, `ring_mcp`, `ring_pip`, `ring_dip`, `thumb_rot`, `thumb_abd`, `thumb_mcp`, `thumb_ip` | `[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.396, 0.3, 0.0, 0.0]` | [rad] every finger straight, the thumb rotated 1.396 rad to face them and abducted 0.3 rad (preshape `power_wrap`) |

Files written before issue 12 stored the Panda's full opening ``[0.08]``
(0 for the other hands); nothing reads the value back, so they import alike.

This project's extras (a foreign reader ignores them): ``object/name``,
``object/source`` and ``object/source_scale`` (the database's mesh file and
scale), ``object/mesh_sha256`` (:func:`planner.geometry.mesh.mesh_hash` of
the mesh); ``gripper/configuration_joints``;
``grasps/qualities/{epsilon, volume, force_closure, reachability,
manipulability, score, p_hold (calibrated probability of holding), rank, simulated_success (-1: not simulated),
robust_epsilon_mean, robust_epsilon_quantile, resist_worst, resist_mean,
open_margin, close_margin, push}`` (NaN when absent) and ``feasibility``
(reasons, comma-separated);
``grasps/joint_names`` (J,), ``joints_closed`` / ``joints_open`` (N, J)
[rad or m]; ``width`` (N,) [m] (NaN: not a parallel jaw); ``preshape``,
``candidate``, ``seed``; ``contacts`` (N,) JSON text ``[{point, normal,
link}]`` in the object frame; ``approach_point``, ``approach_dir`` (N, 3),
``roll`` [rad], ``standoff`` [m]; ``poses_hand_frame`` (N, 4, 4) (the hand
frame in the object frame) and ``export_frame`` (4, 4) with transforms =
poses_hand_frame @ export_frame.

The per-grasp content (:func:`per_grasp`) is shared with the GraspGen JSON
writer. Datasets are chunked and resizable; each batch of rows is appended.
Reading (:func:`read_header`, :func:`read_poses`, :func:`read_grasps`,
:func:`read_simulation`) serves ``grasp import``: our own files come back
losslessly, foreign ones give poses to re-score.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from planner.datasets.columns import Column, grasp_columns, joint_matrix
from planner.datasets.meshes import ExportedObject
from planner.errors import InputError
from planner.geometry.frames import roll_about
from planner.grasp import Grasp, RobustEpsilon, Trial
from planner.plan.contacts import HandContacts
from planner.plan.measures import Measures
from planner.specs.hands import HandSpec
from planner.specs.preshapes import Preshape, load_preshapes

SUFFIX = ".h5"
#: Rows per HDF5 chunk: 1,024 transforms are 128 kB.
CHUNK_ROWS = 1024
#: A transform's rotation rows may deviate from orthonormal by this much (float32 files pass).
ROTATION_TOL = 1e-5

#: ``object_in_gripper`` label source, per file: every row validated in
#: simulation, none (the force-closure flag), or some of each (then a row's
#: ``simulated_success`` >= 0 says it was simulated).
SIMULATION, FORCE_CLOSURE, MIXED = "simulation", "force_closure", "mixed"
FLEX = "qualities/flex/"
#: ACRONYM's motion datasets and the columns they come from.
MOTIONS = {f"{FLEX}object_motion_during_{stage}_{kind}": f"validation_{stage}_{kind}"
           for stage in ("closing", "shaking") for kind in ("linear", "angular")}
#: Datasets whose presence marks a file with this project's extras.
EXTRAS = ("qualities/epsilon", "qualities/volume", "qualities/force_closure", "joint_names", "joints_closed",
          "joints_open", "contacts")
#: The per-hand table of ``gripper/configuration`` above, for the README.
CONFIGURATION_DOC = __doc__[__doc__.index("| hand |"):__doc__.index("\n\nFiles written before")].strip() + "\n"


# -- writing ------------------------------------------------------------------------
def relative_path(stem: str, hand: str) -> str:
    """Where the file of (object, hand) goes in the export folder."""
    return f"{stem}__{hand}{SUFFIX}"


def widest_preshape(hand: HandSpec) -> Preshape:
    """The most open preshape: largest travel against the closing synergy."""
    return max(load_preshapes(hand), key=lambda s: -sum(r * s.joints[j] for j, r in s.close.items()))


def gripper_configuration(hand: HandSpec) -> tuple[list[str], np.ndarray]:
    """``gripper/configuration_joints`` and ``gripper/configuration`` (D,):
    the driven finger joints and their values [m or rad] in the widest
    preshape (the module docstring has the table per hand)."""
    shape = widest_preshape(hand)
    names = [j.name for j in hand.driven]
    return names, np.array([shape.joints[n] for n in names], np.float64)


def joint_names(hand: HandSpec) -> list[str]:
    return [j.name for j in hand.joints]


def per_grasp(grasps: list[Grasp], hand: HandSpec) -> dict[str, Column]:
    """Every per-grasp field of one batch, keyed by its path below ``grasps/``;
    (n, ...) arrays or n strings. ``transforms`` = pose @ export_frame: the
    dataset gripper frame in the scaled mesh frame, metres."""
    c = grasp_columns(grasps)
    labels = np.where(c["validation_success"] >= 0, c["validation_success"], c["force_closure"]).astype(np.int64)
    names = joint_names(hand)
    return {
        "transforms": c["pose"] @ hand.export_frame,
        f"{FLEX}object_in_gripper": labels,
        **{key: c[column] for key, column in MOTIONS.items()},
        "qualities/epsilon": c["epsilon"],
        "qualities/volume": c["volume"],
        "qualities/force_closure": c["force_closure"],
        "qualities/reachability": c["reachability"],
        "qualities/manipulability": c["manipulability"],
        "qualities/score": c["score"],
        "qualities/p_hold": c["p_hold"],
        "qualities/rank": c["rank"],
        "qualities/simulated_success": c["validation_success"],
        "qualities/robust_epsilon_mean": c["robust_mean"],
        "qualities/robust_epsilon_quantile": c["robust_quantile"],
        **{f"qualities/{name}": c[name] for name in MEASURES},
        "qualities/feasibility": c["feasibility"],
        "joints_closed": joint_matrix(c["closed_joints"], names),
        "joints_open": joint_matrix(c["open_joints"], names),
        "width": c["width"],
        "preshape": c["preshape"],
        "candidate": c["candidate"],
        "seed": c["seed"],
        "contacts": c["contacts"],
        "poses_hand_frame": c["pose"],
        "approach_point": c["approach_point"],
        "approach_dir": c["approach_dir"],
        "roll": c["roll"],
        "standoff": c["standoff"],
    }


def label_source(validated: int, total: int) -> str:
    if validated == 0:
        return FORCE_CLOSURE
    return SIMULATION if validated == total else MIXED


def validated_count(grasps: list[Grasp]) -> int:
    return sum(g.validation is not None for g in grasps)


def write(path: Path, info: ExportedObject, hand: HandSpec, batches: Iterable[list[Grasp]]) -> int:
    """Write the file (atomically: a partial export never has the final name); returns N."""
    import h5py

    tmp = path.with_name(path.name + ".tmp")
    total = validated = 0
    with h5py.File(tmp, "w") as f:
        _header(f, info, hand)
        for batch in batches:
            for key, values in per_grasp(batch, hand).items():
                _append(f, f"grasps/{key}", values, total)
            total += len(batch)
            validated += validated_count(batch)
        f[f"grasps/{FLEX}object_in_gripper"].attrs["label_source"] = label_source(validated, total)
    os.replace(tmp, path)
    return total


def _header(f: Any, info: ExportedObject, hand: HandSpec) -> None:
    import h5py

    row = info.row
    configuration_joints, configuration = gripper_configuration(hand)
    f["gripper/type"] = hand.name
    f["gripper/configuration"] = configuration
    f["gripper/configuration_joints"] = np.array(configuration_joints, dtype=h5py.string_dtype())
    f["object/file"] = info.file
    f["object/scale"] = np.float64(info.scale)
    f["object/name"] = row.name
    f["object/source"] = row.source
    f["object/source_scale"] = np.float64(row.scale)
    f["object/mesh_sha256"] = row.mesh_sha256
    for key in ("mass", "friction", "density", "volume"):
        f[f"object/{key}"] = np.float64(getattr(row, key))
    f["object/com"] = np.asarray(row.com, np.float64)
    f["object/inertia"] = np.asarray(row.inertia, np.float64)
    f["grasps/joint_names"] = np.array(joint_names(hand), dtype=h5py.string_dtype())
    f["grasps/export_frame"] = np.asarray(hand.export_frame, np.float64)


def _append(f: Any, key: str, values: Column, start: int) -> None:
    """Rows ``start:`` of a chunked, resizable dataset (made by the first batch)."""
    import h5py

    if isinstance(values, list):
        data = np.array(values, dtype=h5py.string_dtype())
    else:
        data = np.asarray(values)
        data = data.astype(np.int64 if data.dtype.kind in "iub" else np.float64, copy=False)
    if start == 0:  # one h5py call: creating empty and then resizing costs as much again
        f.create_dataset(key, data=data, maxshape=(None, *data.shape[1:]), chunks=(CHUNK_ROWS, *data.shape[1:]))
        return
    ds = f[key]
    ds.resize(start + len(data), axis=0)
    ds[start:] = data


# -- reading ------------------------------------------------------------------------
@dataclass(frozen=True)
class AcronymHeader:
    """What an ACRONYM file says about its gripper and object.

    ``scale``, ``mass`` and ``friction`` are None when absent or not a
    positive number; ``mesh_sha256``: the hash of the mesh the grasps were
    planned on (this project's files since issue 12); ``extras``: the file
    carries this project's qualities, joints and contacts (it can be read
    back losslessly).
    """

    path: Path
    gripper: str
    object_name: str | None
    object_file: str | None
    scale: float | None
    mass: float | None
    friction: float | None
    extras: bool
    mesh_sha256: str | None = None


def _open(path: Path) -> Any:
    import h5py

    if not path.is_file():
        raise InputError(f"{path}: file not found")
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        raise InputError(f"{path}: not an HDF5 file ({exc})") from None


def read_header(path: Path) -> AcronymHeader:
    """The file's gripper and object; a file without ACRONYM's grasps is refused."""
    with _open(path) as f:
        for key in ("grasps/transforms", "gripper/type"):
            if key not in f:
                raise InputError(f"{path}: no '{key}' dataset; not an ACRONYM grasp file")
        return AcronymHeader(
            path=path, gripper=_text(f["gripper/type"][()]),
            object_name=_text(f["object/name"][()]) if "object/name" in f else None,
            object_file=_text(f["object/file"][()]) if "object/file" in f else None,
            scale=_positive(f, "object/scale"), mass=_positive(f, "object/mass"),
            friction=_positive(f, "object/friction"), extras=all(f"grasps/{k}" in f for k in EXTRAS),
            mesh_sha256=_text(f["object/mesh_sha256"][()]) or None if "object/mesh_sha256" in f else None)


def read_poses(path: Path, hand: HandSpec) -> np.ndarray:
    """(N, 4, 4) grasp poses (hand frame in the object frame): the checked
    transforms times the inverse of the file's export frame (else the hand's)."""
    with _open(path) as f:
        g = f["grasps"]
        frame = np.asarray(g["export_frame"][()], float) if "export_frame" in g else hand.export_frame
        return _rigid(path, np.asarray(g["transforms"][()], float)) @ np.linalg.inv(frame)


def _rigid(path: Path, transforms: np.ndarray) -> np.ndarray:
    """(N, 4, 4) checked rigid transforms."""
    if transforms.ndim != 3 or transforms.shape[1:] != (4, 4):
        raise InputError(f"{path}: grasps/transforms has shape {transforms.shape}; expected (N, 4, 4)")
    rot = transforms[:, :3, :3]
    bad = ~np.isfinite(transforms).all(axis=(1, 2))
    bad |= np.abs(rot @ rot.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2), initial=0) > ROTATION_TOL
    bad |= np.abs(transforms[:, 3] - [0, 0, 0, 1]).max(axis=1, initial=0) > ROTATION_TOL
    if bad.any():
        raise InputError(f"{path}: grasps/transforms row {int(np.argmax(bad))} is not a rigid transform")
    return transforms


def read_grasps(path: Path, hand: HandSpec, obj: str, poses: np.ndarray) -> list[Grasp]:
    """This project's grasps back from a file with its extras; candidate = the
    row number, seed 0, the object named ``obj``."""
    n = len(poses)
    with _open(path) as f:
        g = f["grasps"]
        q = g["qualities"]
        names = list(g["joint_names"].asstr()[()])
        closed, opened = g["joints_closed"][()], g["joints_open"][()]
        col = {k: (q[k][()] if k in q else np.full(n, np.nan))  # whole columns: h5py indexing per row is slow
               for k in ("epsilon", "volume", "force_closure", "reachability", "manipulability", *MEASURES)}
        reasons = q["feasibility"].asstr()[()] if "feasibility" in q else [""] * n
        width = g["width"][()] if "width" in g else np.full(n, np.nan)
        preshape = g["preshape"].asstr()[()] if "preshape" in g else ["imported"] * n
        approach_dir = g["approach_dir"][()] if "approach_dir" in g else poses[:, :3, :3] @ hand.approach
        approach_point = (g["approach_point"][()] if "approach_point" in g
                          else poses[:, :3, :3] @ hand.tcp + poses[:, :3, 3])
        roll = g["roll"][()] if "roll" in g else [roll_about(p[:3, :3], hand.approach, d)
                                                  for p, d in zip(poses, approach_dir)]
        standoff = g["standoff"][()] if "standoff" in g else np.zeros(n)
        contacts = g["contacts"].asstr()[()]
    return [Grasp(object=obj, hand=hand.name, preshape=str(preshape[i]), candidate=i, seed=0,
                  approach_point=np.asarray(approach_point[i], float), approach_dir=np.asarray(approach_dir[i], float),
                  roll=float(roll[i]), standoff=float(standoff[i]), pose=poses[i],
                  open_joints=_joints(names, opened[i]), closed_joints=_joints(names, closed[i]),
                  width=_maybe(width[i]), contacts=_contacts(path, json.loads(contacts[i]), hand),
                  epsilon=float(col["epsilon"][i]), volume=float(col["volume"][i]),
                  force_closure=bool(col["force_closure"][i]), reachability=_maybe(col["reachability"][i]),
                  manipulability=_maybe(col["manipulability"][i]),
                  measures=_measures([col[k][i] for k in MEASURES], str(reasons[i])))
            for i in range(n)]


#: The analytic measures a file carries (``grasps/qualities/<name>``; NaN: not measured).
MEASURES = ("resist_worst", "resist_mean", "open_margin", "close_margin", "push")


def _measures(values: list[float], reasons: str) -> Measures | None:
    if np.isnan(values[0]):
        return None
    worst, mean, open_margin, close_margin, push = (float(v) for v in values)
    return Measures(worst, mean, np.inf if np.isnan(open_margin) else open_margin,
                    np.inf if np.isnan(close_margin) else close_margin, push, tuple(r for r in reasons.split(",") if r))


def read_labels(path: Path) -> np.ndarray:
    """(N,) 0/1 ``grasps/qualities/flex/object_in_gripper`` of a grasp file (a
    label set: FleX's, a real robot's outcomes)."""
    with _open(path) as f:
        key = f"grasps/{FLEX}object_in_gripper"
        if key not in f:
            raise InputError(f"{path}: no {key}: not a labelled grasp file")
        labels = np.asarray(f[key][:], float)
        n = len(f["grasps/transforms"]) if "grasps/transforms" in f else len(labels)
    if len(labels) != n or not np.isin(labels, (0.0, 1.0)).all():
        raise InputError(f"{path}: {key} must hold one 0/1 label per grasp ({n}), got {len(labels)} values")
    return labels


def read_simulation(path: Path) -> list[tuple[Trial | None, RobustEpsilon | None]]:
    """Per row, the shake-test result and robust epsilon our own files carry
    (None where the row was not simulated; an empty list for other files).
    What ACRONYM does not store reads as -1 (fingers) or 0 (samples)."""
    with _open(path) as f:
        q = f["grasps/qualities"]
        if "simulated_success" not in q:
            return []
        success = np.asarray(q["simulated_success"][()], int)
        flex = q["flex"] if "flex" in q else {}
        motion = {k: np.asarray(flex[f"object_motion_during_{k}"][()], float) if f"object_motion_during_{k}" in flex
                  else np.full(len(success), np.nan) for k in ("closing_linear", "closing_angular",
                                                               "shaking_linear", "shaking_angular")}
        mean = np.asarray(q["robust_epsilon_mean"][()], float) if "robust_epsilon_mean" in q else None
        quantile = np.asarray(q["robust_epsilon_quantile"][()], float) if "robust_epsilon_quantile" in q else None
    out: list[tuple[Trial | None, RobustEpsilon | None]] = []
    for i, ok in enumerate(success):
        trial = None if ok < 0 else Trial(bool(ok), -1, *(float(np.nan_to_num(motion[k][i], nan=-1.0)) for k in (
            "closing_linear", "closing_angular", "shaking_linear", "shaking_angular")))
        robust = (RobustEpsilon(float(mean[i]), float(quantile[i]), 0)
                  if mean is not None and quantile is not None and np.isfinite(mean[i]) else None)
        out.append((trial, robust))
    return out


def _joints(names: list[str], values: np.ndarray) -> dict[str, float]:
    return {k: float(v) for k, v in zip(names, values) if math.isfinite(v)}


def _maybe(value: float) -> float | None:
    return None if math.isnan(value) else float(value)


def _contacts(path: Path, items: list[dict], hand: HandSpec) -> HandContacts:
    links = tuple(c["link"] for c in items)
    unknown = sorted(set(links) - set(hand.contacts))
    if unknown:
        raise InputError(f"{path}: contact on link {unknown} of hand '{hand.name}', "
                         f"which has contact links {', '.join(hand.contact_links)}")
    return HandContacts.from_items(items)


def _positive(f: Any, key: str) -> float | None:
    if key not in f:
        return None
    value = float(np.asarray(f[key][()]).reshape(-1)[0])
    return value if math.isfinite(value) and value > 0 else None


def _text(value: object) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)
