"""The declaration of every stored field: the schema and its migrations give
exactly the declared columns, each added in the version the declaration
says; the README shows the declaration; the record types and the
declaration agree."""

from __future__ import annotations

import dataclasses
import sqlite3
from pathlib import Path

import pytest

from planner.db.ranking import END_KEPT
from planner.db.schema import MIGRATIONS, SCHEMA, SCHEMA_VERSION
from planner.record.field import KINDS, stored
from planner.record.fields import (
    FIELDS,
    GROUPS,
    TABLES,
    by_name,
    markdown_table,
    ranked_fields,
    record_fields,
    table,
)
from planner.record.grasp import Grasp
from planner.record.measures import Measures

README = Path(__file__).parents[2] / "README.md"


def columns_at(version: int) -> dict[str, dict[str, tuple[str, bool]]]:
    """table -> column -> (SQL type, NOT NULL) after the schema and the migrations up to ``version``."""
    conn = sqlite3.connect(":memory:")
    conn.executescript(SCHEMA)
    for v in range(1, version):
        conn.executescript(MIGRATIONS[v])
    out = {}
    for name in TABLES:
        info = conn.execute(f"PRAGMA table_info({name})").fetchall()
        out[name] = {r[1]: (r[2], bool(r[3])) for r in info}
    conn.close()
    return out


def test_schema_and_migrations_give_exactly_the_declared_columns() -> None:
    got = columns_at(SCHEMA_VERSION)
    for name in TABLES:
        declared = {f.column: (f.sql.split()[0], "NOT NULL" in f.sql) for f in table(name)}
        assert got[name] == declared, name


@pytest.mark.parametrize("version", range(1, SCHEMA_VERSION + 1))
def test_each_column_appears_in_the_version_the_declaration_names(version: int) -> None:
    got = columns_at(version)
    for name in TABLES:
        expected = {f.column for f in table(name) if f.version <= version}
        assert set(got.get(name, {})) == expected, (name, version)


def test_the_readme_shows_the_declaration() -> None:
    assert markdown_table() in README.read_text(), "run `python bench/readme_tables.py` to rewrite the README's tables"


def test_flat_names_are_unique_and_every_stored_attribute_is_declared() -> None:
    names = [f.name for f in FIELDS]
    assert len(names) == len(set(names))
    for cls, group in ((Grasp, ""), (Measures, "measures.")):
        attrs = {f.name for f in dataclasses.fields(cls) if "stored" in f.metadata}
        assert {group + a for a in attrs} <= {f.attr for f in record_fields()}
    # the record's parts that are not stored fields themselves are the groups, and whether its squeeze's end is
    # stored beside it, which the store derives as it reads (planner.db.ranking.end_kept_sql), never a column
    assert {f.name for f in dataclasses.fields(Grasp) if "stored" not in f.metadata} == {*GROUPS, END_KEPT}
    assert set(GROUPS) == {"validation", "mujoco", "robust", "file_label", "measures"}


def test_each_trial_protocol_has_its_own_columns_and_ranked_name() -> None:
    # the MuJoCo trial is stored apart from PyBullet's, every field of the record's Trial in both
    trial = {f.attr.partition(".")[2] for f in record_fields() if f.attr.startswith("validation.")}
    assert trial == {f.attr.partition(".")[2] for f in record_fields() if f.attr.startswith("mujoco.")}
    assert {f.table for f in FIELDS if f.attr.startswith("mujoco.")} == {"mujoco"}
    assert by_name("mujoco_success").ranked == "mujoco_success" and by_name("validation_success").ranked == "success"
    assert "MuJoCo" in by_name("mujoco_success").doc and "PyBullet" in by_name("validation_success").doc
    assert by_name("mujoco_reason").version == 7 and by_name("mujoco_grasp_id").version == 7


def test_every_ranked_field_has_a_neutral_value_and_a_numeric_type() -> None:
    assert {f.ranked for f in ranked_fields()} >= {"epsilon", "success", "settled_epsilon"}
    assert all(f.dtype in ("float64", "int64") for f in ranked_fields())
    assert by_name("settled_epsilon").version == 4 and by_name("validation_reason").version == 3


def test_a_kind_that_does_not_exist_is_refused() -> None:
    with pytest.raises(ValueError, match="kind must be one of"):
        stored("complex", "", 1, "no such kind")
    assert set(KINDS) >= {f.kind for f in FIELDS}
