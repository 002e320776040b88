"""How an object collides in the trials: simplified hulls stay inside their
part and within the tolerance of it; the simplified parts are cached on disk
and read back the same, a damaged cache file is made again."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

from planner.geometry.solid import load_object
from planner.validation import parts


def _outside(points: np.ndarray, hull_points: np.ndarray) -> np.ndarray:
    """(n,) [m] how far each point lies outside the convex hull of ``hull_points`` (<= 0: inside)."""
    planes = ConvexHull(hull_points).equations
    return np.max(points @ planes[:, :3].T + planes[:, 3], axis=1)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.integers(20, 400), st.sampled_from([0.0005, 0.002, 0.01]))
def test_a_simplified_hull_lies_inside_its_part_and_within_the_tolerance(seed, n, tolerance) -> None:
    cloud = np.random.default_rng(seed).normal(size=(n, 3)) * np.array([0.05, 0.03, 0.02])
    vertices, faces = parts.simplified_hull(cloud, tolerance)
    assert len(vertices) <= parts.MAX_VERTICES and faces.shape[1] == 3
    assert np.all(_outside(vertices, cloud) <= 1e-9)  # its vertices are the part's own
    if len(vertices) < parts.MAX_VERTICES:  # it stopped because nothing was farther out than the tolerance
        assert np.all(_outside(cloud, vertices) <= tolerance + 1e-9)


@pytest.fixture
def capsule(tmp_path, monkeypatch):  # type: ignore[no-untyped-def]
    monkeypatch.setenv("GRASP_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(parts, "_PARTS", {})  # nothing remembered from another test
    mesh = trimesh.creation.capsule(height=0.06, radius=0.02, count=[48, 48])
    path = tmp_path / "capsule.obj"
    mesh.export(path)
    return load_object(str(path))


def test_simplified_parts_are_cached_on_disk_and_read_back_the_same(capsule, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    made = parts.simplified_parts(capsule, 0.001)
    files = list((parts.assets.cache_dir("simplified")).glob("*.npz"))
    assert len(files) == 1
    monkeypatch.setattr(parts, "_PARTS", {})  # a new process: only the disk remembers
    monkeypatch.setattr(parts, "simplified_hull", lambda *a: pytest.fail("simplified again"))
    again = parts.simplified_parts(capsule, 0.001)
    assert len(again) == len(made) >= 1
    for (v0, f0), (v1, f1) in zip(made, again):
        assert np.array_equal(v0, v1) and np.array_equal(f0, f1)


def test_a_damaged_cache_file_is_made_again(capsule, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    made = parts.simplified_parts(capsule, 0.001)
    (path,) = parts.assets.cache_dir("simplified").glob("*.npz")
    path.write_bytes(b"not an npz")
    monkeypatch.setattr(parts, "_PARTS", {})
    again = parts.simplified_parts(capsule, 0.001)
    assert all(np.array_equal(a[0], b[0]) for a, b in zip(made, again))
    with np.load(path) as data:  # rewritten whole
        assert int(data["n"]) == len(made)
