"""What an ACRONYM file must hold before its grasps are read back losslessly (this project's extras): joints of
the hand within its limits, contacts as JSON, one row per grasp. A file that fails is refused with a one-line
error naming the dataset (a hand-edited or damaged file would otherwise store grasps that break ``show`` and
exports later). Labels (``object_in_gripper``, read by ``grasp calibrate``) are checked alike, and the
header's numbers."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from planner.datasets.acronym_columns import location
from planner.errors import InputError
from planner.record import fields
from planner.specs.hands import HandSpec


def open_file(path: Path) -> Any:
    """An HDF5 file open for reading; a folder, a missing file or another format refused."""
    import h5py

    if path.is_dir():
        raise InputError(f"{path}: is a folder; give its .h5 files (e.g. {path / '*.h5'})")
    if not path.is_file():
        raise InputError(f"{path}: file not found")
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        raise InputError(f"{path}: not an HDF5 file ({exc})") from None


#: [rad or m] How far past a joint's limit a stored value may lie (the simulator's own overshoot).
LIMIT_SLACK = 1e-3


def check_joints(path: Path, hand: HandSpec, names: list[str], n: int, **matrices: np.ndarray) -> None:
    """``names`` (J,) joints of ``hand``; each matrix (``joints_closed``, ``joints_open``) (n, J), its finite
    values within the joints' limits (NaN: a joint the grasp does not set)."""
    joints = {j.name: j for j in hand.joints}
    unknown = [name for name in names if name not in joints]
    if unknown:
        raise InputError(f"{path}: grasps/joint_names {unknown[:3]} are not joints of hand '{hand.name}' "
                         f"({', '.join(joints)})")
    lower = np.array([joints[name].lower for name in names]) - LIMIT_SLACK
    upper = np.array([joints[name].upper for name in names]) + LIMIT_SLACK
    for key, values in matrices.items():
        values = np.asarray(values, float)
        if values.shape != (n, len(names)):
            raise InputError(f"{path}: grasps/{key} has shape {values.shape}; expected ({n}, {len(names)})")
        if np.isinf(values).any():
            raise InputError(f"{path}: grasps/{key} holds an infinite value")
        outside = np.isfinite(values) & ((values < lower) | (values > upper))
        if outside.any():
            row, col = (int(v[0]) for v in np.nonzero(outside))
            raise InputError(f"{path}: grasps/{key} row {row}: {names[col]} = {values[row, col]:.6g} lies outside "
                             f"its limits [{lower[col] + LIMIT_SLACK:.6g}, {upper[col] - LIMIT_SLACK:.6g}]")


def contact_items(path: Path, texts: list[str], n: int) -> list[list[dict]]:
    """The n rows of ``grasps/contacts``, each a JSON list of contact objects."""
    if len(texts) != n:
        raise InputError(f"{path}: grasps/contacts holds {len(texts)} rows for {n} grasps")
    out = []
    for i, text in enumerate(texts):
        try:
            items = json.loads(text)
        except ValueError:
            items = None
        if not isinstance(items, list) or not all(isinstance(c, dict) and "link" in c for c in items):
            raise InputError(f"{path}: grasps/contacts row {i} is not a JSON list of contacts")
        out.append(items)
    return out


def label_values(path: Path, key: str, data: np.ndarray, n: int | None) -> np.ndarray:
    """(n,) float 0/1 labels of dataset ``key``: numbers or booleans, one per grasp (``n``: the file's grasps;
    None: as many as there are), shaped (n,) or as one column (n, 1), which is unambiguous."""
    data = np.asarray(data)
    if data.dtype.kind not in "biuf":
        kind = "text" if data.dtype.kind in "SUO" else str(data.dtype)
        shown = ", ".join(repr(v) for v in data.ravel()[:2].tolist())
        raise InputError(f"{path}: {key} holds {kind} values ({shown}, ...); it must hold 0/1 numbers "
                         "(1: held, 0: dropped)")
    if data.ndim == 2 and data.shape[1] == 1:
        data = data[:, 0]
    if data.ndim != 1:
        raise InputError(f"{path}: {key} has shape {data.shape}; it must hold one 0/1 label per grasp, (N,) or (N, 1)")
    n = len(data) if n is None else n
    if len(data) != n:
        raise InputError(f"{path}: {key} must hold one 0/1 label per grasp ({n}), got {len(data)} values")
    labels = data.astype(float)
    bad = labels[~np.isin(labels, (0.0, 1.0))]
    if len(bad):
        shown = ", ".join(f"{v:g}" for v in np.unique(bad)[:3])
        raise InputError(f"{path}: {key} must hold 0/1 labels; {len(bad)} of {n} are not ({shown})")
    return labels


def positive_value(f: Any, key: str) -> float | None:
    """A positive number the file gives (None: absent); a value that is not one is refused."""
    if key not in f:
        return None
    value = float(np.asarray(f[key][()]).reshape(-1)[0])
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{Path(f.filename)}: {key} is {value:g}; it must be a positive number")
    return value


def float_values(f: Any, key: str, shape: tuple[int, ...]) -> Any:
    """The finite float dataset ``key`` of that shape as a flat tuple (None: absent or otherwise)."""
    if key not in f:
        return None
    values = np.asarray(f[key][()])
    if values.shape != shape or values.dtype.kind not in "fiu" or not np.isfinite(values).all():
        return None
    return tuple(float(v) for v in values.ravel())


def check_columns(path: Path, g: Any, n: int, groups: tuple[str, ...]) -> None:
    """The columns below ``grasps/`` (``g``) of the record ``groups`` (``validation``, ``mujoco``, ``robust``,
    ``measures``) a file holds, as their declaration says: one row per grasp (``n``), text or numbers, a
    trial's verdict -1/0/1 and a count a whole number (a NaN there was an internal error after the database
    was opened, a 2 a verdict stored as held)."""
    for f in (f for group in groups for f in fields.group(group)):
        key = location(f.name)
        if key not in g:
            continue
        data = np.asarray(g[key][()])
        where = f"{path}: grasps/{key}"
        shape = (n, *f.shape) if f.kind == "vector" else (n,)
        if data.shape != shape:
            raise InputError(f"{where} has shape {data.shape}; expected {shape}, one row per grasp")
        if (f.dtype == "string") != (data.dtype.kind in "SUO"):
            raise InputError(f"{where} holds {'text' if data.dtype.kind in 'SUO' else 'numbers'}; expected "
                             f"{'text' if f.dtype == 'string' else 'numbers'}")
        if f.dtype != "int64":
            continue
        values = data.astype(float)
        allowed = np.isin(values, (-1.0, 0.0, 1.0)) if f.kind == "bool" else np.isfinite(values) & (values % 1 == 0)
        if not allowed.all():
            row = int(np.flatnonzero(~allowed)[0])
            expected = "-1 (not simulated), 0 or 1" if f.kind == "bool" else "a whole number"
            raise InputError(f"{where} row {row} is {values[row]:g}; expected {expected}")
