"""``grasp hands``, ``grasp objects``, ``grasp db objects`` and ``grasp db check``."""

from __future__ import annotations

from pathlib import Path

import click

from planner import api
from planner.cli.app import db_option, report_failures
from planner.errors import DatabaseError


@click.command(name="hands")
@click.argument("name", required=False)
def hands(name: str | None) -> None:
    """List the built-in hands, or show one in detail."""
    if name is None:  # every hand that loads; then one error line per folder that does not (exit 2)
        from planner.errors import PlannerError
        from planner.specs.hands import hand_names

        failed = {}
        for hand_name in hand_names():
            try:
                spec, shapes = api.hand(hand_name)
            except PlannerError as exc:
                failed[f"hand '{hand_name}'"] = str(exc)
                continue
            click.echo(f"{spec.name:12s} {len(spec.joints):2d} finger joints  preshapes: "
                       f"{', '.join(s.name for s in shapes)}  - {spec.description}")
        report_failures(failed)
        return
    spec, shapes = api.hand(name)
    click.echo(f"{spec.name}: {spec.description}\n  urdf: {spec.urdf}\n  root link: {spec.root_link}\n"
               f"  approach: {spec.approach.tolist()}  tcp: {spec.tcp.tolist()} m\n"
               f"  contact links: {', '.join(spec.contact_links)}")
    for j in spec.joints:
        extra = f" mimics {j.mimic} x{j.multiplier}" if j.mimic else f" close rate {j.close}"
        click.echo(f"  joint {j.name} ({j.kind}) [{j.lower}, {j.upper}]{extra}")
    for s in shapes:
        click.echo(f"  preshape {s.name} tags={','.join(s.tags)} '{s.taxonomy}' standoffs={list(s.standoffs)}")


@click.command(name="objects")
def objects() -> None:
    """List the built-in objects."""
    for name, spec in api.objects().items():
        click.echo(f"{name:10s} {spec.kind:8s} mass {spec.mass:.3f} kg  friction {spec.friction:.2f}  "
                   f"- {spec.description}")
    last = f"{api.RANDOM_COUNT - 1:03d}"
    click.echo(f"{api.RANDOM_PREFIX}000 .. {api.RANDOM_PREFIX}{last}  mass {api.RANDOM_MASS:.3f} kg  friction "
               f"{api.DEFAULT_FRICTION:.2f}  - the procedurally generated objects of pybullet_data/random_urdfs, "
               "5-10 cm across")


@click.group()
def db() -> None:
    """Database maintenance."""


@db.command(name="objects")
@db_option
def db_objects(db_path: Path) -> None:
    """List the database's objects as stored: what their grasps were planned
    and measured at (file, scale, mass, density, friction, up, centre of mass, volume; a URDF planned on its
    visual elements says so)."""
    rows = api.stored_objects(db_path)
    if not rows:
        click.echo(f"{db_path}: no objects")
    for row, hands_with in rows:
        click.echo(f"{row.name}: mass {row.mass:.4g} kg, density {row.density:.4g} kg/m^3, friction "
                   f"{row.friction:.3g}, up {row.up}, centre of mass ({', '.join(f'{_mm(v):.4g}' for v in row.com)}) "
                   f"mm, volume {row.volume * 1e6:.4g} cm^3, scale {row.scale:g}, grasps for "
                   f"{', '.join(hands_with) or 'no hand'}; {row.source}"
                   f"{' (its <visual> elements)' if row.geometry == 'visual' and _is_urdf(row.source) else ''}")


def _mm(metres: float) -> float:
    """[mm] of a coordinate, 0 for rounding's leftovers under a nanometre (a centred cylinder's read "(-0, 0, -0)")."""
    return metres * 1e3 if abs(metres) >= 1e-9 else 0.0


def _is_urdf(source: str) -> bool:
    """Whether a stored source is a URDF file (a built-in's is the mesh its URDF names: no elements to say)."""
    return source.lower().endswith(".urdf")


@db.command()
@db_option
def check(db_path: Path) -> None:
    """Run SQLite's integrity check on the database."""
    problems = api.check_db(db_path)
    if problems:
        for p in problems:
            click.echo(p)
        raise DatabaseError(f"{db_path}: integrity check failed ({len(problems)} problem{'s' * (len(problems) > 1)}, "
                            "listed on stdout)")
    click.echo(f"{db_path}: ok")
