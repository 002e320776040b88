"""Hull helpers on polytopes with known inradius (cube, cross-polytope, simplex),
the checked qhull fallback and the memory-bounded checks (issue 13), the
clustering fallback on nearly coincident wrenches."""

from __future__ import annotations

import itertools
import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from quality_support import EXACT, JOGGLE, SPHERE_RADIUS, antipodal_box_case, assert_close, lifted_square_grasp
from scipy.spatial import ConvexHull, QhullError

from planner.quality import PrimitiveWrenches, epsilon, evaluate, force_closure, primitive_wrenches, volume
from planner.quality import hull as hull_module
from planner.quality.active_set import L1Support, LinfSupport, active_set_epsilon
from planner.quality.closure import SIMPLEX, inscribed_radius
from planner.quality.hull import (
    BLOCK_BYTES,
    HullError,
    blocks,
    clusters,
    hull_epsilon,
    max_off_plane,
    max_outside,
    minkowski_points,
    minkowski_vertices,
    qhull,
    unique_rows,
)
from planner.quality.reference import joggled_l1, joggled_linf, reference_epsilon, reference_volume
from planner.quality.tolerances import CLUSTER_RADIUS, FACET_TOL, HULL_TOL
from planner.quality.wrenches import dedupe

CUBE = np.array(list(itertools.product([-1.0, 1.0], repeat=6)))       # inradius 1
CROSS = np.vstack([np.eye(6), -np.eye(6)])                             # inradius 1/sqrt(6)


@pytest.mark.parametrize("points, radius", [(CUBE, 1.0), (CROSS, 1 / np.sqrt(6)),
                                            (SIMPLEX, 1 / 6)])
def test_known_inradii(points: np.ndarray, radius: float) -> None:
    hull = qhull(points)
    assert hull is not None
    assert_close(np.linalg.norm(hull.equations[:, :-1], axis=1), np.ones(len(hull.equations)))
    assert (points @ hull.equations[:, :-1].T + hull.equations[:, -1] <= 1e-12).all()
    assert_close(hull_epsilon(hull), radius)
    assert_close(active_set_epsilon(L1Support(points), 1.0), radius, abs_=1e-12)


def test_inscribed_radius_of_a_scaled_simplex() -> None:
    assert_close(inscribed_radius(SIMPLEX * 2.0), 2 / 6)
    assert inscribed_radius(SIMPLEX + 1.0) < 0         # origin outside


def test_shifted_polytope_gives_negative_distance() -> None:
    hull = qhull(CUBE + 3.0)
    assert hull is not None and hull_epsilon(hull) == pytest.approx(-2.0, abs=EXACT)


def test_flat_points_have_no_hull() -> None:
    flat = CUBE.copy()
    flat[:, 5] = 0.0
    assert qhull(flat) is None


def test_sum_of_axis_segments_is_the_unit_cube() -> None:
    # conv({0, e_k}) summed over k: the cube [0, 1]^6 with its 64 vertices.
    verts = minkowski_vertices(np.eye(6), np.arange(6))
    assert len(verts) == 64
    assert_close(np.sort(verts.sum(axis=1)), np.sort([sum(v) for v in itertools.product([0, 1], repeat=6)]))


def test_linf_support_is_the_sum_of_per_contact_supports(rng: np.random.Generator) -> None:
    wrenches, owner = rng.normal(size=(12, 6)), np.repeat(np.arange(4), 3)
    dirs = rng.normal(size=(20, 6))
    support = LinfSupport(wrenches, owner)
    value, point = support.value(dirs), support.point(dirs)
    verts = minkowski_vertices(wrenches, owner)
    assert_close(value, (dirs @ verts.T).max(axis=1), abs_=1e-12)
    assert_close(np.einsum("fi,fi->f", dirs, point), value, abs_=1e-12)


# Issue 13 (precision): four point contacts on the equator of a 5 cm sphere at
# 0, 90, 180, 270 degrees, contact 0 lifted 1e-14 m, mu 0.5, 4 cone edges.  The
# Minkowski-sum points come in pairs 1.4e-13 apart; qhull 'Q0' and 'Qx' stop
# ("wide merge due to dupridge"), and qhull() used to report them as flat.
SQUARE_LIFT = (1e-14, 0.0, 0.0, 0.0)
SQUARE_ARGS = {"mu": 0.5, "center": np.zeros(3), "torque_scale": SPHERE_RADIUS, "cone_edges": 4}


def square_minkowski_points() -> tuple[np.ndarray, PrimitiveWrenches]:
    wrenches = primitive_wrenches(*lifted_square_grasp(SQUARE_LIFT), **SQUARE_ARGS)
    return minkowski_points(*wrenches), wrenches


def test_the_square_still_stops_qhulls_default_options() -> None:
    # Keeps the regression input meaningful: if a newer qhull builds this hull
    # with its default options, the fallback below is no longer exercised.
    points, _ = square_minkowski_points()
    for options in ("Q0", "Qx"):
        with pytest.raises(QhullError, match="QH6107|QH6271"):
            ConvexHull(points, qhull_options=options)


def test_qhull_gets_past_the_dupridge_stop_with_a_checked_hull() -> None:
    points, wrenches = square_minkowski_points()
    hull = qhull(points)
    assert hull is not None
    tol = HULL_TOL * np.abs(points).max()
    assert max_outside(points, hull.equations) <= tol and max_off_plane(hull) <= tol
    eps, vol = joggled_linf(*wrenches)
    assert_close(hull.volume, vol, rel=JOGGLE, what="volume vs joggled brute force")
    assert_close(hull_epsilon(hull), eps, rel=JOGGLE, what="epsilon vs support function")


def test_qhull_raises_when_no_option_gives_a_hull(monkeypatch: pytest.MonkeyPatch) -> None:
    # With 'Qx' as the only retry the square has no hull: an error, not "flat".
    points, _ = square_minkowski_points()
    retries = hull_module._retries
    monkeypatch.setattr(hull_module, "_retries", lambda scale: retries(scale)[:1])
    with pytest.raises(HullError, match="qhull could not build the 6-D hull of 545 wrenches.*dupridge"):
        qhull(points)


# Issue 13 (memory): the points-by-facets check of 4 soft contacts with 8 cone
# edges was one (9757, 426189) array, 31 GiB.
@pytest.mark.parametrize("rows, cols", [(426189, 9757), (9757, 7), (3, 10**8), (0, 5), (5, 0)])
def test_blocks_cover_every_row_within_the_cap(rows: int, cols: int) -> None:
    slices = list(blocks(rows, cols))
    assert slices[0].start == 0 and all(a.stop == b.start for a, b in zip(slices, slices[1:]))
    assert rows <= slices[-1].stop < rows + (slices[-1].stop - slices[-1].start) + 1
    assert all(s.stop - s.start == 1 or (s.stop - s.start) * cols * 8 <= BLOCK_BYTES for s in slices)


@pytest.mark.parametrize("cap", [2**12, 2**16])
def test_max_outside_is_the_dense_maximum_in_bounded_memory(rng: np.random.Generator, cap: int,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    points = rng.normal(size=(700, 6))
    normals = rng.normal(size=(3000, 6))
    equations = np.column_stack([normals / np.linalg.norm(normals, axis=1, keepdims=True),
                                 -rng.uniform(2, 5, 3000)])
    dense = float((points @ equations[:, :-1].T + equations[:, -1]).max())     # 17 MB
    monkeypatch.setattr(hull_module, "BLOCK_BYTES", cap)
    tracemalloc.start()
    try:
        worst = max_outside(points, equations)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert_close(worst, dense, abs_=1e-12)
    assert peak <= 2 * cap + 8 * points.size, f"peak {peak} bytes with blocks of {cap}"


def test_support_functions_are_the_same_in_blocks(rng: np.random.Generator,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    wrenches, owner = rng.normal(size=(40, 6)), np.repeat(np.arange(5), 8)
    dirs = rng.normal(size=(500, 6))
    whole = [(s.value(dirs), s.point(dirs)) for s in (L1Support(wrenches), LinfSupport(wrenches, owner))]
    monkeypatch.setattr(hull_module, "BLOCK_BYTES", 8 * 40 * 7)      # blocks of 7 directions
    for (value, point), support in zip(whole, (L1Support(wrenches), LinfSupport(wrenches, owner))):
        assert_close(support.value(dirs), value)
        assert_close(support.point(dirs), point)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 30), st.integers(1, 7), st.integers(1, 6))
def test_unique_rows_are_numpys_unique_rows(seed: int, rows: int, pool: int, dim: int) -> None:
    """The rows of a round drawn from a few distinct ones, ties in leading columns included: the same rows in
    the same order as np.unique(axis=0)."""
    rng = np.random.default_rng(seed)
    distinct = rng.normal(size=(pool, dim))
    distinct[:, 0] = rng.integers(0, 2, pool)              # ties in the first column
    points = distinct[rng.integers(0, pool, rows)]
    assert np.array_equal(unique_rows(points), np.unique(points, axis=0))


# Nearly coincident wrenches (hypothesis, test_force_closure_agrees_with_epsilon):
# 7 soft contacts on a box and their mirror images with mu 1e-12 and torsion
# 1e-11 m.  Cone edges 1e-12 and torsion wrenches 2e-10 from their normal
# escape dedupe, and every qhull option stopped: evaluate raised HullError.
def box_union() -> tuple[np.ndarray, np.ndarray]:
    """(L1 generators after dedupe, all primitive wrenches) of the box case."""
    pts, frames, args = antipodal_box_case()
    raw = primitive_wrenches(pts, frames, **args)
    return dedupe(raw, per_contact=False).wrenches, raw.wrenches


def test_the_box_still_stops_every_plain_option() -> None:
    # Keeps the regression input meaningful: if qhull builds this hull
    # directly, the clustering fallback below is no longer exercised.
    union, _ = box_union()
    scale = max(float(np.abs(union).max()), 1.0)
    failures: list[str] = []
    for options, tol in [("Q0", FACET_TOL * scale), *hull_module._retries(scale)]:
        assert hull_module._attempt(union, options, tol, failures) is None
    assert len(failures) == 4 and "dupridge" in failures[1]


def test_qhull_builds_a_checked_hull_of_cluster_representatives() -> None:
    union, raw = box_union()
    scale = max(float(np.abs(union).max()), 1.0)
    bound = (CLUSTER_RADIUS + HULL_TOL) * scale          # documented error of a clustered hull
    hull = qhull(union)
    assert hull is not None and len(hull.points) < len(union)
    rows = {row.tobytes() for row in union}
    assert all(row.tobytes() in rows for row in hull.points), "representatives are input points"
    assert max_outside(hull.points, hull.equations) <= HULL_TOL * scale
    assert max_outside(union, hull.equations) <= bound
    assert abs(hull_epsilon(hull) - reference_epsilon(raw)) <= bound
    assert abs(hull.volume - reference_volume(raw)) <= bound * hull.area
    eps, vol = joggled_l1(raw)
    assert_close(hull.volume, vol, rel=JOGGLE, what="volume vs joggled reference")
    assert_close(hull_epsilon(hull), eps, rel=JOGGLE, what="epsilon vs joggled reference")


def test_evaluate_on_nearly_coincident_wrenches_agrees_with_epsilon_and_the_reference() -> None:
    pts, frames, args = antipodal_box_case()
    union, raw = box_union()
    bound = (CLUSTER_RADIUS + HULL_TOL) * max(float(np.abs(union).max()), 1.0)
    quality = evaluate(pts, frames, **args)
    eps = epsilon(pts, frames, **args)
    assert quality.force_closure and force_closure(pts, frames, **args) and eps > 0
    assert quality.epsilon > 0
    assert abs(quality.epsilon - eps) <= bound
    assert abs(quality.epsilon - reference_epsilon(raw)) <= bound
    assert abs(eps - reference_epsilon(raw)) <= bound
    assert quality.volume == volume(pts, frames, **args)
    assert_close(quality.volume, reference_volume(raw), rel=JOGGLE, what="volume vs reference")


def test_qhull_without_clustering_raises_on_nearly_coincident_wrenches(
        monkeypatch: pytest.MonkeyPatch) -> None:
    union, _ = box_union()
    monkeypatch.setattr(hull_module, "CLUSTER_RADIUS", 0.0)
    with pytest.raises(HullError, match="hull of 114 wrenches.*dupridge.*no two points within 0 to cluster"):
        qhull(union)


def test_clusters_are_connected_components_named_by_their_first_point() -> None:
    r = 1e-3
    points = np.array([[0.0, 0.0], [0.9 * r, 0.0], [5 * r, 0.0], [1.8 * r, 0.0], [0.0, 0.5 * r],
                       [5 * r, 0.9 * r]])
    assert clusters(points, r).tolist() == [0, 0, 2, 0, 0, 2]     # a chain is one cluster
    assert clusters(points, 0.1 * r).tolist() == list(range(6))


def test_a_clustered_hull_that_a_point_lies_far_beyond_is_rejected() -> None:
    # A chain of points 0.9e-11 apart running 1.2e-8 out of a cube corner is
    # one cluster at every radius: its hull is the cube, which the tip of the
    # chain lies beyond by more than CLUSTER_RADIUS, so no hull is accepted.
    outward = np.ones(6) / np.sqrt(6)
    chain = CUBE[-1] + np.arange(1, 1300)[:, None] * 0.9 * CLUSTER_RADIUS * 1e-3 * outward
    failures: list[str] = []
    hull, owner = hull_module._clustered_hull(np.vstack([CUBE, chain]), 1.0, failures)
    assert hull is None and owner is None
    assert len(failures) == 4 and all("64 representatives" in f and "beyond a facet" in f for f in failures)


def test_vertices_of_a_clustered_hull_keep_every_point_of_their_cluster(
        rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch) -> None:
    # 40 points on the unit sphere, each twice 1e-12 apart, and 10 interior
    # points: with no retry after 'Q0' (which stops on the pairs) only the
    # clustering fallback builds the hull, whose vertices index the
    # representatives; both copies of every sphere point are vertices.
    sphere = rng.normal(size=(40, 6))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    pairs = np.vstack([sphere, sphere + 1e-12 * rng.normal(size=sphere.shape)])
    calls = []
    clustered = hull_module._clustered_hull
    monkeypatch.setattr(hull_module, "_retries", lambda scale: [])
    monkeypatch.setattr(hull_module, "_clustered_hull", lambda *a: calls.append(1) or clustered(*a))
    verts = minkowski_vertices(np.vstack([pairs, 0.3 * sphere[:10]]), np.zeros(90, dtype=int))
    assert calls, "the clustering fallback was not exercised"
    assert len(verts) == 80 and {row.tobytes() for row in verts} == {row.tobytes() for row in pairs}
