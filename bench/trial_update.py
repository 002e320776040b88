"""Fit the shipped model's update of p_hold by a trial's verdict (``p_hold_trial``) on the dev set's tuning objects.

The tuning files of bench/acronym_split.toml, re-scored as bench/acronym_eval.py does (its cache:
``--poses`` per file, seed 0, code ``--code``); ``--per-file`` closed poses per file drawn with ``--sample-seed``
tried in ``--engine`` at the file's pose, as bench/acronym_mujoco.py runs them (its cache); p_hold out of
fold (planner.calibration.model.cross_validate, folds grouped by object, the shipped model's penalty and
trees); then planner.calibration.update.fit_update on every tried grasp, as ``grasp calibrate --trial`` fits
it. Printed: agreement with FleX of the verdict, of p_hold >= 0.5 and of p_hold_trial >= 0.5 (the update
fitted without the grasp's fold: planner.calibration.fitting.trial_figures), and the update.
``--write``: add the update to calibration/<hand>.toml (the rest of the file unchanged).

The ranking when every pose is tried (``grasp validate --all``): with ``--per-file`` at least the closed poses
per file, every closed pose of the sample is tried; printed then, for p_hold, p_hold_trial, p_hold times the
verdict (the rule before p_hold_trial) and the verdict alone: the mean per-object ROC AUC against FleX, the mean
over files of the share of the 10 best-ranked poses that hold (force closure as planned or once squeezed first,
as the database ranks), and the label agreement; for p_hold and p_hold_trial also their 95% intervals over
objects (planner.calibration.metrics.object_figures: a bootstrap drawing objects).
``--held-out``: the same on the held-out objects with the shipped model and its update, nothing fitted (run
once; bench/acronym_eval.py --held-out --trial N --engine mujoco reports the label agreement of a sample).

    python bench/trial_update.py --dev ../shared/labelled/acronym_dev --code fed4526c8342 [--write]
    python bench/trial_update.py --dev ../shared/labelled/acronym_dev --code fed4526c8342 --held-out
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import acronym_eval as ae  # noqa: E402
import acronym_mujoco as am  # noqa: E402
from _settings import parse  # noqa: E402

from planner.calibration.fitting import trial_figures  # noqa: E402
from planner.calibration.labels import TRIAL_GROUPS, LabelledSet  # noqa: E402
from planner.calibration.logistic import FOLDER, load_model  # noqa: E402
from planner.calibration.metrics import INTERVAL_SEED, object_figures, roc_auc  # noqa: E402
from planner.calibration.model import cross_validate  # noqa: E402
from planner.calibration.update import fit_update  # noqa: E402
from planner.db.ranking import rank_order, ranks_first  # noqa: E402
from planner.validation.mujoco_settings import MujocoSettings  # noqa: E402
from planner.validation.settings import ShakeSettings  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dev", type=Path, default=ROOT.parent / "shared" / "labelled" / "acronym_dev")
    ap.add_argument("--poses", type=int, default=200)
    ap.add_argument("--per-file", type=int, default=200)
    ap.add_argument("--sample-seed", type=int, default=1)
    ap.add_argument("--engine", choices=sorted(TRIAL_GROUPS), default="mujoco")
    ap.add_argument("--code", default=None, help="acronym_eval's cache key of the re-scoring code")
    ap.add_argument("--hand", default="panda")
    ap.add_argument("--write", action="store_true", help="add the update to calibration/<hand>.toml")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--held-out", action="store_true", help="the shipped model and update on the held-out objects")
    ap.add_argument("--set", dest="overrides", nargs="*", default=[],
                    help="MujocoSettings key=value: the trial's settings other than this tree's defaults")
    a = ap.parse_args()
    code = a.code or ae.source_hash()
    results, data, _ = tried_set(a.dev, a.held_out, a.poses, a.per_file, a.sample_seed, a.engine, code,
                                 overrides=parse(a.overrides, MujocoSettings, "trial_update"))
    path = ROOT / FOLDER / f"{a.hand}.toml"
    shipped = load_model(path)
    if a.held_out:
        p = shipped.predict(data.table)
        q = shipped.given_trial(p, {data.engine: data.verdicts})
        ranking(data, p, np.where(np.isnan(q), p, q), results)
        return 0
    cv = cross_validate(data.table, data.labels, data.groups, a.hand, folds=5, grid=(shipped.l2,))
    figures = trial_figures(data, cv)
    tried = ~np.isnan(data.verdicts)
    update = fit_update(data.engine, cv.p[tried], data.verdicts[tried], data.labels[tried])
    print(f"{int(figures['trialled'])} tried grasps of {len(set(np.array(data.groups)[tried]))} tuning objects "
          f"({a.engine}, {a.per_file} per file, re-scoring code {code}); agreement with FleX:")
    print(f"  verdict {figures['trial_agreement']:.4f}, p_hold >= 0.5 {figures['p_hold_agreement']:.4f} "
          f"(out of fold), p_hold_trial >= 0.5 {figures['p_hold_trial_agreement']:.4f} "
          f"[{figures['p_hold_trial_agreement_lo']:.3f}, {figures['p_hold_trial_agreement_hi']:.3f}] over objects "
          f"(update fitted per fold)")
    print(f"  update on all: logit' = {update.slope:.4f} logit + {update.verdict:.4f} held + {update.intercept:.4f}"
          f" (in-sample agreement {update.agreement:.4f})")
    if np.all(tried):
        q = np.empty(len(tried))
        for f in np.unique(cv.fold):
            train, test = cv.fold != f, cv.fold == f
            q[test] = fit_update(data.engine, cv.p[train], data.verdicts[train], data.labels[train]).apply(
                cv.p[test], data.verdicts[test])
        ranking(data, cv.p, q, results)
    if a.json:
        a.json.write_text(json.dumps({"figures": figures, "update": update.to_dict(), "code": code}, indent=1))
    if a.write:
        figures_out = {**shipped.figures, **{f"{k}_{a.engine}": v for k, v in figures.items()}}
        model = replace(shipped, updates={**shipped.updates, update.engine: update}, figures=figures_out)
        path.write_text(model.to_toml())
        print(f"wrote {path}")
    return 0


def tried_set(dev: Path, held_out: bool, poses: int, per_file: int, sample_seed: int, engine: str,
              code: str, cached_only: bool = False, overrides: dict | None = None) -> tuple[list, LabelledSet, list]:
    """(re-scored files, their closed poses as a LabelledSet with the trial's verdicts (nan: not tried), and per
    closed pose the trial's cached record [held, reason, cpu s, *acronym_mujoco.FULL] or None): the files of one
    side of the split, ``poses`` re-scored per file (seed 0, code ``code``), ``per_file`` closed ones tried in
    ``engine`` at the file's pose (drawn with ``sample_seed``; every trial's whole record cached; ``cached_only``: no
    trial run, a file whose trials are not cached is untried; ``overrides``: MujocoSettings fields)."""
    results = [ae.rescore_file(p, poses, 0, 1, ae.CACHE, code) for p in ae.dev_files(dev, held_out, None)]
    settings = MujocoSettings(**(overrides or {})) if engine == "mujoco" else ShakeSettings()
    records: list = []
    for r in results:
        v = am.run(r, am.picked(r, per_file, sample_seed), engine, settings, ae.CACHE, "original", full=True,
                   cached_only=cached_only)
        records += [v.get(int(p)) for p in np.flatnonzero(r.closed)]
    verdicts = np.array([np.nan if t is None else float(t[0]) for t in records])
    return results, replace(ae.labelled_set(results), verdicts=verdicts, engine=TRIAL_GROUPS[engine]), records


def score_figures(data: LabelledSet, s: np.ndarray) -> tuple[float, float, float]:
    """(mean per-object ROC AUC against the labels, mean over files of the share of the 10 best-ranked poses
    that hold (force closure as planned or once squeezed first: planner.db.ranking.ranks_first), label agreement
    of s >= 0.5) of scores ``s`` (n,) of every pose."""
    y, groups, files = data.labels, np.array(data.groups), np.array(data.files)
    fc = ranks_first(data.table)
    aucs = [roc_auc(y[groups == g], s[groups == g]) for g in np.unique(groups)]
    tops = [float(np.mean(y[i][rank_order(s[i], fc[i])[:10]])) for i in
            (np.flatnonzero(files == f) for f in np.unique(files))]
    return float(np.nanmean(aucs)), float(np.mean(tops)), float(np.mean((s >= 0.5) == (y == 1)))


def ranking(data, p: np.ndarray, q: np.ndarray, results) -> None:  # type: ignore[no-untyped-def]
    """Every closed pose tried: AUC per object, top-10 per file and label agreement of each score."""
    y, v = data.labels, data.verdicts
    groups, files = np.array(data.groups), np.array(data.files)
    fc = ranks_first(data.table)
    print(f"every closed pose tried ({int(np.sum(~np.isnan(v)))} of {len(v)}):")
    for name, s in (("p_hold", p), ("p_hold_trial", q), ("p_hold x verdict", p * np.nan_to_num(v, nan=1.0)),
                    ("verdict", np.nan_to_num(v, nan=0.5))):
        auc, top, agree = score_figures(data, s)
        print(f"  {name:18s} mean per-object AUC {auc:.4f}  top-10 {top:.4f}  label agreement {agree:.4f}")
        if name in ("p_hold", "p_hold_trial"):
            iv = object_figures(y, s, groups, files, fc, 10, np.random.default_rng(INTERVAL_SEED))
            print(f"  {'':18s} 95% over objects: AUC [{iv['auc_mean_lo']:.3f}, {iv['auc_mean_hi']:.3f}]  top-10 "
                  f"[{iv['top10_lo']:.3f}, {iv['top10_hi']:.3f}]  agreement [{iv['agreement_lo']:.3f}, "
                  f"{iv['agreement_hi']:.3f}]  ECE [{iv['ece_lo']:.4f}, {iv['ece_hi']:.4f}]")


if __name__ == "__main__":
    sys.exit(main())
