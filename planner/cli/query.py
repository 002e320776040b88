"""``grasp best`` and ``grasp show``: the stored grasps, in rank order."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from planner import api
from planner.cli.app import EXIT_OTHER, db_option, floats


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
def best(object_name: str, hand: str, db_path: Path, top: int, object_pose: str | None, robot_base: str | None,
         max_candidates: int, as_json: bool) -> None:
    """The best grasps of OBJECT for a hand, from the database."""
    if object_pose is None:
        if robot_base is not None:
            raise click.BadParameter("--robot-base needs --object-pose")
        grasps = api.best(object_name, hand, db_path=db_path, top=top)
        if as_json:
            click.echo(json.dumps([g.to_json() for g in grasps], indent=2))
            return
        for g in grasps:
            _print_grasp(g)
        return
    found = api.best_at(object_name, hand, floats(object_pose) or (), db_path=db_path, top=top,
                        robot_base=floats(robot_base), max_candidates=max_candidates)
    if as_json:
        click.echo(json.dumps([r.to_json() for r in found], indent=2))
        return
    if not found:
        click.echo(f"no grasp among the top {max_candidates} is reachable at that pose", err=True)
        sys.exit(EXIT_OTHER)
    for r in found:
        _print_grasp(r.grasp)
        click.echo("    arm at grasp: " + ", ".join(f"{k}={v:.3f}" for k, v in r.arm_grasp.items()))
        click.echo("    arm at pre-grasp: " + ", ".join(f"{k}={v:.3f}" for k, v in r.arm_pregrasp.items()))


def _print_grasp(g: api.Grasp) -> None:
    pos = g.pose[:3, 3]
    reach = "n/a" if g.reachability is None else f"{g.reachability:.2f}"
    p_hold = "n/a" if g.p_hold is None else f"{g.p_hold:.3f}"
    click.echo(f"#{g.rank} {g.object}/{g.hand} preshape={g.preshape} p_hold={p_hold} score={g.score:.4f} "
               f"epsilon={g.epsilon:.4f} "
               f"reachability={reach} volume={g.volume:.3g} force_closure={g.force_closure} "
               f"contacts={len(g.contacts)} position=({pos[0]:.3f}, {pos[1]:.3f}, {pos[2]:.3f}) m{_measures(g)}")


def _measures(g: api.Grasp) -> str:
    m = g.measures
    if m is None:
        return ""
    settled = "" if m.settled_epsilon is None else f" settled_epsilon={m.settled_epsilon:.4f}"
    return (f" holds={m.resist_worst:.1f}g (mean {m.resist_mean:.1f}g) push={m.push:.2f} "
            f"feasibility={','.join(m.reasons) or 'ok'}{settled}")


@click.command()
@click.argument("object_name", metavar="OBJECT")
@click.option("--hand", required=True)
@db_option
@click.option("--rank", type=int, default=1, show_default=True, help="Which grasp (1 = best).")
@click.option("--top", type=int, help="A contact sheet of the K best grasps instead.")
@click.option("--out", type=click.Path(path_type=Path), default=Path("grasp.png"), show_default=True)
def show(object_name: str, hand: str, db_path: Path, rank: int, top: int | None, out: Path) -> None:
    """Render grasps (hand closed on the object, contacts, friction cones) to a PNG."""
    grasps = api.show(object_name, hand, out, db_path=db_path, rank=rank, top=top)
    click.echo(f"{out}: {len(grasps)} grasp(s) from {len(grasps) and 3} viewpoints")
