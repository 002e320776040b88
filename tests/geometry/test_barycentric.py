"""Barycentric coordinates (planner/geometry/barycentric.py): trimesh's points_to_barycentric to the bit, for any
triangles and points, degenerate triangles included (inf and NaN where trimesh gives them)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.geometry.barycentric import barycentric, barycentric_reference


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 300), st.floats(-6, 1))
def test_the_coordinates_are_trimeshs_to_the_bit(seed: int, n: int, size: float) -> None:
    """Triangles of any size and points near them, on them (their corners, edges' midpoints), and some triangles
    flat (repeated corners): the same bits as trimesh's, and the same warnings aside."""
    rng = np.random.default_rng(seed)
    tri = rng.normal(size=(n, 3, 3)) * 10.0**size
    flat = rng.random(n) < 0.1
    tri[flat, 2] = tri[flat, 1]
    pts = tri.mean(axis=1) + rng.normal(size=(n, 3)) * 10.0**size
    which = rng.integers(0, 3, n)
    on = rng.random(n) < 0.3
    pts[on] = tri[on, which[on]]
    mid = rng.random(n) < 0.2
    pts[mid] = 0.5 * (tri[mid, 0] + tri[mid, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        got, want = barycentric(tri, pts), barycentric_reference(tri, pts)
    assert got.shape == want.shape == (n, 3) and got.dtype == want.dtype
    assert got.tobytes() == want.tobytes()
