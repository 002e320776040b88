"""Validated contact sets: the input every quality function starts from.

Notation (grasping-foundations, sec. 2.2): contact i sits at c_i in the world
frame {W}; its frame {C}_i has axes (n_i, l_i, o_i), n_i the unit normal
pointing INTO the object, l_i and o_i spanning the tangent plane.  R_i is the
rotation of {C}_i relative to {W}, so its columns are n_i, l_i, o_i.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from planner.errors import DegenerateGraspError
from planner.quality.tolerances import FRAME_TOL

#: Contact models, in the order of their integer codes.
MODELS = ("frictionless", "point", "soft")
FRICTIONLESS, POINT, SOFT = 0, 1, 2
#: Norms of the grasp wrench space.
NORMS = ("L1", "Linf")

ModelArg = str | Sequence[str]


@dataclass(frozen=True)
class Contacts:
    """n contacts with their contact models.

    points : (n, 3) float, c_i in {W} [m].
    frames : (n, 3, 3) float, R_i; columns (n_i, l_i, o_i), orthonormal.
    mu : (n,) float, Coulomb friction coefficient per contact (>= 0).
    model : (n,) int, index into MODELS per contact.
    torsion : (n,) float [m], soft-finger torsional moment per unit normal
        force (>= 0); ignored for other models.
    """

    points: np.ndarray
    frames: np.ndarray
    mu: np.ndarray
    model: np.ndarray
    torsion: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.points)
        shapes = {"points": (n, 3), "frames": (n, 3, 3), "mu": (n,),
                  "model": (n,), "torsion": (n,)}
        for name, shape in shapes.items():
            if getattr(self, name).shape != shape:
                raise DegenerateGraspError(
                    f"{name} must have shape {shape}, got {getattr(self, name).shape}")

    @property
    def normals(self) -> np.ndarray:
        """(n, 3) unit normals n_i (first frame columns)."""
        return self.frames[:, :, 0]


def as_array(value: ArrayLike, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a finite float array of ``shape``; -1 in shape = any size."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DegenerateGraspError(f"{name} is not a numeric array ({exc})") from None
    if arr.ndim != len(shape) or any(s not in (-1, a) for s, a in zip(shape, arr.shape)):
        want = str(tuple("n" if s == -1 else s for s in shape)).replace("'", "")
        raise DegenerateGraspError(f"{name} must have shape {want}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise DegenerateGraspError(f"{name} contains NaN or infinite values")
    return arr


def per_contact(value: ArrayLike, name: str, n: int) -> np.ndarray:
    """A scalar or (n,) finite non-negative parameter, broadcast to (n,)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DegenerateGraspError(f"{name} is not a number or numeric array ({exc})") from None
    if arr.ndim > 1 or (arr.ndim == 1 and len(arr) != n):
        raise DegenerateGraspError(f"{name} must be a scalar or have {n} values, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise DegenerateGraspError(f"{name} contains NaN or infinite values")
    if (arr < 0).any():
        raise DegenerateGraspError(f"{name} must be >= 0, got {arr.min():g}")
    return np.broadcast_to(arr, (n,))


def model_codes(model: ModelArg, n: int) -> np.ndarray:
    """(n,) int codes of a model name or a sequence of n names."""
    names = [model] * n if isinstance(model, str) else list(model)
    if len(names) != n:
        raise DegenerateGraspError(f"model has {len(names)} entries for {n} contacts")
    for name in names:
        if name not in MODELS:
            raise DegenerateGraspError(
                f"unknown contact model '{name}'. Available models: {', '.join(MODELS)}")
    return np.array([MODELS.index(name) for name in names], dtype=int)


def check_frames(frames: np.ndarray) -> None:
    """Raise unless every R_i has unit, mutually orthogonal columns."""
    err = np.abs(np.einsum("nki,nkj->nij", frames, frames) - np.eye(3))
    if not len(frames) or err.max() <= FRAME_TOL:
        return
    bad_normal = np.flatnonzero(err[:, 0, 0] > FRAME_TOL)
    if len(bad_normal):
        i = bad_normal[0]
        raise DegenerateGraspError(
            f"normal of contact {i} has length {np.linalg.norm(frames[i, :, 0]):.6g};"
            f" normals must be unit (tolerance {FRAME_TOL:g})")
    i = int(np.flatnonzero(err.max(axis=(1, 2)) > FRAME_TOL)[0])
    raise DegenerateGraspError(
        f"frame of contact {i} is not orthonormal (max |R^T R - I| = {err[i].max():.3g});"
        " its columns must be unit n_i, l_i, o_i")


def as_contacts(points: ArrayLike, frames: ArrayLike, *, mu: ArrayLike = 0.0,
                model: ModelArg = "point", torsion: ArrayLike = 0.0) -> Contacts:
    """Validate raw contact arrays; raise DegenerateGraspError if malformed."""
    pts = as_array(points, "points", (-1, 3))
    n = len(pts)
    rot = as_array(frames, "frames", (n, 3, 3))
    check_frames(rot)
    return Contacts(pts, rot, per_contact(mu, "mu", n), model_codes(model, n),
                    per_contact(torsion, "torsion", n))


def as_center(center: ArrayLike) -> np.ndarray:
    """The reference point p as a finite (3,) array [m]."""
    return as_array(center, "center", (3,))


def as_torque_scale(torque_scale: float) -> float:
    """rho [m] as a finite positive float."""
    rho = float(as_array(torque_scale, "torque_scale", ()))
    if rho <= 0:
        raise DegenerateGraspError(f"torque_scale must be > 0 m, got {rho:g}")
    return rho


def as_norm(norm: str) -> str:
    """Validate the GWS norm name."""
    if norm not in NORMS:
        raise DegenerateGraspError(f"unknown norm '{norm}'. Available norms: {', '.join(NORMS)}")
    return norm
