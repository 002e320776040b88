"""Contacts read from the simulator: shapes, frames, the stored form."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import NUM_TOL, assert_close
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.plan.contacts import spread
from planner.plan.tolerances import MAX_PER_LINK, MERGE_RADIUS
from planner.record.contacts import STORED_DIGITS, HandContacts

#: The stored form keeps 6 decimals of points [m] and normals.
STORED_TOL = 0.5 * 10.0 ** -STORED_DIGITS


def some_contacts(n: int = 5, seed: int = 0) -> HandContacts:
    rng = np.random.default_rng(seed)
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    links = tuple(("left", "right", "palm")[i % 3] for i in range(n))
    return HandContacts(rng.normal(scale=0.03, size=(n, 3)), normals, links)


def test_shapes_are_checked() -> None:
    with pytest.raises(ValueError):
        HandContacts(np.zeros((2, 3)), np.zeros((3, 3)), ("a", "b"))
    with pytest.raises(ValueError):
        HandContacts(np.zeros((2, 3)), np.zeros((2, 3)), ("a",))


def test_counts_and_frames() -> None:
    c = some_contacts(5)
    assert len(c) == 5 and c.touching == 3
    frames = c.frames
    assert frames.shape == (5, 3, 3)
    assert_close(frames[:, :, 0], c.normals)
    assert_close(np.einsum("nki,nkj->nij", frames, frames), np.broadcast_to(np.eye(3), (5, 3, 3)), NUM_TOL)
    assert_close(np.linalg.det(frames), np.ones(5), NUM_TOL)


def test_the_stored_form_reads_back_lazily_and_writes_the_same_text() -> None:
    c = some_contacts(6)
    text = c.json_text()
    back = HandContacts.stored(text, len(c), c.touching)
    assert len(back) == 6 and back.touching == 3 and back.json_text() == text
    assert_close(back.points, c.points, STORED_TOL)
    assert_close(back.normals, c.normals, STORED_TOL)
    assert back.links == c.links
    assert HandContacts(back.points, back.normals, back.links).json_text() == text  # rounding is idempotent
    assert back.to_json()[0] == {"point": [round(float(v), 6) for v in c.points[0]],
                                 "normal": [round(float(v), 6) for v in c.normals[0]], "link": "left"}


@settings(max_examples=100, deadline=None)
@given(points=st.lists(st.tuples(*[st.floats(-0.01, 0.01)] * 3), min_size=1, max_size=30))
def test_spread_keeps_separated_points_including_the_first(points: list) -> None:
    p = np.array(points, float)
    chosen = spread(p)
    assert chosen[0] == 0 and len(chosen) <= MAX_PER_LINK and len(set(chosen.tolist())) == len(chosen)
    kept = p[chosen]
    gaps = np.linalg.norm(kept[:, None] - kept[None], axis=2) + np.eye(len(kept)) * 1.0
    assert (gaps > MERGE_RADIUS).all()
    assert np.array_equal(spread(p), chosen)  # deterministic


def test_spread_of_a_dense_patch_is_one_point_and_of_nothing_is_empty() -> None:
    assert spread(np.full((5, 3), 0.001)).tolist() == [0]
    assert spread(np.zeros((0, 3))).tolist() == []
