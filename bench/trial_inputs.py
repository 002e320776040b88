"""What a trial's whole record adds to p_hold_trial beyond its verdict (issue 26 item 3), tuning objects only.

bench/trial_update.py's tuning set (its ``tried_set``: the tuning files of bench/acronym_split.toml, 200 poses
re-scored per file, every closed pose tried in MuJoCo at the file's pose, each trial's whole record cached) and
its out-of-fold p_hold (planner.calibration.model.cross_validate, 5 folds grouped by object, the shipped penalty
and trees; cached here by re-scoring code). Each variant is a logistic regression of FleX's label on logit
p_hold, the verdict and the variant's extra columns, fitted on four folds and applied to the fifth (the folds of
p_hold's CV); printed: its out-of-fold agreement with FleX (``>= 0.5``) with a 95% interval over objects, the
mean per-object ROC AUC and the top-10 (bench/trial_update.py's ``score_figures``). ``shipped``: the update as
shipped (planner.calibration.update.fit_update, its clamp). ``re-thresholded``: the verdict made again from the
trial's shaking motions with the thresholds (a grid) that give the update its best agreement on the training
folds. Then the trial's motions against FleX's own (``grasps/qualities/flex/object_motion_during_*``, read for
this comparison only, never an input): rank correlations, and where the two thresholds disagree.

    python bench/trial_inputs.py --dev ../shared/labelled/acronym_dev [--code 7e671bb8f46f]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
from scipy.optimize import minimize
from scipy.stats import spearmanr

sys.path.insert(0, str(Path(__file__).resolve().parent))

import acronym_eval as ae  # noqa: E402
import acronym_mujoco as am  # noqa: E402
import trial_update as tu  # noqa: E402

from planner.calibration.logistic import FOLDER, load_model  # noqa: E402
from planner.calibration.metrics import INTERVAL_SEED, agreement, group_interval  # noqa: E402
from planner.calibration.model import _loss, cross_validate, grouped_folds  # noqa: E402
from planner.calibration.update import fit_update, logit  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: [m], [rad] floor of a motion before its log (a trial's motions go down to 0: flags, no contact).
FLOOR = (1e-4, 1e-3)
#: FleX's label as a threshold on its shaking motion (bench/RESULTS.md: reproduces 98.6% of the labels).
FLEX_THRESHOLDS = (0.02, 0.2)
REASONS = ("slipped", "squeezed_out", "no_contact")
#: the re-thresholded verdict's grid, shaking linear [m] x angular [rad], up to the trial's own thresholds
#: (MujocoSettings.max_translation, max_rotation: the last point is the verdict as it is)
GRID = (np.geomspace(2e-3, 0.02, 11), np.geomspace(0.02, 0.5, 11))


def columns(records: list, held: np.ndarray) -> dict[str, np.ndarray]:
    """The trial's record as named (n,) columns: logs of the motions, fingers touching, reasons one-hot."""
    r = np.array([t[3:3 + len(am.FULL)] for t in records], float)
    named = dict(zip(am.FULL, r.T))
    out = {"held": held}
    for phase in ("closing", "shaking"):
        out[f"log {phase} linear"] = np.log10(np.maximum(named[f"{phase}_linear"], FLOOR[0]))
        out[f"log {phase} angular"] = np.log10(np.maximum(named[f"{phase}_angular"], FLOOR[1]))
    out["fingers"] = named["fingers_in_contact"]
    for reason in REASONS:
        out[reason] = np.array([t[1] == reason for t in records], float)
    out["raw shaking linear"], out["raw shaking angular"] = named["shaking_linear"], named["shaking_angular"]
    return out


def fit_predict(z_train: np.ndarray, y: np.ndarray, z_test: np.ndarray, l2: float = 1e-4) -> np.ndarray:
    """A logistic regression of y on standardised columns z (n, k); its probabilities on z_test."""
    mu, sd = z_train.mean(0), z_train.std(0) + 1e-12
    a, b = (z_train - mu) / sd, (z_test - mu) / sd
    w = minimize(_loss, np.zeros(a.shape[1] + 1), args=(a, y, l2), jac=True, method="L-BFGS-B").x
    return 1 / (1 + np.exp(-(w[0] + b @ w[1:])))


def out_of_fold(fold: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    q = np.empty(len(y))
    for f in np.unique(fold):
        train, test = fold != f, fold == f
        q[test] = fit_predict(z[train], y[train], z[test])
    return q


def rethresholded(fold: np.ndarray, y: np.ndarray, p: np.ndarray, c: dict) -> tuple[np.ndarray, list]:
    """p_hold_trial from a verdict re-made with shaking thresholds chosen on the training folds."""
    q, chosen = np.empty(len(y)), []

    def verdict(a: float, b: float) -> np.ndarray:  # tighter only: a slipped trial may have lost its fingers
        return ((c["held"] > 0) & (c["raw shaking linear"] < a) & (c["raw shaking angular"] < b)).astype(float)

    for f in np.unique(fold):
        train, test = fold != f, fold == f
        best = max((fit_update("mujoco", p[train], verdict(a, b)[train], y[train]).agreement, a, b)
                    for a in GRID[0] for b in GRID[1])
        chosen.append(best)
        v = verdict(best[1], best[2])
        q[test] = fit_update("mujoco", p[train], v[train], y[train]).apply(p[test], v[test])
    return q, chosen


def flex_motions(results: list) -> np.ndarray:
    """(n, 4) FleX's closing linear, angular, shaking linear, angular of every closed pose (analysis only)."""
    out = []
    for r in results:
        with h5py.File(r.path, "r") as f:
            q = f["grasps/qualities/flex"]
            cols = [np.asarray(q[f"object_motion_during_{ph}_{k}"]).reshape(-1)
                    for ph in ("closing", "shaking") for k in ("linear", "angular")]
        rows = np.asarray(r.rows)[np.flatnonzero(r.closed)]
        out.append(np.column_stack([c[rows] for c in cols]))
    return np.concatenate(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dev", type=Path, default=ae.DEV)
    ap.add_argument("--code", default=None, help="acronym_eval's cache key of the re-scoring code")
    ap.add_argument("--cached-only", action="store_true", help="only the files whose trials are cached")
    ap.add_argument("--shipped-p-hold", action="store_true",
                    help="the shipped model's p_hold (in sample) instead of the out-of-fold one; folds as its CV's")
    a = ap.parse_args()
    code = a.code or ae.source_hash()
    results, data, records = tu.tried_set(a.dev, False, 200, 200, 1, "mujoco", code, a.cached_only)
    shipped = load_model(ROOT / FOLDER / "panda.toml")
    cached = ae.CACHE / f"trial_inputs_cv.{code}.{shipped.l2}.npz"
    if a.shipped_p_hold:  # quick, optimistic: the shipped model was fitted on these objects
        cv_p = shipped.predict(data.table)
        fold = np.empty(len(cv_p), int)
        for f, test in enumerate(grouped_folds(list(data.groups), 5)):
            fold[test] = f
    elif cached.exists():
        cv_p, fold = np.load(cached)["p"], np.load(cached)["fold"]
    else:
        cv = cross_validate(data.table, data.labels, data.groups, "panda", folds=5, grid=(shipped.l2,))
        cv_p, fold = cv.p, cv.fold
        np.savez(cached, p=cv_p, fold=fold)
    tried = np.flatnonzero([t is not None for t in records])
    if len(tried) < len(records):
        print(f"trial_inputs: {len(records) - len(tried)} closed poses untried (not cached), left out")
        files = {r.path.stem for r, t in zip((r for r in results for _ in range(int(r.closed.sum()))), records)
                 if t is not None}
        results = [r for r in results if r.path.stem in files]
        data = replace(data, table={k: np.asarray(x)[tried] for k, x in data.table.items()},
                       labels=data.labels[tried], groups=tuple(np.asarray(data.groups)[tried]),
                       files=tuple(np.asarray(data.files)[tried]), verdicts=data.verdicts[tried])
        records, cv_p, fold = [records[i] for i in tried], cv_p[tried], fold[tried]
    y, v, groups = data.labels.astype(float), data.verdicts, np.asarray(data.groups)
    c = columns(records, v)
    lp = logit(cv_p)
    motions = ["log shaking linear", "log shaking angular"]
    closing = ["log closing linear", "log closing angular"]
    variants = {
        "logit p, verdict (refit here, no clamp)": [],
        "+ log shaking motions": motions,
        "+ log closing motions": closing,
        "+ fingers in contact": ["fingers"],
        "+ reason one-hot": list(REASONS),
        "+ shaking, closing, fingers, reasons": motions + closing + ["fingers"] + list(REASONS),
        "+ shaking motions x verdict": "x",
    }
    scores = {"p_hold (shipped, in sample)" if a.shipped_p_hold else "p_hold (out of fold)": cv_p,
              "shipped update": np.empty(len(y))}
    for f in np.unique(fold):
        train, test = fold != f, fold == f
        scores["shipped update"][test] = fit_update("mujoco", cv_p[train], v[train], y[train]).apply(
            cv_p[test], v[test])
    for name, extra in variants.items():
        if extra == "x":
            z = np.column_stack([lp, v] + [c[m] * v for m in motions] + [c[m] for m in motions])
        else:
            z = np.column_stack([lp, v] + [c[m] for m in extra])
        scores[name] = out_of_fold(fold, y, z)
    scores["re-thresholded verdict"], chosen = rethresholded(fold, y, cv_p, c)
    members = [np.flatnonzero(groups == g) for g in np.unique(groups)]
    print(f"{len(y)} tried poses of {len(members)} tuning objects (re-scoring code {code}, trial code "
          f"{am.trial_code()}); MuJoCo's verdict agrees {np.mean(v == y):.4f}; out of fold:")
    print(f"  {'variant':42s} agree  [95% over objects]  AUC    top-10")
    for name, q in scores.items():
        lo, hi = group_interval(lambda k, q=q: agreement(y[np.concatenate([members[i] for i in k])],
                                                         q[np.concatenate([members[i] for i in k])]),
                                len(members), np.random.default_rng(INTERVAL_SEED))
        auc, top, agree = tu.score_figures(data, q)
        print(f"  {name:42s} {agree:.4f} [{lo:.3f}, {hi:.3f}]  {auc:.4f} {top:.4f}")
    print("  re-thresholded: thresholds chosen per fold (train agreement, m, rad): "
          + "; ".join(f"{b[0]:.4f} {b[1]:.4f} {b[2]:.3f}" for b in chosen))
    compare_flex(results, y, c)
    return 0


def compare_flex(results: list, y: np.ndarray, c: dict) -> None:
    """The trial's motions against FleX's own on the same poses (analysis only)."""
    fm = flex_motions(results)
    sim = (c["held"] + c["slipped"]) > 0
    flex_moved = (fm[:, 2] > FLEX_THRESHOLDS[0]) | (fm[:, 3] > FLEX_THRESHOLDS[1])
    print(f"FleX's threshold on its own shaking motion reproduces its label on {np.mean(flex_moved != (y == 1)):.4f}")
    names = ("closing linear", "closing angular", "shaking linear", "shaking angular")
    for k, name in enumerate(names):
        ours = c["raw " + name] if name.startswith("shaking") else 10 ** c["log " + name]
        rho = spearmanr(ours[sim], fm[sim, k]).statistic
        print(f"  {name:16s}: Spearman (simulated trials, {int(sim.sum())}) {rho:+.3f}; median MuJoCo "
              f"{np.median(ours[sim]):.4f}, FleX {np.median(fm[sim, k]):.4f}")
    held = c["held"] > 0
    for label, mask in (("MuJoCo holds, FleX drops", held & (y == 0)), ("MuJoCo drops, FleX holds", ~held & (y == 1)),
                        ("both hold", held & (y == 1)), ("both drop", ~held & (y == 0))):
        if mask.any():
            lin, ang = np.median(c["raw shaking linear"][mask]), np.median(c["raw shaking angular"][mask])
            print(f"  {label:26s} {int(mask.sum()):5d}: median shaking MuJoCo {lin:.4f} m {ang:.3f} rad, "
                  f"FleX {np.median(fm[mask, 2]):.4f} m "
                  f"{np.median(fm[mask, 3]):.3f} rad; FleX over its threshold {np.mean(flex_moved[mask]):.2f}")


if __name__ == "__main__":
    sys.exit(main())
