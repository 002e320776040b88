"""Querying stored grasps: the best ones of an object for a hand (diverse
ones with a spacing), and the ranking rule and p_hold model a database applies.
"""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import closing
from pathlib import Path
from typing import TYPE_CHECKING

from planner.api.resolving import DEFAULT_DB, generate_command, resolve_object
from planner.db.lock import writer_of
from planner.db.ranking import RankingRule
from planner.db.store import open_db
from planner.errors import InputError
from planner.record.grasp import Grasp
from planner.specs.hands import check_hand_name, load_hand

if TYPE_CHECKING:
    from planner.calibration.model import LogisticModel
    from planner.db.diverse import Spacing


DIVERSE_BATCH = 500  # grasps read at a time while picking diverse ones


#: What the commonest rejection of a sweep that kept nothing means for the user.
SWEPT_EMPTY = {
    "too_wide": "the object is wider than the hand opens wherever it was sampled",
    "too_thin": "the object is thinner than the fingers can hold",
    "overlap": "the open hand overlapped the object",
    "no_contact": "the fingers closed on air",
    "cone": "no two surface points face each other within the friction cone",
}


def best(name: str, hand: str, *, db_path: Path = DEFAULT_DB, top: int = 1, spacing: Spacing | None = None
         ) -> list[Grasp]:
    """The ``top`` best grasps of an object for a hand, in rank order; with
    ``spacing``, the best ``top`` that are each that far from every better
    one kept (:mod:`planner.db.diverse`)."""
    if top < 1:
        raise InputError(f"--top must be at least 1, got {top}")
    check_hand_name(hand)
    with open_db(Path(db_path), create=False, readonly=True) as db:
        key, row = resolve_object(db, name)
        if spacing is None:
            grasps = db.best(key, hand, top)
        else:
            from planner.db.diverse import diverse

            spec = load_hand(hand)
            with closing(db.grasp_batches(key, hand, size=DIVERSE_BATCH)) as batches:  # its cursor, before the db
                ranked = (g for batch in batches for g in batch if g.rank)
                grasps = diverse(ranked, top, spacing, spec.tcp, spec.approach, spec.roll_symmetry)
        if not grasps:
            known = db.objects_for(hand)
            units, candidates, rejected = db.swept(key, hand)
            if units:  # swept, nothing kept: the same sweep again keeps nothing (unless it was cut short)
                common = rejected.most_common(4)
                why = ", ".join(f"{reason} {count:,}" for reason, count in common)
                meaning = f"; {common[0][0]}: {SWEPT_EMPTY[common[0][0]]}" if common and common[0][0] in SWEPT_EMPTY \
                    else ""
                raise InputError(f"no grasps of '{key}' for hand '{hand}' in {db_path}: its {units} finished units "
                                 f"({candidates:,} candidates) kept none (rejected: {why or 'none'}{meaning}); try "
                                 "another hand or other sweep settings, or, if its sweep was cut short, "
                                 f"`{generate_command(name, row, hand, db_path)}` finishes it")
            writer = writer_of(Path(db_path))
            if writer is not None and _sweeps(writer.command, {name, key}, hand):  # not "run" the very run going on
                raise InputError(f"no grasps of '{key}' for hand '{hand}' in {db_path} yet: "
                                 f"{writer.doing('writing it')}; try again once a unit of it has finished")
            hands = sorted({h for o, h in db.pairs() if o == key})  # asked with another hand than it was swept with
            also = f"; '{key}' has grasps for {', '.join(hands)} (--hand)" if hands else ""
            raise InputError(f"no grasps of '{key}' for hand '{hand}' in {db_path}; objects with grasps for {hand}: "
                             f"{', '.join(known) or '(none)'}{also}; run "
                             f"`{generate_command(name, row, hand, db_path)}`")
    return grasps


def stored_names(names: Sequence[str], *, db_path: Path = DEFAULT_DB) -> tuple[str, ...]:
    """Each of ``names`` as ``db_path`` stores it: a mesh file's path becomes
    the object stored from it (as ``best`` and ``show`` take it); any other
    name is kept as given (the command says if no object of that name has
    grasps)."""
    if not any(Path(n).is_file() for n in names):
        return tuple(names)
    with open_db(Path(db_path), create=False, readonly=True) as db:
        return tuple(resolve_object(db, n)[0] if Path(n).is_file() else n for n in names)


def ranking_rule(db_path: Path = DEFAULT_DB) -> RankingRule:
    """The ranking rule a database's scores were made with (``meta.ranking``)."""
    with open_db(Path(db_path), create=False, readonly=True) as db:
        return db.rule()


def p_hold_outside(name: str, hand: str, *, db_path: Path = DEFAULT_DB) -> list[str]:
    """Where the stored object ``name`` lies outside the labelled objects ``hand``'s p_hold model was fitted on
    (:meth:`~planner.calibration.logistic.LogisticModel.outside`: one text per property; [] inside, or no model,
    object or known domain): there p_hold is an extrapolation, which its trials (``grasp validate``) check."""
    from planner.calibration.logistic import outside

    with open_db(Path(db_path), create=False, readonly=True) as db:
        domain, row = db.model_domain(hand), db.object_row(name)
        return [] if row is None else outside(domain, row.properties())


def object_up(name: str, *, db_path: Path = DEFAULT_DB) -> str:
    """The stored object ``name``'s up as it stands (an axis of its frame, :mod:`planner.specs.up`: what its grip
    measures and its MuJoCo trial read); ``+z`` where it is not stored."""
    with open_db(Path(db_path), create=False, readonly=True) as db:
        row = db.object_row(name)
        return "+z" if row is None else row.up


def untold_ups(*, db_path: Path = DEFAULT_DB, objects: Sequence[str] | None = None,
               hands: Sequence[str] | None = None) -> dict[tuple[str, str], str]:
    """(object, hand) -> the up an import took the object standing on without being told (its file had no
    ``object/up``, nor was ``--up``, a sidecar or the registry's given; :meth:`UnitReads.untold_ups`), for
    ``objects`` and ``hands`` (None: all): its MuJoCo trials load it along that up's reverse."""
    with open_db(Path(db_path), create=False, readonly=True) as db:
        found = db.untold_ups()
    return {(o, h): up for (o, h), up in found.items()
            if (objects is None or o in objects) and (hands is None or h in hands)}


def mesh_modified(name: str, *, db_path: Path = DEFAULT_DB) -> str | None:
    """Where the stored object ``name``'s mesh file was modified after its last unit finished: the file (its grasps
    were planned on the mesh as it was, which ``best`` does not read); None: not modified, or not a file."""
    from planner.specs.object_files import edited_since

    with open_db(Path(db_path), create=False, readonly=True) as db:
        row = db.object_row(name)
        if row is None or row.source.startswith("primitive:") or not Path(row.source).is_file():
            return None
        return row.source if edited_since(Path(row.source), db.last_finished(name), row.geometry) else None


def hand_edited(hand: str, *, db_path: Path = DEFAULT_DB) -> list[str]:
    """The files of ``hand`` edited since the database stored its grasps (:func:`planner.db.hand_files.edited`;
    [] for none): its stored grasps were planned on the hand as it was."""
    from planner.db.hand_files import edited

    with open_db(Path(db_path), create=False, readonly=True) as db:
        return edited(db, hand)


def hand_changed(hand: str, *, db_path: Path = DEFAULT_DB) -> list[str]:
    """What the project changed in ``hand`` since the database stored its grasps
    (:func:`planner.db.hand_files.changed_by_project`; [] for nothing)."""
    from planner.db.hand_files import changed_by_project

    with open_db(Path(db_path), create=False, readonly=True) as db:
        return changed_by_project(db, hand)


def ranks_stale(name: str, hand: str, *, db_path: Path = DEFAULT_DB) -> bool:
    """Whether ``name``'s grasps for ``hand`` carry trial verdicts their ranks do not yet reflect (a ``grasp
    validate`` killed before it re-ranked them; the next ``grasp validate`` on the database re-ranks first)."""
    with open_db(Path(db_path), create=False, readonly=True) as db:
        return (name, hand) in db.unranked()


def p_hold_model(hand: str, *, db_path: Path = DEFAULT_DB) -> LogisticModel | None:
    """The p_hold model a database applies to ``hand``'s grasps (stored by
    ``grasp calibrate``, else the shipped one; None: none)."""
    with open_db(Path(db_path), create=False, readonly=True) as db:
        return db.model(hand)


def _sweeps(command: str, names: set[str], hand: str) -> bool:
    """Whether a writer's recorded ``command`` is a `grasp generate` of one of ``names`` for ``hand`` (any other
    writer, a `validate` or another object's sweep, never stores it: waiting for it gives no grasp)."""
    import shlex

    try:
        words = shlex.split(command)
    except ValueError:  # cut at the lock's COMMAND_CHARS inside a quote
        words = command.split()
    hands = {b for a, b in zip(words, words[1:]) if a == "--hand"} | {w[7:] for w in words if w.startswith("--hand=")}
    return "generate" in words and hand in hands and not names.isdisjoint(words)
