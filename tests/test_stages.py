"""The import arrows between the stages (bench/stage_imports.py parses them):
the record floor imports no stage."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "bench"))

from stage_imports import arrows  # noqa: E402

#: What the record may import: the geometry helpers (contact frames).
RECORD_MAY_IMPORT = {"geometry"}


def test_the_record_imports_no_stage() -> None:
    found = arrows()
    assert found["record"] <= RECORD_MAY_IMPORT, found["record"]


def test_every_stage_that_reads_grasps_imports_the_record_not_the_old_module() -> None:
    found = arrows()
    assert "grasp" not in found  # planner/grasp.py is gone: the record lives in planner/record/
    assert {"db", "datasets", "plan", "validation", "present"} <= {s for s, t in found.items() if "record" in t}
