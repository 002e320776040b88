"""``grasp best`` and ``grasp show``: the stored grasps, in rank order."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from planner import api
from planner.cli.app import EXIT_OTHER, db_option, diverse_options, floats, spacing


@click.command()
@click.argument("object_name", metavar="OBJECT")
@click.option("--hand", required=True)
@db_option
@click.option("--top", type=int, default=1, show_default=True)
@click.option("--object-pose", help="x,y,z,qx,qy,qz,qw of the object on the table (world frame): return only "
              "grasps an arm reaches there now, with joint solutions.")
@click.option("--robot-base", help="x,y,z,qx,qy,qz,qw of the robot base (default: the origin).")
@click.option("--max-candidates", type=int, default=api.MAX_CANDIDATES, show_default=True,
              help="With --object-pose: how many top-ranked grasps to try at most.")
@click.option("--json", "as_json", is_flag=True)
@diverse_options
def best(object_name: str, hand: str, db_path: Path, top: int, object_pose: str | None, robot_base: str | None,
         max_candidates: int, as_json: bool, diverse: bool, min_translation: float, min_rotation: float) -> None:
    """The best grasps of OBJECT for a hand, from the database."""
    apart = spacing(diverse, min_translation, min_rotation)
    if object_pose is None:
        if robot_base is not None:
            raise click.BadParameter("--robot-base needs --object-pose")
        grasps = api.best(object_name, hand, db_path=db_path, top=top, spacing=apart)
        if as_json:
            click.echo(json.dumps([{**g.to_json(), "frames": _frames_json(g)} for g in grasps], indent=2))
            return
        for g in grasps:
            _print_grasp(g)
        return
    if apart is not None:
        raise click.BadParameter("--diverse is not yet available with --object-pose")
    found = api.best_at(object_name, hand, floats(object_pose) or (), db_path=db_path, top=top,
                        robot_base=floats(robot_base), max_candidates=max_candidates)
    world = api.object_pose_matrix(floats(object_pose) or ())
    if as_json:
        click.echo(json.dumps([{**r.to_json(), "frames": _frames_json(r.grasp, world)} for r in found], indent=2))
        return
    if not found:
        click.echo(f"no grasp among the top {max_candidates} is reachable at that pose", err=True)
        sys.exit(EXIT_OTHER)
    for r in found:
        _print_grasp(r.grasp, world, {"the grasp": r.arm_grasp, "the pre-grasp": r.arm_pregrasp})


def _print_grasp(g: api.Grasp, world: object = None, arm: dict | None = None) -> None:
    from planner.present.describe import describe

    spec, _ = api.hand(g.hand)
    for line in describe(g, spec, world, arm):  # type: ignore[arg-type]
        click.echo(line)


def _frames_json(g: api.Grasp, world: object = None) -> dict:
    from planner.present.describe import frames

    spec, _ = api.hand(g.hand)
    out = {"object_frame": frames(g, spec).to_json()}
    if world is not None:
        out["world_frame"] = frames(g, spec, world).to_json()  # type: ignore[arg-type]
    return out


@click.command()
@click.argument("object_name", metavar="OBJECT")
@click.option("--hand", required=True)
@db_option
@click.option("--rank", type=int, default=1, show_default=True, help="Which grasp (1 = best).")
@click.option("--top", type=int, help="A contact sheet of the K best grasps instead.")
@click.option("--out", type=click.Path(path_type=Path), default=Path("grasp.png"), show_default=True)
@diverse_options
def show(object_name: str, hand: str, db_path: Path, rank: int, top: int | None, out: Path, diverse: bool,
         min_translation: float, min_rotation: float) -> None:
    """Render grasps (hand closed on the object, contacts, friction cones) to a PNG."""
    grasps = api.show(object_name, hand, out, db_path=db_path, rank=rank, top=top,
                      spacing=spacing(diverse, min_translation, min_rotation))
    click.echo(f"{out}: {len(grasps)} grasp(s) from {len(grasps) and 3} viewpoints")
