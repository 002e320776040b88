"""Builders and the one tolerance helper shared by the grasp-quality tests."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

#: Named test tolerances (relative unless the name says otherwise).
EXACT = 1e-12          # identities that only suffer round-off
REFERENCE = 1e-9       # fast epsilon / volume vs the plain qhull reference
FINITE_DIFF = 1e-6     # central differences with step 1e-6 on O(1) kinematics
JOGGLE = 1e-6          # vs qhull 'QJ' (joggled input, ~1e-8 relative error)

SPHERE_RADIUS = 0.05   # [m]


def assert_close(actual: object, expected: object, rel: float = EXACT, abs_: float = EXACT,
                 what: str = "") -> None:
    """|actual - expected| <= abs_ + rel * |expected|, elementwise."""
    a, e = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    err = np.abs(a - e)
    bound = abs_ + rel * np.abs(e)
    assert a.shape == e.shape, f"{what}: shape {a.shape} != {e.shape}"
    assert (err <= bound).all(), (
        f"{what}: max error {err.max():.3g} exceeds tolerance (rel {rel:g}, abs {abs_:g});"
        f" actual {a.ravel()[:6]}, expected {e.ravel()[:6]}")


def frames_from_normals(normals: np.ndarray, roll: np.ndarray | None = None) -> np.ndarray:
    """(n, 3, 3) right-handed frames with first column the unit normal,
    tangents rotated by ``roll`` (n,) [rad] about it."""
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    tan_l = np.cross(n, helper)
    tan_l /= np.linalg.norm(tan_l, axis=1, keepdims=True)
    tan_o = np.cross(n, tan_l)
    if roll is not None:
        c, s = np.cos(roll)[:, None], np.sin(roll)[:, None]
        tan_l, tan_o = c * tan_l + s * tan_o, -s * tan_l + c * tan_o
    return np.stack([n, tan_l, tan_o], axis=2)


def sphere_grasp(rng: np.random.Generator, n: int,
                 radius: float = SPHERE_RADIUS) -> tuple[np.ndarray, np.ndarray]:
    """n contacts uniform on a sphere about the origin, normals inward."""
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return radius * d, frames_from_normals(-d, rng.uniform(0, 2 * np.pi, n))


def box_grasp(rng: np.random.Generator, n: int,
              half: tuple[float, float, float] = (0.03, 0.02, 0.05)) -> tuple[np.ndarray, np.ndarray]:
    """n contacts on random faces of an axis-aligned box, normals inward."""
    half_arr = np.asarray(half)
    axis = rng.integers(0, 3, n)
    sign = rng.choice([-1.0, 1.0], n)
    pts = rng.uniform(-1, 1, (n, 3)) * half_arr
    pts[np.arange(n), axis] = sign * half_arr[axis]
    normals = np.zeros((n, 3))
    normals[np.arange(n), axis] = -sign
    return pts, frames_from_normals(normals, rng.uniform(0, 2 * np.pi, n))


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random rotation matrix (3, 3)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def equator_grasp(k: int = 3, radius: float = SPHERE_RADIUS) -> tuple[np.ndarray, np.ndarray]:
    """k contacts evenly spaced on the equator (z = 0) of a sphere, inward."""
    ang = 2 * np.pi * np.arange(k) / k
    d = np.stack([np.cos(ang), np.sin(ang), np.zeros(k)], axis=1)
    return radius * d, frames_from_normals(-d)


def lifted_square_grasp(lift: tuple[float, float, float, float],
                        radius: float = SPHERE_RADIUS) -> tuple[np.ndarray, np.ndarray]:
    """4 contacts at 0, 90, 180, 270 degrees on the equator of a sphere, each
    lifted by ``lift`` [m] in z (nearly coplanar when the lifts are tiny);
    normals towards the centre, tangents without roll."""
    ang = np.pi / 2 * np.arange(4)
    pts = np.stack([radius * np.cos(ang), radius * np.sin(ang), np.asarray(lift, dtype=float)], axis=1)
    return pts, frames_from_normals(-pts)


# Issue 13 regression cases of the L-infinity hull, shared by the tests and
# bench/quality.py: each returns (points, frames, keyword arguments).

def coplanar_soft_case() -> tuple[np.ndarray, np.ndarray, dict]:
    """4 nearly coplanar soft contacts (lifts ~1e-14 m), 6 cone edges: qhull's
    default options stop on the Minkowski sum ("wide merge due to dupridge")."""
    pts, frames = lifted_square_grasp((1.6e-14, -2.2e-14, -1.8e-14, -0.8e-14))
    args = {"mu": 0.58, "center": np.zeros(3), "torque_scale": SPHERE_RADIUS, "cone_edges": 6,
            "model": "soft", "torsion": 0.0008}
    return pts, frames, args


def soft_sphere_case(n: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """The first n of 4 random soft contacts on a sphere (seed 0) with 8 cone
    edges: the dense points-by-facets check of the L-infinity hull was one
    (1210, 75698) array for n = 3 (0.7 GiB) and (9757, 426189) for n = 4
    (31 GiB)."""
    pts, frames = sphere_grasp(np.random.default_rng(0), 4)
    args = {"mu": 0.5, "center": np.zeros(3), "torque_scale": SPHERE_RADIUS, "cone_edges": 8,
            "model": "soft", "torsion": 0.002}
    return pts[:n], frames[:n], args


def antipodal_box_case() -> tuple[np.ndarray, np.ndarray, dict]:
    """7 soft contacts on a box of half extents 0.03 x 0.02 x 0.05 m and their
    mirror images (normals inward), mu 1e-12, torsion 1e-11 m, 7 cone edges,
    found by hypothesis: the cone edges lie ~1e-12 and the torsion wrenches
    ~2e-10 from their normal, farther apart than DEDUP_TOL, and every qhull
    option stopped on (or, 'QJ', failed the check of) the 114 L1 wrenches."""
    pts = np.array([
        [0.01096785, 0.00015442, -0.05], [0.0125339, -0.01596346, -0.05],
        [-0.00224823, 0.02, -0.0065256], [-0.03, 0.00347603, 0.00575331],
        [-0.03, 0.00784863, -0.04235649], [-0.00736268, 0.02, -0.02208967],
        [0.00444993, -0.02, -0.0259019]])
    face = np.array([[0, 0, -1], [0, 1, 0], [1, 0, 0]])         # normal +z
    side = np.array([[0, 0, -1], [-1, 0, 0], [0, 1, 0]])        # normal -y
    end = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]])          # normal +x
    back = np.array([[0, 0, -1], [1, 0, 0], [0, -1, 0]])        # normal +y
    frames = np.array([face, face, side, end, end, side, back], dtype=float)
    mirrored = frames * [-1.0, -1.0, 1.0]                       # columns (n, l, o) -> (-n, -l, o)
    args = {"mu": 1e-12, "center": np.zeros(3), "torque_scale": SPHERE_RADIUS, "cone_edges": 7,
            "model": "soft", "torsion": 1e-11}
    return np.vstack([pts, -pts]), np.concatenate([frames, mirrored]), args


seeds = st.integers(min_value=0, max_value=2**32 - 1)
