"""Torque scale rho from a mesh: max distance and radius of gyration."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from quality_support import assert_close

from planner.errors import InputError, MeshError
from planner.quality import radius_of_gyration, torque_scale_max_distance


def test_max_distance_of_a_cube_is_half_its_diagonal() -> None:
    verts = np.array(list(itertools.product([-0.5, 0.5], repeat=3))) * 0.1 + [1.0, 2.0, 3.0]
    assert_close(torque_scale_max_distance(verts, [1.0, 2.0, 3.0]), 0.05 * np.sqrt(3))


def test_radius_of_gyration_of_a_solid_sphere_and_a_box() -> None:
    mass, radius = 2.0, 0.1
    sphere = np.eye(3) * 0.4 * mass * radius**2
    assert_close(radius_of_gyration(mass, sphere), np.sqrt(0.4) * radius)
    a, b, c = 0.1, 0.2, 0.3                               # box edge lengths [m]
    box = mass / 12 * np.diag([b**2 + c**2, a**2 + c**2, a**2 + b**2])
    assert_close(radius_of_gyration(mass, box), np.sqrt((a**2 + b**2 + c**2) / 18))


@pytest.mark.parametrize("verts, com", [(np.zeros((0, 3)), np.zeros(3)),
                                        (np.full((3, 3), np.nan), np.zeros(3)),
                                        (np.zeros((3, 2)), np.zeros(3)),
                                        (np.zeros((3, 3)), np.zeros(3))])
def test_bad_meshes_raise(verts: np.ndarray, com: np.ndarray) -> None:
    with pytest.raises(MeshError):
        torque_scale_max_distance(verts, com)


@pytest.mark.parametrize("mass, inertia", [(0.0, np.eye(3)), (1.0, -np.eye(3)),
                                           (1.0, np.triu(np.ones((3, 3)))), (1.0, np.eye(2))])
def test_bad_inertia_raises(mass: float, inertia: np.ndarray) -> None:
    with pytest.raises(InputError):
        radius_of_gyration(mass, inertia)
