"""Hand Jacobian J and grasp Jacobian G_J (grasping-foundations, eqs 2.19-2.33).

The partial hand Jacobian J~_i (6 x n_q) maps joint rates qdot to the twist
of the hand at contact i expressed in the contact frame {C}_i (eq 2.19):

    J~_i = blockdiag(R_i^T, R_i^T) [d_i1 ... d_in_q ; l_i1 ... l_in_q]

The book prints the prefactor as "R_i" (eq 2.20), which cannot multiply the
6-row block; we use blockdiag(R_i^T, R_i^T) because that is what puts the
twist in {C}_i with the same convention as t_i,obj = G~_i^T t (eq 2.13):
both have linear part R_i^T (velocity of the material point at c_i) and
angular part R_i^T omega.  For joint j with origin zeta_j and unit axis z_j
(both in {W}) that moves contact i's link:

* revolute:  d_ij = S(c_i - zeta_j)^T z_j = z_j x (c_i - zeta_j),  l_ij = z_j;
* prismatic: d_ij = z_j,  l_ij = 0;

and d_ij = l_ij = 0 otherwise (eqs 2.21-2.22).  J = B J~ (eq 2.29) keeps the
rows each contact transmits, so that J qdot = G^T t (eq 2.31).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from planner.errors import DegenerateGraspError
from planner.quality.contacts import Contacts, ModelArg, as_array, as_contacts
from planner.quality.grasp_matrix import selection_lengths, skew
from planner.quality.tolerances import FRAME_TOL

JOINT_TYPES = ("revolute", "prismatic")


def _joints(joint_origins: ArrayLike, joint_axes: ArrayLike,
            joint_types: Sequence[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    origins = as_array(joint_origins, "joint_origins", (-1, 3))
    axes = as_array(joint_axes, "joint_axes", (len(origins), 3))
    types = list(joint_types)
    if len(types) != len(origins):
        raise DegenerateGraspError(f"joint_types has {len(types)} entries for {len(origins)} joints")
    for name in types:
        if name not in JOINT_TYPES:
            raise DegenerateGraspError(
                f"unknown joint type '{name}'. Available joint types: {', '.join(JOINT_TYPES)}")
    if (np.abs(np.linalg.norm(axes, axis=1) - 1.0) > FRAME_TOL).any():
        raise DegenerateGraspError("joint_axes must be unit vectors")
    return origins, axes, np.array([name == "revolute" for name in types], dtype=bool)


def _affects(contact_links: ArrayLike, joint_affects: ArrayLike, n_c: int, n_q: int) -> np.ndarray:
    links = np.asarray(contact_links)
    if links.shape != (n_c,) or not np.issubdtype(links.dtype, np.integer):
        raise DegenerateGraspError(f"contact_links must be ({n_c},) integers, got {links.shape}")
    affects = np.asarray(joint_affects)
    if affects.shape != (n_c, n_q) or not (affects.dtype == bool or np.isin(affects, (0, 1)).all()):
        raise DegenerateGraspError(f"joint_affects must be ({n_c}, {n_q}) booleans")
    affects = affects.astype(bool)
    for link in np.unique(links):
        rows = affects[links == link]
        if (rows != rows[0]).any():
            raise DegenerateGraspError(
                f"contacts on link {link} disagree in joint_affects; one link, one row")
    return affects


def hand_jacobian(points: ArrayLike, frames: ArrayLike, contact_links: ArrayLike,
                  joint_origins: ArrayLike, joint_axes: ArrayLike,
                  joint_types: Sequence[str], joint_affects: ArrayLike,
                  model: ModelArg = "point") -> np.ndarray:
    """J (l, n_q) = B J~, eqs 2.19-2.29.

    points : (n_c, 3) c_i [m]; frames : (n_c, 3, 3) R_i, columns (n_i, l_i,
    o_i); contact_links : (n_c,) int link of each contact (contacts sharing a
    link must share their joint_affects row); joint_origins : (n_q, 3) zeta_j
    [m]; joint_axes : (n_q, 3) unit z_j; joint_types : n_q names from
    JOINT_TYPES; joint_affects : (n_c, n_q) bool, joint j moves contact i's
    link; model : one name or n_c names.  Rows per contact: l_i (1, 3 or 4),
    in units of m/s (linear) and rad/s (soft-finger spin) per unit qdot.
    """
    return contacts_jacobian(as_contacts(points, frames, model=model), contact_links, joint_origins, joint_axes,
                             joint_types, joint_affects)


def contacts_jacobian(contacts: Contacts, contact_links: ArrayLike, joint_origins: ArrayLike, joint_axes: ArrayLike,
                      joint_types: Sequence[str], joint_affects: ArrayLike) -> np.ndarray:
    """:func:`hand_jacobian` of contacts already validated (``as_contacts``: what the resistance's program holds),
    without validating them again."""
    origins, axes, revolute = _joints(joint_origins, joint_axes, joint_types)
    n_c, n_q = len(contacts.points), len(origins)
    affects = _affects(contact_links, joint_affects, n_c, n_q)
    arm = contacts.points[:, None, :] - origins[None]             # (n_c, n_q, 3)
    lin = np.where(revolute[None, :, None],
                   np.einsum("cjab,jb->cja", np.swapaxes(skew(arm), -1, -2), axes),
                   axes[None])
    ang = np.where(revolute[None, :, None], axes[None], 0.0)
    lin, ang = lin * affects[..., None], ang * affects[..., None]
    rot_t = np.swapaxes(contacts.frames, 1, 2)                  # R_i^T
    tilde = np.concatenate([rot_t @ np.swapaxes(lin, 1, 2), rot_t @ np.swapaxes(ang, 1, 2)],
                           axis=1)                                # (n_c, 6, n_q)
    lengths = selection_lengths(contacts)
    if n_c == 0:
        return np.zeros((0, n_q))
    return np.concatenate([t[:k] for t, k in zip(tilde, lengths)], axis=0)


def grasp_jacobian(grasp: ArrayLike, jacobian: ArrayLike) -> np.ndarray:
    """G_J = (G^+)^T J (eq 2.33), (6, n_q): joint rates to object twist.

    grasp : (6, l) G; jacobian : (l, n_q) J.
    """
    g = as_array(grasp, "grasp matrix", (6, -1))
    j = as_array(jacobian, "hand Jacobian", (g.shape[1], -1))
    return np.linalg.pinv(g).T @ j
