"""The store's writes (planner.db.writing): a database an earlier version ranked is ranked again by the next write,
whichever it is, and until then its records read back rank as its stored ranks do."""

from __future__ import annotations

import json
import sqlite3
from dataclasses import replace
from pathlib import Path

from helpers import made_up

from planner.db.ranking import ENDS_RANKED, RankingRule, first_of
from planner.db.store import UnitRow, open_db, open_for_writing
from planner.plan.measures import Measures


def earlier(path: Path) -> None:
    """``path`` as the version before a stored squeeze's end stood for its parent left it: its formula without the
    words that say so, its grasps ranked by candidate, a planned grasp before its squeeze's end."""
    with sqlite3.connect(path) as conn:
        stored = json.loads(conn.execute("SELECT value FROM meta WHERE key = 'ranking'").fetchone()[0])
        stored["formula"] = stored["formula"].replace(f" {ENDS_RANKED}", "")
        conn.execute("UPDATE meta SET value = ? WHERE key = 'ranking'", (json.dumps(stored, sort_keys=True),))
        conn.execute("UPDATE grasps SET rank = 1 + 2 * candidate + (squeezed_from_turn IS NOT NULL)")


def test_an_earlier_versions_ranks_read_as_they_rank_until_any_write_ranks_them_again(tmp_path: Path) -> None:
    """Read-only (best, show, export, report, the viewer): a parent its stored end stands for today still ranks
    first there, and its record says no end stands for it (the descriptions, ``validate --force-closure`` and the
    viewer's filter agree with the ranks shown). Any write (``validate``, ``calibrate``: not only ``generate``
    and ``import``, which apply a rule) ranks it again first."""
    squeezed = Measures(3.0, 4.0, 0.01, 0.01, 1.0, (), settled_epsilon=0.4, squeezed_force_closure=True)
    parent = replace(made_up(0, 0.0, fc=False), measures=squeezed)
    end = replace(made_up(0, 0.02), squeezed_from_turn=0.3, measures=replace(squeezed, squeezed_force_closure=False))
    path = tmp_path / "g.db"
    with open_for_writing(path) as db:
        db.apply_rule(RankingRule())
        db.write_unit(UnitRow("thing", "panda", "h" * 16, "{}", 5, 0, None), None, [parent, end, made_up(1, 0.01)],
                      RankingRule())
    earlier(path)
    with open_db(path, create=False, readonly=True) as db:
        back = db.best("thing", "panda", 10)
    assert [(g.candidate, g.squeezed_from_turn is not None) for g in back] == [(0, False), (0, True), (1, False)]
    assert [g.end_kept for g in back] == [False, False, False] and first_of(back) == [True, True, True]
    with open_for_writing(path, create=False):  # what `grasp validate` and `grasp calibrate` open it with
        pass
    with open_db(path, create=False, readonly=True) as db:
        back = db.best("thing", "panda", 10)
    assert [(g.candidate, g.squeezed_from_turn is not None) for g in back] == [(0, True), (1, False), (0, False)]
    assert [g.end_kept for g in back] == [False, False, True] and first_of(back) == [True, True, False]
