"""Primitive wrenches: the generators of the grasp wrench space (GWS).

A force f applied at contact c_i gives the object the wrench
w = (f, (c_i - p) x f / rho)  (eqs 2.2-2.3), rho the torque scale [m].
Per contact model (sec. 2.2.2), the primitive forces are

* frictionless: the normal n_i alone;
* point (hard finger with friction): the m edges of the inscribed polyhedral
  friction cone, f_ij = n_i + mu (cos(2 pi j/m) l_i + sin(2 pi j/m) o_i);
* soft finger: the point-contact edges plus the two pure-torsion wrenches
  (n_i, ((c_i - p) x n_i +/- torsion_i n_i) / rho).
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from planner.errors import DegenerateGraspError
from planner.quality.contacts import FRICTIONLESS, SOFT, Contacts, ModelArg, as_center, as_contacts, as_torque_scale
from planner.quality.grasp_matrix import skew
from planner.quality.tolerances import DEDUP_TOL


class PrimitiveWrenches(NamedTuple):
    """wrenches : (k, 6) float, rows (force [N/N], torque / rho [N/N]) in {W}.
    contact : (k,) int, index of the contact each row belongs to (ascending)."""

    wrenches: np.ndarray
    contact: np.ndarray


def as_cone_edges(cone_edges: int) -> int:
    """m, the number of friction-cone edges, as an int >= 3."""
    if isinstance(cone_edges, bool) or not isinstance(cone_edges, (int, np.integer)) \
            or cone_edges < 3:
        raise DegenerateGraspError(f"cone_edges must be an integer >= 3, got {cone_edges!r}")
    return int(cone_edges)


@lru_cache(maxsize=16)
def _cone_table(m: int) -> tuple[np.ndarray, np.ndarray]:
    """(m + 3,) cos and sin of the edge angles 2 pi j / m, padded with zeros
    for the three extra slots (bare normal, torsion +, torsion -)."""
    theta = 2.0 * np.pi * np.arange(m) / m
    cos, sin = np.r_[np.cos(theta), np.zeros(3)], np.r_[np.sin(theta), np.zeros(3)]
    cos.flags.writeable = sin.flags.writeable = False
    return cos, sin


def contact_wrenches(contacts: Contacts, center: np.ndarray, rho: float,
                     m: int) -> PrimitiveWrenches:
    """Primitive wrenches of validated contacts, grouped by contact.

    Slot s of contact i carries the local force L_is = (1, mu_i cos, mu_i sin)
    (the bare normal and torsion slots have no tangential part), so its wrench
    is G~_i[:, :3] L_is, computed for all slots with one matrix product.
    """
    n = len(contacts.points)
    cos, sin = _cone_table(m)
    local = np.empty((n, 3, m + 3))
    local[:, 0] = 1.0
    local[:, 1] = contacts.mu[:, None] * cos
    local[:, 2] = contacts.mu[:, None] * sin
    rot = contacts.frames
    with np.errstate(over="ignore", invalid="ignore"):
        arm = skew(contacts.points - center) @ rot                 # S(c_i - p) R_i
        wrench = np.concatenate([rot, arm / rho], axis=1) @ local   # (n, 6, m + 3)
        spin = (contacts.torsion / rho)[:, None] * rot[:, :, 0]    # torsion * n_i / rho
        wrench[:, 3:, m + 1] += spin
        wrench[:, 3:, m + 2] -= spin
    if not np.isfinite(wrench).all():
        raise DegenerateGraspError("primitive wrenches overflow: check mu, torsion, torque_scale"
                                   " and the contact coordinates (metres)")
    use = np.zeros((n, m + 3), dtype=bool)
    use[:, :m] = (contacts.model != FRICTIONLESS)[:, None]
    use[:, m] = contacts.model == FRICTIONLESS
    use[:, m + 1:] = (contacts.model == SOFT)[:, None]
    return PrimitiveWrenches(wrench.transpose(0, 2, 1)[use], np.nonzero(use)[0])


def dedupe(wrenches: PrimitiveWrenches, *, per_contact: bool) -> PrimitiveWrenches:
    """Merge rows that agree to DEDUP_TOL, keeping the first (order preserved).

    With ``per_contact`` only rows of the same contact merge (what the
    Minkowski-sum GWS needs); otherwise any equal rows merge (L1 GWS).
    """
    w, owner = wrenches
    if len(w) < 2:
        return wrenches
    keys = np.round(w * (1.0 / (DEDUP_TOL * max(float(np.abs(w).max()), 1.0))))
    if per_contact:
        keys = np.column_stack([keys, owner])
    order = np.lexsort(keys.T)
    ranked = keys[order]
    first = np.r_[True, (ranked[1:] != ranked[:-1]).any(axis=1)]
    if first.all():
        return wrenches
    keep = np.sort(order[first])
    return PrimitiveWrenches(w[keep], owner[keep])


def primitive_wrenches(points: ArrayLike, frames: ArrayLike, *, mu: ArrayLike,
                       center: ArrayLike, torque_scale: float, cone_edges: int = 8,
                       model: ModelArg = "point", torsion: ArrayLike = 0.0) -> PrimitiveWrenches:
    """Primitive wrenches of n contacts.

    points : (n, 3) contact points c_i [m]; frames : (n, 3, 3) R_i with
    columns (n_i, l_i, o_i); mu, torsion [m] : scalar or (n,); model : name or
    n names from MODELS; center : (3,) p [m]; torque_scale : rho [m] > 0.
    Returns rows grouped by contact: frictionless 1, point m, soft m + 2.
    """
    contacts = as_contacts(points, frames, mu=mu, model=model, torsion=torsion)
    return contact_wrenches(contacts, as_center(center), as_torque_scale(torque_scale),
                            as_cone_edges(cone_edges))
