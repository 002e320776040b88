"""Rewrite the README's two generated tables from the declaration of the
stored fields (:mod:`planner.record.fields`): the database's field table and
the Parquet / CSV column table (:data:`planner.datasets.table.COLUMNS_DOC`).
``python bench/readme_tables.py [README.md]``; tests check the README holds
both (tests/record/test_fields.py, tests/datasets/test_table.py)."""

from __future__ import annotations

import sys
from pathlib import Path

from planner.datasets.table import COLUMNS_DOC
from planner.record.fields import markdown_table

#: The header line of each generated table, and its text.
TABLES = (("| field | table.column |", markdown_table), ("| column | type | meaning |", lambda: COLUMNS_DOC))


def rewrite(text: str) -> str:
    """``text`` with each generated table (from its header to the next blank line) replaced."""
    for head, table in TABLES:
        start = text.index(head)
        end = text.index("\n\n", start)
        text = text[:start] + table().rstrip("\n") + text[end:]
    return text


def main() -> None:
    path = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).parents[1] / "README.md")
    before = path.read_text(encoding="utf-8")
    after = rewrite(before)
    path.write_text(after, encoding="utf-8")
    print(f"{path}: {'rewritten' if after != before else 'already up to date'}")


if __name__ == "__main__":
    main()
