"""The active-set epsilon's rounds: h taken nearest facet first, up to the
first clean one, decides as h of every facet does (ties of distance
included), and the epsilon it gives is the full hull's."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from quality_support import REFERENCE, assert_close
from scipy.spatial import ConvexHull, QhullError

from planner.quality import active_set
from planner.quality.active_set import L1Support, active_set_epsilon, nearest_dirty, nearest_dirty_reference
from planner.quality.hull import hull_epsilon, qhull, unique_rows
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


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(7, 30), st.integers(1, 12))
def test_the_hull_without_volume_has_convexhulls_points_and_facets(seed: int, start: int, added: int) -> None:
    """After the seed and after each add_points, bit for bit (volume and area are not computed)."""
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(start + 2 * added, 6))
    try:
        plain = ConvexHull(points[:start], incremental=True, qhull_options="Q0")
    except Exception:
        return                                  # qhull's own trouble with the seed: the fast hull has it too
    fast = active_set._Hull(points[:start], incremental=True, qhull_options="Q0")
    try:
        for batch in (None, points[start:start + added], points[start + added:]):
            if batch is not None:
                plain.add_points(batch)
                fast.add_points(batch)
            for name in ("points", "equations", "simplices", "neighbors", "coplanar", "vertices"):
                assert np.array_equal(getattr(fast, name), getattr(plain, name)), name
            assert fast.good is None and plain.good is None      # qhull's 'good' facets only with 'QG'
            assert fast.volume is None and fast.area is None
    finally:
        plain.close()
        fast.close()


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(25, 120))
@example(3925, 25)  # the origin outside: a partial hull's other negative distance
def test_every_seed_gives_the_full_hulls_epsilon(seed: int, gens: int) -> None:
    """The rounds from each seed of SEEDS that qhull takes and that does not stall give the full hull's
    epsilon, and so does the cascade when its first seeds cannot span 6-D (a few of the simplex's directions)."""
    rng = np.random.default_rng(seed)
    wrenches = rng.normal(size=(gens, 6)) + rng.normal(scale=0.2, size=6)
    hull = qhull(wrenches)
    assert hull is not None
    support, scale = L1Support(wrenches), float(np.abs(wrenches).max())
    for dirs in active_set.SEEDS:
        start = unique_rows(support.point(dirs))
        try:
            grown = active_set._Hull(start, incremental=True, qhull_options="Q0")
        except QhullError:
            continue
        try:
            assert_same_epsilon(active_set._grow(support, grown, FACET_TOL * scale, incremental=True),
                                hull_epsilon(hull))
        except active_set._Stalled:
            pass
        finally:
            grown.close()
    saved = active_set.SEEDS
    try:
        active_set.SEEDS = (active_set.SIMPLEX[:3], active_set.SIMPLEX[:6], *saved)
        eps = active_set_epsilon(support, scale)
    finally:
        active_set.SEEDS = saved
    assert eps is not None
    assert_same_epsilon(eps, hull_epsilon(hull))


def assert_same_epsilon(eps: float, full: float) -> None:
    """The full hull's epsilon where the origin is inside; where it is outside (full < 0) a partial hull's
    nearest facet is another negative distance (seed 3925, 25 generators: -0.04814 against -0.04817), and what
    the measures keep of either is 0 (planner.quality.metrics: not force closure)."""
    assert (eps < 0) == (full < 0)
    assert_close(max(eps, 0.0), max(full, 0.0), rel=REFERENCE, abs_=REFERENCE)


@pytest.mark.parametrize("dim, options", [(6, "Q0 QG0"), (6, "Q0 QG-1"), (3, "QG2"), (2, "Q0"), (2, "QG0")])
def test_the_hull_without_volume_has_convexhulls_good_and_vertices(dim: int, options: str) -> None:
    """The rest of what ConvexHull gives but its volume and area: 'good' (a bool per facet, with 'QG') and the
    vertices (in 2-D counter-clockwise, as qhull orders them)."""
    points = np.random.default_rng(dim).normal(size=(40, dim))
    plain, fast = ConvexHull(points, qhull_options=options), active_set._Hull(points, qhull_options=options)
    assert (fast.good is None) == (plain.good is None)
    if plain.good is not None:
        assert fast.good.dtype == plain.good.dtype and np.array_equal(fast.good, plain.good)
    assert np.array_equal(fast.vertices, plain.vertices)


@pytest.mark.parametrize("error", [AttributeError, TypeError, ValueError])
def test_a_scipy_whose_private_hull_base_differs_gets_the_plain_hull(monkeypatch: pytest.MonkeyPatch,
                                                                      error: type[Exception]) -> None:
    """_Hull leans on scipy's private _QhullUser._update: where another version's differs, the active set's
    rounds take the plain ConvexHull (the same epsilon), not an error out of epsilon."""
    class Changed:
        @staticmethod
        def _update(hull: object, qhull: object) -> None:
            raise error("another scipy's private base")

    monkeypatch.setattr(active_set, "_QhullUser", Changed)
    monkeypatch.setattr(active_set, "HULL", getattr(active_set, "_hull_class", lambda: active_set._Hull)(),
                        raising=False)
    wrenches = np.random.default_rng(3).normal(size=(60, 6)) + 0.1
    hull = qhull(wrenches)
    eps = active_set_epsilon(L1Support(wrenches), float(np.abs(wrenches).max()))
    assert hull is not None and eps is not None
    assert_close(eps, hull_epsilon(hull), rel=REFERENCE, abs_=REFERENCE)
    assert active_set.HULL is ConvexHull      # not _Hull failing in every round (ValueError: the merged rebuild)


def test_this_scipy_gets_the_hull_without_volume() -> None:
    assert active_set.HULL is active_set._Hull


def test_directions_within_one_block_are_taken_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """A round's chunk of facets (fewer directions than one block holds) is one product, without the blocks'
    generator (a few microseconds a call, ~11 calls an epsilon); the same values and points as directions taken
    one block at a time; more directions than a block holds still go by blocks."""
    rng = np.random.default_rng(11)
    wrenches, dirs = rng.normal(size=(65, 6)), rng.normal(size=(32, 6))
    support = L1Support(wrenches)
    calls: list[tuple[int, int]] = []

    def counted(rows: int, cols: int):  # type: ignore[no-untyped-def]
        calls.append((rows, cols))
        return active_set.blocks.__wrapped__(rows, cols)  # type: ignore[attr-defined]

    counted.__wrapped__ = active_set.blocks  # type: ignore[attr-defined]
    monkeypatch.setattr(active_set, "blocks", counted)
    proj = dirs @ wrenches.T
    assert np.array_equal(support.value(dirs), proj.max(axis=1))
    assert np.array_equal(support.point(dirs), wrenches[proj.argmax(axis=1)])
    assert calls == []
    many = rng.normal(size=(support._block_rows + 1, 6))
    assert np.array_equal(support.value(many), (many @ wrenches.T).max(axis=1))
    assert calls == [(len(many), len(wrenches))]
