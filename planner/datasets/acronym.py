"""ACRONYM HDF5: one file ``DIR/{object}__{hand}.h5`` per (object, hand),
written and read back.

ACRONYM's published layout, readable by its own tools (``acronym_tools``:
``load_grasps(file)``, ``load_mesh(file, mesh_root_dir=DIR)``)::

    gripper/type             str     hand name
    gripper/configuration    float64 (D,)  the open hand, see below ([0.04] for the Panda)
    object/file              str     "meshes/{object}.obj", relative to DIR (the mesh in metres)
    object/scale             float64 1.0: what turns object/file into metres
    object/{mass,friction,density,volume}  float64 scalars
    object/up                str     the object's up as it stands, an axis of its frame ("+z", "+y", ...)
    object/com               float64 (3,)   [m], object frame
    object/inertia           float64 (3, 3) [kg m^2] about the COM
    grasps/transforms        float64 (N, 4, 4)  pose @ export_frame: gripper
                             frame (+z approach, fingers along x) in the object frame
    grasps/qualities/flex/object_in_gripper  int64 (N,)  1 = success, as ``--label``
                             chooses (planner.datasets.labels); attribute ``label_source``:
                             "file_label", "p_hold_trial", "trial", "p_hold", "force_closure" (a closure
                             flag) or "mixed"
    grasps/qualities/label_from  str (N,)  where each row's label came from
    grasps/qualities/flex/object_motion_during_{closing,shaking}_{linear,angular}
                             float64 (N,) [m] / [rad], NaN when not simulated

``load_mesh`` joins ``object/file`` to ``mesh_root_dir``, loads it with
trimesh and applies ``object/scale``: with ``mesh_root_dir=DIR`` that is the
planner's checked mesh in the object frame, wherever DIR was copied (see
:mod:`planner.datasets.meshes`).

``gripper/configuration`` follows ACRONYM's Panda files, which store ``[0.04]``: the Panda's one driven finger
joint (``panda_finger_joint1``; the other finger mimics it) fully open, i.e. one finger's travel from the centre
line, half the 0.08 m opening. For every hand it is the open hand in the same terms: the driven (non-mimic) finger
joints, in the hand's joint order (named by the extra ``gripper/configuration_joints``), at their values in the
hand's widest preshape (:meth:`~planner.specs.hands.HandSpec.widest`, the one ``grasp import --rescore`` closes a
pose from where the file gives no opening of its own), in joint units:

| hand | `gripper/configuration_joints` | `gripper/configuration` | meaning |
| --- | --- | --- | --- |
| panda | `panda_finger_joint1` | `[0.04]` | [m] one finger's travel from the centre line, fully open: half the 0.08 m opening (ACRONYM's own value); `panda_finger_joint2` mimics it |
| pr2 | `left_gripper_joint`, `right_gripper_joint` | `[0.548, 0.548]` | [rad] each finger's hinge fully open (preshape `wide`) |
| barrett | `bh_j11_joint`, `bh_j12_joint`, `bh_j22_joint`, `bh_j32_joint` | `[0.0, 0.0, 0.0, 0.0]` | [rad] spread 0 (fingers 1 and 2 side by side, facing finger 3) and the three proximal flexions straight (preshape `wrap`); finger 2's spread and the distal joints mimic these |
| allegro | `index_abd`, `index_mcp`, `index_pip`, `index_dip`, `middle_abd`, `middle_mcp`, `middle_pip`, `middle_dip`, `ring_abd`, `ring_mcp`, `ring_pip`, `ring_dip`, `thumb_rot`, `thumb_abd`, `thumb_mcp`, `thumb_ip` | `[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.396, 0.3, 0.0, 0.0]` | [rad] every finger straight, the thumb rotated 1.396 rad to face them and abducted 0.3 rad (preshape `power_wrap`) |

Files written before issue 12 stored the Panda's full opening ``[0.08]`` (0 for the other hands); nothing reads
the value back, so they import alike.

This project's extras (a foreign reader ignores them): ``object/name``,
``object/source`` and ``object/source_scale`` (the database's mesh file and
scale), ``object/mesh_sha256`` (:func:`planner.geometry.mesh.mesh_hash` of
the mesh), ``object/p_hold_outside`` (str: where the object lies outside the labelled objects the hand's p_hold
model was fitted on, e.g. ``density 1,322 kg/m^3 (labels: 150-157 kg/m^3); friction 0.5 (labels: 1)``; '' inside:
there p_hold, and a label taken from it, is an extrapolation); ``gripper/configuration_joints``;
``grasps/qualities/{epsilon, volume, force_closure, reachability, manipulability, score, p_hold, p_hold_trial,
rank}`` (``p_hold``: the calibrated probability of holding, NaN where no model applies; ``p_hold_trial``: p_hold
updated by the trial's verdict, NaN where none), every analytic measure under its declared name (``resist_worst``,
..., ``settled_epsilon``; ``feasibility``: reasons, comma-separated), ``simulated_success`` (-1: not simulated),
the trial's other fields (``validation_fingers_in_contact``, ``validation_reason``), the MuJoCo trial's
(``mujoco_success``, -1: not simulated, ``mujoco_reason``, its motions, ...) and ``robust_epsilon_mean``,
``robust_epsilon_quantile``, ``robust_samples`` (:data:`QUALITIES`, derived from :mod:`planner.record.fields`; NaN
or -1 when absent);
``grasps/joint_names`` (J,), ``joints_closed`` / ``joints_open`` (N, J) [rad or m] (every joint: the mimics a
record leaves out at their coupling; ``joints_open`` and ``preshape``: the opening ``import --rescore`` closes
each pose from) and ``joints_closed_given`` / ``joints_open_given`` (N, J) int (1: the record names the joint, an
import names those); ``width`` (N,) [m] (NaN: a hand with none); ``preshape``, ``candidate``, ``seed``; ``contacts``
(N,) JSON text ``[{point, normal, link}]`` in the object frame; ``approach_point``, ``approach_dir`` (N, 3),
``roll`` [rad], ``standoff`` [m]; ``table_plane`` (N, 4) the table top the grasp was planned on, object frame, [nx,
ny, nz, height] (NaN: planned on the object alone); ``squeezed_from_turn`` (N,) [rad] (NaN: closed where planned,
not a squeeze's end); ``poses_hand_frame`` (N, 4, 4) (the hand frame in the object frame) and ``export_frame`` (4,
4) with transforms = poses_hand_frame @ export_frame.

The per-grasp content (:func:`per_grasp`; where each column goes and how it reads back:
:mod:`planner.datasets.acronym_columns`) is shared with the GraspGen JSON writer. Datasets are chunked and
resizable; each batch of rows is appended. Reading (:func:`read_header`, :func:`read_poses`, :func:`read_grasps`,
:func:`read_simulation`, :func:`read_openings`) serves ``grasp import``: our own files come back losslessly,
foreign ones give poses to re-score.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from planner.datasets import registry
from planner.datasets.acronym_checks import (
    check_columns,
    check_joints,
    contact_items,
    float_values,
    label_values,
    open_file,
    positive_value,
)
from planner.datasets.acronym_columns import (
    DATASETS,
    EXTRAS,
    FLEX,
    IMPLIED,
    MISSING,
    MOTIONS,
    QUALITIES,
    ROBUST_EPSILON,
    as_text,
    candidate_numbers,
    carried,
    file_labels_of,
    joint_names,
    joints_of,
    measures_of,
    openings_of,
    own_file,
    per_grasp,
    trial_columns,
    trials_of,
)
from planner.datasets.columns import Column
from planner.datasets.labels import file_source
from planner.datasets.meshes import ExportedObject
from planner.errors import InputError
from planner.geometry.frames import approach_of
from planner.record.contacts import HandContacts
from planner.record.grasp import FileLabel, Grasp, RobustEpsilon, Trial
from planner.specs.hands import HandSpec
from planner.specs.preshapes import load_preshapes, sweep_preshapes
from planner.specs.up import up_axis

__all__ = ["CHUNK_ROWS", "CONFIGURATION_DOC", "DATASETS", "EXTRAS", "FLEX", "IMPLIED", "MISSING", "MOTIONS",
           "QUALITIES", "ROBUST_EPSILON", "ROTATION_TOL", "SUFFIX", "AcronymHeader", "carried", "gripper_configuration",
           "joint_names", "per_grasp", "read_grasps", "read_header", "read_labels", "read_openings", "read_poses",
           "read_simulation", "relative_path", "write"]

SUFFIX = ".h5"
#: Rows per HDF5 chunk at most: 1,024 transforms are 128 kB. A file of fewer grasps (one batch) is one chunk of
#: its own rows: a chunk is stored whole, so 10 grasps in 1,024-row chunks took ~1.6 MB over ~150 datasets.
CHUNK_ROWS = 1024
#: A transform's rotation rows may deviate from orthonormal by this much (float32 files pass).
ROTATION_TOL = 1e-5
#: The per-hand table of ``gripper/configuration`` above, for the README.
CONFIGURATION_DOC = __doc__[__doc__.index("| hand |"):__doc__.index("\n\nFiles written before")].strip() + "\n"


# -- writing ------------------------------------------------------------------------
def relative_path(stem: str, hand: str) -> str:
    """Where the file of (object, hand) goes in the export folder."""
    return f"{stem}__{hand}{SUFFIX}"


def gripper_configuration(hand: HandSpec) -> tuple[list[str], np.ndarray]:
    """``gripper/configuration_joints`` and ``gripper/configuration`` (D,):
    the driven finger joints and their values [m or rad] in the widest
    preshape (the module docstring has the table per hand)."""
    shape = hand.widest(sweep_preshapes(hand))
    names = [j.name for j in hand.driven]
    return names, np.array([shape.joints[n] for n in names], np.float64)


def write(path: Path, info: ExportedObject, hand: HandSpec, batches: Iterable[list[Grasp]]) -> int:
    """Write the file (atomically: a partial export never has the final name); returns N."""
    import h5py

    tmp = path.with_name(path.name + ".tmp")
    total = 0
    sources: set[str] = set()
    with h5py.File(tmp, "w") as f:
        _header(f, info, hand)
        for batch in batches:
            columns = per_grasp(batch, hand, info.label)
            for key, values in columns.items():
                _append(f, f"grasps/{key}", values, total)
            total += len(batch)
            sources.update(columns["qualities/label_from"])
        f[f"grasps/{FLEX}object_in_gripper"].attrs["label_source"] = file_source(sources)
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
    f["object/up"] = row.up
    f["object/p_hold_outside"] = info.outside_text
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
        rows = min(CHUNK_ROWS, max(1, len(data)))
        f.create_dataset(key, data=data, maxshape=(None, *data.shape[1:]), chunks=(rows, *data.shape[1:]))
        return
    ds = f[key]
    ds.resize(start + len(data), axis=0)
    ds[start:] = data


# -- reading ------------------------------------------------------------------------
@dataclass(frozen=True)
class AcronymHeader:
    """What an ACRONYM file says about its gripper and object.

    ``scale``, ``mass``, ``friction`` and ``up`` are None when absent (a value that
    is not a positive number, an up that is no axis, is refused); ``mesh_sha256``: the hash of the mesh the grasps were
    planned on (this project's files since issue 12); ``extras``: the file
    carries this project's qualities, joints and contacts (it can be read
    back losslessly); ``com`` (3,) [m] and ``inertia`` (9,) [kg m^2, row by row] the object's as the file
    gives them (None: absent or not finite).
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
    up: str | None = None
    com: tuple[float, float, float] | None = None
    inertia: tuple[float, ...] | None = None


def read_header(path: Path) -> AcronymHeader:
    """The file's gripper ("" where it has no ``gripper/type``: a user's own labels, ``--hand`` names it) and
    object; a file without ACRONYM's grasps is refused."""
    with open_file(path) as f:
        if "grasps/transforms" not in f:
            raise InputError(f"{path}: no 'grasps/transforms' dataset; not an ACRONYM grasp file")
        return AcronymHeader(
            path=path, gripper=as_text(f["gripper/type"][()]) if "gripper/type" in f else "",
            object_name=as_text(f["object/name"][()]) if "object/name" in f else None,
            object_file=as_text(f["object/file"][()]) if "object/file" in f else None,
            scale=positive_value(f, "object/scale"), mass=positive_value(f, "object/mass"),
            friction=positive_value(f, "object/friction"), extras=all(f"grasps/{k}" in f for k in EXTRAS),
            mesh_sha256=as_text(f["object/mesh_sha256"][()]) or None if "object/mesh_sha256" in f else None,
            up=up_axis(as_text(f["object/up"][()]), str(path), "object/up") if "object/up" in f else None,
            com=float_values(f, "object/com", (3,)), inertia=float_values(f, "object/inertia", (3, 3)))


def read_poses(path: Path, hand: HandSpec) -> np.ndarray:
    """(N, 4, 4) grasp poses (hand frame in the object frame): the checked
    transforms times the inverse of the file's export frame (else the hand's)."""
    with open_file(path) as f:
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
    """This project's grasps back from a file with its extras, the object named ``obj``: candidate and seed as
    the file gives them (``grasps/candidate``, ``grasps/seed``) where its candidates are distinct, else the row
    number (a squeeze's end its parent's) and 0 (:func:`candidate_numbers`)."""
    n = len(poses)
    with open_file(path) as f:
        g = f["grasps"]
        q = g["qualities"]
        names = list(g["joint_names"].asstr()[()])
        closed, opened = joints_of(path, g, "joints_closed"), joints_of(path, g, "joints_open")
        col = {k: (q[k][()] if k in q else np.full(n, np.nan))  # whole columns: h5py indexing per row is slow
               for k in ("epsilon", "volume", "force_closure", "reachability", "manipulability")}
        check_columns(path, g, n, ("measures", "file_label"))
        measures, labels = measures_of(q, n), file_labels_of(g, n)
        width = g["width"][()] if "width" in g else np.full(n, np.nan)
        preshape = g["preshape"].asstr()[()] if "preshape" in g else ["imported"] * n
        tcps = {shape.name: shape.tcp for shape in load_preshapes(hand)}  # files before the approach rays
        rays = [approach_of(p, hand.approach, tcps.get(str(name), hand.tcp)) for p, name in zip(poses, preshape)]
        approach_dir = g["approach_dir"][()] if "approach_dir" in g else [r[1] for r in rays]
        approach_point = g["approach_point"][()] if "approach_point" in g else [r[0] for r in rays]
        roll = g["roll"][()] if "roll" in g else [r[2] for r in rays]
        standoff = g["standoff"][()] if "standoff" in g else np.zeros(n)
        planes = g["table_plane"][()] if "table_plane" in g else np.full((n, 4), np.nan)
        contacts = contact_items(path, list(g["contacts"].asstr()[()]), n)
        turned = g["squeezed_from_turn"][()] if "squeezed_from_turn" in g else np.full(n, np.nan)
        ends = np.isfinite(turned)  # a squeeze's end shares its parent's candidate
        kept, seeds = candidate_numbers(g["candidate"][()] if "candidate" in g else None,
                                        g["seed"][()] if "seed" in g else np.zeros(n, np.int64), planes, ends)
    check_joints(path, hand, names, n, joints_closed=closed, joints_open=opened)
    return [Grasp(object=obj, hand=hand.name, preshape=str(preshape[i]), candidate=kept[i], seed=seeds[i],
                  approach_point=np.asarray(approach_point[i], float), approach_dir=np.asarray(approach_dir[i], float),
                  roll=float(roll[i]), standoff=float(standoff[i]), pose=poses[i],
                  open_joints=_joints(names, opened[i]), closed_joints=_joints(names, closed[i]),
                  width=_maybe(width[i]), contacts=_contacts(path, contacts[i], hand),
                  epsilon=float(col["epsilon"][i]), volume=float(col["volume"][i]),
                  force_closure=bool(col["force_closure"][i]), reachability=_maybe(col["reachability"][i]),
                  manipulability=_maybe(col["manipulability"][i]),
                  table_plane=None if np.isnan(planes[i]).any() else np.asarray(planes[i], float),
                  squeezed_from_turn=_maybe(turned[i]), measures=measures[i], file_label=labels[i])
            for i in range(n)]


def read_openings(path: Path, hand: HandSpec) -> registry.Openings:
    """Each pose's opening where the file gives it (:func:`openings_of`; ACRONYM's own files give none)."""
    with open_file(path) as f:
        return openings_of(path, f["grasps"], hand, len(f["grasps/transforms"]))


def read_labels(path: Path) -> np.ndarray:
    """(N,) 0/1 ``grasps/qualities/flex/object_in_gripper`` of a grasp file (a
    label set: FleX's, a real robot's outcomes); a column (N, 1) is read as N labels."""
    with open_file(path) as f:
        key = f"grasps/{FLEX}object_in_gripper"
        if key not in f:
            raise InputError(f"{path}: no {key}: not a labelled grasp file")
        n = len(f["grasps/transforms"]) if "grasps/transforms" in f else None
        return label_values(path, key, f[key][()], n)


def read_file_labels(path: Path) -> list[FileLabel | None]:
    """Per pose, the label of the file it came from, kept on import: a foreign file's ``flex/object_in_gripper``
    (FleX's, a user's outcomes); one of ours (:func:`own_file`) keeps them in ``file_label_*``. None: none given."""
    with open_file(path) as f:
        g, n = f["grasps"], len(f["grasps/transforms"])
        if own_file(g) or f"{FLEX}object_in_gripper" not in g:  # ours: its object_in_gripper is its own label
            check_columns(path, g, n, ("file_label",))
            return file_labels_of(g, n)
    return [FileLabel(bool(v), f"{path.name} grasps/{FLEX}object_in_gripper") for v in read_labels(path).tolist()]


def read_simulation(path: Path) -> list[tuple[Trial | None, RobustEpsilon | None, Trial | None]]:
    """Per row, the PyBullet shake-test result, the robust epsilon and the
    MuJoCo trial's result our own files carry (None where the row was not
    simulated; an empty list for other files). What a file does not store
    reads as :data:`MISSING` says; a motion that is not stored as -1."""
    with open_file(path) as f:
        g = f["grasps"]
        if "qualities/simulated_success" not in g:
            return []
        n = len(g["qualities/simulated_success"])
        check_columns(path, g, len(f["grasps/transforms"]) if "transforms" in g else n,
                      ("validation", "mujoco", "robust"))
        trial, mujoco, robust = trials_of(g, "validation", n), trials_of(g, "mujoco", n), trial_columns(g, "robust", n)
    out: list[tuple[Trial | None, RobustEpsilon | None, Trial | None]] = []
    for i in range(n):
        r = None if robust["mean"][i] is None or robust["quantile"][i] is None else \
            RobustEpsilon(**{k: v[i] for k, v in robust.items()})
        out.append((trial[i], r, mujoco[i]))
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


registry.register("acronym", registry.PairWriter(relative_path, write),
                  registry.Reader(read_header, read_poses, read_grasps, read_simulation, read_openings,
                                  read_file_labels))
