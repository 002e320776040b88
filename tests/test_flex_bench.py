"""bench/flex_pose.py and bench/flex_kinds.py's helpers on small made-up inputs with known answers."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from flex_kinds import near_label  # noqa: E402
from flex_pose import cropped, dominant_axis  # noqa: E402

from planner.present.render import View  # noqa: E402


def _pose(turn: np.ndarray, at: tuple[float, float, float]) -> np.ndarray:
    p = np.eye(4)
    p[:3, :3], p[:3, 3] = turn, at
    return p


def _about(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [k for k in range(3) if k != axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def test_dominant_axis_names_the_nearest_signed_axis() -> None:
    assert dominant_axis(np.array([0.1, -0.9, 0.3])) == "-y"
    assert dominant_axis(np.array([0.0, 0.2, 0.7])) == "+z"
    assert dominant_axis(np.array([-0.6, 0.5, 0.0])) == "-x"


def test_near_label_counts_the_swapped_hand_and_nothing_farther() -> None:
    poses = np.stack([_pose(np.eye(3), (0, 0, 0)),
                      _pose(_about(2, np.pi), (0.001, 0, 0)),  # the fingers swapped: the same grasp
                      _pose(_about(2, np.radians(20)), (0, 0.001, 0)),  # turned too far about the approach
                      _pose(np.eye(3), (0.006, 0, 0)),  # too far away
                      _pose(np.eye(3), (0.5, 0, 0))])
    tcp = poses[:, :3, 3] + 0.1034 * poses[:, :3, 2]
    labels = np.array([0, 1, 0, 0, 1])
    assert near_label(poses, labels, tcp, 0) == 1.0
    assert np.isnan(near_label(poses, labels, tcp, 4))


def test_cropped_keeps_every_mark_on_its_pixel() -> None:
    rng = np.random.default_rng(0)
    image = rng.integers(0, 255, (1000, 1000, 3), dtype=np.uint8)
    contacts, com = np.array([[400.0, 500.0], [600.0, 500.0]]), np.array([[500.0, 530.0]])
    out = cropped(View(image, contacts, com))
    assert out.image.shape[0] == out.image.shape[1] < image.shape[0]
    for before, after in ((contacts, out.contacts), (com, out.com)):
        for (x, y), (u, v) in zip(before.astype(int), after.astype(int)):
            assert np.array_equal(image[y, x], out.image[v, u])
