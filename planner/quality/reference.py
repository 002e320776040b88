"""Plain, obviously-correct reference metrics for tests and benchmarks.

One scipy ConvexHull of every primitive wrench with scipy's default options;
epsilon = min over facets of -offset, 0.0 if any offset >= 0 (origin not
strictly inside).  No certificates, no active set, no tolerances: slow and
easy to trust.  Not used by the planner.

``joggled_l1`` / ``joggled_linf`` are the references for inputs on which
qhull's default options stop with a precision error (nearly coincident
wrenches): they joggle instead of merging, and take epsilon from the support
function.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from planner.quality.resistance import ResistanceProgram


def reference_epsilon(wrenches: np.ndarray) -> float:
    """L1 epsilon of primitive wrenches (k, 6); 0.0 if degenerate."""
    try:
        offsets = ConvexHull(wrenches).equations[:, -1]
    except (QhullError, ValueError):
        return 0.0
    return 0.0 if (offsets >= 0).any() else float(-offsets.max())


def reference_volume(wrenches: np.ndarray) -> float:
    """Volume of conv(W) for primitive wrenches (k, 6); 0.0 if degenerate."""
    try:
        return float(ConvexHull(wrenches).volume)
    except (QhullError, ValueError):
        return 0.0


def minkowski_sums(wrenches: np.ndarray, contact: np.ndarray) -> np.ndarray:
    """Every sum (prod_i (k_i + 1), 6) that picks 0 or one primitive wrench per
    contact: their hull is the L-infinity GWS (few contacts only)."""
    total = np.zeros((1, 6))
    for i in np.unique(contact):
        summand = np.vstack([np.zeros((1, 6)), wrenches[contact == i]])
        total = (total[:, None, :] + summand[None]).reshape(-1, 6)
    return total


def reference_linf_epsilon(wrenches: np.ndarray, contact: np.ndarray) -> float:
    """L-infinity epsilon by brute force: the hull of every Minkowski sum."""
    return reference_epsilon(minkowski_sums(wrenches, contact))


def linf_support(wrenches: np.ndarray, contact: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """(f,) h(u) = sum_i max(0, max_j u.w_ij) of the L-infinity GWS for
    directions (f, 6)."""
    proj = dirs @ wrenches.T
    return sum(np.maximum(proj[:, contact == i].max(axis=1), 0.0) for i in np.unique(contact))


def joggled(points: np.ndarray, support: Callable[[np.ndarray], np.ndarray]) -> tuple[float, float]:
    """(epsilon, volume) of conv(points) (k, 6) from qhull 'QJ', whose support
    function for directions (f, 6) is ``support``.  Joggling never stops on
    precision errors; the price is an error of ~1e-8 relative.  epsilon is
    the support function minimised over the joggled facet normals: an upper
    bound within the joggle of the true value (the minimum over all unit
    directions)."""
    hull = ConvexHull(points, qhull_options="QJ")
    return float(support(hull.equations[:, :-1]).min()), float(hull.volume)


def joggled_l1(wrenches: np.ndarray) -> tuple[float, float]:
    """(epsilon, volume) of the L1 GWS conv(W) by ``joggled``."""
    return joggled(wrenches, lambda dirs: (dirs @ wrenches.T).max(axis=1))


def joggled_linf(wrenches: np.ndarray, contact: np.ndarray) -> tuple[float, float]:
    """(epsilon, volume) of the L-infinity GWS by ``joggled`` on every
    Minkowski sum."""
    return joggled(minkowski_sums(wrenches, contact), lambda dirs: linf_support(wrenches, contact, dirs))


def reference_resistance(prog: ResistanceProgram, directions: np.ndarray) -> np.ndarray:
    """Weight resistance [g] per direction of a ``ResistanceProgram``: one
    ``scipy.optimize.linprog`` call per direction, no warm start."""
    from scipy.optimize import linprog

    k = prog.wrench.shape[1]
    out = np.zeros(len(directions))
    if k == 0:
        return out
    for r, d in enumerate(directions):
        load = np.r_[prog.weight * d, np.zeros(3)]
        res = linprog(np.r_[np.zeros(k), -1.0], A_ub=np.hstack([prog.rows, np.zeros((len(prog.rows), 1))]),
                      b_ub=prog.bounds, A_eq=np.hstack([prog.wrench, load[:, None]]), b_eq=np.zeros(6),
                      bounds=[(0, None)] * k + [(0, prog.cap)], method="highs")
        out[r] = min(max(-res.fun, 0.0), prog.cap) if res.status == 0 else 0.0
    return out
