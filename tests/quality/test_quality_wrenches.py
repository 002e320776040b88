"""Primitive wrenches and input validation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from quality_support import EXACT, assert_close, seeds, sphere_grasp

from planner.errors import DegenerateGraspError, InputError
from planner.quality import epsilon, primitive_wrenches

CENTER = np.array([0.01, -0.02, 0.005])
RHO = 0.07


@given(seed=seeds, n=st.integers(1, 6), m=st.integers(3, 12), mu=st.floats(0, 2))
@settings(max_examples=40, deadline=None)
def test_point_cone_edges_follow_the_formula(seed: int, n: int, m: int, mu: float) -> None:
    pts, frames = sphere_grasp(np.random.default_rng(seed), n)
    w, owner = primitive_wrenches(pts, frames, mu=mu, center=CENTER, torque_scale=RHO,
                                  cone_edges=m)
    assert w.shape == (n * m, 6)
    assert (owner == np.repeat(np.arange(n), m)).all()
    theta = 2 * np.pi * np.arange(m) / m
    local = np.stack([np.ones(m), mu * np.cos(theta), mu * np.sin(theta)], axis=1)
    force = np.einsum("nij,mj->nmi", frames, local).reshape(-1, 3)
    torque = np.cross(np.repeat(pts - CENTER, m, axis=0), force) / RHO
    assert_close(w, np.hstack([force, torque]), what="edges")


def test_models_give_1_m_and_m_plus_2_rows(rng: np.random.Generator) -> None:
    pts, frames = sphere_grasp(rng, 3)
    w, owner = primitive_wrenches(pts, frames, mu=[0.2, 0.3, 0.4], center=CENTER,
                                  torque_scale=RHO, cone_edges=6,
                                  model=["frictionless", "point", "soft"], torsion=0.01)
    assert (np.bincount(owner) == [1, 6, 8]).all()
    normal = frames[0, :, 0]
    assert_close(w[0], np.r_[normal, np.cross(pts[0] - CENTER, normal) / RHO])
    n2 = frames[2, :, 0]
    base = np.cross(pts[2] - CENTER, n2)
    assert_close(w[-2], np.r_[n2, (base + 0.01 * n2) / RHO], what="torsion +")
    assert_close(w[-1], np.r_[n2, (base - 0.01 * n2) / RHO], what="torsion -")
    assert_close(np.abs(w[1:7, :3] @ frames[1, :, 0]), np.ones(6), rel=EXACT)


def test_no_contacts_is_not_an_error() -> None:
    w, owner = primitive_wrenches(np.zeros((0, 3)), np.zeros((0, 3, 3)), mu=0.5,
                                  center=np.zeros(3), torque_scale=1.0)
    assert w.shape == (0, 6) and owner.shape == (0,)
    assert epsilon(np.zeros((0, 3)), np.zeros((0, 3, 3)), mu=0.5, center=np.zeros(3),
                   torque_scale=1.0) == 0.0


def _good(rng: np.random.Generator) -> dict:
    pts, frames = sphere_grasp(rng, 4)
    return {"points": pts, "frames": frames, "mu": 0.5, "center": np.zeros(3), "torque_scale": 0.05}


@pytest.mark.parametrize("change, message", [
    ({"points": np.zeros((4, 2))}, "points must have shape"),
    ({"frames": np.zeros((3, 3, 3))}, "frames must have shape"),
    ({"points": np.full((4, 3), np.nan)}, "NaN"),
    ({"mu": -0.1}, "mu must be >= 0"),
    ({"mu": [0.5, 0.5]}, "mu must be a scalar or have 4 values"),
    ({"torque_scale": 0.0}, "torque_scale must be > 0"),
    ({"torque_scale": -1.0}, "torque_scale must be > 0"),
    ({"model": "sticky"}, "Available models: frictionless, point, soft"),
    ({"model": ["point"] * 3}, "model has 3 entries for 4 contacts"),
    ({"norm": "L2"}, "Available norms: L1, Linf"),
    ({"cone_edges": 2}, "cone_edges must be an integer >= 3"),
    ({"torsion": -1.0}, "torsion must be >= 0"),
    ({"center": [0, 0]}, "center must have shape"),
])
def test_malformed_input_raises_one_line_error(rng: np.random.Generator, change: dict,
                                               message: str) -> None:
    kwargs = _good(rng) | change
    with pytest.raises(DegenerateGraspError, match=message) as info:
        epsilon(**kwargs)
    assert "\n" not in str(info.value)
    assert isinstance(info.value, InputError)


def test_non_unit_normal_and_skewed_frame_raise(rng: np.random.Generator) -> None:
    kwargs = _good(rng)
    frames = kwargs["frames"].copy()
    frames[2, :, 0] *= 1.01
    with pytest.raises(DegenerateGraspError, match="normal of contact 2 has length 1.01"):
        epsilon(**kwargs | {"frames": frames})
    frames = kwargs["frames"].copy()
    frames[1, :, 1] = frames[1, :, 0]
    with pytest.raises(DegenerateGraspError, match="frame of contact 1 is not orthonormal"):
        epsilon(**kwargs | {"frames": frames})
