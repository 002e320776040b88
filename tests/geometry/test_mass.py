"""Mass properties: rho and the radius of gyration, also under ``planner.quality``
(whose own tests, tests/quality/test_quality_scale.py, give the known answers)."""

from __future__ import annotations

import numpy as np
from helpers import NUM_TOL, assert_close
from hypothesis import given, settings
from hypothesis import strategies as st

from planner import quality
from planner.geometry import mass


def test_quality_reexports_the_geometry_functions() -> None:
    assert quality.torque_scale_max_distance is mass.torque_scale_max_distance
    assert quality.radius_of_gyration is mass.radius_of_gyration


@settings(max_examples=50, deadline=None)
@given(shift=st.tuples(*[st.floats(-1, 1)] * 3), scale=st.floats(0.1, 10))
def test_rho_moves_with_the_body_and_scales_with_it(shift: tuple, scale: float) -> None:
    verts = np.random.default_rng(0).normal(size=(20, 3))
    com = verts.mean(axis=0)
    rho = mass.torque_scale_max_distance(verts, com)
    assert_close(mass.torque_scale_max_distance(verts + shift, com + shift), rho, 1e-12 * max(1.0, rho))
    assert_close(mass.torque_scale_max_distance(verts * scale, com * scale), rho * scale, 1e-12 * scale * rho)


def test_radius_of_gyration_scales_with_size_not_mass() -> None:
    inertia = np.diag([1.0, 2.0, 3.0])
    k = mass.radius_of_gyration(2.0, inertia)
    assert_close(mass.radius_of_gyration(4.0, 2 * inertia), k, NUM_TOL)
    assert_close(mass.radius_of_gyration(2.0, 4 * inertia), 2 * k, NUM_TOL)
