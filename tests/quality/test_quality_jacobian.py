"""Hand Jacobian J = B J~ against finite differences, and J qdot = G^T t."""

from __future__ import annotations

import numpy as np
import pytest
from quality_support import FINITE_DIFF, assert_close, frames_from_normals, random_rotation

from planner.errors import DegenerateGraspError
from planner.quality import grasp_jacobian, grasp_matrix, hand_jacobian

A1, A2 = 0.05, 0.04             # link lengths [m]
ALONG, OFFSET = 0.025, 0.008    # contact on link 2: distance along it, off its axis [m]
ALONG1 = 0.03                   # contact on link 1 [m]


def finger(q: np.ndarray, tilt: np.ndarray, base: np.ndarray) -> dict:
    """Planar 2R finger in the plane of ``tilt``'s first two axes: joint
    origins/axes, two contact points (link 1, link 2) and the link-2 frame."""
    def to_world(p: np.ndarray) -> np.ndarray:
        return base + tilt @ p
    e1 = np.array([np.cos(q[0]), np.sin(q[0]), 0.0])
    e12 = np.array([np.cos(q[0] + q[1]), np.sin(q[0] + q[1]), 0.0])
    p12 = np.array([-np.sin(q[0] + q[1]), np.cos(q[0] + q[1]), 0.0])
    joint2 = A1 * e1
    return {
        "origins": np.array([to_world(np.zeros(3)), to_world(joint2)]),
        "axes": np.array([tilt[:, 2], tilt[:, 2]]),
        "points": np.array([to_world(ALONG1 * e1), to_world(joint2 + ALONG * e12 + OFFSET * p12)]),
        "normal": tilt @ p12,
    }


@pytest.mark.parametrize("model, rows", [("point", 3), ("soft", 4), ("frictionless", 1)])
def test_two_link_finger_matches_finite_differences(rng: np.random.Generator, model: str,
                                                    rows: int) -> None:
    tilt, base, q = random_rotation(rng), rng.normal(size=3) * 0.1, rng.uniform(-1, 1, 2)
    f = finger(q, tilt, base)
    frames = frames_from_normals(np.array([tilt @ [0, 1.0, 0], f["normal"]]))
    affects = np.array([[True, False], [True, True]])
    jac = hand_jacobian(f["points"], frames, [1, 2], f["origins"], f["axes"],
                        ["revolute", "revolute"], affects, model)
    assert jac.shape == (2 * rows, 2)
    h = 1e-6
    for j in range(2):
        dq = np.eye(2)[j] * h
        dc = (finger(q + dq, tilt, base)["points"] - finger(q - dq, tilt, base)["points"]) / (2 * h)
        omega = f["axes"][j] * affects[:, j, None]          # angular velocity per unit qdot
        for i in range(2):
            expected = np.r_[frames[i].T @ dc[i], frames[i].T @ omega[i]][:rows]
            assert_close(jac[i * rows:(i + 1) * rows, j], expected, rel=FINITE_DIFF,
                         abs_=FINITE_DIFF * A1, what=f"contact {i}, joint {j}")


def test_object_fixed_to_link_two_satisfies_eq_2_31(rng: np.random.Generator) -> None:
    tilt, base, q = random_rotation(rng), rng.normal(size=3) * 0.1, rng.uniform(-1, 1, 2)
    f = finger(q, tilt, base)
    pts = np.array([f["points"][1], f["points"][1] + tilt @ [0.0, 0.0, 0.01]])
    frames = frames_from_normals(np.array([f["normal"], -tilt[:, 2]]))
    center = rng.normal(size=3) * 0.05
    qdot = rng.normal(size=2)
    for model in ("point", "soft"):
        jac = hand_jacobian(pts, frames, [2, 2], f["origins"], f["axes"], ["revolute"] * 2,
                            np.ones((2, 2), dtype=bool), model)
        omega = f["axes"].T @ qdot
        v = sum(qd * np.cross(z, center - o) for qd, z, o in zip(qdot, f["axes"], f["origins"]))
        twist = np.r_[v, omega]
        assert_close(jac @ qdot, grasp_matrix(pts, frames, center, model).T @ twist, abs_=1e-12)


def test_prismatic_joint_translates_the_contact(rng: np.random.Generator) -> None:
    axis = random_rotation(rng)[:, 0]
    pts = rng.normal(size=(1, 3))
    frames = frames_from_normals(rng.normal(size=(1, 3)))
    jac = hand_jacobian(pts, frames, [0], rng.normal(size=(1, 3)), axis[None], ["prismatic"],
                        np.ones((1, 1), dtype=bool), "soft")
    assert_close(jac[:, 0], np.r_[frames[0].T @ axis, 0.0], abs_=1e-12)


def test_grasp_jacobian_is_pinv_g_transpose_j(rng: np.random.Generator) -> None:
    g, j = rng.normal(size=(6, 9)), rng.normal(size=(9, 4))
    gj = grasp_jacobian(g, j)
    assert gj.shape == (6, 4)
    assert_close(gj, np.linalg.pinv(g).T @ j)
    with pytest.raises(DegenerateGraspError):
        grasp_jacobian(g, j[:5])


def test_inconsistent_link_rows_and_bad_joints_raise(rng: np.random.Generator) -> None:
    pts = rng.normal(size=(2, 3))
    frames = frames_from_normals(rng.normal(size=(2, 3)))
    origins, axes = np.zeros((2, 3)), np.tile([0.0, 0.0, 1.0], (2, 1))
    with pytest.raises(DegenerateGraspError, match="disagree in joint_affects"):
        hand_jacobian(pts, frames, [3, 3], origins, axes, ["revolute"] * 2,
                      np.array([[True, False], [True, True]]))
    with pytest.raises(DegenerateGraspError, match="Available joint types"):
        hand_jacobian(pts, frames, [0, 1], origins, axes, ["ball", "revolute"],
                      np.ones((2, 2), dtype=bool))
    with pytest.raises(DegenerateGraspError, match="unit"):
        hand_jacobian(pts, frames, [0, 1], origins, 2 * axes, ["revolute"] * 2,
                      np.ones((2, 2), dtype=bool))


def test_the_jacobian_of_validated_contacts_is_the_hand_jacobian_bit_for_bit() -> None:
    """The resistance's program hands its validated contacts to ``contacts_jacobian`` (not validated again):
    the same J as ``hand_jacobian`` from the raw arrays, every bit, over point and soft contacts, revolute and
    prismatic joints."""
    from planner.quality.contacts import as_contacts
    from planner.quality.jacobian import contacts_jacobian

    rng = np.random.default_rng(7)
    for _ in range(20):
        n, n_q = int(rng.integers(1, 9)), int(rng.integers(1, 4))
        pts = rng.normal(scale=0.05, size=(n, 3))
        frames = np.array([random_rotation(rng) for _ in range(n)])
        models = [str(m) for m in rng.choice(["point", "soft", "frictionless"], size=n)]
        links = rng.integers(0, 3, size=n)
        affects = rng.random((3, n_q)) < 0.7
        axes = rng.normal(size=(n_q, 3))
        axes /= np.linalg.norm(axes, axis=1, keepdims=True)
        args = (links, rng.normal(scale=0.05, size=(n_q, 3)), axes,
                [str(t) for t in rng.choice(["revolute", "prismatic"], size=n_q)], affects[links])
        want = hand_jacobian(pts, frames, *args, model=models)
        assert np.array_equal(contacts_jacobian(as_contacts(pts, frames, model=models), *args), want)
