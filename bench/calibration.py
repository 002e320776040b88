"""Calibration of the analytic score against the shake test (issue 15).

For each hand (Panda, Barrett) and each object of one set of
bench/calibration_split.toml (``--set tuning`` for tuning; ``--set held_out``
is run ONCE, by the lead, at the end):

1. sweep the object into ``DIR/<set>_<hand>.db`` (``grasp generate``: patches,
   measures, no reachability, no GWS volume);
2. read every grasp's contacts again the pre-issue way (legacy closest points)
   and compute its epsilon: the pre-issue score is that epsilon, 0 unless
   force closure (the old rule without reachability: neutral);
3. shake-test a seeded uniform sample of the grasps with contacts (``--per-object``,
   all where fewer), plus the top-10 of the analytic order and of the
   pre-issue order (``validation`` table: ``grasp report DB`` shows it too);
4. report, on the uniform sample: ROC AUC against simulated success of each
   measure, of the analytic score and of the pre-issue score, pooled and per
   object; top-1 (share of objects whose best grasp held) and top-10 (mean
   share of the 10 best that held) of the analytic order and of the
   pre-issue order, over each object's whole sweep.

``--jitter K`` measures how repeatable the trial's label is: every labelled
grasp of the uniform sample is tried again K times with its pose moved by
``--jitter-mm`` (a random direction) and turned by ``--jitter-deg`` (a random
axis), seeded per grasp (cached in ``DIR/<set>_<hand>_jitter.json``). It
reports how often a jittered trial agrees with the label, the ROC AUC of the
jittered trials' mean against the label (a ceiling: what a predictor that
knew the trial's outcome a millimetre away would reach), and the AUCs against
the robust label (held in at least half of the 1 + K trials).

``--cv`` adds 5-fold cross-validation grouped by object of the rule's
parameters (cap, min_open_margin, eps_weight, settled_weight; objective:
pooled AUC + top-1 on the training folds), the figures of the held fold,
per hand and, with several hands, for one rule shared by all of them (the
sum of the hands' objectives; how the defaults were chosen). Tuning only.

    python bench/calibration.py --set tuning [--hands panda barrett] [--objects 20] [--cv]

Figures go to ``DIR/report_<set>.md`` and are printed side by side. Work is
resumable: the databases, legacy epsilons (``DIR/<set>_<hand>_legacy.json``)
and trials already done are kept.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
import typing
import zlib
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import get_type_hints

import numpy as np
import tomllib
from scipy.spatial.transform import Rotation

from planner import api
from planner.db.lock import writer_lock
from planner.db.ranking import RankingRule, rule_measures
from planner.db.store import open_db
from planner.geometry.solid import load_object
from planner.plan.closing import Closed, CloseSettings, Grasper
from planner.plan.sweep import SweepSettings
from planner.plan.unit import grasp_quality
from planner.present.report import roc_auc, top_k_success
from planner.record.grasp import Grasp
from planner.sim import Sim
from planner.specs.hands import load_hand
from planner.validation import run as validation

HERE = Path(__file__).resolve().parent
SPLIT = HERE / "calibration_split.toml"
TOP = 10
SEED = 20261123
#: The measures whose AUC is reported (higher = predicts holding).
MEASURES = ("analytic", "pre_issue", "epsilon", "epsilon_legacy", "settled_epsilon", "resist_worst", "resist_mean",
            "push", "open_margin", "close_margin", "feasible")
#: The rule's parameters cross-validation chooses from (third round: settled_weight, the weight
#: of the settled epsilon where it is measured).
GRID = [dict(cap=c, min_open_margin=m, eps_weight=e, settled_weight=w) for c in (2.0, 5.0, 10.0, 20.0)
        for m in (0.0, 0.002, 0.003, 0.005) for e in (0.1, 1.0, 3.0) for w in (0.0, 1.0, 3.0, 10.0, 30.0)]
#: One rule for every hand (``--cv`` with several hands): the grid of the joint cross-validation.
JOINT_GRID = [dict(cap=c, min_open_margin=m, eps_weight=e, settled_weight=w) for c in (5.0, 20.0)
              for m in (0.0, 0.002) for e in (0.1, 1.0, 3.0) for w in (0.0, 10.0, 30.0, 100.0)]


def split(name: str) -> list[str]:
    data = tomllib.loads(SPLIT.read_text())
    if name not in ("tuning", "held_out", "held_out_2", "held_out_3"):
        raise SystemExit(f"--set must be tuning, held_out, held_out_2 or held_out_3, got {name}")
    return list(data[name])


@dataclass
class Pool:
    """Every grasp of one (hand, object) with its measures and labels."""

    object: str
    grasps: list[Grasp]
    legacy: np.ndarray  # (n,) pre-issue epsilon (legacy point contacts)
    uniform: np.ndarray  # (n,) bool: in the seeded uniform sample

    @cached_property
    def measures(self) -> dict[str, np.ndarray]:
        return rule_measures(self.grasps)

    def columns(self, rule: RankingRule) -> dict[str, np.ndarray]:
        m = self.measures
        fc_legacy = self.legacy > 0
        return {"analytic": rule.analytic(m), "pre_issue": np.where(fc_legacy, self.legacy, 0.0),
                "epsilon": m["epsilon"], "epsilon_legacy": self.legacy, "settled_epsilon": m["settled_epsilon"],
                "resist_worst": m["resist_worst"], "push": m["push"], "open_margin": m["open_margin"],
                "close_margin": m["close_margin"],
                "resist_mean": np.array([np.nan if g.measures is None else g.measures.resist_mean
                                         for g in self.grasps]),
                "feasible": np.array([g.measures is not None and g.measures.feasible for g in self.grasps], float)}

    @property
    def success(self) -> np.ndarray:
        return np.array([np.nan if g.validation is None else g.validation.success for g in self.grasps], float)


def uniform_sample(n: int, per_object: int, hand: str, name: str) -> np.ndarray:
    rng = np.random.default_rng([SEED, zlib.crc32(name.encode()), zlib.crc32(hand.encode())])
    out = np.zeros(n, bool)
    out[rng.choice(n, size=min(per_object, n), replace=False)] = True
    return out


def legacy_epsilons(db_path: Path, hand_name: str, name: str, grasps: list[Grasp]) -> np.ndarray:
    """Epsilon of each grasp from its contacts read the pre-issue way (cached)."""
    cache = db_path.with_name(db_path.stem + "_legacy.json")
    known = json.loads(cache.read_text()) if cache.exists() else {}
    todo = [g for g in grasps if str(g.id) not in known]
    if todo:
        hand, obj = load_hand(hand_name), load_object(name)
        with Sim() as sim:
            grasper = Grasper.for_mesh(sim, hand, obj.mesh, CloseSettings(contacts="points"))
            for g in todo:
                read = grasper.read(g.pose, dict(g.open_joints), dict(g.closed_joints))
                known[str(g.id)] = grasp_quality(read.contacts, hand, obj, 8, False).epsilon \
                    if isinstance(read, Closed) else 0.0
        cache.write_text(json.dumps(known))
    return np.array([known[str(g.id)] for g in grasps], float)


def trial_settings():  # type: ignore[no-untyped-def]
    """The shake test's default settings, whatever the trial's settings type is
    called (``TrialSettings`` on main, ``ShakeSettings`` after issue15-shake):
    the type ``planner.validation.run.Task`` declares for its ``trial``."""
    hint = get_type_hints(validation.Task)["trial"]  # ShakeSettings | MujocoSettings: the shake test's is first
    return (typing.get_args(hint) or (hint,))[0]()


def label(db_path: Path, hand_name: str, name: str, grasps: list[Grasp], workers: int) -> int:
    """Shake-test the grasps that have no trial yet with ``grasp validate``'s
    own tasks, workers and writer (no robust epsilon); returns how many ran."""
    todo = [g for g in grasps if g.validation is None]
    if not todo:
        return 0
    with writer_lock(db_path), open_db(db_path, create=False) as db:
        row, rule = db.object_row(name), db.rule()
        assert row is not None, name
        settings = trial_settings()
        tasks = [validation.Task(row, hand_name, tuple(todo[i:i + validation.BATCH]),
                                 SEED, settings, None) for i in range(0, len(todo), validation.BATCH)]
        for result in validation.execute(tasks, workers):
            if result.error:
                raise SystemExit(f"shake test of {hand_name} on {name} failed: {result.error}")
            validation.write(db, result, rule)
    return len(todo)


def jittered(g: Grasp, k: int, mm: float, deg: float) -> list[Grasp]:
    """k copies of a grasp, its pose moved by ``mm`` [mm] along a random
    direction and turned by ``deg`` about a random axis (object frame), seeded
    by the grasp's candidate and seed."""
    rng = np.random.default_rng([SEED, g.candidate, g.seed, zlib.crc32(g.object.encode()), 1])
    out = []
    for _ in range(k):
        pose = np.array(g.pose, float)
        move, axis = rng.normal(size=3), rng.normal(size=3)
        pose[:3, 3] += move / np.linalg.norm(move) * mm / 1000.0
        pose[:3, :3] = Rotation.from_rotvec(axis / np.linalg.norm(axis) * np.deg2rad(deg)).as_matrix() @ pose[:3, :3]
        out.append(replace(g, pose=pose, validation=None))
    return out


def jitter_labels(db_path: Path, hand: str, pools_: list[Pool], k: int, mm: float, deg: float,
                  workers: int) -> dict[int, list[bool]]:
    """{grasp id: k jittered trial verdicts} of every labelled uniform grasp (cached)."""
    cache = db_path.with_name(f"{db_path.stem}_jitter.json")
    key = f"{k} x {mm} mm {deg} deg"
    data = json.loads(cache.read_text()) if cache.exists() else {}
    known = {int(i): v for i, v in data.get(key, {}).items()}
    with open_db(db_path, create=False, readonly=True) as db:
        rows = {p.object: db.object_row(p.object) for p in pools_}
    tasks = []
    for p in pools_:
        todo = [g for g, u in zip(p.grasps, p.uniform) if u and g.validation is not None and g.id not in known]
        copies = [c for g in todo for c in jittered(g, k, mm, deg)]
        row = rows[p.object]
        assert row is not None, p.object
        tasks += [validation.Task(row, hand, tuple(copies[i:i + validation.BATCH]), SEED,
                                  trial_settings(), None) for i in range(0, len(copies), validation.BATCH)]
    for result in validation.execute(tasks, workers):  # as they finish: copies keep their grasp's id
        if result.error:
            raise SystemExit(f"jittered shake test of {hand} on {result.task.object} failed: {result.error}")
        for copy, trial in zip(result.task.grasps, result.trials):
            known.setdefault(copy.id, []).append(bool(trial.success))
    data[key] = {str(i): v for i, v in known.items()}
    cache.write_text(json.dumps(data))
    return known


def repeatability(pools_: list[Pool], rule: RankingRule, jitter: dict[int, list[bool]]) -> dict:
    """Agreement of jittered trials with the label; AUCs against the robust label."""
    cols = [p.columns(rule) for p in pools_]
    label, near, scores = [], [], {key: [] for key in MEASURES}
    for p, c in zip(pools_, cols):
        for i in np.flatnonzero(p.uniform):
            g = p.grasps[i]
            if g.validation is None or g.id not in jitter:
                continue
            label.append(float(g.validation.success))
            near.append(np.mean(jitter[g.id]))
            for key in MEASURES:
                scores[key].append(c[key][i])
    label_, near_ = np.array(label), np.array(near)
    k = len(next(iter(jitter.values()))) if jitter else 0
    robust = ((label_ + near_ * k) / (1 + k) >= 0.5).astype(float)
    agree = float(np.mean(1.0 - np.abs(near_ - label_))) if len(label_) else float("nan")  # share of jittered trials
    return {"grasps": len(label_), "jitters": k, "agreement": float(agree),
            "ceiling_auc": roc_auc(label_, near_), "robust_held": float(robust.mean()) if len(robust) else float("nan"),
            "robust_auc": {key: roc_auc(robust, np.array(v, float)) for key, v in scores.items()}}


def pools(db_path: Path, hand: str, names: list[str], per_object: int, workers: int,
          rule: RankingRule) -> list[Pool]:
    out = []
    for name in names:
        with open_db(db_path, create=False, readonly=True) as db:
            grasps = [g for batch in db.grasp_batches(name, hand) for g in batch]
        if not grasps:
            continue
        grasps.sort(key=lambda g: g.candidate)
        legacy = legacy_epsilons(db_path, hand, name, grasps)
        pool = Pool(name, grasps, legacy, uniform_sample(len(grasps), per_object, hand, name))
        picks = set(np.flatnonzero(pool.uniform))
        cols = pool.columns(rule)
        for key in ("analytic", "pre_issue"):
            picks |= set(_order(cols[key], grasps)[:TOP])
        t = time.perf_counter()
        ran = label(db_path, hand, name, [grasps[i] for i in sorted(picks)], workers)
        if ran:
            logging.info("%s %s: %d trials in %.0f s", hand, name, ran, time.perf_counter() - t)
        with open_db(db_path, create=False, readonly=True) as db:
            by_id = {g.id: g for batch in db.grasp_batches(name, hand) for g in batch}
        out.append(replace(pool, grasps=[by_id[g.id] for g in grasps]))
    return out


def _order(score: np.ndarray, grasps: list[Grasp]) -> np.ndarray:
    """Indices best first; ties by candidate number (deterministic)."""
    return np.lexsort((np.array([g.candidate for g in grasps]), -np.nan_to_num(score, nan=-np.inf)))


def figures(pools_: list[Pool], rule: RankingRule) -> dict:
    """AUCs on the uniform sample; top-1 / top-10 of both orders."""
    cols = [p.columns(rule) for p in pools_]
    ok = np.concatenate([p.success[p.uniform] for p in pools_])
    out: dict = {"objects": len(pools_), "uniform_labels": int(np.isfinite(ok).sum()),
                 "held_rate": float(np.nanmean(ok)) if len(ok) else float("nan"), "auc": {}, "auc_per_object": {}}
    for key in MEASURES:
        score = np.concatenate([c[key][p.uniform] for c, p in zip(cols, pools_)])
        out["auc"][key] = roc_auc(ok, score)
        per = [roc_auc(p.success[p.uniform], c[key][p.uniform]) for c, p in zip(cols, pools_)]
        per = [v for v in per if np.isfinite(v)]
        out["auc_per_object"][key] = float(np.mean(per)) if per else float("nan")
    for key in ("analytic", "pre_issue"):
        orders = [(_order(c[key], p.grasps), p.success) for c, p in zip(cols, pools_)]
        out[f"top1_{key}"], out[f"top10_{key}"], out[f"unlabelled_{key}"] = top_k_success(orders, TOP)
    return out


def cross_validate(pools_: list[Pool], base: RankingRule, folds: int = 5) -> dict:
    """Parameters chosen on the other folds' objects, figures of the held fold."""
    names = np.array(sorted(p.object for p in pools_))
    np.random.default_rng(SEED).shuffle(names)
    parts = np.array_split(names, folds)
    held_scores, chosen = {}, []
    for part in parts:
        train = [p for p in pools_ if p.object not in set(part)]
        best = max(GRID, key=lambda g: _objective(figures(train, replace(base, **g))))
        chosen.append(best)
        for p in pools_:
            if p.object in set(part):
                held_scores[p.object] = replace(base, **best)
    ok, score, orders = [], [], []
    for p in pools_:
        col = p.columns(held_scores[p.object])["analytic"]
        ok.append(p.success[p.uniform])
        score.append(col[p.uniform])
        orders.append((_order(col, p.grasps), p.success))
    top1, top10, missing = top_k_success(orders, TOP)
    return {"auc": roc_auc(np.concatenate(ok), np.concatenate(score)), "top1": top1, "top10": top10,
            "unlabelled_top": missing, "chosen": chosen}


def cross_validate_joint(by_hand: dict[str, list[Pool]], base: RankingRule, folds: int = 5) -> dict:
    """One rule for all hands: per fold of objects, the :data:`JOINT_GRID`
    point that maximises the sum over hands of the training folds'
    objective; the held fold's figures per hand."""
    names = np.array(sorted({p.object for pools_ in by_hand.values() for p in pools_}))
    np.random.default_rng(SEED).shuffle(names)
    chosen, held = [], {h: {} for h in by_hand}
    for part in np.array_split(names, folds):
        fold = set(part)
        best = max(JOINT_GRID, key=lambda g: sum(
            _objective(figures([p for p in pools_ if p.object not in fold], replace(base, **g)))
            for pools_ in by_hand.values()))
        chosen.append(best)
        for h, pools_ in by_hand.items():
            held[h] |= {p.object: replace(base, **best) for p in pools_ if p.object in fold}
    out: dict = {"chosen": chosen}
    for h, pools_ in by_hand.items():
        ok, score, orders = [], [], []
        for p in pools_:
            col = p.columns(held[h][p.object])["analytic"]
            ok.append(p.success[p.uniform])
            score.append(col[p.uniform])
            orders.append((_order(col, p.grasps), p.success))
        top1, top10, missing = top_k_success(orders, TOP)
        out[h] = {"auc": roc_auc(np.concatenate(ok), np.concatenate(score)), "top1": top1, "top10": top10,
                  "unlabelled_top": missing}
    return out


def _objective(f: dict) -> float:
    return np.nan_to_num(f["auc"]["analytic"]) + np.nan_to_num(f["top1_analytic"])


def report(results: dict[str, dict], set_name: str, rule: RankingRule) -> str:
    hands = list(results)
    lines = [f"# Calibration on the `{set_name}` objects", "",
             f"Rule: `{rule.to_json()}`", "", "| figure | " + " | ".join(hands) + " |",
             "| --- | " + " | ".join("---:" for _ in hands) + " |"]

    def row(label: str, values: list[str]) -> None:
        lines.append(f"| {label} | " + " | ".join(values) + " |")

    row("objects", [str(results[h]["objects"]) for h in hands])
    row("uniformly sampled grasps labelled", [str(results[h]["uniform_labels"]) for h in hands])
    row("held (uniform sample)", [f"{results[h]['held_rate']:.3f}" for h in hands])
    for key in MEASURES:
        row(f"ROC AUC {key} (pooled / per-object mean)",
            [f"{results[h]['auc'][key]:.3f} / {results[h]['auc_per_object'][key]:.3f}" for h in hands])
    for key, label in (("analytic", "analytic order"), ("pre_issue", "pre-issue order (legacy epsilon)")):
        row(f"top-1 held, {label}", [f"{results[h][f'top1_{key}']:.3f}" for h in hands])
        row(f"top-10 held, {label}", [f"{results[h][f'top10_{key}']:.3f}" for h in hands])
    for h in hands:
        if "repeat" in results[h]:
            r = results[h]["repeat"]
            lines += ["", f"{h}: label repeatability, {r['grasps']} labelled uniform grasps x {r['jitters']} jittered "
                      f"trials ({r['jitter']}): a jittered trial agrees with the label {r['agreement']:.3f}; ROC AUC "
                      f"of the jittered trials' mean against the label (ceiling) {r['ceiling_auc']:.3f}; robust label "
                      f"(held in >= half of the 1 + K trials) held {r['robust_held']:.3f}, ROC AUC against it: "
                      + ", ".join(f"{k} {v:.3f}" for k, v in r["robust_auc"].items())]
        if "cv" in results[h]:
            cv = results[h]["cv"]
            lines += ["", f"{h}: 5-fold CV grouped by object (held folds): AUC {cv['auc']:.3f}, top-1 "
                      f"{cv['top1']:.3f}, top-10 {cv['top10']:.3f}, unlabelled top picks {cv['unlabelled_top']}; "
                      f"chosen per fold: {cv['chosen']}"]
    if "joint_cv" in results.get(hands[0], {}):
        joint = results[hands[0]]["joint_cv"]
        lines += ["", "One rule for all hands, 5-fold CV grouped by object (held folds): " + "; ".join(
            f"{h} AUC {joint[h]['auc']:.3f}, top-1 {joint[h]['top1']:.3f}, top-10 {joint[h]['top10']:.3f}, "
            f"unlabelled top picks {joint[h]['unlabelled_top']}" for h in hands)
            + f"; chosen per fold: {joint['chosen']}"]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--set", required=True,
                    help="tuning | held_out | held_out_2 | held_out_3 (held-out sets: the lead, once each, at the end)")
    ap.add_argument("--hands", nargs="+", default=["panda", "barrett"])
    ap.add_argument("--objects", type=int, help="only the first N objects of the set (smoke runs)")
    ap.add_argument("--only", nargs="+", help="only these objects (they must be in the set)")
    ap.add_argument("--per-object", type=int, default=100)
    ap.add_argument("--approaches", type=int, nargs="+", default=[24, 12],
                    help="rays per object, per hand (default: Panda 24, ~230 grasps per object; Barrett 12, ~480)")
    ap.add_argument("--workers", type=int, default=api.default_workers())
    ap.add_argument("--dir", type=Path, default=HERE / "calibration")
    ap.add_argument("--final-held-out", action="store_true",
                    help="required with --set held_out: the one final evaluation, by the lead, after all tuning")
    ap.add_argument("--jitter", type=int, default=0, metavar="K",
                    help="label repeatability: K jittered trials per labelled uniform grasp (default 0: off)")
    ap.add_argument("--jitter-mm", type=float, default=1.0)
    ap.add_argument("--jitter-deg", type=float, default=1.0)
    ap.add_argument("--reuse", action="store_true",
                    help="no sweep: score the grasps already in DIR's databases with today's rule (tuning only)")
    ap.add_argument("--cv", action="store_true", help="cross-validate the rule's parameters (tuning set only)")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    if args.set != "tuning" and not args.final_held_out:
        raise SystemExit("--set held_out is the one final evaluation (the lead's, after all tuning): "
                         "add --final-held-out to run it; tune on --set tuning")
    names = split(args.set)
    if args.only:
        bad = [n for n in args.only if n not in names]
        if bad:
            raise SystemExit(f"not in the {args.set} set: {bad}")
        names = args.only
    names = names[: args.objects] if args.objects else names
    if args.reuse and args.set != "tuning":
        raise SystemExit("--reuse: tuning set only (a held-out evaluation sweeps with the code under test)")
    if args.cv and args.set != "tuning":
        raise SystemExit("--cv tunes: tuning set only")
    args.dir.mkdir(parents=True, exist_ok=True)
    rule = RankingRule(reach_weight=0.0, success_weight=0.0)
    results: dict[str, dict] = {}
    by_hand: dict[str, list[Pool]] = {}
    for hand, approaches in zip(args.hands, args.approaches * len(args.hands)):
        db = args.dir / f"{args.set}_{hand}.db"
        settings = SweepSettings(approaches=approaches, reach_placements=0, volume=False)
        t = time.perf_counter()
        if not args.reuse:
            summary = api.generate(names, hand, db_path=db, settings=settings, workers=args.workers, rule=rule)
            logging.info("%s: %d units swept (%d skipped), %.0f s", hand, summary.units, summary.skipped,
                         time.perf_counter() - t)
        pools_ = pools(db, hand, names, args.per_object, args.workers, rule)
        results[hand] = figures(pools_, rule)
        if args.jitter:
            jitter = jitter_labels(db, hand, pools_, args.jitter, args.jitter_mm, args.jitter_deg, args.workers)
            results[hand]["repeat"] = {**repeatability(pools_, rule, jitter),
                                       "jitter": f"{args.jitter_mm} mm, {args.jitter_deg} deg"}
        if args.cv:
            results[hand]["cv"] = cross_validate(pools_, rule)
            by_hand[hand] = pools_
    if args.cv and len(by_hand) > 1:
        results[args.hands[0]]["joint_cv"] = cross_validate_joint(by_hand, rule)
    text = report(results, args.set, rule)
    out = args.dir / f"report_{args.set}.md"
    out.write_text(text)
    (args.dir / f"figures_{args.set}.json").write_text(json.dumps(results, indent=1, default=str))
    sys.stdout.write(text)


if __name__ == "__main__":
    main()
