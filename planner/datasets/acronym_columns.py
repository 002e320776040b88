"""Where each column of a grasp goes in an ACRONYM file
(:mod:`planner.datasets.acronym`), and back: the datasets below ``grasps/``
and the column of :func:`~planner.datasets.columns.grasp_columns` each
holds, derived from the declaration of the stored fields
(:mod:`planner.record.fields`); a batch of grasps as those datasets
(:func:`per_grasp`, shared with the GraspGen writer); and a file's columns
as the record's values again (:func:`measures_of`, :func:`trials_of`). The
HDF5 file itself is written and read in :mod:`planner.datasets.acronym`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from planner.datasets.columns import Column, given_matrix, grasp_columns, joint_matrix
from planner.datasets.labels import BEST
from planner.datasets.labels import labels as dataset_labels
from planner.datasets.registry import Openings
from planner.errors import InputError
from planner.record import fields
from planner.record.field import Field
from planner.record.grasp import FileLabel, Grasp, Trial
from planner.record.measures import Measures
from planner.specs.hands import HandSpec

FLEX = "qualities/flex/"
#: ACRONYM's motion datasets and the columns they come from.
MOTIONS = {f"{FLEX}object_motion_during_{stage}_{kind}": f"validation_{stage}_{kind}"
           for stage in ("closing", "shaking") for kind in ("linear", "angular")}
#: The robust epsilon's two values, under ACRONYM-style names (``robust_epsilon_mean``).
ROBUST_EPSILON = ("robust_mean", "robust_quantile")
#: ``grasps/qualities/<name>`` -> the column of :func:`grasp_columns` it holds:
#: the record's scores, every analytic measure (``feasibility``: reasons,
#: comma-separated) and, of the trial and the robust epsilon, what ACRONYM's
#: own datasets (``object_in_gripper``, :data:`MOTIONS`) do not hold, all
#: derived from the declaration (:mod:`planner.record.fields`).
QUALITIES = {
    **{name: name for name in ("epsilon", "volume", "force_closure", "reachability", "manipulability", "score",
                               "p_hold", "p_hold_trial", "rank")},
    **{f.name: f.name for f in fields.group("measures")},
    "simulated_success": "validation_success",
    **{f.name: f.name for f in fields.group("validation") if f.name != "validation_success"
       and f.name not in MOTIONS.values()},
    **{f.name: f.name for f in fields.group("mujoco")},
    **{f.name.replace("robust_", "robust_epsilon_") if f.name in ROBUST_EPSILON else f.name: f.name
       for f in fields.group("robust")},
    **{f.name: f.name for f in fields.group("file_label")},
}
#: Per-grasp datasets below ``grasps/`` -> the column of :func:`grasp_columns` each holds
#: (besides ``transforms``, ``object_in_gripper`` and the joint matrices).
DATASETS = {**MOTIONS, **{f"qualities/{name}": column for name, column in QUALITIES.items()},
            **{name: name for name in ("width", "preshape", "candidate", "seed", "contacts", "approach_point",
                                       "approach_dir", "roll", "standoff", "table_plane", "squeezed_from_turn")},
            "poses_hand_frame": "pose"}
#: Datasets whose presence marks a file with this project's extras.
EXTRAS = ("qualities/epsilon", "qualities/volume", "qualities/force_closure", "joint_names", "joints_closed",
          "joints_open", "contacts")
#: Declared fields of the record a file holds otherwise: per file, as matrices, or
#: implied by the contacts.
IMPLIED = {"object": "object/name", "hand": "gripper/type", "open_joints": "joints_open (N, J)",
           "closed_joints": "joints_closed (N, J)", "n_contacts": "contacts", "links_touching": "contacts"}


def carried() -> set[str]:
    """The flat names of the declared record fields a file carries."""
    return {f.name for f in fields.record_fields()} & ({*DATASETS.values()} | set(IMPLIED))


def joint_names(hand: HandSpec) -> list[str]:
    return [j.name for j in hand.joints]


def per_grasp(grasps: list[Grasp], hand: HandSpec, label: str = BEST) -> dict[str, Column]:
    """Every per-grasp field of one batch, keyed by its path below ``grasps/``;
    (n, ...) arrays or n strings. ``transforms`` = pose @ export_frame: the
    dataset gripper frame in the scaled mesh frame, metres; the success label
    as ``label`` chooses (:mod:`planner.datasets.labels`) and, per row, its source."""
    c = grasp_columns(grasps)
    labels, sources = dataset_labels(c, label)
    names = joint_names(hand)
    return {
        "transforms": c["pose"] @ hand.export_frame,
        f"{FLEX}object_in_gripper": labels,
        "qualities/label_from": sources,
        **{key: c[column] for key, column in DATASETS.items()},
        "joints_closed": joint_matrix(c["closed_joints"], names, hand),
        "joints_open": joint_matrix(c["open_joints"], names, hand),
        "joints_closed_given": given_matrix(c["closed_joints"], names),  # which joints each record names
        "joints_open_given": given_matrix(c["open_joints"], names),
    }


#: What a file that lacks a trial or robust field reads as (ACRONYM's own files hold neither).
MISSING = {"validation_fingers_in_contact": -1, "validation_reason": "", "robust_samples": 0,
           "mujoco_success": -1, "mujoco_fingers_in_contact": -1, "mujoco_reason": ""}


def location(name: str) -> str:
    """Where under ``grasps/`` a column of :func:`grasp_columns` is written."""
    return next(key for key, column in DATASETS.items() if column == name)


def measures_of(q: Any, n: int) -> list[Measures | None]:
    """Each row's analytic measures from ``grasps/qualities`` (NaN, or a
    measure the file lacks: not measured; None where resist_worst is not)."""
    group = fields.group("measures")
    columns = {f.attr.partition(".")[2]: _file_values(f, q[f.name][()] if f.name in q else None, n) for f in group}
    first = columns[group[0].attr.partition(".")[2]]
    return [None if first[i] is None else Measures(**{k: v[i] for k, v in columns.items()}) for i in range(n)]


def _file_values(f: Field, data: np.ndarray | None, n: int) -> list:
    """A stored field read from a file column (None: the file lacks it) as the record's values."""
    if f.dtype == "string":
        texts = [""] * n if data is None else [as_text(v) for v in data]
        return [tuple(r for r in t.split(",") if r) for t in texts] if f.kind == "reasons" else texts
    if f.kind == "vector":  # (n, *shape): a row of NaN is a vector not measured
        rows = np.full((n, *f.shape), np.nan) if data is None else np.asarray(data, float)
        return [None if np.isnan(r).all() else r for r in rows]
    values = np.full(n, np.nan) if data is None else np.asarray(data, float)
    if f.kind == "margin":
        return [math.inf if math.isnan(v) else v for v in values.tolist()]
    if f.dtype == "int64":  # a nullable one's neutral -1 or a column the file lacks: not measured
        return [None if math.isnan(v) or (f.nullable and v == f.neutral) else int(v) for v in values.tolist()]
    return [None if math.isnan(v) else v for v in values.tolist()]


def trial_columns(g: Any, group: str, n: int) -> dict[str, list]:
    """The record's values of a trial or robust group, attribute -> n values."""
    out = {}
    for f in fields.group(group):
        key = location(f.name)
        values = _file_values(f, g[key][()] if key in g else None, n)
        if key not in g and f.name in MISSING:
            values = [MISSING[f.name]] * n
        out[f.attr.partition(".")[2]] = values
    return out


def file_labels_of(g: Any, n: int) -> list[FileLabel | None]:
    """The n rows' labels of the files they were imported from, as this project's files keep them
    (``qualities/file_label_success``, -1: none; ``file_label_source``)."""
    columns = trial_columns(g, "file_label", n)
    return [None if ok is None or ok < 0 else FileLabel(bool(ok), source)
            for ok, source in zip(columns["success"], columns["source"])]


def own_file(g: Any) -> bool:
    """Whether ``grasps/`` group ``g`` is of one of this project's exports, whose ``object_in_gripper`` is its own
    label (:mod:`planner.datasets.labels`), never a file's: every export since the first carries
    ``qualities/epsilon`` and that label's attribute ``label_source``, since 2026-12-02 ``qualities/label_from``."""
    label = g.get(f"{FLEX}object_in_gripper")
    return "qualities/epsilon" in g or "qualities/label_from" in g or (label is not None
                                                                       and "label_source" in label.attrs)


def trials_of(g: Any, group: str, n: int) -> list[Trial | None]:
    """The n rows' results of one trial group (None: not simulated, success -1)."""
    columns = trial_columns(g, group, n)
    success = [int(v) for v in np.asarray(columns.pop("success"), float)]
    for k in ("closing_linear", "closing_angular", "shaking_linear", "shaking_angular"):
        columns[k] = [-1.0 if v is None else v for v in columns[k]]
    return [None if ok < 0 else Trial(bool(ok), **{k: v[i] for k, v in columns.items()})
            for i, ok in enumerate(success)]


def openings_of(path: Path, g: Any, hand: HandSpec, n: int) -> Openings:
    """The opening each of the n poses of group ``grasps/`` was planned with, where it says:
    ``joints_open`` of ``hand``'s driven joints as the records gave them (:func:`joints_of`: not a joint the export
    filled in, at its lower limit), ``preshape`` (this project's files). ACRONYM's own files give none (their
    ``gripper/configuration`` is the gripper's full opening, not a pose's): NaN and ''."""
    joints = np.full((n, len(hand.driven)), np.nan)
    if "joints_open" in g and "joint_names" in g:
        names = list(g["joint_names"].asstr()[()])
        opened = joints_of(path, g, "joints_open")
        if opened.shape != (n, len(names)):
            raise InputError(f"{path}: grasps/joints_open has shape {opened.shape}; expected ({n}, {len(names)})")
        for k, joint in enumerate(hand.driven):
            if joint.name in names:
                joints[:, k] = opened[:, names.index(joint.name)]
    given = "preshape" in g and len(g["preshape"]) == n
    return Openings(joints, tuple(g["preshape"].asstr()[()]) if given else ("",) * n)


def joints_of(path: Path, g: Any, key: str) -> np.ndarray:
    """(N, J) ``grasps/<key>`` (``joints_open``, ``joints_closed``) as its records gave them: NaN where
    ``<key>_given`` says a record left the joint out (a mimic the export filled in at its coupling; files without
    it, before issue 26: every joint)."""
    values = np.asarray(g[key][()], float)
    if f"{key}_given" not in g:
        return values
    given = np.asarray(g[f"{key}_given"][()])
    if given.shape != values.shape:
        raise InputError(f"{path}: grasps/{key}_given has shape {given.shape}; expected {values.shape}")
    return np.where(given != 0, values, np.nan)


def as_text(value: object) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def candidate_numbers(given: np.ndarray | None, seeds: np.ndarray, planes: np.ndarray, ends: np.ndarray
                      ) -> tuple[list[int], list[int]]:
    """The n grasps' candidate numbers and seeds in the unit an import stores them in, from a file's (``given``
    (n,) or None, ``seeds`` (n,)) and where a squeeze's end is (``ends`` (n,) bool; ``planes`` (n, 4), NaN: no
    table): the file's where they tell its grasps apart (one sweep's), else the row numbers and seed 0 (several
    sweeps': another seed or table numbers its candidates alike), an end taking its parent's row number where
    its seed, table and candidate find that parent alone, so that it stands for it in the rank as it did
    (:data:`planner.db.ranking.FIRST`)."""
    n = len(ends)
    if given is not None and len(given) == n and len({*zip(given.tolist(), ends.tolist())}) == n:
        return [int(c) for c in given], [int(s) for s in seeds]
    numbers = list(range(n))
    if given is None or len(given) != n:
        return numbers, [0] * n
    keys = [(int(s), None if np.isnan(p).any() else tuple(p.tolist()), int(c)) for s, p, c in zip(seeds, planes, given)]
    rows: dict[tuple, list[list[int]]] = {}
    for i, key in enumerate(keys):
        rows.setdefault(key, [[], []])[bool(ends[i])].append(i)
    for parents, found in rows.values():
        if len(parents) == 1 and len(found) == 1:
            numbers[found[0]] = parents[0]
    return numbers, [0] * n
