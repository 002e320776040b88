"""Plain, obviously-correct reference metrics for tests and benchmarks.

One scipy ConvexHull of every primitive wrench with scipy's default options;
epsilon = min over facets of -offset, 0.0 if any offset >= 0 (origin not
strictly inside).  No certificates, no active set, no tolerances: slow and
easy to trust.  Not used by the planner.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError


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


def reference_linf_epsilon(wrenches: np.ndarray, contact: np.ndarray) -> float:
    """L-infinity epsilon by brute force: the hull of every sum that picks 0 or
    one primitive wrench per contact (prod_i (k_i + 1) points: few contacts only)."""
    total = np.zeros((1, 6))
    for i in np.unique(contact):
        summand = np.vstack([np.zeros((1, 6)), wrenches[contact == i]])
        total = (total[:, None, :] + summand[None]).reshape(-1, 6)
    return reference_epsilon(total)
