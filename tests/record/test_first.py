"""Which grasps rank first: one declaration (planner/record/first.py) that the database, the selections and
planning read, not restated where a stage needs it."""

from __future__ import annotations

import ast
import itertools
from pathlib import Path

from planner.db import ranking
from planner.record import first

PLANNER = Path(first.__file__).parents[1]


def test_first_is_force_closure_as_planned_or_squeezed_without_a_kept_end() -> None:
    combos = list(itertools.product([0, 1], [None, 0, 1], [False, True]))
    measures = {"force_closure": [c[0] for c in combos], "squeezed_force_closure": [c[1] for c in combos],
                first.END_KEPT: [c[2] for c in combos]}
    expected = [bool(fc or (sq and not kept)) for fc, sq, kept in combos]
    assert first.ranks_first(measures).tolist() == expected
    assert ranking.ranks_first is first.ranks_first and ranking.FIRST is first.FIRST  # the database's is this one


def test_no_other_function_restates_the_rule() -> None:
    """planner/plan/unit.py's `_squeezed_first` restated it (force closure once squeezed, not as planned, its end
    not kept) to choose the grasps a unit reaches: a change of the rule would have left planning behind. No function
    that chooses or orders grasps, outside the declaration, reads both a squeeze's force closure and whether its end
    is kept (planner/present words a grasp's closure for people, pointing at the declaration)."""
    restating = []
    for path in PLANNER.rglob("*.py"):
        if path == Path(first.__file__) or path.parent.name == "present":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                read = {n.attr for n in ast.walk(node) if isinstance(n, ast.Attribute)}
                if {"squeezed_force_closure", "end_kept"} <= read:
                    restating.append(f"{path.relative_to(PLANNER.parent)}:{node.lineno}")
    assert restating == []
