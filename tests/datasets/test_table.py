"""Parquet and CSV: one row per grasp, the documented columns, nulls."""

from __future__ import annotations

import csv
import json
import re
import shutil
import sqlite3
from pathlib import Path

import pyarrow.parquet as pq
from helpers import assert_close

from planner import api
from planner.datasets.table import COLUMNS, COLUMNS_DOC
from tests.datasets.support import export, pose, source_rows


def documented_columns() -> list[str]:
    return [name for line in COLUMNS_DOC.splitlines()[2:] for name in re.findall(r"`([a-z_0-9]+)`",
                                                                                  line.split("|")[1])]


def test_tables_have_one_row_per_grasp_and_the_documented_columns(db: Path, tmp_path: Path) -> None:
    total = sqlite3.connect(db).execute("SELECT COUNT(*) FROM grasps").fetchone()[0]
    assert documented_columns() == COLUMNS
    assert COLUMNS_DOC in (Path(__file__).parents[2] / "README.md").read_text()
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


def test_a_csv_export_warns_of_object_names_that_csv_readers_take_for_numbers(db: Path, tmp_path: Path) -> None:
    """A folder of ``000.obj``, ``001.obj`` ... gives objects named '000', '001': pandas.read_csv (and polars)
    read that column as the numbers 0, 1 without a word. The export says so, with a reading that keeps them."""
    import pandas as pd

    renamed = tmp_path / "numbered.db"
    shutil.copy(db, renamed)
    with sqlite3.connect(renamed) as conn:
        for table, column in (("objects", "name"), ("grasps", "object"), ("units", "object")):
            conn.execute(f"UPDATE {table} SET {column} = '001' WHERE {column} = 'box'")
    summary = api.export(renamed, "csv", tmp_path / "out", objects=["001"])
    path = tmp_path / "out" / "grasps.csv"
    assert set(pd.read_csv(path)["object"]) == {1}  # the silent misreading the note is about
    (note,) = [n for n in summary.notes if "'001'" in n]
    assert "dtype={'object': str}" in note and "--format parquet" in note
    assert set(pd.read_csv(path, dtype={"object": str}, keep_default_na=False, na_values=[""])["object"]) == {"001"}
    assert not [n for n in api.export(renamed, "parquet", tmp_path / "out").notes if "'001'" in n]


def test_names_that_csv_readers_turn_into_numbers_booleans_or_missing_values_are_told_apart() -> None:
    from planner.datasets.table import misread_name

    assert all(map(misread_name, ("001", "1e3", "0.5", "-2", "NA", "null", "None", "nan", "True", "false")))
    assert not any(map(misread_name, ("box", "random_001", "a dir/my thing", "0x1f", "1a2b", "mug.obj")))
    assert not misread_name("1_000")  # float() reads it as 1000.0; pandas, polars and pyarrow keep the text


def test_the_csv_note_names_pyarrows_reader_which_misreads_such_names_too(tmp_path: Path) -> None:
    """pyarrow.csv.read_csv (the README's reader that 'reads it right') reads an object '001' as the integer 1 and
    'NA' as null as well; the note named pandas and polars only."""
    import pyarrow.csv as pc

    from planner.datasets.table import csv_notes

    path = tmp_path / "names.csv"
    path.write_text("object,hand\n001,panda\nNA,panda\n")
    assert pc.read_csv(path).column("object").to_pylist() == [1, None]
    (note,) = csv_notes([("001", "panda"), ("NA", "panda")])
    assert "pyarrow.csv.read_csv" in note


def test_every_parquet_column_carries_its_unit_and_meaning(db: Path, tmp_path: Path) -> None:
    schema = pq.read_schema(export(db, "parquet", tmp_path) / "grasps.parquet")
    meta = {f.name: {k.decode(): v.decode() for k, v in (f.metadata or {}).items()} for f in schema}
    assert set(meta) == set(COLUMNS) and all(set(m) == {"unit", "description"} for m in meta.values())
    assert [meta[c]["unit"] for c in ("pose_03", "roll", "resist_worst", "object_mass", "epsilon")] == \
        ["m", "rad", "g", "kg", ""]
    assert {c: meta[c]["unit"] for c in COLUMNS if c.startswith("pose_") and meta[c]["unit"]} == \
        {"pose_03": "m", "pose_13": "m", "pose_23": "m"}  # the rotation's entries and the last row are numbers
    assert all(meta[c]["description"] for c in COLUMNS)
    assert meta["label"]["description"].startswith("success label")
