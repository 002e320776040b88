"""``grasp best`` and ``grasp show``: the stored grasps, in rank order."""

from __future__ import annotations

import shlex
from pathlib import Path

import click

from planner import api
from planner.cli.app import db_option, diverse_options, echo_json, floats, made, missing_folder, spacing, unused
from planner.errors import NotFoundError
from planner.specs.hands import hand_frame


@click.command()
@click.argument("object_name", metavar="OBJECT")
@click.option("--hand", required=True)
@db_option
@click.option("--top", type=int, default=1, show_default=True)
@click.option("--object-pose", help="x,y,z,qx,qy,qz,qw of the object on the table (world frame): return only "
              "grasps an arm reaches there now, with joint solutions.")
@click.option("--robot-base", help="x,y,z,qx,qy,qz,qw of the robot base (default: the origin).")
@click.option("--max-candidates", type=int, default=api.MAX_CANDIDATES, show_default=True,
              help="With --object-pose or --on-table: how many stored grasps to try at most (0: plan on the spot "
              "at once).")
@click.option("--on-table", is_flag=True, help="Put the object on the table in its most probable resting poses "
              "(no --object-pose needed): the best grasps the arm reaches in each.")
@click.option("--table-at", default="0.5,0", show_default=True, help="With --on-table: x,y [m] of the object on the "
              "table top z = 0, world frame.")
@click.option("--stable-poses", type=int, default=3, show_default=True, help="With --on-table: how many resting "
              "poses to try, most probable first.")
@click.option("--plan/--no-plan", default=True, show_default=True, help="With --object-pose or --on-table: when "
              "fewer than --top stored grasps are reachable, plan grasps on the spot with the table under the object "
              "(a small sweep, seconds; not stored; from --seed).")
@click.option("--seed", type=int, default=0, show_default=True, help="With --object-pose or --on-table: seeds the "
              "arm's IK restarts and the grasps planned on the spot.")
@click.option("--json", "as_json", is_flag=True)
@click.option("--explain", is_flag=True, help="Also print why each grasp scores what it does, term by term of the "
              "ranking rule.")
@diverse_options
def best(object_name: str, hand: str, db_path: Path, top: int, object_pose: str | None, robot_base: str | None,
         max_candidates: int, on_table: bool, table_at: str, stable_poses: int, plan: bool, seed: int, as_json: bool,
         explain: bool, diverse: bool, min_translation: float, min_rotation: float) -> None:
    """The best grasps of OBJECT for a hand, from the database (with
    --object-pose or --on-table: those an arm reaches there, planned on the
    spot with the table if none stored is)."""
    rule = api.ranking_rule(db_path) if explain else None
    model = api.p_hold_model(hand, db_path=db_path) if explain else None
    apart = spacing(diverse, min_translation, min_rotation)
    if not on_table:
        unused(["table_at", "stable_poses"], "used with --on-table only")
        if object_pose is None:
            unused(["max_candidates", "plan", "seed"], "used with --object-pose or --on-table only")
    if on_table:
        if object_pose is not None or apart is not None:
            raise click.BadParameter("--on-table chooses the object pose itself: leave out --object-pose, --diverse")
        _on_table(object_name, hand, db_path, top, table_at, stable_poses, robot_base, max_candidates, as_json, plan,
                  seed, rule, model)
        return
    if object_pose is None:
        if robot_base is not None:
            raise click.BadParameter("--robot-base needs --object-pose")
        grasps = api.best(object_name, hand, db_path=db_path, top=top, spacing=apart)
        outside = api.p_hold_outside(grasps[0].object, hand, db_path=db_path)
        up = api.object_up(grasps[0].object, db_path=db_path)
        if as_json:
            flags = api.in_sample(db_path, hand, grasps)
            echo_json([{**g.to_json(), "frames": _frames_json(g, None, rule, model), "p_hold_outside": outside,
                        "object_up": up, "in_sample": s} for g, s in zip(grasps, flags)])
            _extrapolated(grasps[0].object, hand, db_path, [])  # its notes on stderr (p_hold_outside is a key)
            return
        for g in grasps:
            _print_grasp(g, rule=rule, model=model, up=up)
        _extrapolated(grasps[0].object, hand, db_path, outside)
        _in_sample(grasps, hand, db_path)
        return
    if apart is not None:
        raise click.BadParameter("--diverse is not yet available with --object-pose")
    misses: list[tuple[int, str]] = []
    pose = floats(object_pose, "--object-pose") or ()
    base = floats(robot_base, "--robot-base")
    found = api.best_at(object_name, hand, pose, db_path=db_path, top=top, robot_base=base,
                        max_candidates=max_candidates, misses=misses, plan=plan, seed=seed)
    if not found:
        table = "" if api.planned_on_table(object_name, hand, pose, db_path=db_path) else (
            ", grasps planned on the table in this resting pose (none is stored; "
            f"`{api.table_command(object_name, hand, db_path)}` plans the most probable ones)")
        spot = "" if plan else ", planning on the spot (leave out --no-plan)"
        raise NotFoundError(f"none of the {max_candidates} best grasps of '{object_name}' for hand '{hand}' is "
                            f"reachable with the object at {object_pose} ({_misses(misses)}); try more of them "
                            f"(--max-candidates {max_candidates * 10}), an object pose nearer the arm{table}{spot}, "
                            "--on-table, or check --robot-base")
    world = api.object_pose_matrix(pose)
    if as_json:
        outside = api.p_hold_outside(found[0].grasp.object, hand, db_path=db_path)
        flags = api.in_sample(db_path, hand, [r.grasp for r in found])
        echo_json([{**r.to_json(), "frames": _frames_json(r.grasp, world, rule, model), "p_hold_outside": outside,
                    "in_sample": s} for r, s in zip(found, flags)])
        _unreached(misses, object_pose, err=True)  # stdout stays one JSON document
        _extrapolated(found[0].grasp.object, hand, db_path, [])
        return
    up = api.object_up(found[0].grasp.object, db_path=db_path)
    for r in found:
        _print_grasp(r.grasp, world, {"the grasp": r.arm_grasp, "the pre-grasp": r.arm_pregrasp}, rule,
                     model, up)
    _unreached(misses, object_pose, err=False)
    name = found[0].grasp.object  # the notes plain `best` gives (a p_hold extrapolated, ...) hold here too
    _extrapolated(name, hand, db_path, api.p_hold_outside(name, hand, db_path=db_path))
    _in_sample([r.grasp for r in found], hand, db_path)


def _unreached(misses: list[tuple[int, str]], object_pose: str, err: bool) -> None:
    """The ranks tried and left out between those shown (#2 and #3 shown, #1 not: why?), under the grasps
    (``err``: on stderr, beside ``--json``'s list)."""
    if any(rank for rank, _ in misses):
        click.echo(f"note: stored grasps the arm does not reach with the object at {object_pose}: {_misses(misses)}",
                   err=err)


def _in_sample(grasps: list[api.Grasp], hand: str, db_path: Path) -> None:
    """One note where p_hold was fitted on the labels some of these grasps carry (their imported file's)."""
    n = api.in_sample_grasps(db_path, hand, grasps)
    if n:
        click.echo(f"note: in-sample: {n} of these grasps carry the labels of a file the {hand}'s p_hold model was "
                   "fitted on (the file they were imported from): their p_hold against those labels is no check of it",
                   err=True)


def _extrapolated(name: str, hand: str, db_path: Path, outside: list[str]) -> None:
    """A note under the grasps when the object lies outside what the hand's p_hold model was fitted on, and when
    its mesh file changed after it was swept."""
    if api.ranks_stale(name, hand, db_path=db_path):
        click.echo(f"note: the ranks of {name}'s {hand} grasps predate trial verdicts stored by a `grasp validate` "
                   f"that was killed before it re-ranked them: grasps it saw drop may still rank first; any `grasp "
                   f"validate --db {shlex.quote(str(db_path))}` re-ranks them first", err=True)
    files = api.hand_edited(hand, db_path=db_path)
    if files:
        click.echo(f"note: hand '{hand}' was edited since {db_path} stored its grasps ({', '.join(files)} changed): "
                   "these are the grasps of the hand as it was; `show` and `best --object-pose` refuse it", err=True)
    for change in api.hand_changed(hand, db_path=db_path):
        click.echo(f"note: the project changed hand '{hand}' since {db_path} stored its grasps ({change}): sweep "
                   "again (`grasp generate ... --replace`, or another --db) to have them made with it", err=True)
    modified = api.mesh_modified(name, db_path=db_path)
    if modified:
        click.echo(f"note: {modified} was modified (its modification time) after {name}'s grasps were planned on "
                   "it: if its mesh changed, these are the grasps of the mesh as it was (`grasp generate` on the file "
                   "compares the two and refuses a changed one under this name)", err=True)
    if outside:
        click.echo(f"note: p_hold is extrapolated for {name}, outside the labelled objects the {hand}'s model was "
                   f"fitted on: {'; '.join(outside)}. Trials at the object's own mass and friction check its grasps "
                   f"(`grasp validate --db {shlex.quote(str(db_path))} --object {shlex.quote(name)} --hand {hand} "
                   "--top 10`: held ones rank first; p_hold_trial's values come from the same labels).")


def _print_grasp(g: api.Grasp, world: object = None, arm: dict | None = None, rule: object = None,
                 model: object = None, up: str = "+z") -> None:
    from planner.present.describe import describe, explain

    for line in describe(g, hand_frame(g.hand), world, arm, up):  # type: ignore[arg-type]
        click.echo(line)
    if rule is not None:
        click.echo("    why this score (the ranking rule, `meta.ranking` of the database):")
        for line in explain(g, rule, model):  # type: ignore[arg-type]
            click.echo(line)


def _frames_json(g: api.Grasp, world: object = None, rule: object = None, model: object = None) -> dict:
    from planner.present.describe import frames

    spec = hand_frame(g.hand)
    out: dict = {"object_frame": frames(g, spec).to_json()}
    if rule is not None:
        from planner.present.describe import explain_json

        out["explain"] = explain_json(g, rule, model)  # type: ignore[arg-type]
    if world is not None:
        out["world_frame"] = frames(g, spec, world).to_json()  # type: ignore[arg-type]
    return out


@click.command()
@click.argument("object_name", metavar="OBJECT")
@click.option("--hand", required=True)
@db_option
@click.option("--rank", type=int, default=1, show_default=True, help="Which grasp (1 = best).")
@click.option("--top", type=int, help="A contact sheet of the K best grasps instead.")
@click.option("--out", type=click.Path(path_type=Path), default=Path("grasp.png"), show_default=True,
              help="The PNG written (a folder missing above it is made, and said).")
@diverse_options
def show(object_name: str, hand: str, db_path: Path, rank: int, top: int | None, out: Path, diverse: bool,
         min_translation: float, min_rotation: float) -> None:
    """Render grasps (hand closed on the object, contacts, friction cones) to a PNG."""
    if top is not None:
        unused(["rank"], "--top draws the K best instead")
    folder = missing_folder(out)
    grasps = api.show(object_name, hand, out, db_path=db_path, rank=rank, top=top,
                      spacing=spacing(diverse, min_translation, min_rotation))
    click.echo(f"{out}: {len(grasps)} grasp(s) from {len(grasps) and 3} viewpoints{made(folder)}")


def _misses(misses: list[tuple[int, str]]) -> str:
    """Why the best ranks tried were not reachable: the first few, and the
    count of each reason; then why the grasps planned on the spot (rank 0)
    were not."""
    from collections import Counter

    stored = [(rank, why) for rank, why in misses if rank]
    planned = [why for rank, why in misses if not rank]
    text = "no stored grasp tried"
    if stored:
        first = ", ".join(f"#{rank}: {why}" for rank, why in stored[:3])
        counts = "; ".join(f"{n} x {why}" for why, n in Counter(w for _, w in stored).most_common())
        text = f"nearest ranks tried {first}; of {len(stored)} tried: {counts}"
    if planned:
        counts = "; ".join(f"{n} x {why}" for why, n in Counter(planned).most_common())
        text += f"; planned on the spot with the table: {counts}"
    return text


def _on_table(name: str, hand: str, db_path: Path, top: int, table_at: str, poses: int, robot_base: str | None,
              max_candidates: int, as_json: bool, plan: bool, seed: int, rule: object, model: object) -> None:
    tables = api.best_on_table(name, hand, db_path=db_path, top=top, at=floats(table_at, "--table-at") or (),
                               poses=poses, robot_base=floats(robot_base, "--robot-base"),
                               max_candidates=max_candidates, plan=plan, seed=seed)
    if as_json:
        outside = api.p_hold_outside(name, hand, db_path=db_path)
        echo_json([{**t.to_json(), "grasps": [{**r.to_json(), "frames": _frames_json(r.grasp, t.object_pose, rule,
                                                                                       model), "in_sample": s}
                                              for r, s in zip(t.grasps, api.in_sample(db_path, hand,
                                                                                      [r.grasp for r in t.grasps]))],
                    "p_hold_outside": outside} for t in tables])
    for i, t in enumerate(tables if not as_json else ()):
        pose = ",".join(repr(v) for v in t.object_pose7())  # whole: the same command with it repeats the search
        click.echo(f"resting pose {i + 1} of {len(tables)} (probability {t.resting.probability:.2f}): "
                   f"--object-pose {pose}")
        if not t.grasps:
            click.echo(f"    no grasp among the top {max_candidates} is reachable ({_misses(t.misses)})")
        for r in t.grasps:
            _print_grasp(r.grasp, t.object_pose, {"the grasp": r.arm_grasp, "the pre-grasp": r.arm_pregrasp}, rule,
                         model, api.object_up(r.grasp.object, db_path=db_path))
    shown = [r.grasp.object for t in tables for r in t.grasps]
    if shown:  # with --json its notes on stderr, p_hold_outside and in_sample as keys
        _extrapolated(shown[0], hand, db_path, [] if as_json else api.p_hold_outside(shown[0], hand, db_path=db_path))
        if not as_json:
            _in_sample([r.grasp for t in tables for r in t.grasps], hand, db_path)
    if not any(t.grasps for t in tables):
        planned = any(api.planned_on_table(name, hand, t.object_pose7(), db_path=db_path) for t in tables)
        table = "" if planned else f", or grasps planned on the table (`{api.table_command(name, hand, db_path)}`)"
        raise NotFoundError(f"no grasp among the top {max_candidates} is reachable in the {len(tables)} most probable "
                            f"resting poses; try --max-candidates {max_candidates * 4}, another --table-at{table}")
