"""``grasp validate`` and ``grasp report``: physical validation and how well
the scores predict it."""

from __future__ import annotations

from pathlib import Path

import click

from planner import api
from planner.cli.app import (
    db_option,
    echo_json,
    made,
    missing_folder,
    report_failures,
    share,
    show_preparation,
    unused,
)
from planner.validation.mujoco_settings import DEFAULT_ENGINE, ENGINES


@click.command()
@db_option
@click.option("--object", "objects", multiple=True, help="Only these objects (repeat).")
@click.option("--hand", "hands", multiple=True, help="Only these hands (repeat).")
@click.option("--top", type=int, default=10, show_default=True,
              help="Validate each object's K best grasps (grasps force closure as planned, or once squeezed where "
                   "that squeeze's end is not stored beside them, rank first).")
@click.option("--sample", type=int, default=None,
              help="Instead: a uniform sample of N of each object's grasps, drawn with --seed.")
@click.option("--all", "every", is_flag=True, help="Instead: every stored grasp.")
@click.option("--force-closure", "closure_only", is_flag=True,
              help="Of the grasps that rank first only: force closure as planned, or once squeezed where that "
                   "squeeze's end is not stored beside it (the end is tried for it).")
@click.option("--robust", "robust_samples", type=click.IntRange(min=0), default=10, show_default=True,
              help="Noise samples for robust epsilon (0: skip).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of --sample and of the robust noise.")
@click.option("--engine", type=click.Choice(ENGINES), default=DEFAULT_ENGINE, show_default=True,
              help="The dynamic trial: MuJoCo's, or PyBullet's shake trial (another engine and protocol); each "
                   "stores its verdicts apart; a grasp's label and rank take MuJoCo's where it has one.")
@click.option("--workers", type=click.IntRange(min=1), default=api.default_workers(),
              show_default="all cores")
@click.option("--json", "as_json", is_flag=True)
def validate(db_path: Path, objects: tuple[str, ...], hands: tuple[str, ...], top: int, sample: int | None,
             every: bool, closure_only: bool, robust_samples: int, seed: int, engine: str, workers: int,
             as_json: bool) -> None:
    """Shake-test grasps in PyBullet or MuJoCo (the best, a sample or all), add robust epsilon, re-rank.

    The first run on a concave mesh decomposes it into convex parts (CoACD, seconds to minutes,
    cached afterwards); a line on stderr says when that starts and ends."""
    if sample is not None or every:
        unused(["top"], "--sample and --all choose the grasps instead")
    show_preparation(not as_json)
    objects = api.stored_names(objects, db_path=db_path)  # a mesh file's path: the object stored from it
    summary = api.validate(db_path, objects=list(objects) or None, hands=list(hands) or None, top=top,
                           sample=sample, every=every, robust_samples=robust_samples, seed=seed, workers=workers,
                           closure_only=closure_only, engine=engine)
    if as_json:
        echo_json(summary.to_json())
    else:
        click.echo(_tried(summary, engine, closure_only)
                   + (f"; {summary.diverged} diverged (MuJoCo's state; no verdict, not stored)"
                      if summary.diverged else "")
                   + (f"; {summary.kept} already tried with these settings and seed, kept "
                      f"({summary.kept_successes} held)" if summary.kept else "")
                   + (f"; {summary.rounds} rounds (grasps that dropped left the top {top}, the next were tried)"
                      if summary.rounds > 1 else "")
                   + (f"; stopped at {summary.cap} tried of {', '.join(summary.capped)}: its best {top} are not "
                      "all tried (run again to go on)" if summary.capped else ""))
    if engine == "mujoco":  # PyBullet's shake loads the object along the hand's six axes, whatever its up
        _untold(db_path, objects, hands)
    report_failures(summary.failed_tasks)


def _untold(db_path: Path, objects: tuple[str, ...], hands: tuple[str, ...]) -> None:
    """A note on stderr per object an import took standing on an up no one gave: its trials load it along that
    up's reverse, along its side where it stands otherwise (an ACRONYM mesh, on +y, imported without --up)."""
    for (name, hand), up in sorted(api.untold_ups(db_path=db_path, objects=list(objects) or None,
                                                  hands=list(hands) or None).items()):
        click.echo(f"note: '{name}' ({hand}) was imported from a file without object/up and taken standing on {up} "
                   f"(no --up, sidecar or registry gave one): its trials load it along its frame's {_down(up)}; if "
                   "it stands on another axis (ACRONYM's own meshes stand on +y), these verdicts are of it lying on "
                   "its side: import the file again with --up AXIS into another --db", err=True)


def _down(up: str) -> str:
    return ("-" if up.startswith("+") else "+") + up[1:]


def _tried(summary: api.ValidationSummary, engine: str, closure_only: bool) -> str:
    """The summary line's start: the verdicts given, or why none was (never "validated 0 grasps: 0 held (0%)")."""
    if summary.grasps:
        return (f"validated {summary.grasps} grasps in {engine}: {summary.successes} held "
                f"({share(summary.successes, summary.grasps)})")
    if summary.diverged or summary.failed_tasks:  # grasps were selected and tried: none came back with a verdict
        return f"no grasp given a verdict in {engine}" + (": its trials failed (below)" if summary.failed_tasks
                                                         else "")
    return f"nothing new to try in {engine}" + ("" if summary.kept else ": no stored grasp is selected"
                                                + (" (none is force closure as planned or once squeezed)"
                                                   if closure_only else ""))


@click.command()
@db_option
@click.option("--out", type=click.Path(path_type=Path), default=Path("report.html"), show_default=True,
              help="report.html (one self-contained file) or a folder (report.md + PNGs); a folder missing above "
              "it is made, and said.")
def report(db_path: Path, out: Path) -> None:
    """How well epsilon, robust epsilon and reachability predict simulated success; the
    reliability diagram and expected calibration error of p_hold; and how much of each object's
    surface its top grasps' contacts cover."""
    folder = missing_folder(out)  # a folder --out is the report's own: made as export's is
    path, lines = api.report_and_errors(db_path, out)
    click.echo(f"{path}{made(folder)}")
    for line in lines:
        click.echo(line)
    for line in api.coverage(db_path):
        click.echo(line.line())
