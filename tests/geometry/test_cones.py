"""The direction of a normal cone nearest a given one: a wedge's closed form
agrees with non-negative least squares, lies in the cone, and keeps a
direction already inside it."""

import numpy as np
from helpers import assert_close
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from planner.geometry.cones import nearest_in_cone, nearest_in_wedge

unit = st.tuples(*[st.floats(-1, 1)] * 3).map(np.array).filter(lambda v: np.linalg.norm(v) > 0.1).map(
    lambda v: v / np.linalg.norm(v))


@settings(max_examples=200, deadline=None)
@given(unit, unit, unit)
def test_the_wedge_is_the_cones_nearest_direction(n1: np.ndarray, n2: np.ndarray, u: np.ndarray) -> None:
    assume(abs(n1 @ n2) < np.cos(np.radians(10)))  # a wedge the planner calls sharp, not folded flat
    assume(max(u @ n1, u @ n2) > 1e-6)  # u not opposite the whole of it
    wedge = nearest_in_wedge(n1[None], n2[None], u[None])[0]
    assert_close(wedge, nearest_in_cone(np.array([n1, n2]), u), 1e-6)
    a, b = np.linalg.lstsq(np.array([n1, n2]).T, wedge, rcond=None)[0]
    assert a >= -1e-9 and b >= -1e-9  # in the cone


@given(unit, unit, st.floats(0.05, 0.95))
def test_a_direction_inside_the_wedge_is_kept(n1: np.ndarray, n2: np.ndarray, t: float) -> None:
    assume(abs(n1 @ n2) < np.cos(np.radians(10)))
    u = t * n1 + (1 - t) * n2
    u /= np.linalg.norm(u)
    assert_close(nearest_in_wedge(n1[None], n2[None], u[None])[0], u, 1e-9)


def test_opposite_the_wedge_gives_its_mean_and_a_flat_fold_none() -> None:
    n1, n2 = np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]])
    mean = np.array([1, 1, 0]) / np.sqrt(2)
    assert_close(nearest_in_wedge(n1, n2, np.array([[-1.0, -1.0, 0]]) / np.sqrt(2))[0], mean, 1e-12)
    assert_close(nearest_in_wedge(n1, n2, np.array([[0, 0, 1.0]]))[0], mean, 1e-12)  # along the edge
    assert np.isnan(nearest_in_wedge(n1, -n1, np.array([[0, 1.0, 0]]))).all()
    assert np.isnan(nearest_in_cone(np.array([[1.0, 0, 0], [-1.0, 0, 0]]), np.array([0, 1.0, 0]))).all()
