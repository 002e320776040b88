"""Grasp matrix G, partial grasp matrices G~_i, selection matrices, skew."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from quality_support import assert_close, seeds, sphere_grasp

from planner.errors import DegenerateGraspError
from planner.quality import grasp_matrix, partial_grasp_matrix, primitive_wrenches, selection_matrix, skew

CENTER = np.array([0.004, 0.01, -0.02])


@given(r=st.lists(st.floats(-10, 10), min_size=3, max_size=3),
       x=st.lists(st.floats(-10, 10), min_size=3, max_size=3))
def test_skew_is_the_cross_product(r: list[float], x: list[float]) -> None:
    assert_close(skew(r) @ x, np.cross(r, x), abs_=1e-12)
    assert_close(skew(r).T, -skew(r))


def test_selection_matrices_eqs_2_8_to_2_10() -> None:
    assert (selection_matrix("frictionless") == [[1, 0, 0, 0, 0, 0]]).all()
    assert (selection_matrix("point") == np.eye(6)[:3]).all()
    assert (selection_matrix("soft") == np.eye(6)[:4]).all()
    with pytest.raises(DegenerateGraspError, match="Available models"):
        selection_matrix("rolling")


@pytest.mark.parametrize("model, width", [("frictionless", 1), ("point", 3), ("soft", 4)])
def test_grasp_matrix_shape(rng: np.random.Generator, model: str, width: int) -> None:
    pts, frames = sphere_grasp(rng, 5)
    assert grasp_matrix(pts, frames, CENTER, model).shape == (6, 5 * width)


def test_mixed_models_concatenate_blocks(rng: np.random.Generator) -> None:
    pts, frames = sphere_grasp(rng, 3)
    models = ["soft", "frictionless", "point"]
    g = grasp_matrix(pts, frames, CENTER, models)
    assert g.shape == (6, 8)
    for i, (cols, model) in enumerate(zip([(0, 4), (4, 5), (5, 8)], models)):
        full = partial_grasp_matrix(pts[i], frames[i], CENTER)
        assert_close(g[:, cols[0]:cols[1]], full @ selection_matrix(model).T)


@given(seed=seeds, n=st.integers(1, 6))
@settings(max_examples=30, deadline=None)
def test_grasp_matrix_maps_contact_forces_to_net_wrench(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    pts, frames = sphere_grasp(rng, n)
    local = rng.normal(size=(n, 3))                    # (f_n, f_l, f_o) per contact
    force = np.einsum("nij,nj->ni", frames, local)     # the same forces in {W}
    expected = np.r_[force.sum(0), np.cross(pts - CENTER, force).sum(0)]
    assert_close(grasp_matrix(pts, frames, CENTER) @ local.ravel(), expected, abs_=1e-12)


def test_grasp_matrix_agrees_with_primitive_wrenches(rng: np.random.Generator) -> None:
    pts, frames = sphere_grasp(rng, 4)
    mu, rho, m = 0.4, 0.06, 8
    w, owner = primitive_wrenches(pts, frames, mu=mu, center=CENTER, torque_scale=rho,
                                  cone_edges=m)
    g = grasp_matrix(pts, frames, CENTER) * np.r_[np.ones(3), np.full(3, 1 / rho)][:, None]
    theta = 2 * np.pi * np.arange(m) / m
    local = np.stack([np.ones(m), mu * np.cos(theta), mu * np.sin(theta)])
    for i in range(4):
        assert_close(w[owner == i], (g[:, 3 * i:3 * i + 3] @ local).T, abs_=1e-12)


def test_partial_grasp_matrix_transpose_gives_contact_twist(rng: np.random.Generator) -> None:
    pts, frames = sphere_grasp(rng, 1)
    v, omega = rng.normal(size=3), rng.normal(size=3)
    twist = partial_grasp_matrix(pts[0], frames[0], CENTER).T @ np.r_[v, omega]
    point_velocity = v + np.cross(omega, pts[0] - CENTER)   # rigid body at c_i
    assert_close(twist, np.r_[frames[0].T @ point_velocity, frames[0].T @ omega], abs_=1e-12)
