"""Session fixtures: a test cache, and the small databases several test
packages read (each built once per session)."""

import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from helpers import FAST, REFERENCE_ARGS, REFERENCE_OBJECTS, content, grasp  # noqa: E402


@pytest.fixture(autouse=True, scope="session")
def _cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Keep test caches out of the user's home unless asked otherwise."""
    os.environ.setdefault("GRASP_CACHE", str(tmp_path_factory.mktemp("cache")))


@pytest.fixture(autouse=True, scope="session")
def _no_shipped_model() -> None:
    """Tests score by the rule's formula: the project's shipped p_hold models
    (calibration/<hand>.toml) are switched off, in this process and in every
    process it starts, except where a test puts them back (``shipped_models``).
    A model stored in a test's database still applies."""
    from planner.calibration.model import SHIPPED_ENV

    os.environ[SHIPPED_ENV] = "0"


@pytest.fixture
def shipped_models(monkeypatch: pytest.MonkeyPatch) -> None:
    """The shipped p_hold models, as a user's database sees them."""
    from planner.calibration.model import SHIPPED_ENV

    monkeypatch.setenv(SHIPPED_ENV, "1")


@pytest.fixture(scope="session")
def box_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``grasp generate box --hand panda`` with a small sweep (read-only for tests: copy to change it)."""
    db = tmp_path_factory.mktemp("box") / "g.db"
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), "--quiet", *FAST)
    assert code == 0, err
    return db


@pytest.fixture(scope="session")
def reference_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The reference batch, built in one uninterrupted serial run."""
    db = tmp_path_factory.mktemp("reference") / "ref.db"
    code, _, err = grasp("generate", *REFERENCE_OBJECTS, "--hand", "panda", "--db", str(db), *REFERENCE_ARGS)
    assert code == 0, err
    assert content(db)
    return db


@pytest.fixture(scope="session")
def validated_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Box and sphere, the three best grasps of each shake-tested (PyBullet's trial) with two robust samples."""
    db = tmp_path_factory.mktemp("validated") / "g.db"
    code, _, err = grasp("generate", "box", "sphere", "--hand", "panda", "--db", str(db), "--quiet", *FAST)
    assert code == 0, err
    code, _, err = grasp("validate", "--db", str(db), "--top", "3", "--robust", "2", "--workers", "1",
                         "--engine", "pybullet")
    assert code == 0, err
    return db



@pytest.fixture(scope="session")
def stored_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Objects whose database name the registry alone does not give back:
    the duck generated at ``--scale 1.5`` (stored as 'duck'), a user mesh in
    millimetres (``capsule.obj``, ``--scale 0.001``), and the box for the
    Panda and for the PR2 (one object, two hands)."""
    import trimesh

    folder = tmp_path_factory.mktemp("stored")
    mesh = folder / "meshes_in_mm" / "capsule.obj"
    mesh.parent.mkdir()
    trimesh.creation.capsule(height=40.0, radius=20.0).export(mesh)
    db = folder / "g.db"
    # the duck on rays: 6 antipodal points on the 1.5x duck may all be wider than the Panda opens
    for args in (["duck", "--hand", "panda", "--scale", "1.5", "--sampler", "surface"],
                 [str(mesh), "--hand", "panda", "--scale", "0.001"],
                 ["box", "--hand", "panda"], ["box", "--hand", "pr2"]):
        code, _, err = grasp("generate", *args, "--db", str(db), "--quiet", *FAST)
        assert code == 0, err
    return db
