"""The ``grasp`` command: parse, call :mod:`planner.api`, print.

Errors become one line on stderr and an exit code (2 bad input, 3 database,
4 simulator, 1 anything else); ``grasp --debug ...`` shows the traceback.
"""

from __future__ import annotations

import json
import logging
import sqlite3
import sys
import time
from pathlib import Path

import click
import numpy as np

from planner import api
from planner.db.ranking import RankingRule
from planner.db.store import GraspRow
from planner.errors import PlannerError
from planner.plan.sweep import SweepSettings
from planner.specs.hands import hand_names, load_hand
from planner.specs.objects import RANDOM_PREFIX, builtin_specs
from planner.specs.preshapes import load_preshapes

EXIT_INTERNAL = 1
EXIT_INTERRUPTED = 130


class Group(click.Group):
    """Maps every error to a one-line message and an exit code."""

    def invoke(self, ctx: click.Context) -> object:
        debug = "--debug" in sys.argv[1:] or (ctx.params or {}).get("debug", False)
        try:
            return super().invoke(ctx)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException):
            raise
        except PlannerError as exc:
            if debug:
                raise
            click.echo(f"grasp: error: {exc}", err=True)
            ctx.exit(exc.exit_code)
        except sqlite3.Error as exc:
            if debug:
                raise
            click.echo(f"grasp: error: database: {exc}", err=True)
            ctx.exit(3)
        except KeyboardInterrupt:
            click.echo("grasp: interrupted; finished units are saved, run the same command to resume", err=True)
            ctx.exit(EXIT_INTERRUPTED)
        except Exception as exc:
            if debug:
                raise
            click.echo(f"grasp: internal error: {type(exc).__name__}: {exc} (rerun with --debug for details)",
                       err=True)
            ctx.exit(EXIT_INTERNAL)
        return None


@click.group(cls=Group)
@click.option("--debug", is_flag=True, help="Show tracebacks and debug logging.")
@click.version_option(package_name="grasp-planner")
def main(debug: bool) -> None:
    """Knowledge-based grasp planner: build, query and export grasp databases."""
    logging.basicConfig(level=logging.DEBUG if debug else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")


def _floats(text: str | None) -> tuple[float, ...] | None:
    if text is None:
        return None
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise click.BadParameter(f"'{text}' is not a comma-separated list of numbers") from None


@main.command()
@click.argument("objects_", metavar="OBJECT...", nargs=-1, required=True)
@click.option("--hand", required=True, help="Hand name (see `grasp hands`).")
@click.option("--db", "db_path", type=click.Path(path_type=Path), default=api.DEFAULT_DB, show_default=True)
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--approaches", type=int, default=SweepSettings.approaches, show_default=True,
              help="Approach rays per object (surface sampler).")
@click.option("--sampler", type=click.Choice(["surface", "box"]), default="surface", show_default=True)
@click.option("--box-delta", type=float, default=SweepSettings.box_delta, show_default=True,
              help="Grid spacing of the box sampler [m].")
@click.option("--rolls", type=int, default=SweepSettings.rolls, show_default=True)
@click.option("--fan", "fan_count", type=int, default=0, show_default=True, help="Tilted directions per ray.")
@click.option("--standoffs", help="Comma-separated standoffs [m] (default: each preshape's).")
@click.option("--preshapes", "preshape_names", help="Comma-separated preshape names (default: all).")
@click.option("--scale", type=float, help="Scale for mesh files (e.g. 0.001 for millimetres).")
@click.option("--workers", type=int, default=api.default_workers(), show_default="all cores",
              help="Worker processes.")
@click.option("--ray", "ray_target", is_flag=False, flag_value="local", default=None, metavar="[ADDRESS]",
              help="Run on Ray: a cluster address (e.g. ray://head:10001 or auto), or no value for a local "
                   "Ray instance with --workers CPUs. Needs pip install -e '.[ray]'.")
@click.option("--unit-timeout", type=float, help="Give up on a unit of work after this many seconds.")
@click.option("--chunk", type=int, default=SweepSettings.chunk, show_default=True,
              help="Approach rays per unit of work (0: one unit per object).")
@click.option("--reach-placements", type=int, default=SweepSettings.reach_placements, show_default=True,
              help="Table placements for the stored reachability score (0: skip).")
@click.option("--reach-weight", type=float, help="Weight of reachability in the score, 0..1 (default: the "
              "database's rule, else 0.5).")
@click.option("--quiet", is_flag=True, help="No progress bar and no summary table.")
@click.option("--json", "as_json", is_flag=True, help="Print a machine-readable summary.")
def generate(objects_: tuple[str, ...], hand: str, db_path: Path, seed: int, approaches: int, sampler: str,
             box_delta: float, rolls: int, fan_count: int, standoffs: str | None, preshape_names: str | None,
             scale: float | None, workers: int, ray_target: str | None, unit_timeout: float | None, chunk: int,
             reach_placements: int, reach_weight: float | None,
             quiet: bool, as_json: bool) -> None:
    """Sweep preshapes x approaches x rolls x standoffs and store the grasps.

    OBJECT: a built-in name, random_NNN, a mesh file, a folder, a glob,
    @manifest.txt (one object per line, optional scale), builtin:all,
    builtin:random[:COUNT | :FIRST-LAST].
    """
    settings = SweepSettings(approaches=approaches, sampler=sampler, box_delta=box_delta, rolls=rolls,
                             fan_count=fan_count, standoffs=_floats(standoffs), chunk=chunk,
                             reach_placements=reach_placements,
                             preshapes=tuple(preshape_names.split(",")) if preshape_names else None)
    show = not quiet and not as_json
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total} units"),
                  TextColumn("{task.fields[grasps]} grasps, {task.fields[fc]} force-closure, {task.fields[rate]}"),
                  TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(), disable=not show) as bar:
        task = bar.add_task("generating", total=None, grasps=0, fc=0, rate="")
        counts = {"grasps": 0, "fc": 0, "candidates": 0}
        started = time.perf_counter()

        def advance(result: api.UnitResult | None, done: int, total: int) -> None:
            if result is None:
                bar.update(task, total=total)
                return
            counts["grasps"] += len(result.grasps)
            counts["fc"] += result.force_closure
            counts["candidates"] += result.candidates
            rate = counts["candidates"] / max(time.perf_counter() - started, 1e-9)
            bar.update(task, completed=done, grasps=counts["grasps"], fc=counts["fc"], rate=f"{rate:.0f} cand/s")

        rule = RankingRule(reach_weight) if reach_weight is not None else None
        summary = api.generate(objects_, hand, db_path=db_path, settings=settings, seed=seed, workers=workers,
                               scale=scale, rule=rule, progress=advance, use_ray=ray_target is not None,
                               ray_address=None if ray_target in (None, "local") else ray_target,
                               unit_timeout=unit_timeout)
    if as_json:
        click.echo(json.dumps(summary.to_json(), indent=2))
    elif not quiet:
        _print_summary(summary, db_path)
    for name, error in summary.failed.items():
        click.echo(f"grasp: error: {name}: {error}", err=True)
    if summary.failed:
        sys.exit(2)


def _print_summary(summary: api.Summary, db_path: Path) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"grasp generate -> {db_path}")
    for col in ("object", "units", "candidates", "grasps", "force-closure", "worker s", "error"):
        table.add_column(col)
    for row in summary.per_object:
        table.add_row(row["object"], str(row["units"]), str(row["candidates"]), str(row["grasps"]),
                      str(row["force_closure"]),
                      f"{row['seconds']:.1f}", row["error"] or "")
    console = Console()
    console.print(table)
    console.print(f"candidates tried: {summary.candidates}, grasps with contacts: {summary.grasps}, "
                  f"force-closure: {summary.force_closure}, skipped (already done): {summary.skipped}, "
                  f"time: {summary.seconds:.1f} s")
    if summary.rejected:
        console.print("rejected: " + ", ".join(f"{k} {v}" for k, v in sorted(summary.rejected.items())))


def grasp_json(row: GraspRow) -> dict:
    return {"object": row.object, "hand": row.hand, "preshape": row.preshape, "pose": row.pose,
            "joints": row.closed_joints, "open_joints": row.open_joints, "width": row.width,
            "epsilon": row.epsilon, "volume": row.volume, "force_closure": row.force_closure,
            "reachability": row.reachability, "manipulability": row.manipulability, "contacts": row.contacts,
            "rank": row.rank, "score": row.score, "candidate": row.candidate,
            "seed": row.seed}


@main.command()
@click.argument("object_name", metavar="OBJECT")
@click.option("--hand", required=True)
@click.option("--db", "db_path", type=click.Path(path_type=Path), default=api.DEFAULT_DB, show_default=True)
@click.option("--top", type=int, default=1, show_default=True)
@click.option("--object-pose", help="x,y,z,qx,qy,qz,qw of the object on the table (world frame): return only "
              "grasps an arm reaches there now, with joint solutions.")
@click.option("--robot-base", help="x,y,z,qx,qy,qz,qw of the robot base (default: the origin).")
@click.option("--max-candidates", type=int, default=300, show_default=True,
              help="With --object-pose: how many top-ranked grasps to try at most.")
@click.option("--json", "as_json", is_flag=True)
def best(object_name: str, hand: str, db_path: Path, top: int, object_pose: str | None, robot_base: str | None,
         max_candidates: int, as_json: bool) -> None:
    """The best grasps of OBJECT for a hand, from the database."""
    if object_pose is None:
        if robot_base is not None:
            raise click.BadParameter("--robot-base needs --object-pose")
        rows = api.best(object_name, hand, db_path=db_path, top=top)
        if as_json:
            click.echo(json.dumps([grasp_json(r) for r in rows], indent=2))
            return
        for r in rows:
            _print_grasp(r)
        return
    found = api.best_at(object_name, hand, _floats(object_pose) or (), db_path=db_path, top=top,
                        robot_base=_floats(robot_base), max_candidates=max_candidates)
    if as_json:
        click.echo(json.dumps([{**grasp_json(g.grasp), "arm": {"grasp": g.arm_grasp, "pregrasp": g.arm_pregrasp},
                                "arm_manipulability": g.manipulability, "hand_pose_world": g.hand_pose_world}
                               for g in found], indent=2))
        return
    if not found:
        click.echo(f"no grasp among the top {max_candidates} is reachable at that pose", err=True)
        sys.exit(1)
    for g in found:
        _print_grasp(g.grasp)
        click.echo("    arm at grasp: " + ", ".join(f"{k}={v:.3f}" for k, v in g.arm_grasp.items()))
        click.echo("    arm at pre-grasp: " + ", ".join(f"{k}={v:.3f}" for k, v in g.arm_pregrasp.items()))


def _print_grasp(r: GraspRow) -> None:
    pos = np.array(r.pose)[:3, 3]
    reach = "n/a" if r.reachability is None else f"{r.reachability:.2f}"
    click.echo(f"#{r.rank} {r.object}/{r.hand} preshape={r.preshape} score={r.score:.4f} epsilon={r.epsilon:.4f} "
               f"reachability={reach} volume={r.volume:.3g} force_closure={r.force_closure} "
               f"contacts={len(r.contacts)} position=({pos[0]:.3f}, {pos[1]:.3f}, {pos[2]:.3f}) m")


@main.command()
@click.argument("object_name", metavar="OBJECT")
@click.option("--hand", required=True)
@click.option("--db", "db_path", type=click.Path(path_type=Path), default=api.DEFAULT_DB, show_default=True)
@click.option("--rank", type=int, default=1, show_default=True, help="Which grasp (1 = best).")
@click.option("--top", type=int, help="A contact sheet of the K best grasps instead.")
@click.option("--out", type=click.Path(path_type=Path), default=Path("grasp.png"), show_default=True)
def show(object_name: str, hand: str, db_path: Path, rank: int, top: int | None, out: Path) -> None:
    """Render grasps (hand closed on the object, contacts, friction cones) to a PNG."""
    rows = api.show(object_name, hand, out, db_path=db_path, rank=rank, top=top)
    click.echo(f"{out}: {len(rows)} grasp(s) from {len(rows) and 3} viewpoints")


@main.command()
@click.option("--db", "db_path", type=click.Path(path_type=Path), default=api.DEFAULT_DB, show_default=True)
@click.option("--object", "objects_", multiple=True, help="Only these objects (repeat).")
@click.option("--hand", "hands_", multiple=True, help="Only these hands (repeat).")
@click.option("--top", type=int, default=10, show_default=True, help="Validate each object's K best grasps.")
@click.option("--robust", "robust_samples", type=int, default=10, show_default=True,
              help="Noise samples for robust epsilon (0: skip).")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--workers", type=int, default=api.default_workers(), show_default="all cores")
@click.option("--json", "as_json", is_flag=True)
def validate(db_path: Path, objects_: tuple[str, ...], hands_: tuple[str, ...], top: int, robust_samples: int,
             seed: int, workers: int, as_json: bool) -> None:
    """Shake-test the best grasps in PyBullet, add robust epsilon, re-rank."""
    from planner.validation.run import validate as run

    summary = run(db_path, objects=list(objects_) or None, hands=list(hands_) or None, top=top,
                  robust_samples=robust_samples, seed=seed, workers=workers)
    if as_json:
        click.echo(json.dumps(summary.to_json(), indent=2))
    else:
        click.echo(f"validated {summary.grasps} grasps: {summary.successes} held "
                   f"({summary.successes / max(summary.grasps, 1):.0%})")
    for name, error in summary.failed_tasks.items():
        click.echo(f"grasp: error: {name}: {error}", err=True)
    if summary.failed_tasks:
        sys.exit(2)


@main.command()
@click.option("--db", "db_path", type=click.Path(path_type=Path), default=api.DEFAULT_DB, show_default=True)
@click.option("--out", type=click.Path(path_type=Path), default=Path("report.html"), show_default=True,
              help="report.html (one self-contained file) or a folder (report.md + PNGs).")
def report(db_path: Path, out: Path) -> None:
    """How well epsilon, robust epsilon and reachability predict simulated success."""
    from planner.present import report as reporting

    click.echo(str(reporting.write(db_path, out)))


@main.command(name="hands")
@click.argument("name", required=False)
def hands_cmd(name: str | None) -> None:
    """List the built-in hands, or show one in detail."""
    if name is None:
        for hand_name in hand_names():
            spec = load_hand(hand_name)
            shapes = ", ".join(s.name for s in load_preshapes(spec))
            click.echo(f"{hand_name:12s} {len(spec.joints):2d} finger joints  preshapes: {shapes}  "
                       f"- {spec.description}")
        return
    spec = load_hand(name)
    click.echo(f"{spec.name}: {spec.description}\n  urdf: {spec.urdf}\n  root link: {spec.root_link}\n"
               f"  approach: {spec.approach.tolist()}  tcp: {spec.tcp.tolist()} m\n"
               f"  contact links: {', '.join(spec.contact_links)}")
    for j in spec.joints:
        extra = f" mimics {j.mimic} x{j.multiplier}" if j.mimic else f" close rate {j.close}"
        click.echo(f"  joint {j.name} ({j.kind}) [{j.lower}, {j.upper}]{extra}")
    for s in load_preshapes(spec):
        click.echo(f"  preshape {s.name} tags={','.join(s.tags)} '{s.taxonomy}' standoffs={list(s.standoffs)}")


@main.command(name="objects")
def objects_cmd() -> None:
    """List the built-in objects."""
    for name, spec in builtin_specs().items():
        click.echo(f"{name:10s} {spec.kind:8s} mass {spec.mass:.3f} kg  friction {spec.friction:.2f}  "
                   f"- {spec.description}")
    click.echo(f"{RANDOM_PREFIX}000 .. {RANDOM_PREFIX}999  the procedurally generated objects "
               "of pybullet_data/random_urdfs")


@main.group()
def db() -> None:
    """Database maintenance."""


@db.command()
@click.option("--db", "db_path", type=click.Path(path_type=Path), default=api.DEFAULT_DB, show_default=True)
def check(db_path: Path) -> None:
    """Run SQLite's integrity check on the database."""
    problems = api.check_db(db_path)
    if problems:
        for p in problems:
            click.echo(p, err=True)
        raise PlannerError(f"{db_path}: integrity check failed ({len(problems)} problems)")
    click.echo(f"{db_path}: ok")


def _register_export_commands() -> None:
    from planner.cli.data import register

    register(main)


_register_export_commands()
