"""The active-set epsilon's rounds: h taken nearest facet first, up to the
first clean one, decides as h of every facet does (ties of distance
included), and the epsilon it gives is the full hull's."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from quality_support import REFERENCE, assert_close
from scipy.spatial import ConvexHull

from planner.quality import active_set
from planner.quality.active_set import L1Support, active_set_epsilon, nearest_dirty, nearest_dirty_reference
from planner.quality.hull import hull_epsilon, qhull
from planner.quality.tolerances import FACET_TOL

CUBE = np.array(list(itertools.product([-1.0, 1.0], repeat=6)))       # 64 facets, all at distance 1


def _same_round(support: L1Support, equations: np.ndarray, tol: float, first_chunk: int) -> None:
    """A round taken with the first chunk ``first_chunk`` decides as the reference's."""
    saved, active_set.FIRST_CHUNK = active_set.FIRST_CHUNK, first_chunk
    try:
        bound, dirty = nearest_dirty(support, equations, tol)
    finally:
        active_set.FIRST_CHUNK = saved
    want_bound, want_dirty = nearest_dirty_reference(support, equations, tol)
    assert bound == want_bound
    assert dirty.dtype.kind == "i" and np.array_equal(dirty, want_dirty)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(14, 200), st.integers(7, 30), st.integers(1, 64))
def test_a_round_from_the_nearest_facets_is_a_round_from_all(seed: int, gens: int, kept: int, chunk: int) -> None:
    """Random generators, the hull of a few of them (a round's conv(S)), any first chunk."""
    rng = np.random.default_rng(seed)
    wrenches = rng.normal(size=(gens, 6)) + rng.normal(scale=0.3, size=6)
    points = wrenches[rng.choice(gens, size=min(kept, gens), replace=False)]
    hull = qhull(points)
    if hull is None:
        return
    support = L1Support(wrenches)
    for first in (chunk, active_set.FIRST_CHUNK):
        _same_round(support, hull.equations, FACET_TOL, first)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 40))
def test_ties_of_distance_decide_as_every_facet_does(seed: int, chunk: int) -> None:
    """The cube's 64 facets lie at one distance: a generator beyond some of them makes those dirty, and a chunk
    boundary may fall inside the tie."""
    rng = np.random.default_rng(seed)
    hull = ConvexHull(CUBE, qhull_options="Q0")
    beyond = rng.normal(size=(int(rng.integers(0, 4)), 6))
    beyond *= 1.5 / np.abs(beyond).max(axis=1, keepdims=True) if len(beyond) else 1.0
    support = L1Support(np.vstack([CUBE, beyond]))
    _same_round(support, hull.equations, FACET_TOL, chunk)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(25, 120))
def test_the_active_set_gives_the_full_hulls_epsilon(seed: int, gens: int) -> None:
    rng = np.random.default_rng(seed)
    wrenches = rng.normal(size=(gens, 6)) + rng.normal(scale=0.2, size=6)
    hull = qhull(wrenches)
    eps = active_set_epsilon(L1Support(wrenches), float(np.abs(wrenches).max()))
    assert hull is not None and eps is not None
    assert_close(eps, hull_epsilon(hull), rel=REFERENCE, abs_=REFERENCE)
