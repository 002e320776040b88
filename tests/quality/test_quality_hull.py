"""Hull helpers on polytopes with known inradius (cube, cross-polytope, simplex),
the checked qhull fallback and the memory-bounded checks (issue 13)."""

from __future__ import annotations

import itertools
import tracemalloc

import numpy as np
import pytest
from quality_support import EXACT, JOGGLE, SPHERE_RADIUS, assert_close, lifted_square_grasp
from scipy.spatial import ConvexHull, QhullError

from planner.quality import PrimitiveWrenches, primitive_wrenches
from planner.quality import hull as hull_module
from planner.quality.closure import SIMPLEX, inscribed_radius
from planner.quality.hull import (
    BLOCK_BYTES,
    HullError,
    L1Support,
    LinfSupport,
    active_set_epsilon,
    blocks,
    hull_epsilon,
    max_off_plane,
    max_outside,
    minkowski_points,
    minkowski_vertices,
    qhull,
)
from planner.quality.reference import joggled_linf
from planner.quality.tolerances import HULL_TOL

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
