"""Bad inputs, crashes and concurrency never lose or corrupt a database, and
every mistake gets a one-line message naming the input."""

import os
import random
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planner import assets
from planner.cli import main
from planner.db.schema import SCHEMA, SCHEMA_VERSION
from planner.db.store import open_db
from planner.errors import ConfigError, DatabaseError, MeshError, PlannerError
from planner.geometry import mesh as meshes
from planner.specs.hands import hands_dir, load_folder

FAST = ["--approaches", "4", "--rolls", "2", "--preshapes", "wide", "--workers", "1", "--reach-placements", "1",
        "--quiet"]


def cli(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(main, list(args))
    return result.exit_code, result.stderr


def one_line_error(code: int, err: str, expected_code: int, *needles: str) -> None:
    assert code == expected_code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err


@pytest.fixture(scope="module")
def good_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    db = tmp_path_factory.mktemp("rel") / "good.db"
    code, err = cli("generate", "box", "--hand", "panda", "--db", str(db), *FAST)
    assert code == 0, err
    return db


def snapshot(db: Path) -> list[tuple]:
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT * FROM grasps ORDER BY id").fetchall()


# -- inputs -------------------------------------------------------------------
def write_obj(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize("name, content, needle", [
    ("missing.obj", None, "file not found"),
    ("empty.obj", "", "empty"),
    ("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n", "NaN"),
    ("inf.obj", "v 0 0 0\nv inf 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n", "NaN or infinite"),
    ("flat.obj", "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0.1 0.1 0\nf 1 2 3\nf 2 4 3\n", "volume"),
])
def test_broken_mesh_files_one_line_and_db_untouched(good_db: Path, tmp_path: Path, name: str, content: str | None,
                                                     needle: str) -> None:
    path = tmp_path / name
    if content is not None:
        write_obj(path, content)
    before = snapshot(good_db)
    code, err = cli("generate", str(path), "--hand", "panda", "--db", str(good_db), *FAST)
    one_line_error(code, err, 2, name, needle)
    assert snapshot(good_db) == before


def test_millimetres_passed_as_metres(tmp_path: Path) -> None:
    path = tmp_path / "mm.stl"
    trimesh.creation.box(extents=[50.0, 40.0, 80.0]).export(path)
    code, err = cli("generate", str(path), "--hand", "panda", "--db", str(tmp_path / "x.db"), *FAST)
    one_line_error(code, err, 2, "millimetres", "--scale 0.001")
    assert not (tmp_path / "x.db").exists()
    code, err = cli("generate", str(path), "--scale", "0.001", "--hand", "panda", "--db", str(tmp_path / "x.db"),
                    *FAST)
    assert code == 0, err


def test_smaller_than_a_millimetre(tmp_path: Path) -> None:
    path = tmp_path / "tiny.stl"
    trimesh.creation.box(extents=[5e-4, 5e-4, 5e-4]).export(path)
    code, err = cli("generate", str(path), "--hand", "panda", "--db", str(tmp_path / "x.db"), *FAST)
    one_line_error(code, err, 2, "smaller than a millimetre")


def test_open_mesh_is_repaired_and_nonmanifold_refused(tmp_path: Path) -> None:
    box = trimesh.creation.box(extents=[0.04, 0.04, 0.04])
    open_box = trimesh.Trimesh(box.vertices, box.faces[2:], process=False)
    assert meshes.checked_solid(open_box, "open").is_watertight
    # three triangles on one edge (a fin through a box): non-manifold, cannot be closed
    fin_v = np.vstack([box.vertices, [[0.0, 0.0, 0.1]]])
    edge = box.edges_unique[0]
    fin = trimesh.Trimesh(fin_v, np.vstack([box.faces, [[edge[0], edge[1], len(fin_v) - 1]]]), process=False)
    with pytest.raises(MeshError):
        meshes.checked_solid(fin, "fin")


def test_millions_of_faces_refused_before_work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(meshes, "MAX_FACES", 1000)
    big = trimesh.creation.icosphere(subdivisions=4, radius=0.03)  # 5,120 faces
    path = tmp_path / "big.stl"
    big.export(path)
    with pytest.raises(MeshError, match="simplify it below 1,000"):
        meshes.load_mesh_file(path)
    monkeypatch.setattr(meshes, "MAX_FILE_BYTES", 10)
    with pytest.raises(MeshError, match="too large"):
        meshes.load_mesh_file(path)


@pytest.mark.parametrize("args, needle", [
    (["generate", "teapot", "--hand", "panda"], "Available objects: box, bunny"),
    (["generate", "box", "--hand", "shadow"], "Available hands: allegro, barrett, panda, pr2"),
    (["generate", "box", "--hand", "panda", "--preshapes", "fist"], "Available preshapes: half, wide"),
    (["generate", "box", "--hand", "../objects"], "folder name"),
    (["best", "box", "--hand", "panda", "--object-pose", "1,2,3"], "7 finite numbers"),
    (["generate", "box", "--hand", "panda", "--reach-weight", "3"], "--reach-weight must be in [0, 1]"),
])
def test_unknown_names_list_the_valid_ones(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[str],
                                           needle: str) -> None:
    monkeypatch.chdir(tmp_path)
    code, err = cli(*args)
    assert code in (2, 3), err
    one_line_error(code, err, code, needle)


def test_builtin_locators_cannot_escape(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="outside"):
        assets.resolve("../../../etc/passwd", tmp_path, "objects.toml [evil] field 'source'")
    with pytest.raises(ConfigError, match="outside"):
        assets.resolve("pybullet_data:../../../../etc/passwd", tmp_path, "x")
    with pytest.raises(ConfigError, match="absolute"):
        assets.resolve("/etc/passwd", tmp_path, "x")


def hand_copy(tmp_path: Path) -> Path:
    folder = tmp_path / "panda"
    shutil.copytree(hands_dir() / "panda", folder)
    return folder


def test_malformed_toml_names_the_file(tmp_path: Path) -> None:
    folder = hand_copy(tmp_path)
    (folder / "hand.toml").write_text("approach = [0, 0, 1\n")
    with pytest.raises(ConfigError, match=r"hand\.toml: malformed TOML"):
        load_folder(folder)


def test_urdf_with_missing_mesh_and_unknown_joint(tmp_path: Path) -> None:
    folder = hand_copy(tmp_path)
    source = assets.pybullet_data_root() / "franka_panda" / "panda.urdf"
    text = source.read_text().replace("meshes/collision/finger.obj", "meshes/collision/nope.obj")
    (folder / "hand.urdf").write_text(text.replace("package://", str(source.parent) + "/"))
    toml = folder / "hand.toml"
    toml.write_text(toml.read_text().replace('urdf = "pybullet_data:franka_panda/panda.urdf"\nroot',
                                             'urdf = "hand.urdf"\nroot'))
    with pytest.raises(ConfigError, match="mesh file not found: .*nope.obj"):
        load_folder(folder)
    (folder / "hand.urdf").write_text(source.read_text().replace("package://", str(source.parent) + "/"))
    toml.write_text(toml.read_text().replace('name = "panda_finger_joint1"', 'name = "thumb_joint"'))
    with pytest.raises(ConfigError, match="thumb_joint.*hand.urdf"):
        load_folder(folder)


# -- database files -----------------------------------------------------------------
def test_not_sqlite_newer_schema_and_read_only(good_db: Path, tmp_path: Path) -> None:
    junk = tmp_path / "junk.db"
    junk.write_bytes(b"\x00not a database at all" * 100)
    code, err = cli("generate", "box", "--hand", "panda", "--db", str(junk), *FAST)
    one_line_error(code, err, 3, "not an SQLite database")
    newer = tmp_path / "newer.db"
    shutil.copy(good_db, newer)
    with sqlite3.connect(newer) as conn:
        conn.execute("UPDATE meta SET value = ? WHERE key = 'schema_version'", (str(SCHEMA_VERSION + 5),))
    code, err = cli("best", "box", "--hand", "panda", "--db", str(newer))
    one_line_error(code, err, 3, "newer than this planner")
    with open_db(good_db, create=False, readonly=True) as db:  # a read-only handle stands in for a read-only file
        with pytest.raises(DatabaseError, match="read-only"):
            db.set_meta("ranking", "{}")
    assert snapshot(good_db)


def test_older_schema_is_migrated_after_a_backup(tmp_path: Path) -> None:
    old = tmp_path / "old.db"
    with sqlite3.connect(old) as conn:
        for statement in filter(str.strip, SCHEMA.split(";")):
            conn.execute(statement)
        conn.execute("INSERT INTO meta VALUES ('schema_version', '1')")
        conn.execute("INSERT INTO objects VALUES ('o', 's', 1, 'h', 1, 0.5, 1, 1, '[]', '[]', 0.1, '[]')")
    with open_db(old) as db:
        assert db.meta("schema_version") == str(SCHEMA_VERSION)
    with sqlite3.connect(old) as conn:
        assert conn.execute("SELECT name FROM objects").fetchall() == [("o",)]
    backups = list(tmp_path.glob("old.db.v1.*.bak"))
    assert len(backups) == 1
    with sqlite3.connect(backups[0]) as conn:
        assert conn.execute("SELECT value FROM meta").fetchone()[0] == "1"


def test_db_check_reports_corruption(good_db: Path, tmp_path: Path) -> None:
    code, _ = cli("db", "check", "--db", str(good_db))
    assert code == 0
    broken = tmp_path / "broken.db"
    shutil.copy(good_db, broken)
    with sqlite3.connect(broken) as conn:
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    data = bytearray(broken.read_bytes())
    page = 4096
    for i in range(2 * page + 100, min(len(data), 5 * page), 7):
        data[i] ^= 0x5A
    broken.write_bytes(bytes(data))
    code, err = cli("db", "check", "--db", str(broken))
    assert code == 3 and "Traceback" not in err


# -- crashes and concurrency ---------------------------------------------------------------
def gen_cmd(db: Path) -> list[str]:
    return [sys.executable, "-m", "planner.cli", "generate", "box", "sphere", "--hand", "panda", "--db", str(db),
            "--approaches", "8", "--chunk", "2", "--rolls", "2", "--preshapes", "wide", "--reach-placements", "1",
            "--workers", "1", "--quiet"]


def content(db: Path) -> list[tuple]:
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT object, candidate, pose, epsilon, score, rank FROM grasps"
                            " ORDER BY object, candidate").fetchall()


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> list[tuple]:
    db = tmp_path_factory.mktemp("ref") / "ref.db"
    subprocess.run(gen_cmd(db), check=True)
    return content(db)


def test_kill_9_at_random_moments_then_resume(reference: list[tuple], tmp_path: Path) -> None:
    rng = random.Random(1234)
    db = tmp_path / "k.db"
    for _ in range(3):
        proc = subprocess.Popen(gen_cmd(db), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(rng.uniform(1.0, 6.0))
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        if db.exists():
            with open_db(db, create=False, readonly=True) as handle:
                assert handle.integrity_check() == []
    subprocess.run(gen_cmd(db), check=True, stdout=subprocess.DEVNULL)
    assert content(db) == reference


def test_two_writers_second_refuses(tmp_path: Path) -> None:
    db = tmp_path / "two.db"
    first = subprocess.Popen(gen_cmd(db), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.time() + 60
        while not Path(str(db) + ".lock").exists() and time.time() < deadline:
            time.sleep(0.05)
        time.sleep(0.5)
        second = subprocess.run(gen_cmd(db), capture_output=True, text=True)
        if first.poll() is None:
            assert second.returncode == 3
            assert "another `grasp generate` is writing" in second.stderr
    finally:
        first.wait()
    assert open_db(db, create=False, readonly=True).integrity_check() == []


# -- property / fuzz tests --------------------------------------------------------------
coords = st.one_of(st.floats(min_value=-1.0, max_value=1.0, width=32),
                   st.sampled_from([float("nan"), float("inf"), -float("inf")]))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(vertices=st.lists(st.tuples(coords, coords, coords), min_size=0, max_size=12),
       faces=st.lists(st.tuples(st.integers(0, 11), st.integers(0, 11), st.integers(0, 11)), max_size=20),
       scale=st.sampled_from([0.001, 0.05, 1.0]))
def test_fuzz_meshes_load_or_refuse_cleanly(vertices, faces, scale) -> None:  # type: ignore[no-untyped-def]
    v = np.array(vertices, float).reshape(-1, 3) * scale
    f = np.array([t for t in faces if max(t) < len(v)], int).reshape(-1, 3)
    try:
        solid = meshes.checked_solid(trimesh.Trimesh(v, f, process=False), "fuzz")
    except MeshError:
        return
    assert solid.is_watertight and solid.volume > 0 and np.all(np.isfinite(solid.vertices))


toml_values = st.one_of(st.integers(-5, 5), st.floats(allow_nan=True), st.text(max_size=8), st.booleans(),
                        st.lists(st.floats(-2, 2), max_size=4))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(key=st.sampled_from(["approach", "tcp", "root_link", "contact_links", "centering", "roll_symmetry",
                            "urdf", "distance_offset"]), value=toml_values, garbage=st.text(max_size=30))
def test_fuzz_hand_toml_loads_or_refuses_cleanly(tmp_path_factory, key, value, garbage) -> None:  # type: ignore[no-untyped-def]
    import tomllib

    folder = tmp_path_factory.mktemp("fuzz") / "panda"
    shutil.copytree(hands_dir() / "panda", folder)
    toml = folder / "hand.toml"
    data = tomllib.loads(toml.read_text())
    data[key] = value
    lines = [f"{k} = {_toml(v)}" for k, v in data.items() if not isinstance(v, (dict, list)) or
             (isinstance(v, list) and not any(isinstance(x, dict) for x in v))]
    text = "\n".join(lines) + "\n" + "\n".join(toml.read_text().split("\n[[joints]]", 1)[1:2] and
                                               ["[[joints]]" + toml.read_text().split("\n[[joints]]", 1)[1]])
    toml.write_text(text + ("\n# " + garbage.replace("\n", " ") if garbage else ""))
    try:
        load_folder(folder)
    except PlannerError:
        pass


def _toml(value: object) -> str:
    import json

    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and not np.isfinite(value):
        return "nan" if np.isnan(value) else ("inf" if value > 0 else "-inf")
    return json.dumps(value)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(max_size=200))
def test_fuzz_arbitrary_toml_text_is_refused_cleanly(tmp_path_factory, text: str) -> None:  # type: ignore[no-untyped-def]
    folder = tmp_path_factory.mktemp("fuzztext") / "panda"
    shutil.copytree(hands_dir() / "panda", folder)
    (folder / "hand.toml").write_text(text)
    with pytest.raises(PlannerError):
        load_folder(folder)
    presets = folder / "preshapes.toml"
    presets.write_text(text)
    with pytest.raises(PlannerError):
        from planner.specs.toml import Fields, read_toml

        Fields(read_toml(presets), str(presets)).tables("preshape")
