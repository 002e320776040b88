"""Shared test builders and the one tolerance helper."""

from __future__ import annotations

import numpy as np

#: Geometric tolerance of the simulator-based stages [m]: PyBullet's contact
#: margins are corrected to about this.
SIM_TOL = 0.0015
#: Pure floating-point comparisons.
NUM_TOL = 1e-9


def assert_close(actual: object, expected: object, tol: float = NUM_TOL) -> None:
    a, e = np.asarray(actual, float), np.asarray(expected, float)
    assert a.shape == e.shape, f"shape {a.shape} != {e.shape}"
    assert np.allclose(a, e, atol=tol, rtol=0), f"{a} != {e} (tol {tol})"
