"""The import arrows between the stages (bench/stage_imports.py parses them):
the record floor imports no stage."""

from __future__ import annotations

import re
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


#: The shared modules every stage may import (the README: "Shared by all").
SHARED = {"errors", "assets", "threads", "prepare"}
#: The imports from a stage of the README's table to one listed below it, each with its reason (the README says
#: them too); any other is a stage out of its place.
UPWARD = {
    ("record", "geometry"): "contact frames, imported where stored contacts are rebuilt (RECORD_MAY_IMPORT)",
    ("sim", "validation"): "MuJoCo's engine settings, kept where planning reads them without loading a simulator",
    ("plan", "validation"): "the settle continues the shake trial's closing with its settings",
    ("db", "calibration"): "the store scores grasps with the p_hold model it keeps",
    ("datasets", "calibration"): "exports label grasps by p_hold and its trial update",
}


def readme_stages() -> list[str]:
    """The stages in the order of the README's table ("What it does, stage by stage"), each row's first folder
    ``planner/X/`` (and the CLI's with the API's)."""
    text = (Path(__file__).parents[1] / "README.md").read_text(encoding="utf-8")
    table = text[text.index("| stage | folder: modules |"):].split("\n\n", 1)[0]
    order = []
    for row in table.splitlines()[2:]:
        order += [m for m in re.findall(r"`planner/(\w+)/`", row.split("|")[2]) if m not in order]
    return order


def test_every_stage_imports_only_the_stages_above_it_in_the_readme() -> None:
    order = readme_stages()
    found = arrows()
    assert set(found) - SHARED == set(order), "the README's stage table lists every stage, and only those"
    upward = {(here, there) for here, theirs in found.items() if here in order for there in theirs
              if there in order and order.index(there) > order.index(here)}
    assert upward == set(UPWARD), upward ^ set(UPWARD)
    assert all(found[s] <= SHARED for s in SHARED)


#: The heavy backends and the one adapter module that imports each (the README's stage table says so).
ADAPTERS = {"pybullet": "planner/sim/__init__.py", "mujoco": "planner/sim/mujoco_world.py",
            "igl": "planner/geometry/distance.py", "viser": "planner/present/viewer.py"}


def test_each_backend_is_imported_by_its_adapter_alone() -> None:
    import ast

    root = Path(__file__).parents[1]
    importers: dict[str, set[str]] = {name: set() for name in ADAPTERS}
    for path in sorted((root / "planner").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else []
            for name in names:
                if name.split(".")[0] in importers:
                    importers[name.split(".")[0]].add(path.relative_to(root).as_posix())
    assert importers == {name: {module} for name, module in ADAPTERS.items()}
