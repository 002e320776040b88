"""``grasp generate``'s summary of a resumed run (tests/cli/test_generate.py is over 400 lines)."""

from __future__ import annotations

import json
from pathlib import Path

from helpers import FAST, grasp


def test_a_resumed_runs_summary_names_the_objects_an_earlier_run_finished(tmp_path: Path) -> None:
    """A resumed run's table listed only the objects it worked on: those an earlier run finished were not said."""
    db = tmp_path / "g.db"
    assert grasp("generate", "box", "--hand", "panda", "--db", str(db), "--quiet", *FAST)[0] == 0
    code, out, err = grasp("generate", "box", "sphere", "--hand", "panda", "--db", str(db), *FAST)
    assert code == 0, err
    assert "(this run's work)" in " ".join(out.split())  # the title, wrapped where the path is long
    assert "finished by an earlier run, not in the table: box\n" in out
    assert "│ sphere" in out and "│ box" not in out
    code, out, err = grasp("generate", "box", "sphere", "--hand", "panda", "--db", str(db), "--json", *FAST)
    assert code == 0 and json.loads(out)["finished_before"] == ["box", "sphere"], err
