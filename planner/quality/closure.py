"""Force closure without a hull: certificates from non-negative least squares.

Definition used by the whole package: the grasp is force closure iff its L1
epsilon (radius of the largest origin-centred ball in conv(W)) exceeds
FORCE_CLOSURE_TOL.  Two exact certificates decide this in almost every case:

* not force closure: a unit direction u with h(u) = max_j u.w_j <= TOL.
  Then the half-space u.x <= h(u) holds conv(W), so epsilon <= h(u).  The
  least singular direction of W often is one (always when its singular value
  is <= TOL: rank deficit; also for wrench sets thinner than a few TOL, on
  which qhull stops with precision errors), and so is the residual
  r = s - W^T a of NNLS for a direction s outside the positive span (its
  optimality conditions say W r <= 0).
* force closure: points y_k = W^T a_k / sum(a_k) are convex combinations of
  the wrenches, hence inside conv(W); if their simplex holds the origin with
  inradius L > TOL, then epsilon >= L > TOL.  The a_k come from NNLS
  solutions of W^T a = s_k for the 7 vertices s_k of a regular simplex.

Only when neither certificate is conclusive (epsilon within a small factor of
TOL, or NNLS numerically unsure) does the caller fall back to a hull.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from planner.quality.tolerances import FORCE_CLOSURE_TOL, NNLS_RESIDUAL_TOL, SIMPLEX_COND_MAX

DIM = 6


def regular_simplex(dim: int = DIM) -> np.ndarray:
    """(dim + 1, dim) unit vertices of a regular simplex centred at the origin."""
    centred = np.eye(dim + 1) - 1.0 / (dim + 1)
    basis = np.linalg.svd(centred)[2][:dim]       # orthonormal, sum-zero subspace
    verts = centred @ basis.T
    return verts / np.linalg.norm(verts, axis=1, keepdims=True)


SIMPLEX = regular_simplex()


@dataclass(frozen=True)
class ClosureCheck:
    """Outcome of the hull-free test.

    verdict : True / False when a certificate decided, None when undecided.
    lower : a proven lower bound on the L1 epsilon (-inf when none).
    """

    verdict: bool | None
    lower: float = -np.inf


def _separates(wrenches: np.ndarray, direction: np.ndarray) -> bool:
    """True if the unit ``direction`` bounds conv(W) within TOL of the origin."""
    norm = float(np.linalg.norm(direction))
    return norm > 0 and float((wrenches @ direction).max()) <= FORCE_CLOSURE_TOL * norm


def inscribed_radius(points: np.ndarray) -> float:
    """Distance from the origin to the boundary of the simplex with vertices
    ``points`` (dim + 1, dim); negative or -inf when it does not hold it."""
    size = float(np.abs(points).max())
    if not size > 0:
        return -np.inf
    bary = np.vstack([points.T / size, np.ones(len(points))])   # shape, not size
    if np.linalg.cond(bary) > SIMPLEX_COND_MAX:
        return -np.inf
    inv = np.linalg.inv(bary)          # row k: barycentric coordinate k = a_k.x + b_k
    return size * float((inv[:, -1] / np.linalg.norm(inv[:, :-1], axis=1)).min())


def thin(wrenches: np.ndarray) -> bool:
    """The first certificate of :func:`check_closure` alone: True if there are
    at most DIM wrenches (k, 6) or their least singular direction (either
    way) bounds conv(W) within TOL of the origin: not force closure."""
    if len(wrenches) <= DIM:
        return True
    vt = np.linalg.svd(wrenches, full_matrices=False)[2]
    return _separates(wrenches, vt[-1]) or _separates(wrenches, -vt[-1])


def quick_reject(wrenches: np.ndarray) -> bool:
    """The first certificates of :func:`check_closure` alone, for a caller
    about to compute epsilon anyway: True (not force closure) if
    :func:`thin` holds or the NNLS residual for the first simplex vertex
    separates, as check_closure finds; False says nothing.  They catch
    nearly every grasp that is not force closure (Panda mug unit: 133 of
    137 at that first vertex, the rest at the second)."""
    if thin(wrenches):
        return True
    gens = np.ascontiguousarray(wrenches.T)
    try:
        alpha, resid = nnls(gens, SIMPLEX[0])
    except RuntimeError:
        return False
    return bool(resid > NNLS_RESIDUAL_TOL and _separates(wrenches, SIMPLEX[0] - gens @ alpha))


def check_closure(wrenches: np.ndarray) -> ClosureCheck:
    """Decide force closure of primitive wrenches (k, 6) without a hull."""
    if thin(wrenches):
        return ClosureCheck(False)
    gens = np.ascontiguousarray(wrenches.T)
    inner = np.empty_like(SIMPLEX)
    for k, target in enumerate(SIMPLEX):
        try:
            alpha, resid = nnls(gens, target)
        except RuntimeError:           # iteration limit: let the hull decide
            return ClosureCheck(None)
        if resid > NNLS_RESIDUAL_TOL and _separates(wrenches, target - gens @ alpha):
            return ClosureCheck(False)
        total = alpha.sum()
        if total <= 0:
            return ClosureCheck(None)
        inner[k] = gens @ (alpha / total)
    lower = inscribed_radius(inner)
    return ClosureCheck(True, lower) if lower > FORCE_CLOSURE_TOL else ClosureCheck(None, lower)
