"""A patch's regions (planner/plan/patch_clusters.py): where every normal of a patch lies well within half the split
angle of their mean, every pair counts as similar without its dot product, and the regions are those the pairs'
dot products give."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from planner.plan import patch_clusters
from planner.plan.patch_clusters import all_similar, cluster, components


def spread_normals(rng: np.random.Generator, k: int, angle: float) -> np.ndarray:
    """(k, 3) unit normals about a random axis, each tilted from it by up to ``angle`` [rad]."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    side = np.cross(axis, rng.normal(size=3))
    side /= np.linalg.norm(side)
    other = np.cross(axis, side)
    tilt, turn = rng.uniform(0.0, angle, k), rng.uniform(0.0, 2 * np.pi, k)
    return (np.cos(tilt)[:, None] * axis + np.sin(tilt)[:, None] * (np.cos(turn)[:, None] * side
                                                                      + np.sin(turn)[:, None] * other))


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 300), st.floats(0.0, 1.2), st.floats(0.01, np.pi))
def test_normals_said_all_similar_are_similar_in_every_pair(seed: int, k: int, angle: float, split: float) -> None:
    """Whatever the spread: True only where every pair's dot product exceeds cos(split) as _cluster computes it."""
    rng = np.random.default_rng(seed)
    normals = spread_normals(rng, k, angle)
    if all_similar(normals, split):
        first, second = np.triu_indices(k, 1)
        assert np.all(np.einsum("ij,ij->i", normals[first], normals[second]) > np.cos(split))


@pytest.mark.parametrize("angle, split, expected", [(0.0, np.radians(30), True), (np.radians(12), np.radians(30), True),
                                                    (np.radians(40), np.radians(30), False)])
def test_a_flat_or_gently_curved_patch_is_all_similar(angle: float, split: float, expected: bool) -> None:
    """A face's normals (all the same), a cone of half the split angle less a little: all similar; a wider one: not
    (its pairs are read one by one)."""
    rng = np.random.default_rng(1)
    normals = spread_normals(rng, 400, angle)
    normals[:2] = normals[2]
    assert all_similar(normals, split) is expected


@pytest.mark.parametrize("case", ["short", "long", "nan", "empty", "zero_mean", "wide_split"])
def test_normals_not_unit_or_finite_take_the_pairs(case: str) -> None:
    """Normals whose length is off 1, NaN, none, cancelling, or a split angle over pi: False (the pairs decide)."""
    normals = np.tile([0.0, 0.0, 1.0], (5, 1))
    split = np.radians(30)
    if case == "short":
        normals[3] *= 0.99
    elif case == "long":
        normals[3] *= 1 + 1e-6
    elif case == "nan":
        normals[3, 0] = np.nan
    elif case == "empty":
        normals = normals[:0]
    elif case == "zero_mean":
        normals[1::2] *= -1
        normals = normals[:4]
    else:
        split = 1.5 * np.pi
    assert not all_similar(normals, split)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 300), st.floats(0.0, 0.6), st.floats(0.0005, 0.004),
       st.floats(0.05, np.pi))
def test_regions_are_the_same_with_and_without_the_short_cut(seed: int, k: int, angle: float, radius: float,
                                                             split: float) -> None:
    """The labels with every pair's normals read (the short cut off) and with the short cut, from known pairs or a
    tree's: the same, and the components of the similar pairs."""
    rng = np.random.default_rng(seed)
    points = rng.uniform(0.0, 0.01, (k, 3))
    normals = spread_normals(rng, k, angle)
    close = cKDTree(points).query_pairs(radius, output_type="ndarray")
    close = close[np.lexsort((close[:, 1], close[:, 0]))]
    similar = close[np.einsum("ij,ij->i", normals[close[:, 0]], normals[close[:, 1]]) > np.cos(split)]
    want = components(k, similar)
    for pairs in (close, None):
        assert np.array_equal(cluster(points, normals, radius, split, pairs), want)
        saved = patch_clusters.all_similar
        patch_clusters.all_similar = lambda normals, split: False  # type: ignore[assignment]
        try:
            assert np.array_equal(cluster(points, normals, radius, split, pairs), want)
        finally:
            patch_clusters.all_similar = saved


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 300), st.integers(0, 2000))
def test_the_components_of_pairs_in_any_order_are_scipys(seed: int, n: int, count: int) -> None:
    """Pairs in any order (a tree's, unsorted), either end first, repeated or a node with itself: the labels and
    dtype of scipy's public connected_components (numbered by their smallest node), so a tree's pairs need no
    sort before :func:`components`."""
    from planner.plan.patch_clusters import components_reference

    rng = np.random.default_rng(seed)
    pairs = rng.integers(0, n, size=(count, 2))
    got = components(n, pairs)
    want = components_reference(n, pairs[np.argsort(pairs[:, 0], kind="stable")])
    assert got.dtype == want.dtype and np.array_equal(got, want)

