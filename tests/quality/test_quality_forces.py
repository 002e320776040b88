"""Grasping force optimisation in the true friction cones."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from quality_support import assert_close, frames_from_normals, seeds, sphere_grasp

from planner.errors import DegenerateGraspError
from planner.quality import contact_forces, force_closure, grasp_matrix
from planner.quality.tolerances import CONE_TOL, EQUILIBRIUM_TOL

HALF_WIDTH = 0.03    # box half-width along x [m]
WEIGHT = 9.81 * 0.2  # a 200 g box [N]
GRAVITY = np.array([0.0, 0.0, -WEIGHT, 0.0, 0.0, 0.0])

PINCH_POINTS = np.array([[HALF_WIDTH, 0, 0], [-HALF_WIDTH, 0, 0]])
PINCH_FRAMES = frames_from_normals(np.array([[-1.0, 0, 0], [1.0, 0, 0]]))


def check_solution(points: np.ndarray, frames: np.ndarray, forces: np.ndarray,
                   wrench: np.ndarray, mu: float) -> None:
    net = np.r_[forces.sum(0), np.cross(points, forces).sum(0)]
    assert_close(net, -wrench, abs_=EQUILIBRIUM_TOL * max(1.0, np.linalg.norm(wrench)),
                 what="equilibrium")
    normal = np.einsum("ni,ni->n", forces, frames[:, :, 0])
    tangential = np.linalg.norm(forces - normal[:, None] * frames[:, :, 0], axis=1)
    slack = CONE_TOL * max(1.0, np.linalg.norm(forces))
    assert (normal >= -slack).all()
    assert (tangential <= mu * normal + slack).all()


def test_pinched_box_is_held_against_gravity() -> None:
    forces = contact_forces(PINCH_POINTS, PINCH_FRAMES, GRAVITY, mu=0.5, center=np.zeros(3))
    assert forces is not None
    check_solution(PINCH_POINTS, PINCH_FRAMES, forces, GRAVITY, 0.5)
    # least magnitude: each finger lifts half the weight at the cone's edge,
    # so it squeezes with W / (2 mu) = W.
    assert_close(forces, [[-WEIGHT, 0, WEIGHT / 2], [WEIGHT, 0, WEIGHT / 2]], rel=1e-4,
                 abs_=1e-4 * WEIGHT)


def test_no_friction_cannot_resist_a_tangential_load() -> None:
    assert contact_forces(PINCH_POINTS, PINCH_FRAMES, GRAVITY, mu=0.0, center=np.zeros(3)) is None
    assert contact_forces(PINCH_POINTS, PINCH_FRAMES, GRAVITY, mu=0.5, center=np.zeros(3),
                          model="frictionless") is None


def test_frictionless_contacts_push_along_their_normals() -> None:
    load = np.array([3.0, 0, 0, 0, 0, 0])          # pushes the box towards +x
    forces = contact_forces(PINCH_POINTS, PINCH_FRAMES, load, mu=0.0, center=np.zeros(3),
                            model="frictionless")
    assert forces is not None
    assert_close(forces, [[-3.0, 0, 0], [0, 0, 0]], abs_=1e-6)


@given(seed=seeds, mu=st.floats(0.2, 1.0))
@settings(max_examples=40, deadline=None)
def test_solutions_satisfy_equilibrium_and_cones(seed: int, mu: float) -> None:
    rng = np.random.default_rng(seed)
    pts, frames = sphere_grasp(rng, 4)
    wrench = np.r_[rng.normal(size=3), rng.normal(size=3) * 0.05]
    forces = contact_forces(pts, frames, wrench, mu=mu, center=np.zeros(3), torque_scale=0.05)
    # the inscribed 8-edge pyramid lies inside the true cone: closure there
    # means every wrench can be balanced, so the solver must find forces.
    if force_closure(pts, frames, mu=mu, center=np.zeros(3), torque_scale=0.05):
        assert forces is not None
    if forces is not None:
        check_solution(pts, frames, forces, wrench, mu)
        local = np.einsum("nji,nj->ni", frames, forces).ravel()
        assert_close(grasp_matrix(pts, frames, np.zeros(3)) @ local, -wrench,
                     abs_=EQUILIBRIUM_TOL * max(1.0, np.linalg.norm(wrench)))


def test_soft_fingers_are_rejected() -> None:
    with pytest.raises(DegenerateGraspError, match="frictionless' and 'point'"):
        contact_forces(PINCH_POINTS, PINCH_FRAMES, GRAVITY, mu=0.5, center=np.zeros(3),
                       model="soft")


@pytest.mark.parametrize("seed, mu", [(2360, 0.2), (580, 0.2), (952, 0.2), (1169, 0.2)])
def test_a_grasp_near_the_edge_of_closure_still_gets_its_forces(seed: int, mu: float) -> None:
    """Hypothesis found a force-closure grasp (epsilon 7.7e-4) for which SLSQP's line search failed (status 8)
    and contact_forces said no forces exist; 10 of 3,463 such random closure cases. Restarted from forces
    inside the inscribed pyramids (a linear program), it finds them; they balance the load inside the cones."""
    rng = np.random.default_rng(seed)
    pts, frames = sphere_grasp(rng, 4)
    wrench = np.r_[rng.normal(size=3), rng.normal(size=3) * 0.05]
    assert force_closure(pts, frames, mu=mu, center=np.zeros(3), torque_scale=0.05)
    forces = contact_forces(pts, frames, wrench, mu=mu, center=np.zeros(3), torque_scale=0.05)
    assert forces is not None
    check_solution(pts, frames, forces, wrench, mu)
    local = np.einsum("nji,nj->ni", frames, forces).ravel()
    assert_close(grasp_matrix(pts, frames, np.zeros(3)) @ local, -wrench,
                 abs_=EQUILIBRIUM_TOL * max(1.0, np.linalg.norm(wrench)))
