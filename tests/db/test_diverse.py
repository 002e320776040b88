"""Diverse top-K and surface coverage (:mod:`planner.db.diverse`)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from planner import api
from planner.db.diverse import Spacing, coverage, diverse, rotation_distance, tcp_points
from tests.helpers import grasp, made_up

TCP = np.array([0.0, 0.0, 0.1])
APPROACH = np.array([0.0, 0.0, 1.0])


def _posed(i: int, pose: np.ndarray):  # noqa: ANN202 - a made-up grasp at a pose
    return dataclasses.replace(made_up(i, 0.1), pose=pose)


def _pose(rotvec: np.ndarray, t: np.ndarray) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    pose[:3, 3] = t
    return pose


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 0.05), st.floats(0.0, 1.5), st.integers(1, 4))
def test_kept_grasps_are_apart_and_the_best_is_first(seed: int, dt: float, dr: float, symmetry: int) -> None:
    rng = np.random.default_rng(seed)
    grasps = [_posed(i, _pose(rng.normal(size=3), rng.uniform(-0.05, 0.05, 3))) for i in range(30)]
    spacing = Spacing(dt, dr)
    kept = diverse(grasps, 10, spacing, TCP, APPROACH, symmetry)
    assert kept[0] is grasps[0]
    centres = tcp_points(kept, TCP)
    for i in range(len(kept)):
        for j in range(i):
            far = np.linalg.norm(centres[i] - centres[j]) >= dt
            turned = rotation_distance(kept[j].pose[:3, :3], kept[i].pose[:3, :3], APPROACH, symmetry) >= dr
            assert far or turned
    # every grasp left out is too close to one kept before it (greedy in rank order)
    order = {id(g): n for n, g in enumerate(grasps)}
    last = order[id(kept[-1])]
    for g in grasps[:last]:
        if any(g is k for k in kept):
            continue
        c = tcp_points([g], TCP)[0]
        assert any(np.linalg.norm(c - tcp_points([k], TCP)[0]) < dt and
                   rotation_distance(k.pose[:3, :3], g.pose[:3, :3], APPROACH, symmetry) < dr
                   for k in kept if order[id(k)] < order[id(g)])


def test_zero_spacing_keeps_the_ranking() -> None:
    grasps = [_posed(i, _pose(np.zeros(3), np.zeros(3))) for i in range(5)]
    assert diverse(grasps, 3, Spacing(0.0, 0.0), TCP, APPROACH) == grasps[:3]


def test_a_half_turn_is_the_same_grasp_for_a_two_finger_jaw() -> None:
    a = _posed(0, _pose(np.zeros(3), np.zeros(3)))
    b = _posed(1, _pose(np.array([0.0, 0.0, np.pi]), np.zeros(3)))
    assert rotation_distance(a.pose[:3, :3], b.pose[:3, :3], APPROACH, 2) < 1e-9
    assert rotation_distance(a.pose[:3, :3], b.pose[:3, :3], APPROACH, 1) > 3.14
    assert diverse([a, b], 2, Spacing(0.01, 0.5), TCP, APPROACH, 2) == [a]
    assert diverse([a, b], 2, Spacing(0.01, 0.5), TCP, APPROACH, 1) == [a, b]


def test_translation_is_measured_at_the_tool_centre_point() -> None:
    """Two grasps with the same hand base but turned 90 degrees about x: their
    tool centre points (10 cm out) are 14 cm apart."""
    a = _posed(0, _pose(np.zeros(3), np.zeros(3)))
    b = _posed(1, _pose(np.array([np.pi / 2, 0.0, 0.0]), np.zeros(3)))
    gap = np.linalg.norm(np.diff(tcp_points([a, b], TCP), axis=0))
    assert abs(gap - 0.1 * np.sqrt(2)) < 1e-9
    assert diverse([a, b], 2, Spacing(0.1, 10.0), TCP, APPROACH) == [a, b]


def test_coverage() -> None:
    rng = np.random.default_rng(0)
    surface = rng.uniform(-0.05, 0.05, (500, 3))
    assert coverage(surface, np.zeros((0, 3))) == 0.0
    assert coverage(surface, surface) == 1.0
    some = surface[:50]
    small, large = coverage(surface, some, 0.005), coverage(surface, some, 0.02)
    assert 0.1 <= small <= large <= 1.0


def test_best_diverse_on_a_database(box_db: Path) -> None:
    plain = api.best("box", "panda", db_path=box_db, top=6)
    apart = api.best("box", "panda", db_path=box_db, top=6, spacing=Spacing(0.03, np.radians(45)))
    assert apart[0].rank == plain[0].rank == 1
    assert [g.rank for g in apart] == sorted(g.rank for g in apart)
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--top", "3", "--diverse",
                           "--min-translation", "0.03", "--min-rotation", "45")
    assert code == 0, err
    assert [line.split()[0] for line in out.splitlines() if line.startswith("#")] == \
        [f"#{g.rank}" for g in apart[:3]]


def test_export_top_diverse_writes_the_diverse_grasps(box_db: Path, tmp_path: Path) -> None:
    import csv

    apart = api.best("box", "panda", db_path=box_db, top=4, spacing=Spacing(0.03, np.radians(45)))
    code, _, err = grasp("export", "--db", str(box_db), "--format", "csv", "--out", str(tmp_path / "csv"), "--top",
                         "4", "--diverse", "--min-translation", "0.03", "--min-rotation", "45", "--quiet")
    assert code == 0, err
    with open(tmp_path / "csv" / "grasps.csv", newline="") as fh:
        ranks = [int(r["rank"]) for r in csv.DictReader(fh)]
    assert ranks == [g.rank for g in apart]
    code, _, err = grasp("export", "--db", str(box_db), "--format", "csv", "--out", str(tmp_path / "x"), "--diverse")
    assert code == 2 and "--diverse needs --top K" in err
