"""What a process running ``grasp validate``'s tasks keeps from one task to
the next: the stored objects, rebuilt once (:func:`stored`).

:func:`planner.validation.run.plan` cuts an (object, hand)'s grasps into
tasks in a row, so a pool's worker mostly gets the tasks of one object one
after the other; rebuilding the object for each (its file read and hashed,
its mass properties worked out: :func:`planner.db.objects.stored_object`)
cost ~2-3 ms a task of 32 MuJoCo trials, ~0.08 ms a trial. The object is
read-only to the trials, so every task gets the same results from the kept
one. A run in the caller's own process forgets them at its end
(:func:`forget`): a file edited between two runs is read again, as before.
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from planner.db.objects import stored_object
from planner.db.rows import ObjectRow
from planner.geometry.solid import PreparedObject

#: Objects kept per process (the oldest dropped first): tasks of one object come in a row, so a few cover
#: the objects a worker switches between.
KEPT = 4
_OBJECTS: dict[tuple, PreparedObject] = {}


def row_key(row: ObjectRow) -> tuple:
    """Every field of ``row``, arrays by their shape and bytes (rows are equal keys iff equal rows)."""
    values = (getattr(row, f.name) for f in fields(row))
    return tuple((v.shape, v.dtype.str, v.tobytes()) if isinstance(v, np.ndarray) else v for v in values)


def stored(row: ObjectRow) -> PreparedObject:
    """:func:`~planner.db.objects.stored_object` of ``row``, built once per process while kept (an error is
    raised again by the next call: nothing kept)."""
    key = row_key(row)
    if key not in _OBJECTS:
        obj = stored_object(row)
        if len(_OBJECTS) >= KEPT:
            _OBJECTS.pop(next(iter(_OBJECTS)))
        _OBJECTS[key] = obj
    return _OBJECTS[key]


def forget() -> None:
    """Drop every kept object."""
    _OBJECTS.clear()
