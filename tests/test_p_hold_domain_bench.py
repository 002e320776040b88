"""bench/p_hold_domain.py on a small database: each object's grasps tried at its own mass and friction and at the
labels' conditions, the rows consistent with the database."""

import json
import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from p_hold_domain import main  # noqa: E402

from planner.db.store import open_db  # noqa: E402


def test_rows_for_the_box_at_its_own_and_the_labels_conditions(box_db: Path, tmp_path: Path, shipped_models: None,
                                                               capsys) -> None:
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    with open_db(db) as d:
        d.apply_rule(d.rule())  # p_hold from the shipped model
    out = tmp_path / "rows.json"
    assert main(["--db", str(db), "--per-object", "3", "--json-out", str(out)]) == 0
    rows = json.loads(out.read_text())
    assert [r["object"] for r in rows] == ["box"] and rows[0]["grasps"] == 3
    assert rows[0]["friction"] == 0.5 and any(w.startswith("friction 0.5") for w in rows[0]["outside"])
    assert all(0.0 <= rows[0][k] <= 1.0 for k in ("p_hold", "stored", "labels"))
    assert "labels' conditions: density 150.0 kg/m^3, friction 1" in capsys.readouterr().out
