"""``grasp export`` and ``grasp import``: dataset files out of and into a database."""

from __future__ import annotations

from pathlib import Path

import click

from planner import api
from planner.cli.app import (
    LazyHelp,
    db_option,
    diverse_options,
    echo_json,
    rate_text,
    report_failures,
    show_preparation,
    spacing,
)


@click.command(name="export")
@db_option
@click.option("--format", "fmt", required=True, metavar="FORMAT", cls=LazyHelp,
              help_text=lambda: f"One of: {', '.join(api.EXPORT_FORMATS)}.")
@click.option("--out", "out_dir", type=click.Path(path_type=Path), required=True,
              help="Output folder (created if missing).")
@click.option("--object", "objects", metavar="NAME", multiple=True, help="Only this object (repeat).")
@click.option("--hand", "hands", metavar="H", multiple=True, help="Only this hand (repeat).")
@click.option("--min-epsilon", type=float, help="Only grasps with epsilon >= this.")
@click.option("--top", type=int, help="Only the K best-ranked grasps per (object, hand).")
@click.option("--quiet", is_flag=True, help="Print nothing on success.")
@click.option("--json", "as_json", is_flag=True, help="Print a machine-readable summary.")
@click.option("--label", default="best", show_default=True, type=click.Choice(["best", "file_label",
              "p_hold_trial", "trial", "p_hold", "force_closure"]),
              help="The success label written: per grasp the label of the file it was imported from, else p_hold "
              "updated by its trial's verdict >= 0.5, else the trial's verdict, else p_hold >= 0.5, else the "
              "force-closure flag (best); or one of them (all but force_closure export only grasps that have one).")
@diverse_options
def export(db_path: Path, fmt: str, out_dir: Path, objects: tuple[str, ...], hands: tuple[str, ...],
           min_epsilon: float | None, top: int | None, quiet: bool, as_json: bool, label: str, diverse: bool,
           min_translation: float, min_rotation: float) -> None:
    """Export grasps as dataset files: acronym (HDF5 per object and hand),
    graspgen (JSON per object and hand), dexgraspnet (.npy per object and
    hand), moveit (YAML of moveit_msgs/Grasp per object and hand), parquet or
    csv (one table of all grasps)."""

    def progress(path: Path, count: int) -> None:
        if not quiet and not as_json:
            click.echo(f"{path}: {count} grasps")

    objects = api.stored_names(objects, db_path=db_path)  # a mesh file's path: the object stored from it
    summary = api.export(db_path, fmt, out_dir, objects=objects, hands=hands, min_epsilon=min_epsilon, top=top,
                         spacing=spacing(diverse, min_translation, min_rotation), label=label, progress=progress)
    if as_json:
        echo_json(summary.to_json())
    elif not quiet:
        click.echo(f"exported {summary.grasps} grasps as {fmt} to {len(summary.files)} file(s) in {out_dir} "
                   f"({rate_text(summary.grasps, summary.seconds, 'grasps')})")
        for note in summary.notes:
            click.echo(f"note: {note}", err=True)


@click.command(name="import")
@click.argument("paths", metavar="PATH...", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--format", "fmt", default="acronym", show_default=True, metavar="FORMAT", cls=LazyHelp,
              help_text=lambda: f"Input format: {', '.join(api.IMPORT_FORMATS)} (HDF5, this project's or foreign).")
@db_option
@click.option("--hand", help="Hand name, when the file's gripper/type is not one (see `grasp hands`).")
@click.option("--object", "object_name", metavar="NAME",
              help="Built-in object name or mesh path (default: the built-in its object/name names where that is its "
                   "mesh, else its object/file, named by its object/name or else by the file's name without .h5).")
@click.option("--rescore", is_flag=True, help="Re-close and re-score every pose even if the file has qualities: "
              "from the opening the file planned it with (this project's files: its joints_open and preshape) where "
              "that open hand is within its limits and free at the pose, else from the widest preshape (ACRONYM's "
              "own files), backed off while it collides.")
@click.option("--up", help="The objects' up where a file gives none (object/up): +x -x +y -y +z -z; ACRONYM's own "
              "meshes stand on +y [default: a mesh's sidecar TOML, else the mesh file's, +z for an OBJ, said on "
              "stderr].")
@click.option("--mass", type=float, help="One mass [kg] for the object of every file of the command that gives none "
              "(object/mass); a file whose own object/mass differs is refused: import the files that lack one in a "
              "command of their own [default: a mesh's sidecar TOML, the registry's, else 0.2, said on stderr].")
@click.option("--friction", type=float, help="One Coulomb friction coefficient, 0 < mu <= 3, for the object of every "
              "file of the command that gives none (object/friction), as --mass [default: a mesh's sidecar TOML, the "
              "registry's, else 0.5, said].")
@click.option("--workers", type=click.IntRange(min=1), default=api.default_workers(),
              show_default="all cores",
              help="Worker processes for re-scoring.")
@click.option("--json", "as_json", is_flag=True, help="Print a machine-readable summary.")
def import_files(paths: tuple[Path, ...], fmt: str, db_path: Path, hand: str | None, object_name: str | None,
                 rescore: bool, up: str | None, mass: float | None, friction: float | None, workers: int,
                 as_json: bool) -> None:
    """Import grasp files into the database (one unit per file; a file
    imported before is skipped). Files without this project's qualities are
    re-scored by closing the hand at each pose (see --rescore for the opening it closes from)."""

    def progress(r: api.ImportResult) -> None:
        if as_json:
            return
        if r.same_as is not None:  # a failed one's error is said at the end, for each path given
            if not r.error:
                same = "given again" if r.same_as == r.path else f"the same file as {r.same_as}"
                click.echo(f"{r.path}: {same} ({r.object}/{r.hand}); read once")
            return
        if r.skipped:
            click.echo(f"{r.path}: already imported as {r.object}/{r.hand}; skipped")
            if r.unstored_labels:  # imported before schema v16: its grasps are stored, its labels never were
                click.echo(f"note: {r.path}: the labels of its {r.unstored_labels} grasps stored are not in {db_path} "
                           "(imported before the database kept a file's own labels); import it into a new --db to "
                           "keep them", err=True)
            return
        if r.error:
            return  # one error line each at the end
        how = "re-scored" if r.rescored else "imported"
        dropped = f"; dropped: {', '.join(f'{k} {v}' for k, v in sorted(r.rejected.items()))}" if r.rejected else ""
        kept = f"; the file's labels kept: {r.labels[0]} held, {r.labels[1]} dropped" if sum(r.labels) else ""
        click.echo(f"{r.path}: {how} {r.grasps} grasps ({r.force_closure} force-closure) as {r.object}/{r.hand}"
                   f"{dropped}{kept}")
        if kept and api.fitted_on(db_path, r.hand, r.path):
            click.echo(f"note: {r.path}: the {r.hand}'s p_hold model was fitted on this file's labels: p_hold and the "
                       "score against them (`grasp report`) are in-sample, no check of it", err=True)

    show_preparation(not as_json)  # a mesh repaired (ACRONYM's are often open): one line each, the first time only
    results = api.import_files(paths, db_path, fmt=fmt, hand=hand, object_name=object_name, rescore=rescore,
                               workers=workers, progress=progress, up=up, mass=mass, friction=friction)
    if as_json:
        echo_json([r.to_json() for r in results])
    report_failures({str(r.path): r.error for r in results if r.error})
