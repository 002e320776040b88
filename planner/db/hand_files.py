"""Which files each hand's grasps in a database were made with
(``meta.hand_files``: hand -> {file label: digest}, :mod:`planner.specs.hand_files`).

A database keys its units by the sweep's settings and the hand's name, not by
the hand's files: a hand edited after a sweep would get its new grasps stored,
its old ones validated, or imported grasps scored, under the same name as the
hand it was. Every writer that uses a hand's geometry (``generate``,
``validate``, ``import``) calls :func:`check_hand_files` first: an edited hand
is refused, naming the files, before anything is written; every reader that
puts stored joint values on the hand's geometry (``show``, ``view``, ``best``
at an object pose or on the table) calls :func:`refuse_edited`, and ``best``
notes it. The record is made
by the first such write (for a database written before it existed: the files
as they are then).
"""

from __future__ import annotations

import json
from collections.abc import Iterable

from planner.db.store import Database
from planner.errors import InputError
from planner.specs.hand_files import changed, declared, hand_files

#: The meta key of the record.
META_KEY = "hand_files"


def edited(db: Database, hand: str) -> list[str]:
    """The files of ``hand`` that differ from those the database's grasps of
    it were made with ([]: the same, no record, or no grasps of it)."""
    before = json.loads(db.meta(META_KEY) or "{}").get(hand)
    if before is None:
        return []
    now = hand_files(hand)
    return changed(before, now) if before != now and db.hand_swept(hand) else []


def changed_by_project(db: Database, hand: str) -> list[str]:
    """What the project changed in ``hand``'s files since the database's grasps of it were made (the
    declarations of :data:`planner.specs.hand_files.SAME_HAND`; [] for none)."""
    before = json.loads(db.meta(META_KEY) or "{}").get(hand)
    return [] if before is None or not db.hand_swept(hand) else declared(before, hand_files(hand))


def refuse_edited(db: Database, hand: str, doing: str) -> None:
    """Refuse ``doing`` (what would put the stored grasps' joint values on
    the hand's geometry: a picture, the reach check) with an edited hand."""
    files = edited(db, hand)
    if files:
        raise InputError(f"hand '{hand}' was edited since {db.path.name} stored its grasps ({', '.join(files)} "
                         f"changed): {doing} would put their joint values on the edited hand; restore its files, "
                         f"or sweep the edited hand under a new name (copy hands/{hand}/ and preshapes/{hand}.toml)")


def check_hand_files(db: Database, hands: Iterable[str]) -> None:
    """Refuse the first of ``hands`` whose files differ from those the
    database's grasps of it were made with; record the files of those the
    database has no record of (or no grasps of)."""
    stored = json.loads(db.meta(META_KEY) or "{}")
    new = dict(stored)
    for hand in sorted(set(hands)):
        now = hand_files(hand)
        before = stored.get(hand)
        if before == now or (before is not None and not changed(before, now)):
            continue  # the same files, or the project's own changes that leave the hand what it was
        if before is not None and db.hand_swept(hand):
            raise InputError(
                f"hand '{hand}' was edited since {db.path.name} stored its grasps "
                f"({', '.join(changed(before, now))} changed): grasps of both would sit under one name; "
                f"copy hands/{hand}/ and preshapes/{hand}.toml to a new hand name, or use another --db")
        new[hand] = now
    if new != stored:
        db.set_meta(META_KEY, json.dumps(new, sort_keys=True))
