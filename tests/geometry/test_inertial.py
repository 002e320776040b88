"""A given centre of mass and inertia checked against the mesh: a body's inertia always passes, placeholders
and impossible tensors do not (the mesh's is kept, said), a centre outside the hull is refused in one line."""

from __future__ import annotations

import logging

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from planner.errors import InputError
from planner.geometry.inertial import given_inertial, hull_distance, implausible
from planner.specs.objects import ObjectSpec

BOX = (0.04, 0.06, 0.1)  # [m]


@settings(max_examples=50, deadline=None)
@given(arrays(float, (12, 3), elements=st.floats(-1, 1)), arrays(float, 12, elements=st.floats(0.01, 1)),
       st.floats(0.01, 0.5))
def test_every_bodys_inertia_is_plausible(points: np.ndarray, masses: np.ndarray, size: float) -> None:
    """Point masses anywhere within ``rho`` of their centre: their inertia about it passes every check (a rod
    or a single point, which no solid is, aside)."""
    centre = masses @ points / masses.sum()
    r = (points - centre) * size
    inertia = sum(m * (v @ v * np.eye(3) - np.outer(v, v)) for m, v in zip(masses, r))
    if np.linalg.eigvalsh(inertia).min() <= 1e-6 * np.trace(inertia):
        return  # (nearly) collinear or coincident points: a rod or a point, not a solid
    assert implausible(inertia, float(masses.sum()), float(np.linalg.norm(r, axis=1).max())) is None


@pytest.mark.parametrize("inertia, why", [
    (np.eye(3), "trace 3 kg m^2, more than"),  # pybullet_data's placeholder on a 0.1 kg duck
    (np.diag([1e-5, 1e-5, 0.0]), "not positive"),  # random_urdfs' izz="0"
    (np.diag([1e-6, 1e-6, 1e-5]), "triangle inequality"),
    (np.array([[1e-5, 2e-6, 0], [0, 1e-5, 0], [0, 0, 1e-5]]), "not symmetric"),
])
def test_placeholders_and_impossible_tensors_are_named(inertia: np.ndarray, why: str) -> None:
    found = implausible(inertia, 0.1, 0.05)
    assert found is not None and why in found


def spec(**given: object) -> ObjectSpec:
    return ObjectSpec(name="brick", kind="mesh", source="/data/brick.urdf", mass=0.2, **given)  # type: ignore[arg-type]


def mesh_props() -> tuple[trimesh.Trimesh, np.ndarray, np.ndarray]:
    mesh = trimesh.creation.box(extents=BOX)
    mesh.density = 0.2 / mesh.volume
    return mesh, mesh.center_mass, mesh.moment_inertia


def test_a_given_centre_inside_is_used_with_the_meshs_inertia_unmoved() -> None:
    mesh, com, inertia = mesh_props()
    got_com, got_inertia = given_inertial(spec(com=(0.01, -0.02, 0.05), com_from="brick.toml"), mesh, com, inertia)
    assert got_com.tolist() == [0.01, -0.02, 0.05]  # on the top face: inside to the micrometre
    assert np.array_equal(got_inertia, inertia)
    assert hull_distance(mesh, np.array([0.0, 0.0, 0.06])) == pytest.approx(0.01)


def test_a_centre_outside_the_hull_is_refused_naming_the_file_the_value_and_who_gave_it() -> None:
    mesh, com, inertia = mesh_props()
    with pytest.raises(InputError) as exc:
        given_inertial(spec(com=(0.0, 0.0, 0.08), com_from="brick.urdf <inertial><origin>"), mesh, com, inertia)
    message = str(exc.value)
    assert "\n" not in message and message.startswith("/data/brick.urdf: its centre of mass [0, 0, 0.08] m")
    assert "(brick.urdf <inertial><origin>) lies 30 mm outside" in message and "brick.toml" in message


def test_a_plausible_inertia_is_used_and_a_placeholder_said_and_replaced(caplog: pytest.LogCaptureFixture) -> None:
    mesh, com, inertia = mesh_props()
    own = np.diag([3e-4, 2e-4, 1.5e-4]) / 0.2  # per kg
    assert np.allclose(given_inertial(spec(gyration=tuple(own.ravel())), mesh, com, inertia)[1], own * 0.2)
    with caplog.at_level(logging.INFO, logger="planner.prepare"):
        got = given_inertial(spec(gyration=tuple((np.eye(3) / 0.2).ravel())), mesh, com, inertia)[1]
    assert np.array_equal(got, inertia)
    assert "brick.urdf's <inertia> is not a body's of 0.2 kg within its mesh (trace 3 kg m^2" in caplog.text
