"""Hulls of the grasp wrench space: qhull behind one function, the hull's
epsilon, and the Minkowski-sum points of the L-infinity GWS (the active-set
epsilon, which only builds the part of the hull near the origin, is in
active_set.py).

qhull itself sits behind ``qhull``: every hull is checked (no point beyond a
facet) before use, rebuilt with other options when the check or qhull
fails, as a last resort built from one representative per cluster of
nearly coincident points (and checked against all of them), and a failure
on a full-dimensional set raises HullError rather than passing for "flat".
Every points-by-facets product runs in blocks of at most BLOCK_BYTES,
whatever the number of points and facets.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, QhullError, cKDTree

from planner.errors import DegenerateGraspError
from planner.quality.tolerances import CLUSTER_RADIUS, FACET_TOL, HULL_TOL, MERGE_RADIUS, RANK_TOL

#: The clustering fallback of ``qhull`` tries radii of CLUSTER_RADIUS times
#: 10^-CLUSTER_DECADES, ..., 10^-1, 1: from 1e-11, ten times DEDUP_TOL.
CLUSTER_DECADES = 3

#: Largest temporary array [bytes] of any points-by-facets (or directions-by-
#: wrenches) product.  A 6-D hull of a Minkowski sum has ~1e4 points and ~1e6
#: facets: done in one piece the check needs tens of GiB (issue 13: 31 GiB for
#: 4 soft contacts with 8 cone edges).  64 MiB blocks still hold >= 1,000 rows
#: for 8,000 columns, long enough for BLAS to run at full speed.
BLOCK_BYTES = 64 * 2**20


class HullError(DegenerateGraspError):
    """qhull could not build a trustworthy hull of a full-dimensional set."""


def blocks(rows: int, cols: int) -> Iterator[slice]:
    """Row slices of a (rows, cols) float64 product, each <= BLOCK_BYTES
    (at least one row)."""
    step = max(1, BLOCK_BYTES // (8 * max(cols, 1)))
    for start in range(0, max(rows, 1), step):
        yield slice(start, start + step)


def max_outside(points: np.ndarray, equations: np.ndarray) -> float:
    """Largest signed distance of points (k, d) beyond facets (f, d + 1)
    (normal.x + offset, > 0 outside); -inf when there are none.  Computed in
    blocks of at most BLOCK_BYTES."""
    worst = -np.inf
    for rows in blocks(len(points), points.shape[1] + 1):     # one block up to 1.2M points
        homog = np.hstack([points[rows], np.ones((len(points[rows]), 1))])
        for facets in blocks(len(equations), len(homog)):
            worst = max(worst, float((homog @ equations[facets].T).max(initial=-np.inf)))
    return worst


def max_off_plane(hull: ConvexHull) -> float:
    """Largest distance of a facet's own vertices from its plane: 0 up to
    round-off for simplicial facets, up to the merge width for merged ones
    (qhull's 'Qt' gives a merged facet's pieces the merged plane)."""
    worst = 0.0
    dim = hull.points.shape[1]
    for facets in blocks(len(hull.simplices), dim * dim):
        corners = hull.points[hull.simplices[facets]]             # (b, d, d)
        eqs = hull.equations[facets]
        dist = np.einsum("bkd,bd->bk", corners, eqs[:, :-1]) + eqs[:, -1:]
        worst = max(worst, float(np.abs(dist).max(initial=0.0)))
    return worst


def _retries(scale: float) -> list[tuple[str, float]]:
    """(qhull options, accepted error) tried in order when 'Q0' fails.

    'Q0' (no pre-merging) is 2-3x faster than scipy's 6-D default 'Qx', but
    without merging round-off may leave a facet that a point pokes through.
    'Qx' merges such facets, but on nearly coincident points (contacts that
    are nearly coplanar and symmetric, friction cones of mu ~ 1e-9) it may
    stop with a topology error ("wide merge due to dupridge"); pre-merging
    facets whose centrums are within MERGE_RADIUS often gets past it, and
    'QJ' (joggled input: no merging, no precision errors) nearly always.
    Every hull is checked before use, so the order only changes the speed.
    """
    return [("Qx", HULL_TOL * scale), (f"Qx C-{MERGE_RADIUS * scale:.3g}", HULL_TOL * scale),
            ("QJ", HULL_TOL * scale)]


def affine_rank(points: np.ndarray) -> int:
    """Dimension of the affine hull of (k, d) points (singular values of the
    centred points above RANK_TOL times the largest)."""
    if len(points) < 2:
        return 0
    sing = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    return int((sing > sing[0] * RANK_TOL).sum()) if sing[0] > 0 else 0


def qhull(points: np.ndarray) -> ConvexHull | None:
    """Checked convex hull of (k, d) points; None if they are not
    full-dimensional.

    A hull is returned only if no point lies beyond a facet, nor (for merged or
    joggled hulls) a facet vertex off its plane, by more than the accepted
    error of its options (FACET_TOL or HULL_TOL times the largest
    |coordinate|).  When every option fails on the points themselves, the
    hull may be that of one representative per cluster of points within
    CLUSTER_RADIUS times the largest |coordinate| (``hull.points`` is then
    those representatives, a subset of ``points``): it lies inside the true
    hull to the accepted error of its options, and no point lies beyond it
    by more than CLUSTER_RADIUS plus that error, times the largest
    |coordinate| (see CLUSTER_RADIUS for the error of epsilon and volume).  Raises
    HullError if no option gives such a hull although the points are
    full-dimensional: never a silent wrong hull.
    """
    return _checked_hull(points)[0]


def _checked_hull(points: np.ndarray) -> tuple[ConvexHull | None, np.ndarray | None]:
    """``qhull`` and, if its hull is of cluster representatives, (k,) the row
    of ``hull.points`` that stands for each point (None otherwise: the hull
    is of ``points`` themselves)."""
    scale = max(float(np.abs(points).max(initial=0.0)), 1.0)
    failures: list[str] = []
    hull = _attempt(points, "Q0", FACET_TOL * scale, failures)
    if hull is not None:
        return hull, None
    if affine_rank(points) < points.shape[1]:
        return None, None           # checked first: joggling would make a flat set look full
    for options, tol in _retries(scale):
        hull = _attempt(points, options, tol, failures)
        if hull is not None:
            return hull, None
    hull, owner = _clustered_hull(points, scale, failures)
    if hull is not None:
        return hull, owner
    raise HullError(f"qhull could not build the {points.shape[1]}-D hull of {len(points)} wrenches "
                    f"(largest |coordinate| {scale:.3g}): " + "; ".join(failures))


def clusters(points: np.ndarray, radius: float) -> np.ndarray:
    """(k,) for each of the (k, d) points the index of the first point of its
    cluster: the connected components of the graph joining points less than
    ``radius`` apart (Euclidean)."""
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    if len(pairs) == 0:
        return np.arange(len(points))
    graph = coo_matrix((np.ones(len(pairs), dtype=bool), (pairs[:, 0], pairs[:, 1])),
                       shape=(len(points), len(points)))
    _, label = connected_components(graph, directed=False)
    _, first = np.unique(label, return_index=True)
    return first[label]


def _clustered_hull(points: np.ndarray, scale: float,
                    failures: list[str]) -> tuple[ConvexHull | None, np.ndarray | None]:
    """The last resort of ``qhull`` on full-dimensional points (k, d): the
    options of ``qhull`` on one representative (its first point) per
    cluster of points within r * scale, for r = CLUSTER_RADIUS times 10^-3,
    10^-2, 10^-1, 1 (the finest clustering qhull can use gives the smallest
    error).  A hull is checked on the representatives as usual, and is
    accepted only if no point lies beyond a facet by more than the accepted
    error of its options plus r * scale: that check, not the clustering
    (a chain of close points can be a long cluster), bounds the error.
    (hull, owner) as ``_checked_hull``; (None, None), with the reasons
    appended to ``failures``, if no hull passes."""
    merged = len(points)
    for radius in CLUSTER_RADIUS * scale * 10.0 ** -np.arange(CLUSTER_DECADES, -1, -1):
        first = clusters(points, radius)
        reps = np.unique(first)
        if len(reps) == merged:
            continue                # no pair closer than radius, or the same clusters again
        merged = len(reps)
        what = f"{merged} representatives within {radius:.2g}"
        sub = points[reps]
        if affine_rank(sub) < points.shape[1]:
            failures.append(f"{what}: flat")
            break                   # coarser clusters keep a subset of these representatives
        for options, tol in [("Q0", FACET_TOL * scale), *_retries(scale)]:
            tried: list[str] = []
            hull = _attempt(sub, options, tol, tried)
            if hull is not None:
                error = max_outside(points, hull.equations)
                if error <= tol + radius:
                    return hull, np.searchsorted(reps, first)
                tried.append(f"'{options}': a point lies {error:.2g} beyond a facet "
                             f"(accepted {tol + radius:.2g})")
            failures.extend(f"{what}: {reason}" for reason in tried)
    if merged == len(points):
        failures.append(f"no two points within {CLUSTER_RADIUS * scale:.2g} to cluster")
    return None, None


def _attempt(points: np.ndarray, options: str, tol: float, failures: list[str]) -> ConvexHull | None:
    """qhull with ``options`` if its hull passes the check to ``tol``; else
    None, with the reason appended to ``failures``.  Facets of 'Q0' are exact
    simplices; merged or joggled ones are also checked for flatness."""
    try:
        hull = ConvexHull(points, qhull_options=options)
    except (QhullError, ValueError) as exc:
        lines = [line.strip() for line in str(exc).strip().splitlines()] or [repr(exc)]
        failures.append(f"'{options}': " + next((ln for ln in lines if ln.startswith("QH6")), lines[0]))
        return None
    error = max_outside(points, hull.equations)
    if options != "Q0":
        error = max(error, max_off_plane(hull))
    if error <= tol:
        return hull
    failures.append(f"'{options}': a point lies {error:.2g} off a facet (accepted {tol:.2g})")
    return None


def unique_rows(points: np.ndarray) -> np.ndarray:
    """The distinct rows of (k, d) points without NaN in lexicographic order:
    ``np.unique(points, axis=0)`` at a fifth of its cost (no structured
    dtype). Of rows equal as floats the first in a stable sort is kept; they
    differ at most in a zero's sign, which support points here never do."""
    ranked = points[np.lexsort(points.T[::-1])]
    first = np.ones(len(ranked), bool)
    np.any(ranked[1:] != ranked[:-1], axis=1, out=first[1:])
    return ranked[first]


def hull_epsilon(hull: ConvexHull) -> float:
    """min over facets of the origin's distance to the facet plane (signed:
    negative when the origin is outside).  qhull's normals are unit and
    normal.x + offset <= 0 inside, so the distance is -offset."""
    return float(-hull.equations[:, -1].max())


def minkowski_points(wrenches: np.ndarray, contact: np.ndarray) -> np.ndarray:
    """Points (k, 6) whose hull is sum_i conv({0} U W_i): every sum of 0 or
    one wrench per contact, pruned to hull vertices after every contact but
    the last (whose hull the caller builds anyway)."""
    starts = np.flatnonzero(np.r_[True, contact[1:] != contact[:-1]])
    verts = np.zeros((1, 6))
    for i, rows in enumerate(np.split(wrenches, starts[1:])):
        if i:
            verts = _extreme(verts)
        summand = np.vstack([np.zeros((1, 6)), rows])
        sums = (verts[:, None, :] + summand[None]).reshape(-1, 6)
        verts = np.unique(sums, axis=0)       # repeated points make 'Q0' fail more often
    return verts


def minkowski_vertices(wrenches: np.ndarray, contact: np.ndarray) -> np.ndarray:
    """Vertices (v, 6) of sum_i conv({0} U W_i)."""
    return _extreme(minkowski_points(wrenches, contact))


def _extreme(points: np.ndarray) -> np.ndarray:
    """The points of (k, 6) (distinct) that are vertices of their hull (0 is a
    member), in the linear span they reach; all of them if qhull fails (costs
    time, not accuracy).  For a hull of cluster representatives, every point
    of a cluster whose representative is a vertex (the others lie within the
    accepted error of the hull, see ``qhull``)."""
    _, sing, vt = np.linalg.svd(points, full_matrices=False)
    rank = int((sing > sing[0] * RANK_TOL).sum()) if sing[0] > 0 else 0
    if rank <= 1:
        if rank == 0:
            return points[:1]
        coord = points @ vt[0]
        return points[[coord.argmin(), coord.argmax()]]
    try:
        hull, owner = _checked_hull(points @ vt[:rank].T)
    except HullError:
        return points
    if hull is None:
        return points
    return points[hull.vertices] if owner is None else points[np.isin(owner, hull.vertices)]
