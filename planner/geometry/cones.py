"""The direction of a cone of unit vectors nearest a given one: the normal
cone of a mesh's sharp edge (two face normals: a wedge) or vertex (its faces'
normals), where a contact's normal must lie
(:meth:`planner.plan.patch_surfaces.ObjectSurface.contact_normals`)."""

from __future__ import annotations

import numpy as np
from scipy.optimize import nnls


def nearest_in_wedge(n1: np.ndarray, n2: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(k, 3) the unit direction of the cone {a n1 + b n2: a, b >= 0} of unit
    ``n1``, ``n2`` (k, 3) nearest each unit ``u`` (k, 3): ``u`` itself
    inside, else its projection on the wedge's plane or on its nearer side;
    the sides' mean where ``u`` is opposite the whole wedge or along its
    edge; NaN where the wedge is folded flat (n1 = -n2)."""
    c = np.einsum("ij,ij->i", n1, n2)  # sharp edges only: c <= cos(sharp_angle), n1 + n2 != 0 unless folded flat
    d1, d2 = np.einsum("ij,ij->i", u, n1), np.einsum("ij,ij->i", u, n2)
    det = np.maximum(1.0 - c * c, 1e-12)
    a, b = (d1 - c * d2) / det, (d2 - c * d1) / det  # u's projection on the plane = a n1 + b n2
    inside = (a >= 0) & (b >= 0)
    plane = a[:, None] * n1 + b[:, None] * n2
    side = np.where((d1 >= d2)[:, None], n1, n2)
    out = np.where(inside[:, None], plane, side)
    # u opposite the whole wedge, or along its edge (no projection): the sides' mean
    none = (~inside & (np.maximum(d1, d2) <= 0)) | (np.linalg.norm(out, axis=1) < 1e-9)
    out[none] = n1[none] + n2[none]
    length = np.linalg.norm(out, axis=1, keepdims=True)
    return np.divide(out, length, out=np.full_like(out, np.nan), where=length > 1e-12)  # NaN: folded flat


def nearest_in_cone(normals: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(3,) the unit direction of the cone of ``normals`` (f, 3) nearest ``u`` (3,) (non-negative least squares); the
    normals' mean where ``u`` is opposite the whole cone; NaN where that is 0 too (normals that cancel)."""
    weights, _ = nnls(normals.T, u)
    out = normals.T @ weights
    if np.linalg.norm(out) < 1e-12:
        out = normals.sum(axis=0)
    length = np.linalg.norm(out)
    return out / length if length > 1e-12 else np.full(3, np.nan)
