"""Hull helpers on polytopes with known inradius: cube, cross-polytope, simplex."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from quality_support import EXACT, assert_close

from planner.quality.closure import SIMPLEX, inscribed_radius
from planner.quality.hull import L1Support, LinfSupport, active_set_epsilon, hull_epsilon, minkowski_vertices, qhull

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
