"""An object turned in its file so that its up is another axis, and told so, is measured as the upright
original: the same com_height, gravity_arm, torque_per_mu and p_hold on every grasp at the same pose (turned
with it). A glTF file is Y-up by its specification: a Y-up .glb of the mug is measured like the Z-up mug
without being told. Untold (+z), the turned copy is measured lying on its side."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import FAST, grasp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planner.calibration import features
from planner.calibration.model import SHIPPED_ENV, LogisticModel, default_model
from planner.datasets.importer import RescoreUnit, rescore_poses
from planner.geometry.solid import load_object
from planner.record.grasp import Grasp
from planner.specs.hands import load_hand
from planner.specs.objects import resolve_spec
from planner.specs.up import AXES

#: An exact turn of the file frame per up: the original's +z goes to that axis. The turns to +-y and -z keep x,
#: so a sweep's tangents (taken about x unless a normal lies near it) turn with the object and its candidates
#: correspond; +-x cannot keep x.
TURNS = {"+z": np.eye(3), "-z": np.diag([1.0, -1.0, -1.0]), "+y": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),
         "-y": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]), "+x": np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]),
         "-x": np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]])}
#: A quarter turn about +z, exact.
QUARTER = np.array([[0.0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
#: [m] the grip measures of one grasp at one pose, measured about the up in either frame (the same numbers,
#: other roundings); p_hold also reads local_sdf, sampled in the hand frame: 1e-7 apart measured.
MEASURE_TOL, P_HOLD_TOL = 1e-9, 1e-5
#: [m] contacts closing found alike in both frames (PyBullet's closing differs by millimetres on a few poses).
SAME_CONTACTS = 1e-6
WEIGHT = ("com_height", "gravity_arm", "torque_per_mu")


def turn(axis: str) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = TURNS[axis]
    return out


def brick() -> trimesh.Trimesh:
    """A box off its frame's origin: its centre of mass sits apart from every grip."""
    mesh = trimesh.creation.box(extents=(0.05, 0.04, 0.08))
    mesh.apply_translation((0.0, 0.005, 0.01))
    return mesh


def weight_measures(grasps: list[Grasp], model: LogisticModel) -> np.ndarray:
    """(n, 4) com_height, gravity_arm, torque_per_mu and ``model``'s p_hold of each grasp."""
    m = np.array([[getattr(g.measures, k) for k in WEIGHT] for g in grasps])
    return np.hstack([m, model.predict(features.of_grasps(grasps))[:, None]])


@pytest.fixture(scope="module")
def panda_model() -> LogisticModel:
    """The Panda's shipped p_hold model (the tests' own runs score without it)."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(SHIPPED_ENV, "1")
        model = default_model("panda")
    assert model is not None
    return model


@pytest.fixture(scope="module")
def upright(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray, list[Grasp]]:
    """The upright brick's file, poses of its swept grasps, and those poses closed and measured (+z up)."""
    folder = tmp_path_factory.mktemp("upright")
    brick().export(folder / "brick.obj")
    code, _, err = grasp("generate", str(folder / "brick.obj"), "--hand", "panda", "--db", str(folder / "g.db"),
                         "--quiet", *FAST[:6], "--approaches", "8")
    assert code == 0, err
    with sqlite3.connect(folder / "g.db") as conn:
        poses = np.array([np.reshape(json.loads(p), (4, 4)) for (p,) in conn.execute("SELECT pose FROM grasps")])
    spec = resolve_spec(str(folder / "brick.obj"))
    return folder, poses, rescore_poses(RescoreUnit(0, 0, poses, load_hand("panda"), spec)).grasps


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(axis=st.sampled_from(AXES), quarters=st.integers(0, 3))
def test_a_turned_copy_told_its_up_is_measured_as_the_upright_original(upright, panda_model, tmp_path_factory,  # type: ignore[no-untyped-def]
                                                                      axis: str, quarters: int) -> None:
    """Any up, the copy also turned about it by quarter turns (exact: a turn by another angle rounds the mesh,
    and the grip measures' surface samples near a pad's band flip, 0.1 mm apart): the hand closed at each pose
    (turned with the object), where it finds the same contacts, gives the same weight measures and p_hold."""
    folder, poses, reference = upright
    motion = turn(axis) @ np.linalg.matrix_power(QUARTER, quarters)
    path = tmp_path_factory.mktemp("turned") / "brick.obj"
    trimesh.load(folder / "brick.obj", force="mesh", process=False).apply_transform(motion).export(path)
    told = rescore_poses(RescoreUnit(0, 0, motion @ poses, load_hand("panda"), resolve_spec(str(path), up=axis)))
    same = [i for i, (a, b) in enumerate(zip(reference, told.grasps)) if a.candidate == b.candidate and
            len(a.contacts) == len(b.contacts) and
            np.abs(np.sort(a.contacts.points @ motion[:3, :3].T, axis=0) -
                   np.sort(b.contacts.points, axis=0)).max() < SAME_CONTACTS]
    assert len(reference) == len(told.grasps) and len(same) >= len(reference) // 2
    want, got = (weight_measures([gs[i] for i in same], panda_model) for gs in (reference, told.grasps))
    assert np.allclose(got[:, :3], want[:, :3], rtol=0, atol=MEASURE_TOL)
    assert np.allclose(got[:, 3], want[:, 3], rtol=0, atol=P_HOLD_TOL)


def sweep_rows(db: Path) -> list[tuple[np.ndarray, np.ndarray]]:
    """(pose (4, 4), [com_height, gravity_arm, torque_per_mu, p_hold]) of every stored grasp."""
    with sqlite3.connect(db) as conn:
        return [(np.reshape(json.loads(r[0]), (4, 4)), np.array(r[1:], float)) for r in
                conn.execute("SELECT pose, com_height, gravity_arm, torque_per_mu, p_hold FROM grasps")]


def corresponding(a: Path, b: Path, motion: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The measures of the grasps of database ``a`` and ``b`` at the same pose, ``b``'s turned by ``motion``."""
    theirs = sweep_rows(b)
    return [(va, vb) for pa, va in sweep_rows(a) for pb, vb in theirs if np.abs(motion @ pa - pb).max() < 1e-9]


def assert_measured_alike(pairs: list[tuple[np.ndarray, np.ndarray]]) -> None:
    assert pairs and not np.isnan([v for pair in pairs for v in pair]).any()
    want, got = np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])
    assert np.allclose(got[:, :3], want[:, :3], rtol=0, atol=MEASURE_TOL)
    assert np.allclose(got[:, 3], want[:, 3], rtol=0, atol=P_HOLD_TOL)


def test_a_y_up_copy_swept_with_up_y_stores_the_upright_measures(tmp_path: Path, shipped_models: None) -> None:
    """The whole sweep: a Y-up copy under the same name, given --up +y, stores at each pose of the upright's
    the very com_height, gravity_arm, torque_per_mu and p_hold; without it, other ones."""
    for folder, motion in (("z", np.eye(4)), ("y", turn("+y"))):
        (tmp_path / folder).mkdir()
        brick().apply_transform(motion).export(tmp_path / folder / "brick.obj")
    run = ("--hand", "panda", "--quiet", *FAST[:6], "--approaches", "16")
    for db, path, extra in (("z.db", "z", ()), ("y.db", "y", ("--up", "+y")), ("side.db", "y", ())):
        code, _, err = grasp("generate", str(tmp_path / path / "brick.obj"), "--db", str(tmp_path / db), *run, *extra)
        assert code == 0, err
    assert_measured_alike(corresponding(tmp_path / "z.db", tmp_path / "y.db", turn("+y")))
    sideways = corresponding(tmp_path / "z.db", tmp_path / "side.db", turn("+y"))
    assert sideways and max(abs(a[0] - b[0]) for a, b in sideways) > 1e-3


def test_a_y_up_glb_of_the_mug_is_measured_like_the_mug_without_being_told(tmp_path: Path, shipped_models: None
                                                                              ) -> None:
    """glTF is Y-up: the mug turned to Y-up and saved as .glb (float32 positions, as glTF stores them) is
    measured by default like the same numbers in a Z-up OBJ (the built-in mug's frame)."""
    mug = load_object("mug").mesh
    y_up = (np.asarray(mug.vertices) @ TURNS["+y"].T).astype(np.float32).astype(float)
    for folder in ("y", "z"):
        (tmp_path / folder).mkdir()
    trimesh.Trimesh(y_up, mug.faces, process=False).export(tmp_path / "y" / "mug.glb")
    trimesh.Trimesh(y_up @ TURNS["+y"], mug.faces, process=False).export(tmp_path / "z" / "mug.obj", digits=17)
    run = ("--hand", "panda", "--quiet", *FAST[:6], "--approaches", "64")
    for folder, name in (("z", "mug.obj"), ("y", "mug.glb")):
        code, _, err = grasp("generate", str(tmp_path / folder / name), "--db", str(tmp_path / f"{folder}.db"), *run)
        assert code == 0, err
    with sqlite3.connect(tmp_path / "y.db") as conn:
        assert conn.execute("SELECT up FROM objects").fetchall() == [("+y",)]
    assert_measured_alike(corresponding(tmp_path / "z.db", tmp_path / "y.db", turn("+y")))
