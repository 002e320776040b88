"""``grasp generate``: sweep objects for a hand into a database, with a progress bar."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click

from planner import api
from planner.cli.app import db_option, echo_json, floats, per_second, report_failures, show_preparation, unused

DEFAULTS = api.SweepSettings()


@click.command(help=f"""Sweep preshapes x approaches x rolls x standoffs and store the grasps.

    OBJECT: a built-in name, random_NNN, a mesh or URDF file, a folder, a glob, @manifest.txt (one object per
    line: {api.MANIFEST_LINE}), builtin:all, builtin:random[:COUNT | :FIRST-LAST]. A mesh or URDF file's sidecar
    (banana.obj + banana.toml) may give mass or density, friction, up and com = [x, y, z] (its centre of mass [m],
    object frame); a URDF gives its own below it (its <inertial> masses and origins, its
    <contact><lateral_friction>); a URDF's sidecar may give geometry = "visual".
    """)
@click.argument("names", metavar="OBJECT...", nargs=-1, required=True)
@click.option("--hand", required=True, help="Hand name (see `grasp hands`).")
@db_option
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--approaches", type=int, help="Approach rays (surface sampler) or surface points (antipodal) per "
              "object [default: the sampler's: " + ", ".join(f"{k} {v['approaches']}" for k, v in
                                                            api.SAMPLER_DEFAULTS.items() if k != "box") + "].")
@click.option("--sampler", type=click.Choice(api.SAMPLERS),
              help="surface or box: OpenRAVE-style approach rays (multi-finger hands); antipodal: point pairs "
                   "for parallel jaws [default: the hand's, from its hand.toml].")
@click.option("--box-delta", type=float, default=DEFAULTS.box_delta, show_default=True,
              help="Grid spacing of the box sampler [m].")
@click.option("--rolls", type=int, help="Rolls about each ray; antipodal: approach directions about each closing "
              "axis [default: the sampler's: " + ", ".join(f"{k} {v['rolls']}" for k, v in
                                                          api.SAMPLER_DEFAULTS.items() if k != "box") + "].")
@click.option("--depths", help="Antipodal: comma-separated depths [m] of the tool centre point past the chord's "
              "middle [default: " + ",".join(f"{d:g}" for d in DEFAULTS.depths) + "].")
@click.option("--fan", "fan_count", type=int, default=0, show_default=True, help="Tilted directions per ray.")
@click.option("--standoffs", help="Comma-separated standoffs [m] (default: each preshape's).")
@click.option("--preshapes", "preshape_names", help="Comma-separated preshape names (default: all).")
@click.option("--scale", type=float, help="Scale for mesh and URDF files (e.g. 0.001 for millimetres).")
@click.option("--mass", type=float, help="Mass of every object given [kg] (a manifest line's own wins) "
              "[default: a mesh's or URDF's sidecar TOML, a URDF's <inertial> masses, the registry's, else 0.2].")
@click.option("--density", type=float, help="Uniform density of every object given [kg/m^3]: the mass is density "
              "x the mesh's volume; excludes --mass.")
@click.option("--friction", type=float, help="Coulomb friction coefficient of every object given, 0 < mu <= 3 "
              "[default: a mesh's or URDF's sidecar TOML, a URDF's <lateral_friction>, the registry's, else 0.5].")
@click.option("--up", help="The axis of every object's file that is up as it stands: +x -x +y -y +z -z (x, y, z "
              "mean +); its grip measures and its MuJoCo trial's weight read it; the file's frame is kept "
              "[default: a mesh's or URDF's sidecar TOML, else +y for .glb/.gltf (glTF's own), else +z].")
@click.option("--geometry", type=click.Choice(api.GEOMETRIES), help="Which elements of every URDF file given "
              "make the object: collision (what PyBullet simulates) or visual (the drawn shape, where a collision "
              "mesh is a rough stand-in); refused for other objects [default: a URDF's sidecar TOML, else "
              "collision where the file has any].")
@click.option("--workers", type=click.IntRange(min=1), default=api.default_workers(),
              show_default="all cores",
              help="Worker processes.")
@click.option("--ray", "ray_target", is_flag=False, flag_value="local", default=None, metavar="[ADDRESS]",
              help="Run on Ray: a cluster address (e.g. ray://head:10001 or auto), or no value for a local "
                   "Ray instance with --workers CPUs. Needs pip install -e '.[ray]'.")
@click.option("--unit-timeout", type=float, help="Give up on a unit of work after this many seconds.")
@click.option("--chunk", type=int, help="Approach rays or points per unit of work (0: one unit per object) "
              "[default: the sampler's: " + ", ".join(f"{k} {v['chunk']}" for k, v in
                                                     api.SAMPLER_DEFAULTS.items() if k != "box") + "].")
@click.option("--reach-placements", type=int, default=DEFAULTS.reach_placements, show_default=True,
              help="Table placements for the stored reachability score (0: skip).")
@click.option("--reach-top", type=int, default=DEFAULTS.reach_top, show_default=True,
              help="Reachability for this many force-closure grasps per unit of work, highest epsilon first "
                   "(0: all). `grasp best --object-pose` checks any grasp exactly.")
@click.option("--volume", is_flag=True, help="Also compute the grasp wrench space volume of force-closure grasps "
              "(a full 6-D hull: 0.3 s per many-contact grasp); without it the stored volume is 0.")
@click.option("--settle/--no-settle", default=None, help="Measure the settled epsilon of every force-closure "
              "grasp (a dynamic closing on the free object: the Barrett's ~16 ms per grasp) [default: the hand's "
              "`settle` in hand.toml].")
@click.option("--fc-budget", type=int, default=DEFAULTS.fc_budget, show_default=True,
              help="About this many force-closure grasps per object: each of its units of work stops trying new "
                   "rays or points once it has its share (the budget / the object's units, rounded up); 0: no "
                   "limit.")
@click.option("--reach-weight", type=float, help="Weight of reachability in the score, 0..1 (default: the "
              "database's rule, else 0.5).")
@click.option("--on-table", is_flag=True, help="Plan on a table: for each object in each of its most probable "
              "resting poses (--stable-poses), with the table top as an obstacle, approaches from above its level "
              "only and the pre-grasp clear of it; the grasps record the table plane, and `grasp best "
              "--object-pose/--on-table` tries them first.")
@click.option("--stable-poses", type=click.IntRange(min=1), default=3, show_default=True,
              help="With --on-table: how many resting poses, most probable first.")
@click.option("--replace", is_flag=True, help="Sweep again an object stored for this hand and seed with other "
              "settings (another planner version, budget, reach settings...: the same candidates), then remove the "
              "stored sweep, its grasps and their trials, once the new one is whole; without it such a run is "
              "refused (it would store every grasp twice).")
@click.option("--quiet", is_flag=True, help="No progress bar and no summary table.")
@click.option("--json", "as_json", is_flag=True, help="Print a machine-readable summary.")
def generate(names: tuple[str, ...], hand: str, db_path: Path, seed: int, approaches: int | None,
             sampler: str | None, box_delta: float, rolls: int | None, depths: str | None, fan_count: int,
             standoffs: str | None, preshape_names: str | None, scale: float | None, mass: float | None,
             density: float | None, friction: float | None, up: str | None, geometry: str | None, workers: int,
             ray_target: str | None, unit_timeout: float | None, chunk: int | None, reach_placements: int,
             reach_top: int, volume: bool, settle: bool | None, fc_budget: int, reach_weight: float | None,
             on_table: bool, stable_poses: int, replace: bool, quiet: bool, as_json: bool) -> None:
    """Sweep objects for a hand into the database (the help text: the decorator's, which names the manifest
    line as the manifest reader declares it)."""
    if not on_table:
        unused(["stable_poses"], "used with --on-table only")
    settings = api.SweepSettings(approaches=approaches, sampler=sampler, box_delta=box_delta, rolls=rolls,
                                 depths=floats(depths, "--depths") or DEFAULTS.depths, fan_count=fan_count,
                                 standoffs=floats(standoffs, "--standoffs"), chunk=chunk,
                                 reach_placements=reach_placements,
                                 reach_top=reach_top, volume=volume, settle=settle, fc_budget=fc_budget,
                                 preshapes=tuple(preshape_names.split(",")) if preshape_names is not None else None)
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    show = not quiet and not as_json
    show_preparation(show)  # a mesh repaired, a proxy that did not fit: one line each, the first time only
    # the bar starts when the work does (the first progress call): an input error comes alone. It counts
    # candidates, finished ones of the running units included, so its ETA shows within seconds.
    bar = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[candidates]} candidates"),
                   TextColumn("{task.fields[units]} units"),
                   TextColumn("{task.fields[grasps]} grasps, {task.fields[fc]} force-closure, {task.fields[rate]}"),
                   TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(), disable=not show,
                   console=_console())  # in a log, its last line whole (it read "generat… 32768/32768 candida…")
    counts = {"grasps": 0, "fc": 0}
    started = time.perf_counter()
    tasks: list = []

    def advance(p: api.GenerateProgress) -> None:
        if p.result is not None:
            counts["grasps"] += len(p.result.grasps)
            counts["fc"] += p.result.force_closure
        rate = per_second(p.candidates_done, time.perf_counter() - started)
        total = "?" if p.candidates_total is None else str(p.candidates_total)
        shown = dict(total=p.candidates_total, completed=p.candidates_done, candidates=f"{p.candidates_done}/{total}",
                     units=f"{p.units_done}/{p.units_total}", grasps=counts["grasps"], fc=counts["fc"],
                     rate=f"{rate} cand/s")
        if tasks:
            bar.update(tasks[0], **shown)
        else:
            tasks.append(bar.add_task("generating", **shown))
            bar.start()

    rule = api.RankingRule(reach_weight) if reach_weight is not None else None
    try:
        summary = api.generate(names, hand, db_path=db_path, settings=settings, seed=seed, workers=workers,
                               scale=scale, rule=rule, progress=advance, use_ray=ray_target is not None,
                               ray_address=None if ray_target in (None, "local") else ray_target,
                               unit_timeout=unit_timeout, mass=mass, density=density, friction=friction, up=up,
                               geometry=geometry, on_table=stable_poses if on_table else 0, replace=replace)
    finally:
        if tasks:
            bar.stop()
    if as_json:
        echo_json(summary.to_json())
    elif not quiet:
        _print_summary(summary, db_path)
    report_failures(summary.failed)


def _console():  # type: ignore[no-untyped-def]
    """Rich's console: a terminal's width; written to a file or a pipe (a log), as wide as a line needs (Rich's
    80 columns cut the summary's headings to "obje…", "fric…" and the bar's last line)."""
    from rich.console import Console

    return Console() if sys.stdout.isatty() else Console(width=400)


def _closures(count: int, ends: int, long: bool = False) -> str:
    """Force-closure grasps, saying how many of them are squeezes' ends kept beside their parents (not new
    candidates: each is the turned pose of a planned grasp of the same candidate that is not force closure)."""
    said = f"{ends} of them squeezes' ends, each beside its parent" if long else f"{ends} ends"
    return f"{count} ({said})" if ends else str(count)


def _print_summary(summary: api.Summary, db_path: Path) -> None:
    from rich.table import Table

    table = Table(title=f"grasp generate -> {db_path}" + (" (this run's work)" if summary.skipped else ""))
    for col in ("object", "mass kg", "friction", "up", "units", "candidates", "grasps", "force-closure", "worker s",
                "error"):
        table.add_column(col)
    for row in summary.per_object:
        table.add_row(row["object"], "" if row["mass"] is None else f"{row['mass']:.4g}",
                      "" if row["friction"] is None else f"{row['friction']:.3g}", row["up"] or "", str(row["units"]),
                      str(row["candidates"]), str(row["grasps"]), _closures(row["force_closure"], row["ends"]),
                      f"{row['seconds']:.1f}",
                      "yes" if row["error"] else "")  # the error whole, once, on its own line below the table
    console = _console()
    console.print(table)
    console.print(f"candidates tried: {summary.candidates}, grasps with contacts: {summary.grasps}, "
                  f"force-closure: {_closures(summary.force_closure, summary.ends, long=True)}, "
                  f"skipped (already done): {summary.skipped}, "
                  f"time: {summary.seconds:.1f} s")
    if summary.finished_before:  # a resumed run's table lists only the objects it worked on
        console.print(f"finished by an earlier run, not in the table: {', '.join(summary.finished_before)}")
    if summary.rejected:
        console.print("rejected: " + ", ".join(f"{k} {v}" for k, v in sorted(summary.rejected.items())))
    if summary.replaced:
        console.print(f"replaced: {summary.replaced} grasps of the earlier sweeps removed (--replace)")
