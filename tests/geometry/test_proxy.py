"""The collision proxy (planner.geometry.proxy): fewer faces, within its
stated tolerance of the exact surface, measured by a distance that is never
below the truth."""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
import pytest
import trimesh
from helpers import brute_distances
from hypothesis import given, settings
from hypothesis import strategies as st
from scanlike import capsule

from planner import prepare
from planner.geometry.mesh import mesh_hash
from planner.geometry.proxy import PROXY, ProxySettings, build_proxy, collision_proxy, distances

#: [m] what a brute-force closest point and the candidate search may differ by (round-off).


@pytest.fixture(scope="module")
def fine() -> trimesh.Trimesh:
    return capsule(12_000)  # above ProxySettings.above


def _brute(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """(n,) [m] exact distance of each point to every face of ``mesh``."""
    return brute_distances(mesh.triangles, points)


def test_a_fine_mesh_gets_a_proxy_of_fewer_faces_within_the_tolerance(fine) -> None:  # type: ignore[no-untyped-def]
    s = ProxySettings()
    proxy = build_proxy(fine, s)
    assert not proxy.exact
    assert len(proxy.mesh.faces) < len(fine.faces) / 2
    assert 0.0 < proxy.deviation <= s.tolerance
    # checked on other points, the exact way: both surfaces within the measured deviation
    rng = np.random.default_rng(5)
    on_exact = trimesh.sample.sample_surface(fine, 150, seed=1)[0]
    on_proxy = trimesh.sample.sample_surface(proxy.mesh, 150, seed=2)[0]
    assert _brute(proxy.mesh, on_exact).max() <= proxy.deviation * 1.25  # sampled, so a little margin
    assert _brute(fine, on_proxy).max() <= proxy.deviation * 1.25
    assert rng is not None


def test_a_mesh_at_or_below_the_threshold_is_its_own_proxy() -> None:
    mesh = capsule(2_000)
    proxy = collision_proxy(mesh, mesh_hash(mesh))
    assert proxy.exact and proxy.mesh is mesh and proxy.deviation == 0.0


def test_the_proxy_is_cached_by_the_mesh_hash(fine) -> None:  # type: ignore[no-untyped-def]
    first = collision_proxy(fine, mesh_hash(fine))
    again = collision_proxy(fine, mesh_hash(fine))
    assert again.mesh is not first.mesh  # read back from the cache
    assert np.array_equal(again.mesh.vertices, first.mesh.vertices)
    assert np.array_equal(again.mesh.faces, first.mesh.faces)
    assert again.deviation == first.deviation


def test_no_proxy_within_an_impossible_tolerance_means_the_exact_mesh(fine) -> None:  # type: ignore[no-untyped-def]
    proxy = build_proxy(fine, ProxySettings(tolerance=1e-7, samples=500))
    assert proxy.exact and proxy.mesh is fine


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="ProxySettings"):
        ProxySettings(faces=2)
    with pytest.raises(ValueError, match="ProxySettings"):
        ProxySettings(tolerance=0.0)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(-0.003, 0.003))
def test_the_distance_is_the_truth_near_the_surface(seed: int, offset: float) -> None:
    # a coarse capsule has long slivers along its side: where trimesh's own closest point can miss
    mesh = trimesh.creation.capsule(height=0.07, radius=0.022, count=[12, 12])
    rng = np.random.default_rng(seed)
    points, faces = trimesh.sample.sample_surface(mesh, 20, seed=seed)
    points = points + offset * mesh.face_normals[faces] + rng.normal(0.0, 1e-4, points.shape)
    np.testing.assert_allclose(distances(mesh, points), _brute(mesh, points), atol=1e-9)


def test_making_a_proxy_is_announced_once(caplog: pytest.LogCaptureFixture) -> None:
    mesh = capsule(6_000)
    with caplog.at_level(logging.INFO, logger=prepare.LOGGER):
        collision_proxy(mesh, mesh_hash(mesh), name="scan")
        collision_proxy(mesh, mesh_hash(mesh), name="scan")  # cached: nothing to announce
    lines = [r.getMessage() for r in caplog.records if r.name == prepare.LOGGER]
    assert len(lines) == 2 and all(line.startswith(f"{PROXY} of scan: ") for line in lines)
    assert "started" in lines[0] and "done in" in lines[1]


def test_a_proxy_that_does_not_fit_is_said(caplog: pytest.LogCaptureFixture) -> None:
    """A rough scan whose decimations all miss the tolerance is closed against its exact mesh, at its cost:
    said once (it was a debug line nobody saw)."""
    mesh = capsule(20_000)
    with caplog.at_level(logging.INFO, logger=prepare.LOGGER):
        proxy = collision_proxy(mesh, mesh_hash(mesh), ProxySettings(tolerance=1e-7, samples=500), name="rough")
    lines = [r.getMessage() for r in caplog.records if r.name == prepare.LOGGER]
    assert proxy.exact and any(line.startswith("rough: no collision proxy of fewer than") and
                               "closing uses the exact mesh" in line for line in lines), lines


def test_a_rough_scan_gets_a_proxy_within_the_tolerance_nearly_everywhere(caplog: pytest.LogCaptureFixture) -> None:
    """A scan's noise, not its shape, keeps every decimation from the tolerance somewhere: it was closed on
    its exact mesh, at ~7x the cost; it gets the first proxy within the tolerance at 99.9% of the samples and
    within the spike bound everywhere, and says so. (A capsule of 15k faces, 0.2 mm of noise along its
    normals: its 4,000-face proxy, the only one tried, is 0.56 mm away at most, 0.38 mm at 99.9%.)"""
    mesh = capsule(15_000)
    noise = np.random.default_rng(0).normal(0.0, 0.0002, (len(mesh.vertices), 1))
    rough = trimesh.Trimesh(mesh.vertices + mesh.vertex_normals * noise, mesh.faces, process=False)
    s = ProxySettings()
    with caplog.at_level(logging.INFO, logger=prepare.LOGGER):
        proxy = build_proxy(rough, s, name="rough")
    assert not proxy.exact and s.tolerance < proxy.deviation <= s.spike
    lines = [r.getMessage() for r in caplog.records if r.name == prepare.LOGGER]
    assert any(line.startswith("rough: a rough surface: its collision proxy of 4,000 faces") for line in lines), lines
    assert build_proxy(rough, replace(s, quantile=1.0)).exact  # the rule before: the exact mesh
