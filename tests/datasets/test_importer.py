"""Import: our ACRONYM files come back losslessly, foreign ones are re-scored."""

from __future__ import annotations

import json
import shutil
import sqlite3
from collections import Counter
from dataclasses import fields, is_dataclass, replace
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import assert_close, grasp, one_line_error

from planner.datasets import importer
from planner.datasets.importer import import_files
from planner.db.store import open_db
from planner.geometry.solid import load_object
from planner.record.contacts import HandContacts
from planner.specs.hands import load_hand
from tests import crash_units
from tests.datasets.support import SAME_ORDER_RULE, export, pose, source_rows

#: Re-closing a stored pose reproduces its epsilon to within this fraction.
RESCORE_REL_TOL = 0.05
#: PyBullet's contacts depend slightly on what the same world simulated
#: before, so a file re-scored in one world or in several gets epsilons that
#: differ by this fraction at most (measured: 5e-5).
SIM_HISTORY_REL = 1e-3
PANDA = load_hand("panda")


def test_acronym_round_trip_is_lossless(db: Path, tmp_path: Path) -> None:
    out = export(db, "acronym", tmp_path / "h5")
    files = sorted(out.glob("*.h5"))
    assert [f.name for f in files] == ["box__panda.h5", "sphere__panda.h5"]
    fresh = tmp_path / "fresh.db"
    with open_db(fresh) as handle:  # the same ranking rule, so the same scores
        handle.apply_rule(SAME_ORDER_RULE)
    code, _, err = grasp("import", "--format", "acronym", *map(str, files), "--db", str(fresh))
    assert code == 0, err
    for obj in ("box", "sphere"):
        before = source_rows(db, obj)
        after = sqlite3.connect(fresh)
        after.row_factory = sqlite3.Row
        imported = after.execute("SELECT * FROM grasps WHERE object = ? ORDER BY rank, id", (obj,)).fetchall()
        assert len(imported) == len(before) > 0
        for a, b in zip(before, imported):
            assert_close(pose(b), pose(a))
            for key in ("epsilon", "volume", "force_closure", "score", "width", "reachability", "manipulability",
                        "preshape", "roll", "standoff", "n_contacts", "links_touching", "candidate", "seed"):
                assert a[key] == b[key], key
            for key in ("contacts", "approach_point", "approach_dir"):
                assert json.loads(a[key]) == json.loads(b[key]), key
            for key in ("closed_joints", "open_joints"):  # the stored joints exactly, named as stored: the file's
                assert json.loads(b[key]) == json.loads(a[key]), key  # (N, J) matrix adds a mimic left out
    # the shake-test and robust-epsilon results came back too
    sim = "SELECT g.candidate, v.success, r.mean, r.quantile FROM grasps g JOIN validation v ON v.grasp_id = g.id" \
          " JOIN robust r ON r.grasp_id = g.id WHERE g.object = 'box' ORDER BY g.candidate"
    assert sorted(tuple(r)[1:] for r in sqlite3.connect(fresh).execute(sim)) == \
        sorted(tuple(r)[1:] for r in sqlite3.connect(db).execute(sim))
    # the same files again: already imported, nothing added
    count = sqlite3.connect(fresh).execute("SELECT COUNT(*) FROM grasps").fetchone()[0]
    code, out_text, _ = grasp("import", *map(str, files), "--db", str(fresh))
    assert code == 0 and "skipped" in out_text
    assert sqlite3.connect(fresh).execute("SELECT COUNT(*) FROM grasps").fetchone()[0] == count


def foreign_file(db: Path, tmp_path: Path, obj: str, mesh: str) -> tuple[Path, np.ndarray]:
    """A file with only ACRONYM's datasets, made of our force-closure grasps
    of ``obj`` (its mesh saved as ``meshes/<mesh>.obj``); and their epsilon."""
    path = export(db, "acronym", tmp_path / f"ours_{obj}", "--object", obj) / f"{obj}__panda.h5"
    foreign = tmp_path / "foreign" / "grasps" / f"{mesh}.h5"
    foreign.parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / "foreign" / "meshes").mkdir(exist_ok=True)
    load_object(obj).mesh.export(tmp_path / "foreign" / "meshes" / f"{mesh}.obj")
    with h5py.File(path, "r") as src, h5py.File(foreign, "w") as dst:
        keep = src["grasps/qualities/force_closure"][()] == 1
        dst["gripper/type"], dst["gripper/configuration"] = "franka_panda", [0.08]
        dst["object/file"], dst["object/scale"] = f"meshes/{mesh}.obj", 1.0
        for key in ("mass", "friction", "density", "volume", "com", "inertia"):
            dst[f"object/{key}"] = src[f"object/{key}"][()]
        dst["grasps/transforms"] = src["grasps/transforms"][()][keep]
        dst["grasps/qualities/flex/object_in_gripper"] = np.ones(keep.sum(), np.int64)
        epsilon = src["grasps/qualities/epsilon"][()][keep]
    return foreign, epsilon


def test_foreign_acronym_file_is_rescored(db: Path, tmp_path: Path) -> None:
    """A file with only ACRONYM's datasets: the hand is closed at each pose
    and the grasp evaluated again; force-closure grasps come back as such."""
    foreign, epsilon = foreign_file(db, tmp_path, "box", "crate")
    fresh = tmp_path / "fresh.db"
    code, out, err = grasp("import", str(foreign), "--db", str(fresh))
    assert code == 0 and "re-scored" in out, err
    conn = sqlite3.connect(fresh)
    rows = conn.execute("SELECT candidate, epsilon, force_closure, object FROM grasps ORDER BY candidate").fetchall()
    assert {r[3] for r in rows} == {"crate"} and len(rows) >= 0.8 * len(epsilon)
    close = [r[2] == 1 and abs(r[1] - epsilon[r[0]]) <= RESCORE_REL_TOL * epsilon[r[0]] for r in rows]
    assert np.mean(close) >= 0.8
    settings = json.loads(conn.execute("SELECT settings FROM units").fetchone()[0])
    assert settings["import"] == "acronym" and len(settings["sha256"]) == 64 and settings["rescore"]


def test_a_relative_path_finds_acronyms_meshes_folder(db: Path, tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """`cd grasps && grasp import crate.h5`: Path('crate.h5').parent.parent is '.', so meshes/ one folder up was
    looked for at meshes/crate.obj twice."""
    foreign, _ = foreign_file(db, tmp_path, "box", "crate")
    monkeypatch.chdir(foreign.parent)
    code, out, err = grasp("import", foreign.name, "--db", str(tmp_path / "fresh.db"))
    assert code == 0 and "re-scored" in out, err
    (tmp_path / "foreign" / "meshes" / "crate.obj").unlink()
    code, _, err = grasp("import", foreign.name, "--db", str(tmp_path / "other.db"))
    one_line_error(code, err, 2, "crate.h5: object/file 'meshes/crate.obj' not found",
                   str(tmp_path / "foreign" / "meshes" / "crate.obj"), "pass --object NAME or a mesh path")


def imported(db: Path) -> list[tuple]:
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT object, candidate, pose, closed_joints, contacts, epsilon, volume, force_closure,"
                            " score, rank FROM grasps ORDER BY object, candidate").fetchall()


@pytest.fixture(scope="module")
def two_foreign_files(db: Path, tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    folder = tmp_path_factory.mktemp("foreign")
    return [foreign_file(db, folder, "box", "crate")[0], foreign_file(db, folder, "sphere", "ball")[0]]


def test_rescoring_in_workers_gives_the_same_grasps_in_input_order(two_foreign_files: list[Path], tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    one, many = tmp_path / "one.db", tmp_path / "many.db"
    import_files(two_foreign_files, one, workers=1)
    monkeypatch.setattr(importer, "RESCORE_CHUNK", 4)  # several units per file, in two workers
    split = import_files(two_foreign_files, many, workers=2)
    assert [r.path for r in split] == two_foreign_files and [r.object for r in split] == ["crate", "ball"]
    assert all(r.error is None and r.rescored and r.grasps > 0 for r in split)
    a, b = imported(one), imported(many)
    assert [(r[0], r[1], r[7]) for r in a] == [(r[0], r[1], r[7]) for r in b]  # the same poses kept, same closure
    assert np.allclose([r[5] for r in b], [r[5] for r in a], rtol=SIM_HISTORY_REL, atol=0)
    again = tmp_path / "again.db"
    import_files(two_foreign_files, again, workers=1)  # the same split, in this process: identical
    assert imported(again) == b


def test_a_file_whose_rescoring_kills_its_workers_is_recorded_failed_and_retried(
        two_foreign_files: list[Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    db = tmp_path / "crash.db"
    with monkeypatch.context() as patch:
        patch.setattr(importer, "rescore_poses", crash_units.rescore_segfaults_on_first_file)
        results = import_files(two_foreign_files, db, workers=2)
    assert "killed by SIGSEGV" in (results[0].error or "") and "2 times" in (results[0].error or "")
    assert results[0].grasps == 0 and results[1].error is None and results[1].grasps > 0
    with sqlite3.connect(db) as conn:
        status = dict(conn.execute("SELECT object, status FROM units").fetchall())
    assert status == {"crate": "failed", "ball": "done"}
    code, out, err = grasp("import", *map(str, two_foreign_files), "--db", str(db), "--workers", "2")
    assert code == 0, err
    assert "crate.h5: re-scored" in out and "ball.h5: already imported" in out


def test_rescoring_solves_the_weight_resistances_together_as_highs_does_one_at_a_time(
        db: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Re-scored poses wait for their weight resistances and are solved in one batch (as a sweep's,
    ``measured_later``), not one grasp at a time by HiGHS; every measure as HiGHS's one at a time gives it (the
    resistances to its tolerance, the rest the same)."""
    from planner.quality import resistance, resistance_batch

    poses, obj = np.array([pose(r) for r in source_rows(db, "box")]), load_object("box")
    batches, solve_many = [], resistance_batch.solve_many

    def counted(programs, directions):  # type: ignore[no-untyped-def]
        batches.append(len(programs))
        return solve_many(programs, directions)

    def one_at_a_time(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise AssertionError("a re-scored grasp's resistance solved alone")

    with monkeypatch.context() as patch:
        patch.setattr(resistance_batch, "solve_many", counted)
        patch.setattr(resistance, "solve", one_at_a_time)
        together = importer._rescore(poses, PANDA, obj, Counter())
    assert batches == [len(together)] and len(together) >= 5
    with monkeypatch.context() as patch:  # the path before: HiGHS, one grasp after the other
        patch.setattr(resistance_batch, "solve_many", lambda programs, directions: [
            resistance.solve(p, directions) for p in programs])
        alone = importer._rescore(poses, PANDA, obj, Counter())
    assert [g.candidate for g in together] == [g.candidate for g in alone]
    assert any(g.measures.resist_worst > 1.0 for g in alone)  # real pinches, not zeros compared
    for a, b in zip(together, alone):
        assert a.measures.resist_worst == pytest.approx(b.measures.resist_worst, rel=1e-7, abs=1e-7)
        assert a.measures.resist_mean == pytest.approx(b.measures.resist_mean, rel=1e-7, abs=1e-7)
        assert _same(replace(a, measures=replace(a.measures, resist_worst=0.0, resist_mean=0.0)),
                     replace(b, measures=replace(b.measures, resist_worst=0.0, resist_mean=0.0)))


def _same(a: object, b: object) -> bool:
    """Records (dataclasses of arrays, mappings, sequences, numbers) equal to the bit, NaN equal to NaN."""
    if is_dataclass(a):
        return type(a) is type(b) and all(_same(getattr(a, f.name), getattr(b, f.name)) for f in fields(a))
    if isinstance(a, HandContacts):
        return all(_same(getattr(a, k), getattr(b, k)) for k in ("points", "normals", "links", "radius", "region"))
    if isinstance(a, np.ndarray | float | np.floating):
        return np.array_equal(a, b, equal_nan=True)  # type: ignore[arg-type]
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, tuple | list):
        return type(a) is type(b) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))  # type: ignore[arg-type]
    return a == b


def test_unknown_gripper_needs_hand(db: Path, tmp_path: Path) -> None:
    path = tmp_path / "robotiq.h5"
    with h5py.File(path, "w") as f:
        f["gripper/type"], f["grasps/transforms"] = "robotiq_2f85", np.tile(np.eye(4), (2, 1, 1))
        f["object/file"], f["object/scale"] = "nowhere.obj", 1.0
    code, _, err = grasp("import", str(path), "--db", str(tmp_path / "i.db"))
    assert code == 2 and "gripper type 'robotiq_2f85' is not a known hand; pass --hand" in err
    code, _, err = grasp("import", str(path), "--db", str(tmp_path / "i.db"), "--hand", "panda")
    assert code == 2 and "object/file 'nowhere.obj' not found" in err


def stored_hash(db: Path, name: str) -> str:
    with open_db(db, create=False, readonly=True) as handle:
        found = handle.object_row(name)
    assert found is not None
    return found.mesh_sha256


def test_new_files_import_the_mesh_their_grasps_were_planned_on(stored_db: Path, tmp_path: Path) -> None:
    """The duck generated at --scale 1.5 is stored as 'duck', larger than the
    registry's duck: its import takes the exported mesh, the box the registry's."""
    out = export(stored_db, "acronym", tmp_path / "h5", "--hand", "panda")
    fresh = tmp_path / "fresh.db"
    code, _, err = grasp("import", *map(str, sorted(out.glob("*.h5"))), "--db", str(fresh))
    assert code == 0, err
    for name in ("box", "capsule", "duck"):
        assert stored_hash(fresh, name) == stored_hash(stored_db, name), name
        imported = source_rows(fresh, name)
        assert_close([pose(r) for r in imported], [pose(r) for r in source_rows(stored_db, name, "hand = 'panda'")])
    sources = dict(sqlite3.connect(fresh).execute("SELECT name, source FROM objects"))
    assert sources["box"] == "primitive:box" and sources["duck"] == str(out / "meshes" / "duck.obj")


def test_files_written_before_issue_12_import_alike(stored_db: Path, tmp_path: Path) -> None:
    """The older layout: object/file the database's source (absolute, or
    primitive:box), object/scale its scale, no mesh hash, configuration [0.08]."""
    out = export(stored_db, "acronym", tmp_path / "h5", "--hand", "panda", "--object", "box", "--object", "capsule")
    for path in sorted(out.glob("*.h5")):
        with h5py.File(path, "r+") as f:
            source, scale = f["object/source"][()].decode(), f["object/source_scale"][()]
            for key in ("object/file", "object/scale", "object/source", "object/source_scale", "object/mesh_sha256",
                        "gripper/configuration", "gripper/configuration_joints"):
                del f[key]
            f["object/file"], f["object/scale"], f["gripper/configuration"] = source, scale, [0.08]
    shutil.rmtree(out / "meshes")
    fresh = tmp_path / "fresh.db"
    code, out_text, err = grasp("import", *map(str, sorted(out.glob("*.h5"))), "--db", str(fresh))
    assert code == 0 and "re-scored" not in out_text, err
    for name in ("box", "capsule"):
        assert stored_hash(fresh, name) == stored_hash(stored_db, name), name
        assert len(source_rows(fresh, name)) == len(source_rows(stored_db, name, "hand = 'panda'"))


def _db_bytes(path: Path) -> bytes:
    with sqlite3.connect(path) as conn:
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    return path.read_bytes()


def test_two_scales_of_one_mesh_are_two_objects_and_another_mesh_is_refused(db: Path, tmp_path: Path) -> None:
    """ACRONYM names each file by category, mesh and scale: a foreign file's
    object takes the file's stem, so two scales of one mesh are two objects;
    a file naming a stored object from another mesh is refused before
    anything is written."""
    crate, _ = foreign_file(db, tmp_path, "box", "crate")
    half = crate.with_name("crate_half.h5")
    shutil.copy(crate, half)
    with h5py.File(half, "r+") as f:
        del f["object/scale"]
        f["object/scale"] = 0.5
    fresh = tmp_path / "fresh.db"
    results = import_files([crate, half], fresh, workers=1)
    assert [r.object for r in results] == ["crate", "crate_half"] and all(r.grasps > 0 for r in results)
    with open_db(fresh, create=False, readonly=True) as store:
        full, small = store.object_row("crate"), store.object_row("crate_half")
    assert full is not None and small is not None and small.scale == 0.5 and full.scale == 1.0
    other, _ = foreign_file(db, tmp_path / "elsewhere", "sphere", "crate")  # another mesh, the same file name
    before = _db_bytes(fresh)
    code, _, err = grasp("import", str(other), "--db", str(fresh))
    assert code == 2 and "object 'crate' is stored in" in err and "from another mesh" in err, err
    assert _db_bytes(fresh) == before


def _copy_with(src: Path, dst: Path, change) -> Path:  # type: ignore[no-untyped-def]
    shutil.copy(src, dst)
    with h5py.File(dst, "r+") as f:
        change(f)
    return dst


def _set(key: str, value):  # type: ignore[no-untyped-def]
    def change(f):  # type: ignore[no-untyped-def]
        del f[key]
        f[key] = value
    return change


def _joint(f, row: int, col: int, value: float) -> None:  # type: ignore[no-untyped-def]
    data = f["grasps/joints_closed"][()]
    data[row, col] = value
    _set("grasps/joints_closed", data)(f)


def _trial(f, name: str, change) -> None:  # type: ignore[no-untyped-def]
    key = f"grasps/qualities/{name}"
    _set(key, change(f[key][()].astype(float) if f[key].dtype.kind in "iuf" else f[key][()]))(f)


@pytest.mark.parametrize("change, message", [
    (_set("grasps/joint_names", np.array(["x", "y", "z"], dtype=h5py.string_dtype())), "are not joints of hand"),
    (lambda f: _joint(f, 0, 0, 50.0), "lies outside its limits"),
    (lambda f: _joint(f, 1, 0, np.inf), "holds an infinite value"),
    (_set("object/mass", -1.0), "object/mass is -1; it must be a positive number"),
    (lambda f: f["grasps/contacts"].__setitem__(0, "not json"), "grasps/contacts row 0 is not a JSON list"),
    (_set("grasps/joints_open_given", np.ones((1, 2), np.int64)), "grasps/joints_open_given has shape (1, 2)"),
    # a trial's columns: read after the database was opened (an internal error, an empty database left)
    (lambda f: _trial(f, "simulated_success", lambda v: np.where(np.arange(len(v)) == 1, np.nan, v)),
     "grasps/qualities/simulated_success row 1 is nan; expected -1 (not simulated), 0 or 1"),
    (lambda f: _trial(f, "mujoco_success", lambda v: np.where(np.arange(len(v)) == 0, 2, v)),
     "grasps/qualities/mujoco_success row 0 is 2; expected -1"),  # was stored as held
    (lambda f: _trial(f, "simulated_success", lambda v: v[:1]), "simulated_success has shape (1,); expected"),
    (lambda f: _trial(f, "robust_samples", lambda v: np.full(len(v), 0.5)), "robust_samples row 0 is 0.5"),
    (lambda f: _trial(f, "validation_reason", lambda v: np.zeros(len(v))), "validation_reason holds numbers"),
    (lambda f: _trial(f, "mujoco_success", lambda v: np.array([b"held"] * len(v))), "holds text; expected numbers"),
])
def test_a_damaged_file_is_refused_naming_the_dataset(db: Path, tmp_path: Path, change, message: str) -> None:
    """Hand-edited or damaged files were stored and broke `show` later (a joint 'x': KeyError)."""
    files = sorted(export(db, "acronym", tmp_path / "h5").glob("box__*.h5"))
    bad = _copy_with(files[0], tmp_path / "bad.h5", change)
    fresh = tmp_path / "fresh.db"
    code, _, err = grasp("import", "--format", "acronym", str(bad), "--db", str(fresh))
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert not fresh.exists() and not Path(f"{fresh}.lock").exists()  # no empty database left at --db


@pytest.mark.parametrize("rescore", [False, True])
@pytest.mark.parametrize("transforms, message", [
    (lambda t: np.where(np.arange(t.size).reshape(t.shape) == 3, np.nan, t), "row 0 is not a rigid transform"),
    (lambda t: t[:, :3, :3], "expected (N, 4, 4)"),
])
def test_a_file_with_bad_poses_is_refused_before_the_database_is_made(db: Path, tmp_path: Path, transforms,
                                                                      message: str, rescore: bool) -> None:
    """A NaN or a wrong shape in grasps/transforms was refused only after the database had been created: an
    empty grasp database and its lock file were left at --db."""
    files = sorted(export(db, "acronym", tmp_path / "h5").glob("box__*.h5"))

    def change(f: h5py.File) -> None:
        new = transforms(f["grasps/transforms"][:])
        del f["grasps/transforms"]
        f["grasps/transforms"] = new

    bad = _copy_with(files[0], tmp_path / "bad.h5", change)
    fresh = tmp_path / "fresh.db"
    code, _, err = grasp("import", "--format", "acronym", str(bad), "--db", str(fresh),
                         *(["--rescore"] if rescore else []))
    one_line_error(code, err, 2, message)
    assert not fresh.exists() and not Path(f"{fresh}.lock").exists()


def test_our_file_is_refused_on_another_mesh_or_hand_and_back_into_its_own_database(db: Path, tmp_path: Path) -> None:
    files = sorted(export(db, "acronym", tmp_path / "h5").glob("box__*.h5"))
    fresh = tmp_path / "fresh.db"
    code, _, err = grasp("import", "--format", "acronym", str(files[0]), "--db", str(fresh), "--object", "sphere")
    assert code == 2 and "is not the mesh this file's grasps were planned on" in err and "--rescore" in err, err
    code, _, err = grasp("import", "--format", "acronym", str(files[0]), "--db", str(fresh), "--hand", "barrett")
    assert code == 2 and "pass --rescore to re-score the poses with hand 'barrett'" in err, err
    copy = tmp_path / "copy.db"
    shutil.copy(db, copy)
    before = sqlite3.connect(copy).execute("SELECT COUNT(*), (SELECT source FROM objects WHERE name = 'box') "
                                           "FROM grasps").fetchone()
    code, _, err = grasp("import", "--format", "acronym", str(files[0]), "--db", str(copy))
    assert code == 2 and "grasps are stored in" in err and "an export of this database?" in err, err
    after = sqlite3.connect(copy).execute("SELECT COUNT(*), (SELECT source FROM objects WHERE name = 'box') "
                                          "FROM grasps").fetchone()
    assert after == before


def test_an_export_imported_back_into_its_own_database_is_refused_whole(tmp_path: Path) -> None:
    """Its poses come back as `transforms @ inv(export_frame)`: -0.0 where the store has 0.0 (a box's
    axis-aligned grasps) made rounded bytes differ, so such a grasp was imported twice and a file undercounted
    (the shared fixture's grasps happen to keep +0.0; these eight rays do not)."""
    from planner import api
    from planner.plan.sweep import SweepSettings

    db = tmp_path / "g.db"
    api.generate(["box"], "panda", db_path=db, workers=1,
                 settings=SweepSettings(approaches=8, rolls=2, preshapes=("wide",), reach_placements=1))
    count = len(source_rows(db, "box"))
    assert all((pose(row) == 0).any() for row in source_rows(db, "box"))  # exact zeros: what slipped through
    copy = tmp_path / "copy.db"
    shutil.copy(db, copy)
    files = sorted(export(db, "acronym", tmp_path / "h5").glob("box__*.h5"))
    code, _, err = grasp("import", "--format", "acronym", str(files[0]), "--db", str(copy))
    assert code == 2 and f"{count} of its {count} grasps are stored in" in err, err
    assert len(source_rows(copy, "box")) == count


def test_an_export_does_not_replace_another_databases_mesh(db: Path, tmp_path: Path) -> None:
    out = export(db, "acronym", tmp_path / "h5")
    mesh = out / "meshes" / "box.obj"
    mesh.write_text(mesh.read_text().replace("v ", "v 1", 1))  # another object named box exported there
    before = {p.name: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    code, _, err = grasp("export", "--db", str(db), "--format", "acronym", "--out", str(out))
    assert code == 2 and "holds another mesh than this database's 'box'" in err, err
    assert {p.name: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_one_file_given_twice_is_read_and_scored_once_and_said_so(db: Path, tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """`grasp import a.h5 a.h5` re-scored the file twice (stored once) and printed its line twice."""
    foreign, _ = foreign_file(db, tmp_path, "box", "crate")
    closed = Counter[str]()
    rescore = importer.rescore_poses

    def counted(unit: importer.RescoreUnit) -> importer.Rescored:
        closed["poses"] += len(unit.poses)
        return rescore(unit)

    monkeypatch.setattr(importer, "rescore_poses", counted)
    again = foreign.parent / ".." / "grasps" / foreign.name  # the same file by another path
    code, out, err = grasp("import", str(foreign), str(again), "--db", str(tmp_path / "a.db"), "--workers", "1")
    assert code == 0, err
    lines = out.splitlines()
    assert len(lines) == 2 and "re-scored" in lines[0], out
    assert lines[1] == f"{again}: the same file as {foreign} (crate/panda); read once", out
    with h5py.File(foreign, "r") as f:
        assert closed["poses"] == len(f["grasps/transforms"])
    code, out, err = grasp("import", str(foreign), str(foreign), "--db", str(tmp_path / "a.db"), "--json")
    assert code == 0, err
    said = json.loads(out)
    assert [r["skipped"] for r in said] == [True, True] and said[1]["same_as"] == str(foreign), out
    code, out, err = grasp("import", str(foreign), str(foreign), "--db", str(tmp_path / "a.db"))
    assert code == 0 and out.splitlines()[1] == f"{foreign}: given again (crate/panda); read once", out


def test_the_same_bytes_beside_another_mesh_are_not_said_the_same_file(db: Path, tmp_path: Path) -> None:
    """Two copies of one file whose object/file finds another mesh beside each (d1's box, d2's sphere, both
    'crate') were said "the same file" and the second object dropped unseen: refused, as before the copies were
    read once, with the two paths."""
    first, _ = foreign_file(db, tmp_path / "d1", "box", "crate")
    second = tmp_path / "d2" / "foreign" / "grasps" / "crate.h5"
    second.parent.mkdir(parents=True)
    (tmp_path / "d2" / "foreign" / "meshes").mkdir()
    shutil.copyfile(first, second)
    load_object("sphere").mesh.export(tmp_path / "d2" / "foreign" / "meshes" / "crate.obj")
    code, out, err = grasp("import", str(first), str(second), "--db", str(tmp_path / "a.db"), "--workers", "1")
    one_line_error(code, err, 2, f"{second} and {first} name one object 'crate' with other meshes")
    assert "the same file" not in out, out


@pytest.mark.parametrize("sidecar", ["friction = 0.9", 'up = "+y"', "com = [0.01, 0, 0]"])
def test_copies_of_one_file_beside_one_mesh_with_other_sidecars_are_refused(db: Path, tmp_path: Path,
                                                                           sidecar: str) -> None:
    """Two copies of one file (no object/friction, no object/up) beside copies of one mesh, one with a sidecar of
    another friction, up or centre of mass: read once as "the same file", the first's taken for both without a word.
    Refused with the two paths and what differs, as two meshes under one name are."""
    first, _ = foreign_file(db, tmp_path / "d1", "box", "crate")
    with h5py.File(first, "r+") as f:
        del f["object/friction"]
    second = tmp_path / "d2" / "foreign" / "grasps" / "crate.h5"
    shutil.copytree(tmp_path / "d1" / "foreign", second.parents[1])
    (second.parents[1] / "meshes" / "crate.toml").write_text(sidecar + "\n")
    out_db = tmp_path / "a.db"
    code, out, err = grasp("import", str(first), str(second), "--db", str(out_db), "--workers", "1")
    # each value beside its path: the second's (its sidecar's) first, as its path is (the values were said the
    # other way round, "d2 and d1 ... friction 0.5 and 0.9" where d2's is 0.9)
    what = {"f": "friction 0.9 and 0.5", "u": "up +y and +z",  # a com as well: read once, the second's dropped
            "c": "centres of mass [0.01, 0, 0] and [0, 0, 0] m (or other inertias)"}[sidecar[0]]
    one_line_error(code, err, 2, f"{second} and {first} name one object 'crate' with {what}")
    assert "the same file" not in out and not out_db.exists(), out


def test_validate_says_an_imported_objects_up_was_taken_untold(db: Path, tmp_path: Path) -> None:
    """A file without object/up imported without --up stands on +z: its MuJoCo trials load it along -z and
    `validate` said "held" with no word of it (an ACRONYM mug, on +y, tried lying on its side); the import's
    one line was the only warning. Told (--up), nothing is said; the unit's digest is the same either way."""
    foreign, _ = foreign_file(db, tmp_path, "box", "crate")
    for told, name in (([], "untold"), (["--up", "+z"], "told")):
        out_db = tmp_path / f"{name}.db"
        code, _, err = grasp("import", str(foreign), "--db", str(out_db), "--workers", "1", *told)
        assert code == 0 and ("no object/up" in err) == (not told), err
        code, out, err = grasp("validate", "--db", str(out_db), "--top", "1", "--robust", "0", "--workers", "1")
        assert code == 0 and "validated 1 grasps" in out, err
        said = [line for line in err.splitlines() if "taken standing on +z" in line]
        assert said == ([] if told else ["note: 'crate' (panda) was imported from a file without object/up and "
                                         "taken standing on +z (no --up, sidecar or registry gave one): its trials "
                                         "load it along its frame's -z; if it stands on another axis (ACRONYM's own "
                                         "meshes stand on +y), these verdicts are of it lying on its side: import "
                                         "the file again with --up AXIS into another --db"]), err
    with sqlite3.connect(tmp_path / "untold.db") as a, sqlite3.connect(tmp_path / "told.db") as b:
        assert a.execute("SELECT settings_hash FROM units").fetchall() == \
            b.execute("SELECT settings_hash FROM units").fetchall()


def test_an_up_told_later_is_no_longer_said_untold(db: Path, tmp_path: Path) -> None:
    """The same file imported again with --up (skipped: imported before), or read once beside a copy whose sidecar
    gives the up: the up is told, yet the unit kept `up_taken` and `validate` went on saying no one gave it."""
    from planner import api

    foreign, _ = foreign_file(db, tmp_path / "d1", "box", "crate")
    out_db = tmp_path / "a.db"
    code, _, err = grasp("import", str(foreign), "--db", str(out_db), "--workers", "1")
    assert code == 0 and api.untold_ups(db_path=out_db) == {("crate", "panda"): "+z"}, err
    code, out, err = grasp("import", str(foreign), "--db", str(out_db), "--workers", "1", "--up", "+z")
    assert code == 0 and "skipped" in out and api.untold_ups(db_path=out_db) == {}, (out, err)
    copy = tmp_path / "d2" / "foreign" / "grasps" / "crate.h5"
    shutil.copytree(tmp_path / "d1" / "foreign", copy.parents[1])
    (copy.parents[1] / "meshes" / "crate.toml").write_text('up = "+z"\n')
    for order in ((foreign, copy), (copy, foreign)):
        out_db = tmp_path / f"{order[0].parents[2].name}.db"
        code, out, err = grasp("import", *map(str, order), "--db", str(out_db), "--workers", "1")
        assert code == 0 and "the same file" in out and api.untold_ups(db_path=out_db) == {}, (out, err)


def test_validate_in_pybullet_does_not_say_an_untold_up(db: Path, tmp_path: Path) -> None:
    """PyBullet's shake loads the object along the hand's six axes whatever its up: the note that "its trials load
    it along its frame's -z" (MuJoCo's) was said of its verdicts too."""
    foreign, _ = foreign_file(db, tmp_path, "box", "crate")
    out_db = tmp_path / "a.db"
    code, _, err = grasp("import", str(foreign), "--db", str(out_db), "--workers", "1")
    assert code == 0 and "no object/up" in err, err
    code, out, err = grasp("validate", "--db", str(out_db), "--top", "1", "--robust", "0", "--workers", "1",
                           "--engine", "pybullet")
    assert code == 0 and "validated 1 grasps in pybullet" in out, err
    assert "taken standing on" not in err, err


def test_a_files_own_values_replacing_its_meshs_sidecar_are_said(db: Path, tmp_path: Path) -> None:
    """A file with its own object/friction and object/up beside a mesh whose sidecar gives others: the file's are
    taken (its grasps were measured with them), and the sidecar's were dropped without a word (`generate` says a
    replaced sidecar value)."""
    foreign, _ = foreign_file(db, tmp_path, "box", "crate")
    with h5py.File(foreign, "r+") as f:
        f["object/up"] = "+z"
        friction = float(f["object/friction"][()])
    (foreign.parents[1] / "meshes" / "crate.toml").write_text(f'friction = {friction * 2}\nup = "+y"\n')
    out_db = tmp_path / "a.db"
    code, _, err = grasp("import", str(foreign), "--db", str(out_db), "--workers", "1")
    assert code == 0, err
    assert f"{foreign}: its object/friction {friction:g} replaces crate.toml's friction {friction * 2:g}; its " \
           "object/up +z replaces crate.toml's up +y (its grasps were measured with the file's)" in err, err
    with sqlite3.connect(out_db) as conn:
        assert conn.execute("SELECT friction, up FROM objects").fetchone() == (friction, "+z")
