"""Export: filters, one-line errors, streaming in batches."""

from __future__ import annotations

import errno
import hashlib
import os
import sqlite3
from pathlib import Path

import h5py
import numpy as np
import pyarrow.parquet as pq
import pytest
from helpers import grasp

from planner.datasets import exporter
from planner.db import store
from tests.datasets.support import export

FORMATS = ("acronym", "graspgen", "dexgraspnet", "parquet", "csv")


@pytest.mark.parametrize("args, where", [
    (["--min-epsilon", "{median}"], "epsilon >= {median}"),
    (["--top", "3"], "rank <= 3"),
    (["--object", "sphere"], "object = 'sphere'"),
    (["--object", "box", "--hand", "panda", "--top", "2", "--min-epsilon", "0.01"],
     "object = 'box' AND rank <= 2 AND epsilon >= 0.01"),
])
def test_filters_restrict_rows(db: Path, tmp_path: Path, args: list[str], where: str) -> None:
    eps = sorted(r[0] for r in sqlite3.connect(db).execute("SELECT epsilon FROM grasps"))
    median = repr(eps[len(eps) // 2])  # "{median}": a cut inside the fixture's range of epsilons
    args, where = [a.format(median=median) for a in args], where.format(median=median)
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
    got, _, err = grasp(*(a.format(db=db) for a in args))
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


def files(folder: Path) -> dict[str, object]:
    """Every file of an export folder by its relative path, read (the manifest without the time it was written)."""
    import json

    out = {str(p.relative_to(folder)): read_all(p) for p in sorted(folder.rglob("*")) if p.is_file()}
    for name in [n for n in out if n.startswith("export-") and n.endswith(".json")]:
        manifest = json.loads(folder.joinpath(name).read_text())
        out[name] = {**{k: v for k, v in manifest.items() if k not in ("finished_at", "files")},  # when; bytes, hash:
                     "files": [{k: v for k, v in f.items() if k not in ("bytes", "sha256", "mtime_ns")}  # the batches
                               for f in manifest["files"]]}
    return out


def test_a_complete_export_says_so_last_and_a_new_one_first_takes_that_back(db: Path, tmp_path: Path) -> None:
    """A folder of an export killed midway looked like a finished one (a kill -9 of a GraspGen export, stop 53). The
    manifest export-<format>.json is written after the last file, and removed before a new export of the format
    writes its first grasp file: present, it lists that export whole."""
    import json

    from planner.datasets import acronym

    out = export(db, "acronym", tmp_path / "a")
    manifest = json.loads((out / "export-acronym.json").read_text())
    assert manifest["complete"] and manifest["database"] == str(db.resolve())
    assert [f["path"] for f in manifest["files"]] == ["box__panda.h5", "sphere__panda.h5"]
    assert sum(f["grasps"] for f in manifest["files"]) == manifest["grasps"] == sum(
        len(acronym.read_labels(out / f["path"])) for f in manifest["files"])
    assert all(f["bytes"] == (out / f["path"]).stat().st_size for f in manifest["files"])
    seen = []
    original = exporter._write_pair

    def failing(*args, **kwargs):  # type: ignore[no-untyped-def]
        seen.append((out / "export-acronym.json").exists())
        if len(seen) == 2:
            raise OSError(28, "No space left on device")
        return original(*args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(exporter, "_write_pair", failing)
        code, _, err = grasp("export", "--db", str(db), "--format", "acronym", "--out", str(out), "--quiet")
    assert code == 2 and "cannot write the export" in err
    assert seen == [False, False] and not (out / "export-acronym.json").exists()  # the stopped export: no manifest
    export(db, "acronym", out)
    assert json.loads((out / "export-acronym.json").read_text())["grasps"] == manifest["grasps"]


def test_export_streams_in_batches(db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    expected = {fmt: files(export(db, fmt, tmp_path / fmt)) for fmt in FORMATS}
    sizes: list[int] = []
    decode = store._grasps
    monkeypatch.setattr(exporter, "BATCH_SIZE", 2)
    monkeypatch.setattr(store, "_grasps", lambda rows: sizes.append(len(rows)) or decode(rows))
    for fmt in FORMATS:
        got = files(export(db, fmt, tmp_path / f"{fmt}-2"))
        assert got.keys() == expected[fmt].keys()
        for name, value in got.items():
            np.testing.assert_equal(value, expected[fmt][name])
    assert max(sizes) == 2 and len(sizes) > len(FORMATS) * 4


def test_every_format_says_where_the_objects_p_hold_is_extrapolated(db: Path, tmp_path: Path,
                                                                     shipped_models: None) -> None:
    import json

    copy = tmp_path / "g.db"
    copy.write_bytes(db.read_bytes())
    with store.open_db(copy) as d:
        d.apply_rule(d.rule())  # p_hold from the shipped Panda model (friction 1 in its labels; the box's 0.5)
        outside = d.model("panda").outside(d.object_row("box").properties())  # type: ignore[union-attr]
    text = "; ".join(outside)
    assert "friction 0.5 (labels: 1)" in text
    out = {fmt: export(copy, fmt, tmp_path / fmt, "--object", "box") for fmt in FORMATS}
    with h5py.File(out["acronym"] / "box__panda.h5", "r") as f:
        assert f["object/p_hold_outside"][()].decode() == text
    assert json.loads((out["graspgen"] / "grasp_data/panda/box.json").read_text())["object"]["p_hold_outside"] == text
    rows = np.load(out["dexgraspnet"] / "dataset/panda/box.npy", allow_pickle=True)
    assert {r["p_hold_outside"] for r in rows} == {text}
    assert set(pq.read_table(out["parquet"] / "grasps.parquet").column("p_hold_outside").to_pylist()) == {text}
    assert text in (out["csv"] / "grasps.csv").read_text()


@pytest.mark.parametrize("fmt", ["acronym", "csv"])
def test_filters_that_leave_no_grasp_write_nothing(db: Path, tmp_path: Path, fmt: str) -> None:
    out = tmp_path / "out"
    code, _, err = grasp("export", "--db", str(db), "--format", fmt, "--out", str(out), "--min-epsilon", "100")
    assert code == 2 and "passes the filters" in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


def test_a_label_no_grasp_has_says_what_it_needs(db: Path, tmp_path: Path) -> None:
    """--label trial on grasps no trial tried, --label p_hold for a hand without a model (a Barrett's database)
    said only that nothing passed 'the filters (--top, --min-epsilon, --label)'."""
    out = tmp_path / "out"
    code, _, err = grasp("export", "--db", str(db), "--format", "csv", "--out", str(out), "--object", "sphere",
                         "--label", "trial")
    assert code == 2 and "--label trial takes only grasps a trial tried (`grasp validate`)" in err, err
    assert not out.exists()
    sel = exporter.Selection(label="p_hold")
    assert "hand barrett has no p_hold model (`grasp calibrate` fits one)" in exporter._why_none(sel, {"barrett": None})


@pytest.mark.parametrize("fmt", ["csv", "moveit", "acronym"])
@pytest.mark.parametrize("stop, code, needle", [
    (OSError(errno.ENOSPC, "No space left on device"), 2, "cannot write the export (No space left on device)"),
    (KeyboardInterrupt(), 130, "interrupted; no file under its final name is partial"),
])
def test_an_export_stopped_midway_leaves_no_file_half_written(box_db: Path, tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch, fmt: str,
                                                               stop: BaseException, code: int, needle: str) -> None:
    """A full disk or Ctrl-C while a file is written: one line (the full disk's was an internal error with a
    traceback, Ctrl-C's said 'run the same command to resume' and printed a database traceback), no partial
    file under any name (the .tmp files stayed)."""
    real = os.replace

    def replace_then_stop(src: object, dst: object) -> None:
        if str(dst).endswith((".csv", ".yaml", ".h5")):  # the grasp file itself, its .tmp written in full
            raise stop
        real(src, dst)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "replace", replace_then_stop)
    monkeypatch.setattr(exporter.os, "replace", replace_then_stop)
    out = tmp_path / "out"
    exit_code, _, err = grasp("export", "--db", str(box_db), "--format", fmt, "--out", str(out), "--quiet")
    assert exit_code == code and needle in err and len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err and "Exception ignored" not in err, err
    left = [p for p in out.rglob("*") if p.suffix in (".tmp", ".csv", ".yaml", ".h5")]
    assert left == [], left


def test_an_export_refused_before_writing_leaves_no_folder_it_made(tmp_path: Path) -> None:
    """A name clash ('a/cube' and 'a__cube': one mesh file) is found after --out is made; that empty folder (and
    the parents it needed) stayed behind. A folder that was there stays."""
    import trimesh
    from helpers import FAST

    for rel in ("a/cube.obj", "b/cube.obj", "a__cube.obj"):
        (tmp_path / rel).parent.mkdir(exist_ok=True)
        trimesh.creation.box(extents=[0.04, 0.04, 0.05]).export(tmp_path / rel)
    (tmp_path / "m.txt").write_text("a/cube.obj\nb/cube.obj\na__cube.obj\n")
    db = tmp_path / "g.db"
    code, _, err = grasp("generate", f"@{tmp_path / 'm.txt'}", "--hand", "panda", "--db", str(db), "--quiet", *FAST)
    assert code == 0, err
    kept = tmp_path / "kept"
    kept.mkdir()
    for out in (tmp_path / "new" / "deeper", kept):
        code, _, err = grasp("export", "--db", str(db), "--format", "acronym", "--out", str(out))
        assert code == 2 and "objects 'a/cube' and 'a__cube' would share the mesh file a__cube.obj" in err, err
    assert not (tmp_path / "new").exists() and kept.is_dir() and not any(kept.iterdir())


def test_exports_into_one_folder_are_each_listed_by_its_manifest(db: Path, tmp_path: Path) -> None:
    """`grasp export --object box` then `--object sphere` into one folder: the manifest described only the sphere's
    export, beside the box's file it did not mention. Now each earlier export whose files are still there is listed
    in `earlier`, with those files only; a file written again is the new export's alone."""
    import json

    out = export(db, "acronym", tmp_path / "a", "--object", "box", "--top", "3")
    export(db, "acronym", out, "--object", "sphere", "--top", "2")
    manifest = json.loads((out / "export-acronym.json").read_text())
    assert [f["path"] for f in manifest["files"]] == ["sphere__panda.h5"] and manifest["selection"]["top"] == 2
    [box] = manifest["earlier"]
    assert [f["path"] for f in box["files"]] == ["box__panda.h5"] and box["selection"]["objects"] == ["box"]
    assert box["grasps"] == 3 and box["files"][0]["bytes"] == (out / "box__panda.h5").stat().st_size
    export(db, "acronym", out, "--top", "1")  # both files again: nothing earlier is left
    again = json.loads((out / "export-acronym.json").read_text())
    assert again["earlier"] == [] and again["grasps"] == 2


@pytest.mark.parametrize("damage", ["earlier null", "earlier 5", "grasps text", "grasps null", "path a list",
                                    "path outside"])
def test_a_damaged_earlier_manifest_does_not_stop_the_next_export(db: Path, tmp_path: Path, damage: str) -> None:
    """An edited or damaged manifest ("earlier": null, a file's "grasps": "many", its "path" a list) stopped the
    next export into the folder at its end, with an internal error, its files written and no manifest; a path
    outside the folder (/etc/passwd, at its size) was listed as an earlier export's file."""
    import json

    out = export(db, "acronym", tmp_path / "a", "--object", "box", "--top", "3")
    manifest = out / "export-acronym.json"
    record = json.loads(manifest.read_text())
    [box] = record["files"]
    outside = tmp_path / "outside.txt"
    outside.write_text("not an export's")
    record["earlier"] = {"earlier null": None, "earlier 5": 5}.get(damage, [])
    if damage in ("grasps text", "grasps null"):
        box["grasps"] = "many" if damage == "grasps text" else None
    if damage == "path a list":
        box["path"] = [box["path"]]
    if damage == "path outside":
        record["earlier"] = [{"files": [{"path": str(outside), "grasps": 1, "bytes": outside.stat().st_size}]},
                             {"files": [{"path": "../outside.txt", "grasps": 1, "bytes": outside.stat().st_size}]}]
    manifest.write_text(json.dumps(record))
    code, _, err = grasp("export", "--db", str(db), "--format", "acronym", "--out", str(out), "--quiet",
                         "--object", "sphere", "--top", "2")
    assert code == 0, err
    again = json.loads(manifest.read_text())
    assert [f["path"] for f in again["files"]] == ["sphere__panda.h5"]
    kept = [f["path"] for r in again["earlier"] for f in r["files"]]
    assert kept == (["box__panda.h5"] if damage in ("earlier null", "earlier 5", "path outside") else []), kept


def test_an_export_stopped_midway_keeps_the_earlier_exports_for_the_next(db: Path, tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """The box exported, the sphere's export stopped (Ctrl-C, a full disk) and run again: the manifest, removed by
    the stopped one, was the box's record's only copy, and the sphere's listed nothing earlier beside the box's
    file. A stopped export still leaves no manifest."""
    import json

    out = export(db, "acronym", tmp_path / "a", "--object", "box", "--top", "3")
    real = os.replace

    def stop(src: object, dst: object) -> None:
        if str(dst).endswith(".h5"):
            raise KeyboardInterrupt
        real(src, dst)  # type: ignore[arg-type]

    with monkeypatch.context() as m:
        m.setattr(exporter.os, "replace", stop)
        code, _, _ = grasp("export", "--db", str(db), "--format", "acronym", "--out", str(out), "--quiet",
                           "--object", "sphere")
    assert code == 130 and not (out / "export-acronym.json").exists()
    export(db, "acronym", out, "--object", "sphere", "--top", "2")
    manifest = json.loads((out / "export-acronym.json").read_text())
    assert [f["path"] for r in manifest["earlier"] for f in r["files"]] == ["box__panda.h5"]
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []


def test_an_earlier_export_file_written_over_at_its_size_is_not_listed(db: Path, tmp_path: Path) -> None:
    """An earlier export's files were matched by their size only: the box's file replaced by other bytes of the
    same length (another export's, an edit) was still listed under `earlier` as the box's export. Each file's
    sha256 is in the manifest and has to match."""
    import json

    out = export(db, "acronym", tmp_path / "a", "--object", "box", "--top", "3")
    box = out / "box__panda.h5"
    [entry] = json.loads((out / "export-acronym.json").read_text())["files"]
    assert entry["sha256"] == hashlib.sha256(box.read_bytes()).hexdigest()
    data = bytearray(box.read_bytes())
    data[-1] ^= 0xFF  # the same length, other content
    box.write_bytes(bytes(data))
    export(db, "acronym", out, "--object", "sphere", "--top", "2")
    assert json.loads((out / "export-acronym.json").read_text())["earlier"] == []


def test_an_earlier_export_file_left_as_it_was_is_not_hashed_again(db: Path, tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Each export read every earlier export's files in the folder again for their sha256 (a dataset exported
    object by object hashed its first files once per later export). A file whose size and modification time are
    those recorded is the one written; one touched since is hashed, and kept where its bytes are the same."""
    import json

    from planner.datasets import exporter

    out = export(db, "acronym", tmp_path / "a", "--object", "box", "--top", "3")
    box = out / "box__panda.h5"
    hashed: list[str] = []
    real = exporter._sha256
    monkeypatch.setattr(exporter, "_sha256", lambda path: hashed.append(path.name) or real(path))
    export(db, "acronym", out, "--object", "sphere", "--top", "2")
    assert hashed == ["sphere__panda.h5"]
    [earlier] = json.loads((out / "export-acronym.json").read_text())["earlier"]
    assert [f["path"] for f in earlier["files"]] == ["box__panda.h5"]
    os.utime(box, ns=(box.stat().st_atime_ns, box.stat().st_mtime_ns + 10**9))  # touched, the same bytes
    hashed.clear()
    export(db, "acronym", out, "--object", "sphere", "--top", "1")
    assert hashed == ["sphere__panda.h5", "box__panda.h5"]
    [earlier] = json.loads((out / "export-acronym.json").read_text())["earlier"]
    assert [f["path"] for f in earlier["files"]] == ["box__panda.h5"]
    hashed.clear()  # its new time recorded: not hashed again
    export(db, "acronym", out, "--object", "sphere", "--top", "2")
    assert hashed == ["sphere__panda.h5"]
