"""``grasp calibrate``: fit p_hold to labelled grasp files and store it."""

from __future__ import annotations

import math
from pathlib import Path

import click

from planner import api
from planner.cli.app import db_option, made, missing_folder, show_preparation

#: Below this many objects the bootstrap's intervals (drawn from the objects at hand) are said to be too narrow.
FEW_OBJECTS = 10


@click.command()
@click.argument("labels", nargs=-1, required=True, type=click.Path(path_type=Path))
@db_option
@click.option("--poses", type=int, default=200, show_default=True,
              help="A seeded uniform sample of this many poses per file (0: every pose).")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--folds", type=int, default=5, show_default=True, help="Cross-validation folds, grouped by object.")
@click.option("--hand", help="The hand, if the files' gripper/type does not say it.")
@click.option("--workers", type=int, default=api.default_workers(), show_default="all cores",
              help="Worker processes for re-scoring the sampled poses.")
@click.option("--model-out", type=click.Path(path_type=Path),
              help="Also write the model as TOML (a missing folder above it is made).")
@click.option("--plot", type=click.Path(path_type=Path),
              help="Write the held-out reliability diagram (PNG; a missing folder above it is made).")
@click.option("--no-store", is_flag=True, help="Fit and report only; leave the database alone.")
@click.option("--trees/--no-trees", default=True, show_default=True,
              help="Boost interaction trees on the additive model (--no-trees: one curve per measure alone).")
@click.option("--trial", type=int, default=0, show_default=True, metavar="N",
              help="Also try N closed grasps per file in a dynamic trial and fit how its verdict updates p_hold "
              "(p_hold_trial: the label and rank of a validated grasp).")
@click.option("--engine", type=click.Choice(["mujoco", "pybullet"]), default="mujoco", show_default=True,
              help="The trial of --trial (as grasp validate --engine runs it).")
def calibrate(labels: tuple[Path, ...], db_path: Path, poses: int, seed: int, folds: int, hand: str | None,
              workers: int, model_out: Path | None, plot: Path | None, no_store: bool, trees: bool, trial: int,
              engine: str) -> None:
    """Fit p_hold, the calibrated probability of holding, to labelled grasp files (ACRONYM layout:
    grasps/transforms and grasps/qualities/flex/object_in_gripper) and store it for their hand."""

    def progress(path: Path, closed: int, sampled: int) -> None:
        click.echo(f"{path}: {closed} of {sampled} poses closed on the object", err=True)

    show_preparation()  # a labelled file's mesh repaired: one line each, the first time only
    folders = {path: missing_folder(path) for path in (model_out, plot) if path is not None}  # said once written
    result = api.calibrate(list(labels), db_path=None if no_store else db_path, poses=poses or None, seed=seed,
                           folds=folds, hand=hand, workers=workers, model_out=model_out, plot=plot,
                           progress=progress, trees=trees, trial=trial, engine=engine)
    f = result.figures
    click.echo(f"p_hold for {result.model.hand}: {int(f['grasps'])} closed labelled grasps of {int(f['objects'])} "
               f"objects, success rate {f['success_rate']:.3f}")
    click.echo(f"held out ({int(f['folds'])} folds grouped by object): mean per-object AUC {f['auc_mean']:.3f} "
               f"{_interval(f, 'auc_mean', 3)} (width baseline {_value(f['auc_width'], 3)}), pooled AUC "
               f"{f['auc_pooled']:.3f}, top-10 hold {f['top10']:.3f} {_interval(f, 'top10', 3)}, ECE {f['ece']:.4f} "
               f"{_interval(f, 'ece', 4)}, p_hold >= 0.5 agrees {f['agreement']:.3f} {_interval(f, 'agreement', 3)}, "
               f"log-loss {f['log_loss']:.4f}")
    few = "; from so few objects they understate the spread" if f["objects"] < FEW_OBJECTS else ""
    click.echo(f"  [95% intervals over objects: a bootstrap drawing objects, how far another set of as many objects "
               f"could move each figure{few}]")
    if "trialled" in f:
        click.echo(f"{int(f['trialled'])} grasps tried in {engine}: agreement with the labels: the verdict "
                   f"{f['trial_agreement']:.3f}, p_hold >= 0.5 {f['p_hold_agreement']:.3f}, p_hold given the "
                   f"verdict >= 0.5 {_value(f.get('p_hold_trial_agreement', math.nan), 3)} "
                   f"{_interval(f, 'p_hold_trial_agreement', 3)} (held out)")
    for o in result.per_object:
        auc = "n/a" if math.isnan(o["auc_p_hold"]) else f"{o['auc_p_hold']:.3f}"
        width = "n/a" if math.isnan(o["auc_width"]) else f"{o['auc_width']:.3f}"
        click.echo(f"  {Path(o['object']).stem}: {o['grasps']} grasps, success {o['success_rate']:.2f}, "
                   f"AUC {auc} (width {width})")
    for path, what in ((model_out, "the fitted model"), (plot, "its reliability diagram")):
        if path is not None:
            click.echo(f"{path}: {what}{made(folders[path])}")
    if not no_store:
        click.echo(f"stored in {db_path}: best, exports and reports of {result.model.hand} grasps use it")
        shipped = api.shipped_figures(result.model.hand)
        if shipped:
            click.echo(f"note: it replaces, for this database's {result.model.hand} grasps, the shipped model "
                       f"(calibration/{result.model.hand}.toml, ACRONYM's dev set: {int(shipped.get('objects', 0))} "
                       f"objects, held-out AUC {shipped.get('auc_mean', math.nan):.3f}, ECE "
                       f"{shipped.get('ece', math.nan):.4f}); --no-store compares without storing", err=True)


def _interval(figures: dict[str, float], name: str, digits: int) -> str:
    lo, hi = figures.get(f"{name}_lo", math.nan), figures.get(f"{name}_hi", math.nan)
    return "[n/a]" if not (math.isfinite(lo) and math.isfinite(hi)) else f"[{lo:.{digits}f}, {hi:.{digits}f}]"


def _value(x: float, digits: int) -> str:
    """``x`` to ``digits`` decimals, or n/a where it is not a number (a hand without a width: not a parallel jaw)."""
    return f"{x:.{digits}f}" if math.isfinite(x) else "n/a"
