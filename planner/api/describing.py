"""Descriptions and maintenance: the built-in hands (with their preshapes)
and objects, a database's objects as stored, its integrity check, the
default number of workers.
"""

from __future__ import annotations

import os
from pathlib import Path

from planner.db.store import ObjectRow, open_db
from planner.specs.hands import HandSpec, hand_names, load_hand
from planner.specs.objects import ObjectSpec, builtin_specs
from planner.specs.preshapes import Preshape, load_preshapes


def hands() -> list[tuple[HandSpec, tuple[Preshape, ...]]]:
    """Every built-in hand with its preshapes."""
    return [hand(name) for name in hand_names()]


def hand(name: str) -> tuple[HandSpec, tuple[Preshape, ...]]:
    """One hand and its preshapes."""
    spec = load_hand(name)
    return spec, load_preshapes(spec)


def objects() -> dict[str, ObjectSpec]:
    """The built-in objects by name (``random_NNN`` are not listed)."""
    return builtin_specs()


def stored_objects(db_path: Path) -> list[tuple[ObjectRow, list[str]]]:
    """Every object of the database as stored (file, scale, mass, density,
    friction, up, volume: what its grasps were planned and measured at), with
    the hands that have grasps of it."""
    with open_db(Path(db_path), create=False, readonly=True) as db:
        hands: dict[str, list[str]] = {}
        for obj, hand in db.pairs():
            hands.setdefault(obj, []).append(hand)
        rows = [db.object_row(name) for name in db.object_names()]
        return [(row, hands.get(row.name, [])) for row in rows if row is not None]


def check_db(db_path: Path) -> list[str]:
    """``PRAGMA integrity_check`` problems (empty list: healthy)."""
    with open_db(Path(db_path), create=False, readonly=True) as db:
        return db.integrity_check()


def default_workers() -> int:
    return max(1, os.cpu_count() or 1)
