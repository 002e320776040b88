"""``grasp view``: the browser viewer (:mod:`planner.present.viewer`)."""

from __future__ import annotations

import time
from pathlib import Path

import click

from planner import api
from planner.cli.app import db_option, diverse_options, floats, spacing


@click.command()
@click.argument("object_name", metavar="OBJECT")
@click.option("--hand", "hands", multiple=True, help="Hand(s) to show (repeat; default: every hand with grasps).")
@db_option
@click.option("--top", type=int, default=50, show_default=True, help="How many best grasps of each hand to list.")
@click.option("--host", default="127.0.0.1", show_default=True, help="Address to serve on (0.0.0.0: every interface).")
@click.option("--port", type=int, default=8080, show_default=True,
              help="Port to serve on; taken by another program: the next free one, said on stderr (0: any free one).")
@click.option("--object-pose", help="x,y,z,qx,qy,qz,qw of the object (world frame): list only grasps the arm "
              "reaches there, and draw the arm.")
@click.option("--robot-base", help="x,y,z,qx,qy,qz,qw of the robot base (default: the origin).")
@diverse_options
def view(object_name: str, hands: tuple[str, ...], db_path: Path, top: int, host: str, port: int,
         object_pose: str | None, robot_base: str | None, diverse: bool, min_translation: float,
         min_rotation: float) -> None:
    """Browse OBJECT's grasps in 3D in a web browser: the hand closed and open,
    contacts with friction cones, the approach, the arm; filters and measures."""
    if robot_base is not None and object_pose is None:
        raise click.BadParameter("--robot-base needs --object-pose")
    viewer = api.view(object_name, hands or None, db_path=db_path, top=top, host=host, port=port,
                      object_pose=floats(object_pose, "--object-pose"), robot_base=floats(robot_base, "--robot-base"),
                      spacing=spacing(diverse, min_translation, min_rotation))
    served = viewer.server.get_port()
    if port and served != port:  # viser moves on to the next free port without a word: a bookmark would miss it
        click.echo(f"grasp view: port {port} is in use: serving on port {served} instead", err=True)
    click.echo(f"grasp viewer: {viewer.url} ({len(viewer.entries)} grasps; Ctrl-C to stop)")
    try:
        while True:
            time.sleep(3600)
    finally:
        viewer.stop()
