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
``--compare`` (tuning objects only; issue 26 item 3): what the trial's other fields add to p_hold_trial beyond its
verdict. Each of VARIANTS adds a few columns of the trial's record (trial_columns: the dropped reason one-hot, logs
of the object's motion while the fingers closed and while shaken, fingers in contact) beside logit p_hold and the
verdict, fitted as fit_update fits today's update (its loss, penalty and clamp: fit_terms, apply_terms) on four of
p_hold's folds and applied to the fifth; printed per variant: pooled and per-object agreement of >= 0.5 with FleX,
mean per-object ROC AUC, top-10, ECE, and its difference from today's update in agreement, AUC and top-10 with 95%
intervals over objects (a paired bootstrap drawing objects), then the weights fitted on every tried pose. p_hold out
of fold is cached by re-scoring code (``trial_update_cv.*.npz`` in acronym_eval's cache). ``--cached-only``: only
the files whose trials are cached (nothing run; e.g. the files whose convex parts are cached, tried first).

    python bench/trial_update.py --dev ../shared/labelled/acronym_dev --code fed4526c8342 [--write]
    python bench/trial_update.py --dev ../shared/labelled/acronym_dev --code fed4526c8342 --held-out
    python bench/trial_update.py --dev ../shared/labelled/acronym_dev --code 3468b84a5057 --cached-only --compare
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from collections import Counter
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
from planner.calibration.metrics import (  # noqa: E402
    INTERVAL_SEED,
    expected_calibration_error,
    group_interval,
    object_figures,
    roc_auc,
)
from planner.calibration.model import CrossValidation, cross_validate  # noqa: E402
from planner.calibration.update import fit_update, logit  # noqa: E402
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
    ap.add_argument("--compare", action="store_true",
                    help="p_hold_trial with the trial's other fields as inputs, out of fold, against today's")
    ap.add_argument("--cached-only", action="store_true", help="only the files whose trials are cached (no trial run)")
    ap.add_argument("--set", dest="overrides", nargs="*", default=[],
                    help="MujocoSettings key=value: the trial's settings other than this tree's defaults")
    a = ap.parse_args()
    if a.compare and a.held_out:
        ap.error("--compare fits on the tuning objects only; --held-out measures the shipped update, nothing fitted")
    code = a.code or ae.source_hash()
    results, data, records = tried_set(a.dev, a.held_out, a.poses, a.per_file, a.sample_seed, a.engine, code,
                                       a.cached_only, overrides=parse(a.overrides, MujocoSettings, "trial_update"))
    path = ROOT / FOLDER / f"{a.hand}.toml"
    shipped = load_model(path)
    if a.held_out:
        p = shipped.predict(data.table)
        q = shipped.given_trial(p, {data.engine: data.verdicts})
        ranking(data, p, np.where(np.isnan(q), p, q), results)
        return 0
    if a.compare:
        compare(data, out_of_fold(data, a.hand, shipped.l2, code), records)
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


def out_of_fold(data: LabelledSet, hand: str, l2: float, code: str) -> CrossValidation:
    """p_hold out of fold as main's (5 folds grouped by object, penalty ``l2``), cached by re-scoring code and the
    calibration modules' source."""
    h = hashlib.sha256()
    for p in sorted((ROOT / "planner" / "calibration").glob("*.py")):
        h.update(p.read_bytes())
    key = ae.CACHE / f"trial_update_cv.{code}.{h.hexdigest()[:10]}.{hand}.{l2}.{len(data.labels)}.npz"
    if key.exists():
        z = np.load(key)
        return CrossValidation(z["p"], z["fold"], z["l2"])
    cv = cross_validate(data.table, data.labels, data.groups, hand, folds=5, grid=(l2,))
    np.savez(key, p=cv.p, fold=cv.fold, l2=cv.l2)
    return cv


#: Where a cached record's FULL fields start (after held, reason, cpu seconds: acronym_mujoco.run).
FULL_RECORD_START = 3
#: [m], [rad]: the floor of a trial's motion before its log (motions go down to 0: never loaded, no contact)
FLOOR = (1e-4, 1e-3)
#: the dropped reasons one-hot (held is the verdict; the rest, e.g. '' of a record without one, are all 0)
REASONS = ("slipped", "squeezed_out", "no_contact")


def trial_columns(records: list) -> dict[str, np.ndarray]:
    """The tried poses' records (tried_set's) as named (n,) columns that may enter p_hold_trial."""
    r = np.array([t[FULL_RECORD_START:FULL_RECORD_START + len(am.FULL)] for t in records], float)
    named = dict(zip(am.FULL, r.T))
    out = {}
    for phase in ("closing", "shaking"):
        out[f"log {phase} linear"] = np.log10(np.maximum(named[f"{phase}_linear"], FLOOR[0]))
        out[f"log {phase} angular"] = np.log10(np.maximum(named[f"{phase}_angular"], FLOOR[1]))
    out["closing angular"] = named["closing_angular"]
    out["fingers"] = named["fingers_in_contact"]
    for reason in REASONS:
        out[reason] = np.array([t[1] == reason for t in records], float)
    held = np.array([float(t[0]) for t in records])
    for phase in ("closing", "shaking"):
        for k in ("linear", "angular"):
            out[f"held x log {phase} {k}"] = held * out[f"log {phase} {k}"]
    return out


#: The comparison's variants: extra columns beside logit p_hold and the verdict (today's update: none).
VARIANTS = {
    "today's update": [],
    "+ reason one-hot": list(REASONS),
    "+ log closing linear, closing angular": ["log closing linear", "closing angular"],
    "+ log closing linear": ["log closing linear"],
    "+ closing angular": ["closing angular"],
    "+ log closing motions": ["log closing linear", "log closing angular"],
    "+ log shaking motions": ["log shaking linear", "log shaking angular"],
    "+ held x log shaking motions": ["held x log shaking linear", "held x log shaking angular"],
    "+ held x log closing motions": ["held x log closing linear", "held x log closing angular"],
    "+ fingers in contact": ["fingers"],
    "+ reason, log closing linear": list(REASONS) + ["log closing linear"],
    "+ log closing linear, log shaking linear": ["log closing linear", "log shaking linear"],
    "+ squeezed_out, no_contact, log closing linear, fingers": ["squeezed_out", "no_contact", "log closing linear",
                                                               "fingers"],
    "+ all (reason, closing, shaking, fingers)": list(REASONS) + ["log closing linear", "log closing angular",
                                                                 "log shaking linear", "log shaking angular",
                                                                 "fingers"],
}


def fit_terms(p: np.ndarray, held: np.ndarray, extra: np.ndarray, y: np.ndarray) -> np.ndarray:
    """fit_update's fit (its loss, penalty 1e-6 and start) with ``extra`` (n, k) columns beside logit p_hold and
    the verdict: the weights [intercept, slope, verdict, *extra]."""
    from scipy.optimize import minimize

    from planner.calibration.model import _loss

    z = np.column_stack([logit(p), held, extra])
    w0 = np.concatenate([[0.0, 1.0, 0.0], np.zeros(extra.shape[1])])
    return minimize(_loss, w0, args=(z, y, 1e-6), jac=True, method="L-BFGS-B").x


def apply_terms(w: np.ndarray, p: np.ndarray, held: np.ndarray, extra: np.ndarray) -> np.ndarray:
    """p_hold_trial of weights ``w`` (fit_terms'), with fit_update's clamp (held never lowers, dropped never
    raises, where the verdict's weight is positive)."""
    q = 1.0 / (1.0 + np.exp(-(w[0] + w[1] * logit(p) + w[2] * held + extra @ w[3:])))
    return q if w[2] <= 0 else np.where(held > 0.5, np.maximum(q, p), np.minimum(q, p))


def compare(data: LabelledSet, cv: CrossValidation, records: list) -> None:
    """Each variant's p_hold_trial fitted on four of p_hold's folds and applied to the fifth (the tried poses),
    its figures and its difference from today's update, 95% over objects (module docstring)."""
    tried = np.flatnonzero([t is not None for t in records])
    sub = replace(data, table={k: np.asarray(x)[tried] for k, x in data.table.items()}, labels=data.labels[tried],
                  groups=tuple(np.asarray(data.groups)[tried]), files=tuple(np.asarray(data.files)[tried]),
                  verdicts=data.verdicts[tried])
    y, v, p, fold = sub.labels.astype(float), sub.verdicts, cv.p[tried], cv.fold[tried]
    cols = trial_columns([records[i] for i in tried])
    groups = np.asarray(sub.groups)
    members = [np.flatnonzero(groups == g) for g in np.unique(groups)]
    scores = {"p_hold alone": p}
    weights = {}
    for name, extra in VARIANTS.items():
        x = np.column_stack([cols[c] for c in extra]) if extra else np.zeros((len(y), 0))
        q = np.empty(len(y))
        for f in np.unique(fold):
            train, test = fold != f, fold == f
            q[test] = apply_terms(fit_terms(p[train], v[train], x[train], y[train]), p[test], v[test], x[test])
        scores[name] = q
        weights[name] = fit_terms(p, v, x, y)
    today = scores["today's update"]
    print(f"{len(y)} tried poses of {len(members)} tuning objects, {len(set(sub.files))} files; MuJoCo's verdict "
          f"agrees {np.mean(v == y):.4f}; reasons: " + ", ".join(
              f"{r} {n}" for r, n in sorted(Counter(records[i][1] for i in tried).items())))
    print(f"  {'variant (out of fold)':56s} agree  per-obj AUC    top-10 ECE     minus today's [95% over objects]: "
          f"agree, AUC, top-10")
    files = np.asarray(sub.files)
    fc = ranks_first(sub.table)
    in_file = {f: np.flatnonzero(files == f) for f in np.unique(files)}
    object_files = [sorted(set(files[m])) for m in members]

    def tops(s: np.ndarray) -> dict[str, float]:
        return {f: float(np.mean(y[i][rank_order(s[i], fc[i])[:10]])) for f, i in in_file.items()}

    def intervals(q: np.ndarray) -> list[tuple[float, float, float]]:
        """(figure over all objects, lo, hi) of each difference from today's: agreement, mean AUC, top-10."""
        t_q, t_0 = tops(q), tops(today)
        auc = [roc_auc(y[m], q[m]) - roc_auc(y[m], today[m]) for m in members]

        def agree(k: np.ndarray) -> float:
            i = np.concatenate([members[j] for j in k])
            return float(np.mean((q[i] >= 0.5) == (y[i] == 1)) - np.mean((today[i] >= 0.5) == (y[i] == 1)))

        def top(k: np.ndarray) -> float:
            picked = [f for j in k for f in object_files[j]]
            return float(np.mean([t_q[f] - t_0[f] for f in picked]))

        def mean_auc(k: np.ndarray) -> float:
            return float(np.nanmean([auc[j] for j in k]))

        every = np.arange(len(members))
        return [(stat(every), *group_interval(stat, len(members), np.random.default_rng(INTERVAL_SEED)))
                for stat in (agree, mean_auc, top)]

    for name, q in scores.items():
        auc, top, agree = score_figures(sub, q)
        per_object = np.mean([np.mean((q[m] >= 0.5) == (y[m] == 1)) for m in members])
        diffs = "  ".join(f"{d:+.4f} [{lo:+.4f}, {hi:+.4f}]" for d, lo, hi in intervals(q))
        print(f"  {name:56s} {agree:.4f} {per_object:.4f}  {auc:.4f} {top:.4f} "
              f"{expected_calibration_error(y, q):.4f}  {diffs}")
    print("  weights fitted on every tried pose (intercept, slope, verdict, extra columns in the variant's order):")
    for name, w in weights.items():
        print(f"  {name:56s} " + " ".join(f"{x:+.3f}" for x in w))


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
