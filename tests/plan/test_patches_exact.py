"""Exact speed cuts of the contact patches (planner/plan/patches.py, patch_surfaces.py): each the same bits as the
plain way it replaces: a band's subsample, a link's pairs among a band, the joint queries split back per link, a
patch of one region."""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from planner.plan.patches import PatchSettings, _split, _subsample, _subsample_at, hand_surfaces
from planner.specs.hands import load_hand


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 2**16), st.integers(1, 50), st.integers(0, 3000))
def test_a_subsample_is_the_seeded_choice_of_its_band_and_made_once_per_size(seed: int, start: int, size: int,
                                                                          extra: int) -> None:
    """The subsample of a band (ascending sample indices, any gaps) is the sorted seeded choice the sweep took of
    it (rng.choice of the indices themselves), its nearest rows follow it, and a second band of the same size
    takes its positions from the cache."""
    rng = np.random.default_rng(seed)
    n = size + 1 + extra
    idx = start + np.cumsum(rng.integers(1, 5, n))
    nearest = (rng.normal(size=(n, 3)), rng.random(n), rng.integers(0, 99, n))
    s = PatchSettings(max_exact=size, seed=seed % 7)
    want = np.sort(np.random.default_rng(s.seed).choice(idx, size, replace=False))
    _subsample_at.cache_clear()
    got, near, weight = _subsample(idx, nearest, s)
    at = np.searchsorted(idx, want)
    assert got.tobytes() == want.tobytes() and weight == n / size
    assert all(a.tobytes() == b[at].tobytes() for a, b in zip(near, nearest))
    _subsample(idx + 1, nearest, s)
    assert _subsample_at.cache_info().hits == 1



def _pairs_among_reference(surface, idx: np.ndarray, radius: float) -> np.ndarray:  # type: ignore[no-untyped-def]
    """LinkSurface.pairs_among as it was before 2026-12-07 (three repeats and a column stack)."""
    surface.pairs_among(idx[:1], radius)  # the link's own pairs, made once
    start, partner = surface._near[radius]
    first, last = start[idx], start[idx + 1]
    count = last - first
    rows = np.repeat(np.arange(len(idx)), count)
    at = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count) + np.repeat(first, count)
    position = np.full(len(surface.points), -1)
    position[idx] = np.arange(len(idx))
    cols = position[partner[at]]
    keep = cols >= 0
    return np.column_stack([rows[keep], cols[keep]])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 3000), st.sampled_from([0.0025, 0.004]))
def test_a_links_pairs_among_a_band_are_those_of_the_plain_way(seed: int, k: int, radius: float) -> None:
    """Any band of a finger's samples (one sample to most of them): the same pairs in the same order and dtype."""
    finger = hand_surfaces(load_hand("panda"), PatchSettings())["panda_leftfinger"]
    rng = np.random.default_rng(seed)
    idx = np.sort(rng.choice(len(finger.points), size=min(k, len(finger.points)), replace=False))
    got, want = finger.pairs_among(idx, radius), _pairs_among_reference(finger, idx, radius)
    assert got.dtype == want.dtype and got.shape == want.shape and got.tobytes() == want.tobytes()


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.lists(st.integers(0, 50), min_size=1, max_size=5))
def test_joint_answers_split_back_as_np_split_cuts_them(seed: int, sizes: list[int]) -> None:
    """Rows of a query made for several parts at once, cut back into the parts (empty parts too): np.split's."""
    rng = np.random.default_rng(seed)
    parts = [np.zeros(n) for n in sizes]
    arrays = (rng.normal(size=(sum(sizes), 3)), rng.integers(0, 9, sum(sizes)))
    got = _split(arrays, parts)
    cuts = np.cumsum(sizes)[:-1]
    want = [np.split(a, cuts) for a in arrays]
    assert [[g.tobytes() for g in row] for row in got] == [[w.tobytes() for w in row] for row in want]
    assert all(len(row) == len(parts) for row in got)


def _link_regions_reference(link, surface, points, idx, weight, closest, gap, floor, normals, s):  # type: ignore[no-untyped-def]
    """patches._link_regions as it was before 2026-12-07 (a mask per label, one label too)."""
    from planner.plan import patches

    pairs = surface.pairs_among(idx, s.link_radius) if weight == 1.0 else None
    labels = patches._cluster(points[idx], normals, s.link_radius * np.sqrt(weight), s.split_angle, pairs)
    out = []
    for label in np.unique(labels):
        sel = labels == label
        if gap[sel].min() > floor + s.touch:
            continue
        mean = normals[sel].mean(axis=0)
        mean /= np.linalg.norm(mean)
        points_in = closest[sel]
        uv = patches._plane(points_in, mean) if len(points_in) >= 2 else None
        out.append(patches.Region(link, points_in, normals[sel], weight * float(surface.area[idx[sel]].sum()),
                                  patches._width(uv), mean, uv))
    return out


@settings(max_examples=40, deadline=None)
@example(seed=3, k=300, bent=0.0, fringe=0.0, weight=1.0)  # one region
@example(seed=3, k=300, bent=1.0, fringe=0.0004, weight=2.5)  # several, a fringe
@given(st.integers(0, 2**32 - 1), st.integers(1, 600), st.floats(0.0, 1.0), st.floats(0.0, 0.0004),
       st.sampled_from([1.0, 2.5]))
def test_a_links_regions_are_those_of_a_mask_per_region(seed: int, k: int, bent: float, fringe: float,
                                                       weight: float) -> None:
    """Patches of a finger's samples, one region (flat) or several (a share of the normals turned away, a fringe
    not touching), whole or subsampled: the regions, field by field to the bit, of a mask per region."""
    from planner.plan import patches

    s = PatchSettings()
    finger = hand_surfaces(load_hand("panda"), s)["panda_leftfinger"]
    rng = np.random.default_rng(seed)
    centre = finger.points[rng.integers(len(finger.points))]  # the k samples nearest one: mostly one piece
    idx = np.sort(np.argsort(np.linalg.norm(finger.points - centre, axis=1), kind="stable")[:k])
    points = finger.points + rng.normal(scale=1e-3, size=3)
    closest = points[idx] + rng.normal(scale=1e-5, size=(k, 3))
    normals = np.tile(rng.normal(size=3), (k, 1))
    turned = rng.random(k) < bent * 0.3
    normals[turned] = rng.normal(size=3)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    gap = rng.uniform(0.0, 0.0002, k) + np.where(rng.random(k) < 0.2, fringe, 0.0)
    floor = float(gap.min())
    got = patches._link_regions("f", finger, points, idx, weight, closest, gap, floor, normals, s)
    want = _link_regions_reference("f", finger, points, idx, weight, closest, gap, floor, normals, s)
    _assert_same_regions(got, want)



def _assert_same_regions(got, want) -> None:  # type: ignore[no-untyped-def]
    """Regions field by field to the bit, in the same order."""
    assert len(got) == len(want)
    for a, b in zip(got, want):
        assert (a.link, a.area, a.diameter) == (b.link, b.area, b.diameter)
        for field in ("points", "normals", "normal"):
            assert getattr(a, field).tobytes() == getattr(b, field).tobytes()
        assert (a.plane is None and b.plane is None) or a.plane.tobytes() == b.plane.tobytes()


def _finger_near(name: str, seed: int):  # type: ignore[no-untyped-def]
    """(surface, finger, pose): the Panda's left finger placed near a random point of the object ``name``, turned
    anyway, within a few millimetres of it."""
    from scipy.spatial.transform import Rotation

    from planner.geometry.solid import load_object
    from planner.plan.patches import ObjectSurface

    surface = ObjectSurface(load_object(name).mesh)
    finger = hand_surfaces(load_hand("panda"), surface.settings)["panda_leftfinger"]
    rng = np.random.default_rng(seed)
    at = surface.mesh.sample(1, seed=seed)[0]
    pose = np.eye(4)
    pose[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    pose[:3, 3] = at - pose[:3, :3] @ finger.points[rng.integers(len(finger.points))] + rng.normal(scale=0.002, size=3)
    return surface, finger, pose


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31), st.sampled_from(["mug", "random_002", "box"]))
def test_the_links_regions_together_are_each_links_own(seed: int, name: str) -> None:
    """Two fingers near the object asked together (each sample's own bound read before its exact distance): the
    regions, field by field to the bit, of each link's own link_regions (every sample of its cells measured)."""
    from planner.plan.patches import _together, link_regions

    surface, finger, pose = _finger_near(name, seed)
    _, right, other = _finger_near(name, seed + 1)
    got = _together([("l", finger, pose), ("r", right, other)], surface)
    want = link_regions("l", finger, pose, surface) + link_regions("r", right, other, surface)
    _assert_same_regions(got, want)


@pytest.mark.parametrize("seed", range(8))
def test_only_samples_whose_own_bound_may_be_in_the_band_are_measured(seed: int) -> None:
    """The exact closest points are asked only of samples whose own lower bound is within depth + prefilter of the
    least upper bound of the samples of their cells (fewer than every sample of those cells on the mug)."""
    from planner.plan.patch_surfaces import SLACK
    from planner.plan.patches import _together

    surface, finger, pose = _finger_near("mug", seed)
    s, asked = surface.settings, []
    nearest = surface.nearest
    surface.nearest = lambda points: asked.append(np.array(points)) or nearest(points)  # type: ignore[method-assign]
    _together([("l", finger, pose)], surface)
    if not asked:
        return  # nothing of the finger within reach
    lower, upper = surface.bounds(asked[0])
    assert np.all(lower <= upper.min() + s.depth + s.prefilter + 2 * SLACK)
