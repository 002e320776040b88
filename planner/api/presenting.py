"""Pictures and the viewer: :func:`show` renders stored grasps to a PNG,
:func:`view` starts the browser viewer (on grasps an arm reaches, with an
object pose), :func:`coverage` measures how much of the surface the best
grasps touch.
"""

from __future__ import annotations

import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from planner.api.querying import best
from planner.api.reaching import ReachableGrasp, best_at
from planner.api.resolving import DEFAULT_DB, _pose7, _stored, resolve_object
from planner.db.store import open_db
from planner.errors import InputError
from planner.record.grasp import Grasp
from planner.specs.hands import load_hand
from planner.specs.inputs import check_output, writing

if TYPE_CHECKING:
    from planner.db.diverse import Spacing


#: The most grasps one ``grasp show --top`` sheet draws (each three views, one row).
MAX_SHEET = 100


def show(name: str, hand: str, out: Path, *, db_path: Path = DEFAULT_DB, rank: int = 1, top: int | None = None,
         spacing: Spacing | None = None) -> list[Grasp]:
    """Render grasp ``rank`` (or the ``top`` K as a contact sheet; with
    ``spacing``, the K best diverse ones) to a PNG."""
    from planner.present import render  # matplotlib: only for pictures

    count = 1 if top is None else top
    first = 1 if top is not None else rank
    if count < 1 or first < 1:
        raise InputError("--rank and --top must be at least 1")
    if count > MAX_SHEET:
        raise InputError(f"--top {count}: a contact sheet holds at most {MAX_SHEET} grasps (500 made a 517-megapixel "
                         "PNG that image readers refuse); browse more in `grasp view`")
    spec = load_hand(hand)
    if Path(out).suffix.lower() != ".png":
        raise InputError(f"{out}: the picture is written as PNG; give a .png path")
    check_output(Path(out), "--out")
    with open_db(Path(db_path), create=False, readonly=True) as db:
        key, obj = _stored(db, name, hand, "the picture")
        if spacing is None:
            grasps, stored = db.best(key, hand, count, first - 1), db.grasp_count(key, hand)
        else:  # fewer than asked for: every diverse one (their count, not every stored grasp's, is the last rank)
            diverse = best(key, hand, db_path=db_path, top=first - 1 + count, spacing=spacing)
            grasps, stored = diverse[first - 1:], len(diverse)
    if not grasps and (first == 1 or stored == 0):
        best(key, hand, db_path=db_path)  # raises, saying why the object has none
    if not grasps:
        raise InputError(f"no grasp of rank {first} for '{key}' and hand '{hand}' in {db_path}: it has {stored}"
                         f"{'' if spacing is None else ' diverse ones'} (--rank 1 to {stored})")
    views = [(render.grasp_views(spec, obj, g), render.title(g)) for g in grasps]
    with writing(Path(out), "--out"):
        render.save_sheet(views, Path(out))
    return grasps


def view(name: str, hands: Sequence[str] | None = None, *, db_path: Path = DEFAULT_DB, top: int = 50,
         host: str = "127.0.0.1", port: int = 8080, object_pose: Sequence[float] | None = None,
         robot_base: Sequence[float] | None = None, spacing: Spacing | None = None):  # -> viewer.Viewer
    """Start the browser viewer on the ``top`` best grasps of each hand (all
    hands with grasps of the object when ``hands`` is None). With
    ``object_pose`` only grasps the arm reaches at that pose are offered,
    placed in the world with the arm (stored ones; if none is reachable,
    grasps planned on the spot with the table, as ``best --object-pose``). Returns the running viewer (``url``,
    ``stop()``)."""
    from planner.db.hand_files import refuse_edited
    from planner.db.objects import stored_object
    from planner.present import scene as scenes
    from planner.present import viewer

    if top < 1:
        raise InputError(f"--top must be at least 1, got {top}")
    with open_db(Path(db_path), create=False, readonly=True) as db:
        key, row = resolve_object(db, name)
        stored = sorted(h for o, h in db.pairs() if o == key)
        if row is None or not stored:
            raise InputError(f"no grasps of '{key}' in {db_path}; run `grasp generate {shlex.quote(name)} --hand H "
                             f"--db {shlex.quote(str(db_path))}`")
        obj = stored_object(row)
    chosen = list(hands) if hands else stored
    with open_db(Path(db_path), create=False, readonly=True) as db:
        for h in chosen:
            if h in stored:
                refuse_edited(db, h, "the viewer")
    missing = [h for h in chosen if h not in stored]
    if missing:
        raise InputError(f"no grasps of '{key}' for hand(s) {', '.join(missing)} in {db_path} "
                         f"(hands with grasps: {', '.join(stored)})")
    specs = {h: load_hand(h) for h in chosen}
    world = None if object_pose is None else _pose7(object_pose, "--object-pose")
    base = None if robot_base is None else _pose7(robot_base, "--robot-base")
    entries: list[viewer.Entry] = []
    for h in chosen:
        if object_pose is None:
            found = [(g, None, ()) for g in best(key, h, db_path=db_path, top=top, spacing=spacing)]
        else:
            reached = best_at(key, h, object_pose, db_path=db_path, top=top, robot_base=robot_base, plan=False) or \
                best_at(key, h, object_pose, db_path=db_path, top=top, robot_base=robot_base, max_candidates=0)
            found = [(r.grasp, r.arm_grasp, (_arm_line(r),)) for r in reached]
        for g, arm, extra in found:
            def build(g=g, arm=arm, spec=specs[h]):  # noqa: B023 - bound per grasp
                return scenes.grasp_scene(spec, obj.mesh, g, obj.friction, world, arm, base)
            entries.append(viewer.Entry(g, build, extra))
    if not entries:
        raise InputError(f"no grasp of '{key}' is reachable at --object-pose {object_pose}, stored or planned on "
                         "the spot with the table; `grasp best ... --object-pose ...` says why")
    return viewer.Viewer(entries, specs, scenes.object_part(obj.mesh, world), host=host, port=port,
                         up=obj.spec.up if world is None else "+z")  # with a pose: the world's, z up


def coverage(db_path: Path, top: int = 10):  # -> list[planner.present.coverage.Coverage]
    """Surface coverage of the ``top`` best (and diverse) grasps' contacts, per object and hand."""
    from planner.present.coverage import coverages

    return coverages(Path(db_path), top)


def _arm_line(r: ReachableGrasp) -> str:
    joints = ", ".join(f"{k} {v:.3f}" for k, v in r.arm_grasp.items())
    return f"arm joints at the grasp [rad]: {joints}"
