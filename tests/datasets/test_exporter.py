"""Dataset export (acronym, graspgen, dexgraspnet, parquet, csv) and ACRONYM import."""

from __future__ import annotations

import csv
import json
import re
import sqlite3
from pathlib import Path

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner
from helpers import assert_close

import planner.cli
from planner import api
from planner.datasets import exporter
from planner.datasets.table import COLUMNS, COLUMNS_DOC
from planner.db import store
from planner.db.ranking import RankingRule
from planner.db.store import open_db
from planner.geometry.solid import load_object
from planner.plan.sweep import SweepSettings

h5py = pytest.importorskip("h5py")
pq = pytest.importorskip("pyarrow.parquet")

#: The database keeps poses to 7 decimals; rebuilding one from Euler angles
#: re-orthonormalises the rounded rotation, which moves it by about that much.
ROUNDED_TOL = 1e-6
#: Fingertip points of a closed Panda lie this close to the surface [m]
#: (PyBullet's margins are corrected to ~0.3 mm; 2 mm leaves room).
SURFACE_TOL = 0.002
#: Re-closing a stored pose reproduces its epsilon to within this fraction.
RESCORE_REL_TOL = 0.05
PANDA_PAD_Z = 0.1034  # ACRONYM's Panda: finger pads at z = 10.34 cm
FORMATS = ("acronym", "graspgen", "dexgraspnet", "parquet", "csv")
SMALL = SweepSettings(approaches=6, rolls=2, preshapes=("wide",), reach_placements=1)


def run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(planner.cli.main, list(args))
    return result.exit_code, result.stdout, result.stderr


@pytest.fixture(scope="module")
def db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """box and sphere for the Panda; the two best box grasps carry fake
    validation and robust rows (the best one 'dropped' despite force closure)."""
    path = tmp_path_factory.mktemp("export") / "g.db"
    summary = api.generate(["box", "sphere"], "panda", db_path=path, settings=SMALL, workers=1)
    assert not summary.failed and summary.force_closure > 0
    with sqlite3.connect(path) as conn:
        ids = [r[0] for r in conn.execute("SELECT id FROM grasps WHERE object = 'box' ORDER BY rank LIMIT 2")]
        for gid, success in zip(ids, (0, 1)):
            conn.execute("INSERT INTO validation VALUES (?, ?, 2, 0.001, 0.01, 0.002, 0.02, 0, '{}')", (gid, success))
            conn.execute("INSERT INTO robust VALUES (?, 0.05, 0.02, 25, 0, '{}')", (gid,))
    with open_db(path) as handle:  # a rule under which the fake validation leaves the ranking as it was
        handle.apply_rule(SAME_ORDER_RULE, force=True)
    return path


#: success does not weigh in, so the 'dropped' grasp keeps rank 1
SAME_ORDER_RULE = RankingRule(success_weight=0.0)


def export(db: Path, fmt: str, out: Path, *extra: str) -> Path:
    code, _, err = run("export", "--db", str(db), "--format", fmt, "--out", str(out), "--quiet", *extra)
    assert code == 0, err
    return out


def source_rows(db: Path, obj: str, where: str = "1") -> list[sqlite3.Row]:
    conn = sqlite3.connect(db)
    conn.row_factory = sqlite3.Row
    return conn.execute(f"SELECT * FROM grasps WHERE object = ? AND {where} ORDER BY rank, id", (obj,)).fetchall()


def pose(row: sqlite3.Row) -> np.ndarray:
    return np.array(json.loads(row["pose"])).reshape(4, 4)


def test_acronym_round_trip_is_lossless(db: Path, tmp_path: Path) -> None:
    out = export(db, "acronym", tmp_path / "h5")
    files = sorted(out.glob("*.h5"))
    assert [f.name for f in files] == ["box__panda.h5", "sphere__panda.h5"]
    fresh = tmp_path / "fresh.db"
    with open_db(fresh) as handle:  # the same ranking rule, so the same scores
        handle.apply_rule(SAME_ORDER_RULE)
    code, _, err = run("import", "--format", "acronym", *map(str, files), "--db", str(fresh))
    assert code == 0, err
    for obj in ("box", "sphere"):
        before = source_rows(db, obj)
        after = sqlite3.connect(fresh)
        after.row_factory = sqlite3.Row
        imported = after.execute("SELECT * FROM grasps WHERE object = ? ORDER BY candidate", (obj,)).fetchall()
        assert len(imported) == len(before) > 0
        for a, b in zip(before, imported):
            assert_close(pose(b), pose(a))
            for key in ("epsilon", "volume", "force_closure", "score", "width", "reachability", "manipulability",
                        "preshape", "roll", "standoff", "n_contacts", "links_touching"):
                assert a[key] == b[key], key
            for key in ("closed_joints", "open_joints", "contacts", "approach_point", "approach_dir"):
                assert json.loads(a[key]) == json.loads(b[key]), key
    # the shake-test and robust-epsilon results came back too
    sim = "SELECT g.candidate, v.success, r.mean, r.quantile FROM grasps g JOIN validation v ON v.grasp_id = g.id" \
          " JOIN robust r ON r.grasp_id = g.id WHERE g.object = 'box' ORDER BY g.candidate"
    assert sorted(tuple(r)[1:] for r in sqlite3.connect(fresh).execute(sim)) == \
        sorted(tuple(r)[1:] for r in sqlite3.connect(db).execute(sim))
    # the same files again: already imported, nothing added
    count = sqlite3.connect(fresh).execute("SELECT COUNT(*) FROM grasps").fetchone()[0]
    code, out_text, _ = run("import", *map(str, files), "--db", str(fresh))
    assert code == 0 and "skipped" in out_text
    assert sqlite3.connect(fresh).execute("SELECT COUNT(*) FROM grasps").fetchone()[0] == count


def fingertips(transforms: np.ndarray, width: np.ndarray, axis: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """ACRONYM's Panda drawn at the transforms: (N, 3) pad centres of both fingers."""
    offset = np.zeros((len(width), 4))
    offset[:, axis] = width / 2
    offset[:, 2], offset[:, 3] = PANDA_PAD_Z, 1.0
    flip = offset * [-1, -1, 1, 1]
    return np.einsum("nij,nj->ni", transforms, offset)[:, :3], np.einsum("nij,nj->ni", transforms, flip)[:, :3]


def grips(mesh: trimesh.Trimesh, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,) both pads on the surface, the object between them."""
    n = len(a)
    dist = trimesh.proximity.signed_distance(mesh, np.vstack([a, b, (a + b) / 2]))  # > 0 inside
    on_surface = (np.abs(dist[:n]) < SURFACE_TOL) & (np.abs(dist[n:2 * n]) < SURFACE_TOL)
    return on_surface & (dist[2 * n:] > 0)


def test_acronym_layout_read_by_plain_h5py(db: Path, tmp_path: Path) -> None:
    path = export(db, "acronym", tmp_path, "--object", "box") / "box__panda.h5"
    with h5py.File(path, "r") as f:  # what ACRONYM's own loaders read
        transforms = np.array(f["grasps/transforms"])
        success = np.array(f["grasps/qualities/flex/object_in_gripper"])
        mesh_file = f["object/file"][()].decode("utf-8")
        scale, gripper = f["object/scale"][()], f["gripper/type"][()].decode()
        width, fc = f["grasps/width"][()], f["grasps/qualities/force_closure"][()]
        label_source = f["grasps/qualities/flex/object_in_gripper"].attrs["label_source"]
        assert f["gripper/configuration"].shape == (1,) and f["object/inertia"].shape == (3, 3)
        assert_close(f["grasps/poses_hand_frame"][()] @ f["grasps/export_frame"][()], transforms)
    rows = source_rows(db, "box")
    assert transforms.shape == (len(rows), 4, 4) and transforms.dtype == np.float64
    assert success.dtype == np.int64 and set(success) <= {0, 1}
    assert (mesh_file, scale, gripper) == ("primitive:box", 1.0, "panda")
    # labels: simulated where validated (the best grasp was 'dropped'), else the force-closure flag
    assert label_source == "mixed" and success[0] == 0 and success[1] == 1
    assert list(success[2:]) == [r["force_closure"] for r in rows[2:]]
    mesh = load_object("box").mesh
    closure = fc == 1
    a, b = fingertips(transforms[closure], width[closure])
    assert closure.sum() > 0 and grips(mesh, a, b).all()
    a, b = fingertips(transforms[closure], width[closure], axis=1)  # fingers along y: not ACRONYM's frame
    assert not grips(mesh, a, b).all()


def test_label_source_simulation_when_every_grasp_was_validated(db: Path, tmp_path: Path) -> None:
    path = export(db, "acronym", tmp_path, "--object", "box", "--top", "2") / "box__panda.h5"
    with h5py.File(path, "r") as f:
        labels = f["grasps/qualities/flex/object_in_gripper"]
        assert labels.attrs["label_source"] == "simulation" and list(labels[()]) == [0, 1]
        assert list(f["grasps/qualities/simulated_success"][()]) == [0, 1]
        assert_close(f["grasps/qualities/flex/object_motion_during_shaking_angular"][()], [0.02, 0.02])
        assert_close(f["grasps/qualities/robust_epsilon_mean"][()], [0.05, 0.05])


def test_object_scale_turns_the_mesh_file_into_the_object() -> None:
    """What ACRONYM readers do with object/file and object/scale; the duck's
    URDF scales its mesh file by 0.05 on top of the registry's scale."""
    duck = load_object("duck")
    scale = duck.file_scale
    raw = trimesh.load(duck.source_file, force="mesh", process=False)
    assert scale == pytest.approx(0.05)
    assert_close(raw.extents * scale, duck.mesh.extents)


def test_graspgen_json_has_the_acronym_content(db: Path, tmp_path: Path) -> None:
    export(db, "acronym", tmp_path / "h5", "--object", "box")
    export(db, "graspgen", tmp_path / "json", "--object", "box")
    data = json.loads((tmp_path / "json" / "box__panda.json").read_text())
    with h5py.File(tmp_path / "h5" / "box__panda.h5", "r") as f:
        assert_close(np.array(data["grasps"]["transforms"]), f["grasps/transforms"][()])
        assert data["grasps"]["object_in_gripper"] == list(f["grasps/qualities/flex/object_in_gripper"][()])
        assert data["grasps"]["epsilon"] == list(f["grasps/qualities/epsilon"][()])
        assert data["object"]["scale"] == f["object/scale"][()] and data["object"]["file"] == "primitive:box"
    assert data["gripper"]["type"] == "panda" and data["gripper"]["configuration"] == [pytest.approx(0.08)]
    assert data["grasps"]["simulated_success"][:3] == [0, 1, -1]
    assert data["grasps"]["robust_epsilon_mean"][2] is None  # NaN -> null
    assert {"point", "normal", "link"} <= set(data["grasps"]["contacts"][0][0])


def documented_columns() -> list[str]:
    return [name for line in COLUMNS_DOC.splitlines()[2:] for name in re.findall(r"`([a-z_0-9]+)`",
                                                                                  line.split("|")[1])]


def test_tables_have_one_row_per_grasp_and_the_documented_columns(db: Path, tmp_path: Path) -> None:
    total = sqlite3.connect(db).execute("SELECT COUNT(*) FROM grasps").fetchone()[0]
    assert documented_columns() == COLUMNS
    table = pq.read_table(export(db, "parquet", tmp_path) / "grasps.parquet")
    assert table.num_rows == total and table.column_names == COLUMNS
    rows = table.to_pylist()
    box = source_rows(db, "box")
    first = next(r for r in rows if r["object"] == "box" and r["rank"] == 1)
    assert_close([first[f"pose_{i}{j}"] for i in range(4) for j in range(4)], pose(box[0]).ravel())
    assert first["validation_success"] == 0 and first["robust_samples"] == 25 and first["object_mass"] > 0
    assert json.loads(first["closed_joints"]) == json.loads(box[0]["closed_joints"])
    unvalidated = [r for r in rows if r["rank"] > 2 or r["object"] != "box"]
    assert all(r["validation_success"] is None and r["robust_epsilon_mean"] is None for r in unvalidated)
    with open(export(db, "csv", tmp_path) / "grasps.csv", newline="") as fh:
        lines = list(csv.reader(fh))
    assert lines[0] == COLUMNS and len(lines) == total + 1
    by_id = {int(r[COLUMNS.index("grasp_id")]): dict(zip(COLUMNS, r)) for r in lines[1:]}
    assert float(by_id[box[0]["id"]]["epsilon"]) == box[0]["epsilon"]  # full precision
    assert by_id[box[-1]["id"]]["validation_success"] == ""


def test_dexgraspnet_npy_loads_into_documented_dicts(db: Path, tmp_path: Path) -> None:
    from scipy.spatial.transform import Rotation

    export(db, "dexgraspnet", tmp_path, "--object", "box")
    data = np.load(tmp_path / "box__panda.npy", allow_pickle=True)
    rows = source_rows(db, "box")
    assert data.dtype == object and len(data) == len(rows)
    wrist = {"WRJTx", "WRJTy", "WRJTz", "WRJRx", "WRJRy", "WRJRz"}
    for grasp, row in zip(data, rows):
        qpos = grasp["qpos"]
        assert set(qpos) == wrist | {"panda_finger_joint1", "panda_finger_joint2"}
        assert grasp["scale"] == 1.0 and grasp["epsilon"] == row["epsilon"]
        rebuilt = np.eye(4)
        rebuilt[:3, :3] = Rotation.from_euler("xyz", [qpos["WRJRx"], qpos["WRJRy"], qpos["WRJRz"]]).as_matrix()
        rebuilt[:3, 3] = [qpos["WRJTx"], qpos["WRJTy"], qpos["WRJTz"]]
        assert_close(rebuilt, pose(row), ROUNDED_TOL)
        assert qpos["panda_finger_joint1"] == json.loads(row["closed_joints"])["panda_finger_joint1"]


@pytest.mark.parametrize("args, where", [
    (["--min-epsilon", "0.05"], "epsilon >= 0.05"),
    (["--top", "3"], "rank <= 3"),
    (["--object", "sphere"], "object = 'sphere'"),
    (["--object", "box", "--hand", "panda", "--top", "2", "--min-epsilon", "0.01"],
     "object = 'box' AND rank <= 2 AND epsilon >= 0.01"),
])
def test_filters_restrict_rows(db: Path, tmp_path: Path, args: list[str], where: str) -> None:
    table = pq.read_table(export(db, "parquet", tmp_path, *args) / "grasps.parquet")
    ids = sorted(r[0] for r in sqlite3.connect(db).execute(f"SELECT id FROM grasps WHERE {where}"))
    assert 0 < len(ids) < sqlite3.connect(db).execute("SELECT COUNT(*) FROM grasps").fetchone()[0]
    assert sorted(table.column("grasp_id").to_pylist()) == ids


@pytest.mark.parametrize("args, code, message", [
    (["export", "--db", "nowhere.db", "--format", "acronym", "--out", "o"], 3, "no such database"),
    (["export", "--db", "{db}", "--format", "tfrecord", "--out", "o"], 2, "unknown format 'tfrecord'"),
    (["export", "--db", "{db}", "--format", "csv", "--out", "o", "--object", "teapot"], 2, "no grasps of object"),
    (["export", "--db", "{db}", "--format", "csv", "--out", "o", "--top", "0"], 2, "--top must be at least 1"),
    (["import", "missing.h5", "--db", "i.db"], 2, "missing.h5: file not found"),
    (["import", "{db}", "--db", "i.db"], 2, "not an HDF5 file"),
    (["import", "--format", "npy", "x.h5", "--db", "i.db"], 2, "unknown import format 'npy'"),
])
def test_errors_are_one_line_with_exit_code(db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                            args: list[str], code: int, message: str) -> None:
    monkeypatch.chdir(tmp_path)
    got, _, err = run(*(a.format(db=db) for a in args))
    assert got == code and message in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def read_all(path: Path) -> object:
    if path.suffix == ".h5":
        with h5py.File(path, "r") as f:
            out: dict = {}
            f.visititems(lambda k, v: out.__setitem__(k, v[()]) if isinstance(v, h5py.Dataset) else None)
            return out
    if path.suffix == ".npy":
        return np.load(path, allow_pickle=True).tolist()
    if path.suffix == ".parquet":
        return pq.read_table(path).to_pylist()
    return path.read_text()


def test_export_streams_in_batches(db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    expected = {fmt: {p.name: read_all(p) for p in export(db, fmt, tmp_path / fmt).iterdir()} for fmt in FORMATS}
    sizes: list[int] = []
    decode = store._grasps
    monkeypatch.setattr(exporter, "BATCH_SIZE", 2)
    monkeypatch.setattr(store, "_grasps", lambda rows: sizes.append(len(rows)) or decode(rows))
    for fmt in FORMATS:
        got = {p.name: read_all(p) for p in export(db, fmt, tmp_path / f"{fmt}-2").iterdir()}
        assert got.keys() == expected[fmt].keys()
        for name, value in got.items():
            np.testing.assert_equal(value, expected[fmt][name])
    assert max(sizes) == 2 and len(sizes) > len(FORMATS) * 4


def test_foreign_acronym_file_is_rescored(db: Path, tmp_path: Path) -> None:
    """A file with only ACRONYM's datasets: the hand is closed at each pose
    and the grasp evaluated again; force-closure grasps come back as such."""
    path = export(db, "acronym", tmp_path / "ours", "--object", "box") / "box__panda.h5"
    foreign = tmp_path / "foreign" / "grasps" / "Box_0.h5"
    foreign.parent.mkdir(parents=True)
    (tmp_path / "foreign" / "meshes").mkdir()
    load_object("box").mesh.export(tmp_path / "foreign" / "meshes" / "crate.obj")
    with h5py.File(path, "r") as src, h5py.File(foreign, "w") as dst:
        keep = src["grasps/qualities/force_closure"][()] == 1
        dst["gripper/type"], dst["gripper/configuration"] = "franka_panda", [0.08]
        dst["object/file"], dst["object/scale"] = "meshes/crate.obj", 1.0
        for key in ("mass", "friction", "density", "volume", "com", "inertia"):
            dst[f"object/{key}"] = src[f"object/{key}"][()]
        dst["grasps/transforms"] = src["grasps/transforms"][()][keep]
        dst["grasps/qualities/flex/object_in_gripper"] = np.ones(keep.sum(), np.int64)
        epsilon = src["grasps/qualities/epsilon"][()][keep]
    fresh = tmp_path / "fresh.db"
    code, out, err = run("import", str(foreign), "--db", str(fresh))
    assert code == 0 and "re-scored" in out, err
    conn = sqlite3.connect(fresh)
    rows = conn.execute("SELECT candidate, epsilon, force_closure, object FROM grasps ORDER BY candidate").fetchall()
    assert {r[3] for r in rows} == {"crate"} and len(rows) >= 0.8 * len(epsilon)
    close = [r[2] == 1 and abs(r[1] - epsilon[r[0]]) <= RESCORE_REL_TOL * epsilon[r[0]] for r in rows]
    assert np.mean(close) >= 0.8
    settings = json.loads(conn.execute("SELECT settings FROM units").fetchone()[0])
    assert settings["import"] == "acronym" and len(settings["sha256"]) == 64 and settings["rescore"]


def test_unknown_gripper_needs_hand(db: Path, tmp_path: Path) -> None:
    path = tmp_path / "robotiq.h5"
    with h5py.File(path, "w") as f:
        f["gripper/type"], f["grasps/transforms"] = "robotiq_2f85", np.tile(np.eye(4), (2, 1, 1))
        f["object/file"], f["object/scale"] = "nowhere.obj", 1.0
    code, _, err = run("import", str(path), "--db", str(tmp_path / "i.db"))
    assert code == 2 and "gripper type 'robotiq_2f85' is not a known hand; pass --hand" in err
    code, _, err = run("import", str(path), "--db", str(tmp_path / "i.db"), "--hand", "panda")
    assert code == 2 and "object/file 'nowhere.obj' not found" in err
