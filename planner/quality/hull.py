"""Hulls of the grasp wrench space: qhull behind one function, plus the
active-set epsilon that only builds the part of the hull near the origin.

A GWS K is described by its support function h(u) = max_{x in K} u.x and
support points.  For unit u, the half-space u.x <= h(u) contains K, and
epsilon(K) = min_{|u|=1} h(u) is attained at a facet normal of K.

Active set (in the spirit of the expanding-polytope algorithm): keep a few
support points S, take qhull of S.  conv(S) lies inside K, so its nearest
facet distance is a lower bound on epsilon.  A facet of conv(S) whose
normal u has h(u) <= its distance + tol supports K as well, so the nearest
such "clean" facet is an upper bound.  Add the support points of dirty
facets nearer than that bound and repeat; when the nearest facet is clean,
both bounds meet and epsilon is exact (to FACET_TOL).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from planner.quality.closure import SIMPLEX
from planner.quality.tolerances import FACET_TOL, RANK_TOL

#: Seed directions: the coordinate axes both ways, then the simplex both ways.
SEED_DIRECTIONS = np.vstack([np.eye(6), -np.eye(6), SIMPLEX, -SIMPLEX])
#: Support points of at most this many dirty facets are added per round.
ADD_PER_ROUND = 8
MAX_ROUNDS = 200


class _Stalled(Exception):
    """The incremental active set hit round-off; rebuild with merging."""


def _outside(points: np.ndarray, equations: np.ndarray) -> np.ndarray:
    """(k, f) signed distances of points (k, d) beyond facets (f, d + 1)."""
    return np.hstack([points, np.ones((len(points), 1))]) @ equations.T


def qhull(points: np.ndarray) -> ConvexHull | None:
    """Convex hull of (k, d) points, or None if they are not full-dimensional.

    'Q0' (no pre-merging) is 2-3x faster than scipy's 6-D default 'Qx', but
    without merging round-off may leave a facet that a point pokes through.
    We check that every point is inside every facet (to FACET_TOL) and
    otherwise rerun with the default options, which merge such facets.
    """
    tol = FACET_TOL * max(float(np.abs(points).max(initial=0.0)), 1.0)
    try:
        hull = ConvexHull(points, qhull_options="Q0")
        if float(_outside(points, hull.equations).max()) <= tol:
            return hull
    except (QhullError, ValueError):
        pass
    try:
        return ConvexHull(points)
    except (QhullError, ValueError):
        return None


def hull_epsilon(hull: ConvexHull) -> float:
    """min over facets of the origin's distance to the facet plane (signed:
    negative when the origin is outside).  qhull's normals are unit and
    normal.x + offset <= 0 inside, so the distance is -offset."""
    return float(-hull.equations[:, -1].max())


class L1Support:
    """Support function of conv(W) for wrenches W (k, 6)."""

    def __init__(self, wrenches: np.ndarray) -> None:
        self.wrenches = wrenches
        self._gens = np.ascontiguousarray(wrenches.T)

    def _project(self, dirs: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(dirs) @ self._gens     # strided operands are 4x slower

    def value(self, dirs: np.ndarray) -> np.ndarray:
        """(f,) h(u) for directions (f, 6)."""
        proj = self._project(dirs)
        return np.take_along_axis(proj, proj.argmax(axis=1)[:, None], axis=1)[:, 0]

    def point(self, dirs: np.ndarray) -> np.ndarray:
        """(f, 6) a maximiser of u.x over the GWS for each direction."""
        return self.wrenches[self._project(dirs).argmax(axis=1)]


class LinfSupport(L1Support):
    """Support function of the Minkowski sum of conv({0} U W_i) over contacts i
    (rows of ``wrenches`` grouped by ascending ``contact``): the sum over
    contacts of max(0, max_j u.w_ij)."""

    def __init__(self, wrenches: np.ndarray, contact: np.ndarray) -> None:
        super().__init__(wrenches)
        self._starts = np.flatnonzero(np.r_[True, contact[1:] != contact[:-1]])

    def value(self, dirs: np.ndarray) -> np.ndarray:
        best = np.maximum.reduceat(self._project(dirs), self._starts, axis=1)
        return np.maximum(best, 0.0).sum(axis=1)

    def point(self, dirs: np.ndarray) -> np.ndarray:
        proj = self._project(dirs)
        total = np.zeros((len(dirs), 6))
        for rows in np.split(np.arange(len(self.wrenches)), self._starts[1:]):
            best = rows[proj[:, rows].argmax(axis=1)]
            gain = proj[np.arange(len(dirs)), best]
            total += np.where(gain[:, None] > 0, self.wrenches[best], 0.0)
        return total


def active_set_epsilon(support: L1Support, scale: float) -> float | None:
    """Exact epsilon (signed, to FACET_TOL * scale) of the GWS behind
    ``support`` (an L1Support or LinfSupport); None if the support points
    are not full-dimensional.

    First with one incremental 'Q0' qhull (new points are added to the
    existing hull, 1.5-3x faster than rebuilding); if round-off interferes,
    again with a merged hull rebuilt every round.
    """
    seed = np.unique(support.point(SEED_DIRECTIONS), axis=0)
    tol = FACET_TOL * scale
    try:
        hull = ConvexHull(seed, incremental=True, qhull_options="Q0")
        try:
            return _grow(support, hull, tol, incremental=True)
        finally:
            hull.close()
    except (QhullError, ValueError, _Stalled):
        pass
    merged = qhull(seed)
    try:
        return None if merged is None else _grow(support, merged, tol, incremental=False)
    except (QhullError, ValueError, _Stalled):
        return None


def _grow(support: L1Support, hull: ConvexHull, tol: float, *, incremental: bool) -> float:
    """Add support points of the nearest dirty facets until the nearest facet
    is clean; return its distance.  Raises _Stalled on round-off trouble."""
    known = {row.tobytes() for row in hull.points}
    for _ in range(MAX_ROUNDS):
        eqs = hull.equations
        dist = -eqs[:, -1]
        clean = support.value(eqs[:, :-1]) <= dist + tol
        bound = dist[clean].min() if clean.any() else np.inf
        dirty = np.flatnonzero(~clean & (dist < bound))
        if len(dirty) == 0:
            if float(_outside(hull.points, eqs).max()) > tol:
                raise _Stalled
            return float(bound)
        dirty = dirty[np.argsort(dist[dirty])[:ADD_PER_ROUND]]
        new = [row for row in np.unique(support.point(eqs[dirty, :-1]), axis=0)
               if row.tobytes() not in known]
        if not new:
            raise _Stalled
        known.update(row.tobytes() for row in new)
        if incremental:
            hull.add_points(np.array(new))
        else:
            hull = qhull(np.vstack([hull.points, new]))
            if hull is None:
                raise _Stalled
    raise _Stalled


def minkowski_vertices(wrenches: np.ndarray, contact: np.ndarray) -> np.ndarray:
    """Vertices (v, 6) of sum_i conv({0} U W_i), pruned to hull vertices after
    every contact (in the linear span reached so far, since 0 is a member)."""
    starts = np.flatnonzero(np.r_[True, contact[1:] != contact[:-1]])
    verts = np.zeros((1, 6))
    for rows in np.split(wrenches, starts[1:]):
        summand = np.vstack([np.zeros((1, 6)), rows])
        verts = _extreme((verts[:, None, :] + summand[None]).reshape(-1, 6))
    return verts


def _extreme(points: np.ndarray) -> np.ndarray:
    """The points of (k, 6) that are vertices of their hull (0 is a member)."""
    points = np.unique(points, axis=0)
    _, sing, vt = np.linalg.svd(points, full_matrices=False)
    rank = int((sing > sing[0] * RANK_TOL).sum()) if sing[0] > 0 else 0
    if rank <= 1:
        if rank == 0:
            return points[:1]
        coord = points @ vt[0]
        return points[[coord.argmin(), coord.argmax()]]
    hull = qhull(points @ vt[:rank].T)
    return points if hull is None else points[hull.vertices]
