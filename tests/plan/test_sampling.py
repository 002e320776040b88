"""Approach rays: the surface and box samplers, the fan."""

import numpy as np
import trimesh
from helpers import assert_close

from planner.plan import sampling


def test_surface_rays_on_sphere_point_to_the_centre() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.03)
    rays = sampling.sample(mesh, sampler="surface", count=50, rng=np.random.default_rng(1))
    assert len(rays) == 50
    radial = rays.points / np.linalg.norm(rays.points, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", rays.directions, -radial) > 0.98)


def test_surface_rays_are_reproducible() -> None:
    mesh = trimesh.creation.box(extents=[0.05, 0.04, 0.08])
    a = sampling.sample(mesh, sampler="surface", count=20, rng=np.random.default_rng(7))
    b = sampling.sample(mesh, sampler="surface", count=20, rng=np.random.default_rng(7))
    assert_close(a.points, b.points)


def test_box_rays_hit_faces_with_axis_normals() -> None:
    mesh = trimesh.creation.box(extents=[0.05, 0.04, 0.08])
    rays = sampling.sample(mesh, sampler="box", count=0, rng=np.random.default_rng(0), delta=0.02)
    assert len(rays) > 20
    assert np.allclose(np.abs(rays.normals).max(axis=1), 1.0)
    assert np.allclose(np.abs(rays.points).max(axis=0), [0.025, 0.02, 0.04])


def test_fan_tilts_by_the_angle() -> None:
    mesh = trimesh.creation.box(extents=[0.05, 0.04, 0.08])
    base = sampling.sample(mesh, sampler="surface", count=5, rng=np.random.default_rng(0))
    fanned = sampling.fan(base, 4, 0.3)
    assert len(fanned) == 25
    cos = np.einsum("ij,ij->i", fanned.directions[5:], np.tile(base.directions, (4, 1)))
    assert_close(cos, np.full(20, np.cos(0.3)), 1e-9)
