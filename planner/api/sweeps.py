"""One sweep per object, hand, seed and table plane: a ``generate`` run whose
settings would try an object's stored candidates again is refused, or with
``--replace`` the stored sweep is removed once this run's own sweep of the
object is whole (:class:`Replacement`).

A database keys its units by the sweep's settings: a run with other settings
that try the same candidates (another budget, reach settings, preshapes
named or not, a newer planner, another ``--chunk``) started a second sweep
and stored every grasp again with the same pose. What differs is named, with
the way out: the stored ``--chunk`` or order of ``--preshapes`` to resume,
another ``--seed`` or ``--db``, or ``--replace``. A stored sweep is removed
only after the run has stored every unit of the object without a failure
(its grasps are never lost to an interrupted, failed or unreachable run; an
interrupted ``--replace`` run leaves both sweeps, and the next ``--replace``
run removes the old one), and never where this run does not sweep all of its
preshapes again.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import TYPE_CHECKING

from planner.db.store import Database
from planner.errors import InputError
from planner.plan.sweep import differences, stored_conflict
from planner.specs.hands import HandSpec
from planner.specs.preshapes import sweep_preshapes

if TYPE_CHECKING:
    from planner.plan.unit import UnitSpec  # the sweep's engine: not loaded by this check


class Replacement:
    """The stored sweeps a run would sweep again: refused at construction
    unless ``replace``; with it, each removed (:meth:`Database.remove_sweep`)
    once the run's units of its object are all stored without an error
    (:meth:`ready`, then :meth:`stored` after each unit). ``removed``: the
    grasps removed so far."""

    def __init__(self, db: Database, hand: HandSpec, seed: int, units: Sequence[UnitSpec],
                 todo: Sequence[UnitSpec], replace: bool) -> None:
        self.db, self.hand, self.seed, self.removed = db, hand.name, seed, 0
        self.pending: dict[str, list[str]] = {}  # object -> stored settings to remove once its sweep is whole
        self.waiting = Counter(_name(u) for u in todo)
        self.failed: set[str] = set()
        for name in sorted({_name(u) for u in (units if replace else todo)}):
            ours = sorted({u.settings.to_json() for u in units if _name(u) == name})
            swept = db.swept_settings(name, hand.name, seed)
            for stored in sorted(swept - set(ours)):
                found = stored_conflict(stored, ours)
                if found is not None:
                    _check(name, hand, seed, *found, replace, unfinished=bool(swept & set(ours)))
                    self.pending.setdefault(name, []).append(stored)

    def ready(self) -> None:
        """Remove the stored sweeps of the objects this run has nothing left to do for."""
        for name in [n for n in self.pending if not self.waiting[n]]:
            self._remove(name)

    def stored(self, unit: UnitSpec, failed: bool) -> None:
        """After ``unit`` is stored (``failed``: with an error): its object's stored sweeps go once all of its
        units are stored and none failed."""
        name = _name(unit)
        self.waiting[name] -= 1
        self.failed |= {name} if failed else set()
        if name in self.pending and not self.waiting[name] and name not in self.failed:
            self._remove(name)

    def _remove(self, name: str) -> None:
        for stored in self.pending.pop(name):
            self.removed += self.db.remove_sweep(name, self.hand, self.seed, stored)


def _name(unit: UnitSpec) -> str:
    return unit.label or unit.object_name


def _check(name: str, hand: HandSpec, seed: int, old: dict, new: dict, keys: list[str], replace: bool,
           unfinished: bool) -> None:
    """Refuse what ``replace`` cannot mend, and, without it, every stored sweep this run would sweep again
    (``unfinished``: some of this run's units are stored already, beside the other sweep: a ``--replace`` run
    that was stopped)."""
    lost = _preshapes(hand, old) - _preshapes(hand, new)
    if replace and lost:
        raise InputError(f"{name} was swept for {hand.name} with seed {seed} and preshapes {', '.join(sorted(lost))} "
                         "too: --replace would remove their grasps, which this run does not sweep again; name them "
                         "in --preshapes too (or leave --preshapes out)")
    if replace:
        return
    again = "or --replace to remove the stored sweep (its grasps and their trials) and sweep it again"
    if unfinished:
        raise InputError(f"{name} holds two sweeps for {hand.name} with seed {seed}: part of this run's and one "
                         f"with other settings ({differences(old, new, keys)}), as a --replace run that was stopped "
                         "leaves them; run it again with --replace to finish (the other is removed once this one "
                         "is whole)")
    if keys == ["preshapes"] and _preshapes(hand, old) == _preshapes(hand, new):
        named = f"--preshapes {','.join(old['preshapes'])}" if old["preshapes"] else "no --preshapes (all of them)"
        raise InputError(f"{name} was swept for {hand.name} with {named}: the same preshapes, named otherwise (and "
                         f"the candidates are numbered in their order); resume with {named}, {again}")
    if keys == ["chunk"]:
        raise InputError(f"{name} was swept for {hand.name} with these settings but --chunk {old['chunk']}: another "
                         f"--chunk cuts the same candidates into other units and would store every grasp again; "
                         f"resume with --chunk {old['chunk']}, use another --db, {again}")
    raise InputError(f"{name} was swept for {hand.name} with seed {seed} and other settings "
                     f"({differences(old, new, keys)}): a second sweep under one seed would stand beside it (where "
                     f"the two try the same candidates, every grasp twice); give another --seed for other "
                     f"candidates, another --db, {again}")


def _preshapes(hand: HandSpec, settings: dict) -> set[str]:
    """The preshapes a sweep with ``settings`` (as stored) tries."""
    names = settings.get("preshapes")
    on_table = settings.get("table_plane") is not None
    return set(names) if names else {s.name for s in sweep_preshapes(hand, None, on_table)}

