"""The active-set epsilon: only the part of the GWS hull near the origin.

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

Only the facets up to the nearest clean one decide a round, so h is taken
facet by facet in order of distance, in chunks, up to the first clean one
(:func:`nearest_dirty`): the same bound and dirty facets as h of every facet
(:func:`nearest_dirty_reference`; h to a few ulp), for less when the generators are many
(the Barrett's mug sweep: 2.5 -> 2.35 ms an epsilon, one BLAS thread; the
Panda's ~70 generators: the same time).

The seed S is small (:data:`SEEDS`: the support points of 7 directions
first): every point is a hull vertex that each later qhull round pays for,
and the rounds bring in the points near the origin that matter.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial import ConvexHull, QhullError

try:  # scipy's private base of its hulls, for _Hull; without it the plain ConvexHull (the same facets)
    from scipy.spatial._qhull import _QhullUser
except ImportError:  # pragma: no cover
    _QhullUser = None

from planner.quality.closure import SIMPLEX
from planner.quality.hull import HullError, blocks, max_outside, qhull, unique_rows
from planner.quality.tolerances import FACET_TOL

#: Seed directions: the coordinate axes both ways, then the simplex both ways.
SEED_DIRECTIONS = np.vstack([np.eye(6), -np.eye(6), SIMPLEX, -SIMPLEX])
#: The seeds tried in turn: the support points of the simplex's 7 directions
#: first, then of its 14 both ways, then of SEED_DIRECTIONS (the last also
#: for the merged rebuild).  The answer is exact from any seed; a seed of
#: fewer points gives a hull of fewer points and facets, whose qhull rounds
#: cost less (the Panda's random_003 unit, 1,001 epsilons, one BLAS thread:
#: 2.9 ms an epsilon from SEED_DIRECTIONS alone, 2.1 from the 14, 1.8 from
#: the 7 first).  A seed of fewer than 7 distinct points cannot span 6-D, and
#: one whose rounds stall is left for the next.
SEEDS = (SIMPLEX, np.vstack([SIMPLEX, -SIMPLEX]), SEED_DIRECTIONS)
#: Support points of at most this many dirty facets are added per round.
ADD_PER_ROUND = 8
MAX_ROUNDS = 200
#: Facets whose support value is taken at once, nearest first; each further
#: chunk is twice the one before.  The last round's nearest facet is clean,
#: so it needs one chunk; earlier rounds a few dozen dirty facets.
FIRST_CHUNK = 32


class _Stalled(Exception):
    """The incremental active set hit round-off; rebuild with merging."""


class _Hull(ConvexHull):
    """scipy's ConvexHull without its volume and area (None): ``_update``,
    run after every ``add_points``, computes them for every facet (~0.1 ms
    a round on the Panda's ~1,000-facet hulls), and the active set reads
    only the points and facets, which are ConvexHull's bit for bit."""

    def _update(self, qhull) -> None:  # type: ignore[no-untyped-def]
        qhull.triangulate()
        self.simplices, self.neighbors, self.equations, self.coplanar, good = qhull.get_simplex_facet_array()
        self.good = good.astype(bool) if b"QG" in qhull.options else None   # as ConvexHull: only with 'QG'
        self.volume, self.area = None, None
        self._vertices = qhull.get_extremes_2d() if qhull.ndim == 2 else None  # as ConvexHull: 2-D in order
        self.nsimplex = self.simplices.shape[0]
        _QhullUser._update(self, qhull)


def _hull_class() -> type[ConvexHull]:
    """_Hull where, on the installed scipy, it gives ConvexHull's points and facets after a seed and an
    add_points (its base and the arrays its _update reads are scipy's private ones, which another version may
    change), else the plain ConvexHull: never an error nor a silent fall to the merged rebuild of every epsilon."""
    if _QhullUser is None:
        return ConvexHull
    points = np.vstack([np.eye(6), -np.eye(6), SIMPLEX, -SIMPLEX])
    try:
        hulls = [cls(points[:12], incremental=True, qhull_options="Q0") for cls in (_Hull, ConvexHull)]
        try:
            for hull in hulls:
                hull.add_points(points[12:])
            fast, plain = hulls
            same = all(np.array_equal(getattr(fast, name), getattr(plain, name))
                       for name in ("points", "equations", "simplices", "neighbors", "coplanar"))
        finally:
            for hull in hulls:
                hull.close()
    except Exception:  # noqa: BLE001 - whatever another scipy's private base does, the public hull serves
        return ConvexHull
    return _Hull if same else ConvexHull


#: The hull class of the active set's rounds (:func:`_hull_class`).
HULL = _hull_class()


class L1Support:
    """Support function of conv(W) for wrenches W (k, 6)."""

    def __init__(self, wrenches: np.ndarray) -> None:
        self.wrenches = wrenches
        self._gens = np.ascontiguousarray(wrenches.T)
        self._block_rows = next(blocks(1, len(wrenches))).stop  # the directions of one block (:func:`blocks`)

    def value(self, dirs: np.ndarray) -> np.ndarray:
        """(f,) h(u) for directions (f, 6)."""
        return self._by_block(self._value, dirs)

    def point(self, dirs: np.ndarray) -> np.ndarray:
        """(f, 6) a maximiser of u.x over the GWS for each direction."""
        return self._by_block(self._point, dirs)

    def _by_block(self, fn: Callable[[np.ndarray], np.ndarray], dirs: np.ndarray) -> np.ndarray:
        dirs = np.ascontiguousarray(dirs)         # strided operands are 4x slower
        if len(dirs) <= self._block_rows:  # one block (every round of the Panda's and the Barrett's): no generator
            return fn(dirs)
        parts = [fn(dirs[rows]) for rows in blocks(len(dirs), len(self.wrenches))]
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def _value(self, dirs: np.ndarray) -> np.ndarray:
        proj = dirs @ self._gens
        return proj[np.arange(len(proj)), proj.argmax(axis=1)]   # a row's max, faster than max(axis=1)

    def _point(self, dirs: np.ndarray) -> np.ndarray:
        return self.wrenches[(dirs @ self._gens).argmax(axis=1)]


class LinfSupport(L1Support):
    """Support function of the Minkowski sum of conv({0} U W_i) over contacts i
    (rows of ``wrenches`` grouped by ascending ``contact``): the sum over
    contacts of max(0, max_j u.w_ij)."""

    def __init__(self, wrenches: np.ndarray, contact: np.ndarray) -> None:
        super().__init__(wrenches)
        self._starts = np.flatnonzero(np.r_[True, contact[1:] != contact[:-1]])

    def _value(self, dirs: np.ndarray) -> np.ndarray:
        best = np.maximum.reduceat(dirs @ self._gens, self._starts, axis=1)
        return np.maximum(best, 0.0).sum(axis=1)

    def _point(self, dirs: np.ndarray) -> np.ndarray:
        proj = dirs @ self._gens
        total = np.zeros((len(dirs), 6))
        for rows in np.split(np.arange(len(self.wrenches)), self._starts[1:]):
            best = rows[proj[:, rows].argmax(axis=1)]
            gain = proj[np.arange(len(dirs)), best]
            total += np.where(gain[:, None] > 0, self.wrenches[best], 0.0)
        return total


def active_set_epsilon(support: L1Support, scale: float, *, seeds: tuple[np.ndarray, ...] = SEEDS,
                       hull_class: type[ConvexHull] | None = None) -> float | None:
    """Exact epsilon (to FACET_TOL * scale; where the origin is outside, some negative distance) of the GWS behind
    ``support`` (an L1Support or LinfSupport); None if the support points
    are not full-dimensional.

    From each seed of ``seeds`` (directions (k, 6) each) in turn with one
    incremental 'Q0' qhull of ``hull_class`` (default HULL; new points are
    added to the existing hull, 1.5-3x faster than rebuilding); if round-off
    interferes on all of them, again from the last seed with a merged hull
    rebuilt every round.  (``seeds=(SEED_DIRECTIONS,)``,
    ``hull_class=ConvexHull``: the implementation before 2026-12-06, which
    the tests compare with.)
    """
    tol = FACET_TOL * scale
    for dirs in seeds:
        seed = unique_rows(support.point(dirs))
        if len(seed) <= seed.shape[1]:
            continue
        try:
            hull = (hull_class or HULL)(seed, incremental=True, qhull_options="Q0")
            try:
                return _grow(support, hull, tol, incremental=True)
            finally:
                hull.close()
        except (QhullError, ValueError, _Stalled):
            pass
    try:
        merged = qhull(seed)
        return None if merged is None else _grow(support, merged, tol, incremental=False)
    except (QhullError, ValueError, _Stalled, HullError):
        return None


def _grow(support: L1Support, hull: ConvexHull, tol: float, *, incremental: bool) -> float:
    """Add support points of the nearest dirty facets until the nearest facet
    is clean; return its distance.  Raises _Stalled on round-off trouble."""
    known = {row.tobytes() for row in hull.points}
    for _ in range(MAX_ROUNDS):
        eqs = hull.equations
        dist = -eqs[:, -1]
        bound, dirty = nearest_dirty(support, eqs, tol)
        if len(dirty) == 0:
            if max_outside(hull.points, eqs) > tol:
                raise _Stalled
            return float(bound)
        dirty = dirty[np.argsort(dist[dirty])[:ADD_PER_ROUND]]
        new = [row for row in unique_rows(support.point(eqs[dirty, :-1]))
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


def nearest_dirty(support: L1Support, equations: np.ndarray, tol: float) -> tuple[float, np.ndarray]:
    """(bound, dirty) of one round for facets ``equations`` (f, 7): the
    distance of the nearest clean facet (inf if none) and the indices
    (ascending) of the dirty facets nearer than it.  h is taken in order of
    distance (stable), FIRST_CHUNK facets first, then twice as many each
    time, up to the first clean facet: facets beyond it cannot change either
    answer.  The same as :func:`nearest_dirty_reference` but where a facet's
    h lies within a few ulp (~1e-15) of its distance + tol: BLAS sums a
    chunk's products in another order than the whole matrix's (a 1-row
    chunk takes its vector path), so h may differ in the last bits."""
    dist = -equations[:, -1]
    order = np.argsort(dist, kind="stable")
    seen, start, size = [], 0, FIRST_CHUNK
    bound = np.inf
    while start < len(order) and bound == np.inf:
        rows = order[start:start + size]
        clean = support.value(equations[rows, :-1]) <= dist[rows] + tol
        if clean.any():
            bound = dist[rows[int(clean.argmax())]]
        seen.append(rows[~clean])
        start, size = start + size, 2 * size
    dirty = np.concatenate(seen) if seen else np.zeros(0, int)
    return bound, np.sort(dirty[dist[dirty] < bound])


def nearest_dirty_reference(support: L1Support, equations: np.ndarray, tol: float) -> tuple[float, np.ndarray]:
    """:func:`nearest_dirty` from h of every facet."""
    dist = -equations[:, -1]
    clean = support.value(equations[:, :-1]) <= dist + tol
    bound = dist[clean].min() if clean.any() else np.inf
    return bound, np.flatnonzero(~clean & (dist < bound))
