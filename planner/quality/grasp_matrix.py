"""Grasp matrix G (grasping-foundations, sec. 2.3.1, eqs 2.13-2.18 and 2.28).

The partial grasp matrix G~_i (6 x 6) maps the object twist t = (v, omega)
of the reference point p in {W} to the object twist at contact i expressed
in the contact frame {C}_i:  t_i,obj = G~_i^T t  (eq 2.13), with

    G~_i = [[R_i,               0  ],
            [S(c_i - p) R_i,    R_i]]                               (2.14)

Dually, G~_i maps a contact wrench written in {C}_i (force components along
n_i, l_i, o_i, then moment components) to the wrench it exerts on the object
at p in {W}.  The selection matrix B_i (l_i x 6, eqs 2.8-2.10) keeps the
l_i twist components a contact model transmits, and G^T = B G~^T (2.28), so
G = G~ B^T maps the stacked transmitted contact-force components (l,) to the
net object wrench (6,).  No torque scaling: G is the book's G.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from planner.errors import DegenerateGraspError
from planner.quality.contacts import MODELS, Contacts, ModelArg, as_array, as_center, as_contacts

#: l_i, the number of twist components each contact model transmits.
TRANSMITTED = {"frictionless": 1, "point": 3, "soft": 4}
_LENGTHS = np.array([TRANSMITTED[name] for name in MODELS])


def skew(r: ArrayLike) -> np.ndarray:
    """S(r) of eq 2.15, so that S(r) x = r x x.  r : (..., 3) -> (..., 3, 3)."""
    r = np.asarray(r, dtype=float)
    out = np.zeros(r.shape + (3,))
    out[..., 0, 1], out[..., 0, 2] = -r[..., 2], r[..., 1]
    out[..., 1, 0], out[..., 1, 2] = r[..., 2], -r[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -r[..., 1], r[..., 0]
    return out


def selection_matrix(model: str) -> np.ndarray:
    """B_i (l_i, 6) of eqs 2.8-2.10 for one contact model name."""
    if model not in TRANSMITTED:
        raise DegenerateGraspError(
            f"unknown contact model '{model}'. Available models: {', '.join(MODELS)}")
    return np.eye(6)[: TRANSMITTED[model]]


def partial_grasp_matrices(contacts: Contacts, center: np.ndarray) -> np.ndarray:
    """G~_i for validated contacts, (n, 6, 6), eq 2.14."""
    n = len(contacts.points)
    rot = contacts.frames
    out = np.zeros((n, 6, 6))
    out[:, :3, :3] = rot
    out[:, 3:, 3:] = rot
    out[:, 3:, :3] = skew(contacts.points - center) @ rot
    return out


def partial_grasp_matrix(point: ArrayLike, frame: ArrayLike, center: ArrayLike) -> np.ndarray:
    """G~_i (6, 6) of eq 2.14 for c_i = point (3,), R_i = frame (3, 3), p = center."""
    contacts = as_contacts(as_array(point, "point", (3,))[None],
                           as_array(frame, "frame", (3, 3))[None])
    return partial_grasp_matrices(contacts, as_center(center))[0]


def selection_lengths(contacts: Contacts) -> np.ndarray:
    """(n,) int, l_i per contact."""
    return _LENGTHS[contacts.model]


def grasp_matrix(points: ArrayLike, frames: ArrayLike, center: ArrayLike,
                 model: ModelArg = "point") -> np.ndarray:
    """G (6, l) with G^T = B G~^T (eq 2.28), l = sum of l_i (eq 2.12).

    points : (n, 3) c_i [m]; frames : (n, 3, 3) R_i, columns (n_i, l_i, o_i);
    center : (3,) p [m]; model : one name or n names (per-contact models).
    Column block i holds the first l_i columns of G~_i: force along n_i, l_i,
    o_i [N] and, for soft fingers, the moment about n_i [N m].
    """
    contacts = as_contacts(points, frames, model=model)
    tilde = partial_grasp_matrices(contacts, as_center(center))
    lengths = selection_lengths(contacts)
    if len(lengths) == 0:
        return np.zeros((6, 0))
    return np.concatenate([g[:, :k] for g, k in zip(tilde, lengths)], axis=1)
