"""The planner's score, its p_hold and its shake trial against ACRONYM's FleX labels (issue 26).

For each grasp file of ``../shared/labelled/acronym_dev`` whose object is on the ``tuning`` side of
bench/acronym_split.toml (``--held-out``: the held-out side, run ONCE by the lead at the end; a
held-out object is refused otherwise), a fixed-seed uniform sample of ``--poses`` poses is
re-scored as ``grasp import --format acronym FILE --rescore`` does (the same API,
:func:`planner.datasets.importer.rescore_poses`, with the file's mass and friction), and compared
pose by pose with ``object_in_gripper``:

- ROC AUC against the label, per file, of p_hold (the shipped model, or ``--model FILE``: a Panda
  grasp's stored score where a model applies, reachability and trials aside) and of the rule's
  formula (``auc_formula``: the stored score where no model applies); a pose rejected by closing
  counts as the lowest score;
- the width baseline ("smaller closed width is better", rejected poses lowest);
- AUC of p_hold (the shipped model, or ``--model FILE``) and its expected calibration error over
  the closed poses;
- the share of each file's 10 best-scored poses that hold in FleX (ties broken by row order);
- rejections by reason;
- ``--trial N``: ``grasp validate``'s shake trial on N of each file's closed poses (the file's mass
  and friction), its agreement with FleX (closed poses; and counting rejected poses as drops);
  ``--engine mujoco``: the MuJoCo trial instead (``grasp validate --engine mujoco``), started at the
  file's own pose (``--trial-pose original``, its default: what FleX simulated) or the planner's
  re-centred one (``planned``, the PyBullet trial's default).

Figures are averaged per object (its files' mean), then over objects and per category. Results
of re-scoring and trials are cached under ``--cache`` keyed by the file, the sample and a hash
of the planner's source, so a second run only computes what changed.

    python bench/acronym_eval.py [--poses 200] [--trial 30] [--engine mujoco] [--json] [--held-out]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import pickle
import sys
import time
import zlib
from collections import Counter, defaultdict
from contextlib import closing
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import tomllib

from planner.calibration import features
from planner.calibration.fitting import calibrate
from planner.calibration.labels import LabelledSet, file_digest, object_properties
from planner.calibration.metrics import (
    INTERVAL_SEED,
    agreement,
    expected_calibration_error,
    group_interval,
    roc_auc,
)
from planner.calibration.model import DEFAULT_FEATURES, DEFAULT_TREES, default_model, load_model
from planner.datasets import importer
from planner.datasets.acronym import read_labels
from planner.db.ranking import RankingRule, first_measures, rank_order, ranks_first
from planner.geometry.solid import prepare
from planner.run import pool
from planner.validation import mujoco_trial
from planner.validation.mujoco_settings import ENGINES, MujocoSettings
from planner.validation.shake import ShakeSettings, trials

ROOT = Path(__file__).resolve().parents[1]
SPLIT = ROOT / "bench" / "acronym_split.toml"
DEV = ROOT.parent / "shared" / "labelled" / "acronym_dev"
CACHE = Path.home() / ".cache" / "grasp-planner" / "acronym_eval"
#: The k of "the k best-scored poses hold".
TOP_K = 10


def object_key(path: Path) -> tuple[str, str]:
    """(category, ``Category_id``) of a dev file ``Category_id_scale.h5``."""
    category, object_id, _scale = path.stem.split("_", 2)
    return category, f"{category}_{object_id}"


def dev_files(dev: Path, held_out: bool, only: list[str] | None) -> list[Path]:
    split = tomllib.loads(SPLIT.read_text())
    side = set(split["held_out" if held_out else "tuning"])
    if only:
        bad = [o for o in only if o in split["held_out"] and not held_out]
        if bad:
            sys.exit(f"acronym_eval: {', '.join(bad)} held out: measured only with --held-out, once, by the lead")
        side &= set(only)
    files = sorted(p for p in (dev / "grasps").glob("*.h5") if object_key(p)[1] in side)
    if not files:
        sys.exit(f"acronym_eval: no grasp files of the selected objects in {dev / 'grasps'}")
    return files


def source_hash() -> str:
    """Hash of the source re-scoring runs (planning stages, the importer): a
    cached result is reused only by the same code."""
    h = hashlib.sha256()
    stages = ("plan", "quality", "geometry", "sim", "specs", "record")
    for p in sorted((ROOT / "planner").rglob("*.py")):
        if p.name in ("mujoco_world.py", "mujoco_mjcf.py"):  # the MuJoCo trial's engine: re-scoring never runs it
            continue
        if p.parent.name in stages or p.name == "importer.py":
            h.update(p.read_bytes())
    for folder in ("hands", "preshapes"):
        for p in sorted((ROOT / folder).rglob("*")):
            if p.is_file():
                h.update(p.read_bytes())
    return h.hexdigest()[:12]


def sample(n: int, k: int, seed: int, stem: str) -> np.ndarray:
    rng = np.random.default_rng([seed, zlib.crc32(stem.encode())])
    return np.sort(rng.choice(n, size=min(k, n), replace=False))


@dataclass
class FileResult:
    """One file's sampled poses: ``rows`` (m,) of the file, ``labels`` (m,) 0/1,
    ``reasons`` (m,) '' where closed, the closed grasps (in row order, ``candidate`` = sampled position)."""

    path: Path
    rows: np.ndarray
    labels: np.ndarray
    reasons: list[str]
    grasps: list = field(default_factory=list)
    rejected: dict[str, int] = field(default_factory=dict)  # closing's and scoring's reasons, counted
    trial: dict[int, bool] = field(default_factory=dict)  # sampled position -> held
    top_trial: dict[int, bool] = field(default_factory=dict)  # --trial-top: sampled position -> held

    @property
    def closed(self) -> np.ndarray:
        return np.array([r == "" for r in self.reasons])


def rescore_file(path: Path, poses: int, seed: int, workers: int, cache: Path, code: str) -> FileResult:
    key = cache / f"{path.stem}.{poses}.{seed}.{code}.pkl"
    if key.exists():
        return pickle.loads(key.read_bytes())
    hand, spec, all_poses = importer.read_for_rescoring(path)
    labels_all = np.asarray(read_labels(path), int)  # (N,) or an (N, 1) column, as `grasp calibrate` reads them
    rows = sample(len(all_poses), poses, seed, path.stem)
    chunk = importer.RESCORE_CHUNK
    units = [importer.RescoreUnit(0, i, all_poses[rows[i:i + chunk]], hand, spec)
             for i in range(0, len(rows), chunk)]
    grasps: dict[int, object] = {}
    rejected: Counter = Counter()
    with closing(pool.execute(importer.rescore_poses, units, workers)) as outcomes:
        for _unit, outcome, _ in outcomes:
            if isinstance(outcome, pool.Failure):
                raise SystemExit(f"acronym_eval: {path.name}: {outcome}")
            rejected.update(outcome.rejected)
            grasps.update({g.candidate: g for g in outcome.grasps})  # candidate = sampled position
    reasons = ["" if i in grasps else "rejected" for i in range(len(rows))]
    result = FileResult(path, rows, labels_all[rows], reasons, [grasps[i] for i in sorted(grasps)], dict(rejected))
    cache.mkdir(parents=True, exist_ok=True)
    key.write_bytes(pickle.dumps(result))
    return result


def run_trials(result: FileResult, n: int, seed: int, settings: ShakeSettings | MujocoSettings, cache: Path, code: str,
               pose: str = "planned") -> None:
    closed = np.flatnonzero(result.closed)
    if n <= 0 or not len(closed):
        return
    picked = [int(closed[i]) for i in sample(len(closed), n, seed + 1, result.path.stem)]
    result.trial, result.trial_reasons = _trialled(result, picked, settings, cache, code, pose,  # type: ignore[attr-defined]
                                                   f"{seed}.{n}")


def run_top_trials(result: FileResult, p_hold: np.ndarray, k: int, settings: ShakeSettings | MujocoSettings,
                   cache: Path, code: str, pose: str) -> None:
    """``--trial-top``: trial the file's ``k`` best closed poses in rank order (``p_hold`` (m,) per sampled
    pose, -inf where rejected; force closure as planned or once squeezed first) into ``result.top_trial``."""
    fc = np.zeros(len(result.rows))
    fc[np.flatnonzero(result.closed)] = ranks_first(first_measures(result.grasps))
    picked = [int(i) for i in rank_order(p_hold, fc)[:k] if result.closed[i]]
    if picked:
        digest = hashlib.sha256(json.dumps(picked).encode()).hexdigest()[:8]
        result.top_trial, _ = _trialled(result, picked, settings, cache, code, pose, f"top{k}-{digest}")


def _trialled(result: FileResult, picked: list[int], settings: ShakeSettings | MujocoSettings, cache: Path,
              code: str, pose: str, which: str) -> tuple[dict[int, bool], dict[int, str]]:
    """The trial's verdicts (held, reason) of the sampled positions ``picked``, cached under ``which``."""
    mujoco = isinstance(settings, MujocoSettings)
    if mujoco or pose != "planned":  # the PyBullet trial at planned poses keeps the keys of its earlier figures
        tag = hashlib.sha256((settings.to_json() + pose + trial_source()).encode()).hexdigest()[:8]
        tag = ("mujoco-" if mujoco else "") + tag
    else:
        tag = hashlib.sha256(settings.to_json().encode()).hexdigest()[:8]
    key = cache / f"{result.path.stem}.trial.{len(result.rows)}.{which}.{tag}.{code}.json"
    if key.exists():
        stored = json.loads(key.read_text())
        return ({int(k): bool(v[0] if isinstance(v, list) else v) for k, v in stored.items()},
                {int(k): v[1] for k, v in stored.items() if isinstance(v, list)})
    hand, spec, poses = importer.read_for_rescoring(result.path)
    by_pos = {g.candidate: g if pose == "planned" else replace(g, pose=poses[result.rows[g.candidate]])
              for g in result.grasps}
    obj = prepare(spec)
    run = mujoco_trial.trials if mujoco else trials
    outcome = run(hand, obj, [by_pos[p] for p in picked], settings)
    held = {p: bool(t.success) for p, t in zip(picked, outcome)}
    reasons = {p: t.reason for p, t in zip(picked, outcome)}
    key.write_text(json.dumps({p: [held[p], reasons[p]] for p in picked}))
    return held, reasons


def trial_source() -> str:
    """Hash of the trial modules' source (the trial's cache key; re-scoring's is :func:`source_hash`)."""
    h = hashlib.sha256()
    extra = [ROOT / "planner" / "sim" / "mujoco_world.py", ROOT / "planner" / "geometry" / "decompose.py"]  # the parts
    for p in sorted((ROOT / "planner" / "validation").glob("*.py")) + extra:
        if p.name not in ("run.py", "robust.py"):
            h.update(p.read_bytes())
    return h.hexdigest()[:12]


def scores(result: FileResult, model, rule: RankingRule, p_hold: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """(m,) per sampled pose: the rule's formula, -width, p_hold (``p_hold`` given:
    (closed,) out-of-fold predictions), what ranks first (``fc``: force closure as planned or squeezed,
    :func:`planner.db.ranking.ranks_first`) and force closure as planned (``fc_planned``); rejected poses -inf (fc
    0)."""
    m = len(result.rows)
    out = {name: np.full(m, -np.inf) for name in ("formula", "width", "p_hold")}
    out["fc"], out["fc_planned"] = np.zeros(m), np.zeros(m)
    closed = np.flatnonzero(result.closed)
    if len(closed):
        table = features.of_grasps(result.grasps)
        out["formula"][closed] = rule.scores(_rule_measures(table))
        out["width"][closed] = -np.nan_to_num(table["width"], nan=np.inf)
        out["fc"][closed] = ranks_first(table)  # as the database ranks: force closure planned or squeezed
        out["fc_planned"][closed] = table["force_closure"]  # the order before 2026-12-07
        if p_hold is not None:
            out["p_hold"][closed] = p_hold
        else:
            out["p_hold"][closed] = model.predict(table) if model is not None else np.nan
    return out


def _rule_measures(table: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {k: table[k] for k in ("epsilon", "force_closure", "resist_worst", "push", "open_margin", "close_margin",
                                  "settled_epsilon")}


def top_hold(order_score: np.ndarray, fc: np.ndarray, labels: np.ndarray, k: int = TOP_K) -> float:
    """Share of the k first poses in the database's rank order (``fc`` first, then score) that hold."""
    return float(np.mean(labels[rank_order(order_score, fc)[:k]]))


def evaluate(results: list[FileResult], model, rule: RankingRule, oof: dict[str, np.ndarray] | None = None,
             trial_group: str = "") -> dict:
    """``trial_group``: the record group of ``--trial``'s engine (``mujoco``, ``validation``): where the model
    updates p_hold by that trial's verdict, the agreement of p_hold_trial >= 0.5 too."""
    per_file = []
    for r in results:
        s = scores(r, model, rule, None if oof is None else oof[r.path.stem])
        closed = r.closed
        row = {"file": r.path.stem, "category": object_key(r.path)[0], "object": object_key(r.path)[1],
               "poses": len(r.rows), "closed": int(closed.sum()), "success_rate": float(r.labels.mean()),
               "auc_formula": roc_auc(r.labels, s["formula"]), "auc_width": roc_auc(r.labels, s["width"]),
               "top10_formula": top_hold(s["formula"], s["fc"], r.labels),
               "top10_formula_planned_fc": top_hold(s["formula"], s["fc_planned"], r.labels),
               "rejected": r.rejected}
        if model is not None:
            row["auc_p_hold"] = roc_auc(r.labels, s["p_hold"])
            row["top10_p_hold"] = top_hold(s["p_hold"], s["fc"], r.labels)
            row["top10_p_hold_planned_fc"] = top_hold(s["p_hold"], s["fc_planned"], r.labels)  # planned FC first
            top_trial = getattr(r, "top_trial", {})  # a result pickled before --trial-top has none
            if top_trial:  # as the database ranks once the trial tried them (success_weight 1)
                factor = np.ones(len(r.rows))
                for p, held in top_trial.items():
                    factor[p] = float(held)
                row["top10_validated"] = top_hold(s["p_hold"] * factor, s["fc"], r.labels)
                if trial_group in model.updates:  # as the database ranks them now: by p_hold given the verdict
                    pos = np.array(sorted(top_trial))
                    updated = s["p_hold"].copy()
                    updated[pos] = model.given_trial(s["p_hold"][pos], {trial_group: factor[pos]})
                    row["top10_validated_multiplied"] = row["top10_validated"]
                    row["top10_validated"] = top_hold(updated, s["fc"], r.labels)
                row["top_trial_n"] = len(top_trial)
        if r.trial:
            pos = np.array(sorted(r.trial))
            verdict = np.array([r.trial[p] for p in pos], int)
            row["trial_n"] = len(pos)
            row["trial_agree"] = float(np.mean(verdict == r.labels[pos]))
            if model is not None and trial_group in model.updates:  # the label an export writes after the trial
                q = model.given_trial(s["p_hold"][pos], {trial_group: verdict.astype(float)})
                row["p_hold_trial_agree"] = float(np.mean((q >= 0.5) == (r.labels[pos] == 1)))
                row["p_hold_tried_agree"] = float(np.mean((s["p_hold"][pos] >= 0.5) == (r.labels[pos] == 1)))
            row["trial_drops_flex_holds"] = int(np.sum((verdict == 0) & (r.labels[pos] == 1)))
            row["trial_holds_flex_drops"] = int(np.sum((verdict == 1) & (r.labels[pos] == 0)))
            reasons = getattr(r, "trial_reasons", {})
            row["trial_reasons"] = dict(Counter(reasons.get(p, "?") for p in pos))
        per_file.append(row)
    pooled: dict = {}
    if model is not None:
        closed_p = np.concatenate([scores(r, model, rule, None if oof is None else oof[r.path.stem])["p_hold"][r.closed]
                                   for r in results])
        closed_y = np.concatenate([r.labels[r.closed] for r in results])
        pooled["ece_p_hold"] = expected_calibration_error(closed_y, closed_p) if len(closed_y) else float("nan")
        pooled["closed_poses"] = int(len(closed_y))
        # p_hold >= 0.5 as a label (what an export without a trial writes): agreement with FleX, pooled
        pooled["p_hold_label_agree"] = float(np.mean((closed_p >= 0.5) == (closed_y == 1))) if len(closed_y) else \
            float("nan")
    trial_rows = [f for f in per_file if "trial_n" in f]
    if trial_rows:
        n = sum(f["trial_n"] for f in trial_rows)
        pooled["trial_agree_pooled"] = sum(f["trial_agree"] * f["trial_n"] for f in trial_rows) / n
        pooled["trial_n"] = n
        for key in ("p_hold_trial_agree", "p_hold_tried_agree"):
            if all(key in f for f in trial_rows):
                pooled[key + "_pooled"] = sum(f[key] * f["trial_n"] for f in trial_rows) / n
        pooled["trial_drops_flex_holds"] = sum(f["trial_drops_flex_holds"] for f in trial_rows)
        pooled["trial_holds_flex_drops"] = sum(f["trial_holds_flex_drops"] for f in trial_rows)
        pooled["trial_reasons"] = dict(sum((Counter(f["trial_reasons"]) for f in trial_rows), Counter()))
    pooled["squeeze"] = squeeze_figures(results)
    pooled["rejected"] = dict(sum((Counter(f["rejected"]) for f in per_file), Counter()))
    pooled["poses"] = sum(f["poses"] for f in per_file)
    objects = _by(per_file, "object")
    closed = [(object_key(r.path)[1], r.labels[r.closed],
               scores(r, model, rule, None if oof is None else oof[r.path.stem])["p_hold"][r.closed])
              for r in results] if model is not None else []
    return {"files": per_file, "objects": objects, "categories": _by_category(per_file),
            "mean": _mean(objects), "intervals": intervals(objects, closed), **pooled}


def squeeze_figures(results: list[FileResult]) -> dict[str, dict[str, float]]:
    """Per category and ``all``, over the closed poses: the share force closure as planned and as squeezed
    (:mod:`planner.plan.squeeze`), and FleX's hold rate of the squeezed force-closure poses and of the others."""
    rows: dict[str, list[tuple[float, float, int]]] = defaultdict(list)
    for r in results:
        for g, label in zip(r.grasps, r.labels[r.closed]):
            squeezed = g.measures.squeezed_force_closure if g.measures is not None else None
            item = (float(g.force_closure), np.nan if squeezed is None else float(squeezed), int(label))
            rows[object_key(r.path)[0]].append(item)
            rows["all"].append(item)
    out = {}
    for name, items in sorted(rows.items()):
        planned, squeezed, held = (np.array(c, float) for c in zip(*items))
        out[name] = {"closed": len(items), "fc_planned": float(planned.mean()), "fc_squeezed": float(np.nanmean(
            squeezed)), "hold_squeezed_fc": float(held[squeezed == 1].mean()) if (squeezed == 1).any() else np.nan,
            "hold_not_squeezed_fc": float(held[squeezed == 0].mean()) if (squeezed == 0).any() else np.nan}
    return out


def intervals(objects: list[dict], closed: list[tuple[str, np.ndarray, np.ndarray]]) -> dict[str, tuple[float, float]]:
    """95% intervals over objects (planner.calibration.metrics.group_interval, a bootstrap drawing objects) of
    the MEAN row's figures (means over objects) and of the pooled ECE and label agreement of p_hold;
    ``closed``: (object, labels, p_hold) of each file's closed poses."""
    rng = np.random.default_rng(INTERVAL_SEED)
    out = {}
    for m in ("auc_p_hold", "auc_width", "auc_formula", "top10_p_hold", "top10_formula", "top10_p_hold_planned_fc"):
        values = np.array([o.get(m, np.nan) for o in objects], float)
        if np.isfinite(values).any():
            out[m] = group_interval(lambda picked, v=values: float(np.nanmean(v[picked])), len(values), rng)
    names = sorted({name for name, _, _ in closed})
    if names:
        y = [np.concatenate([lab for n, lab, _ in closed if n == name]) for name in names]
        p = [np.concatenate([q for n, _, q in closed if n == name]) for name in names]

        def pooled(picked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return np.concatenate([y[i] for i in picked]), np.concatenate([p[i] for i in picked])

        out["ece_p_hold"] = group_interval(lambda picked: expected_calibration_error(*pooled(picked)), len(names), rng)
        out["p_hold_label_agree"] = group_interval(lambda picked: agreement(*pooled(picked)), len(names), rng)
    return out


METRICS = ("auc_formula", "auc_width", "auc_p_hold", "top10_formula", "top10_p_hold", "top10_formula_planned_fc",
           "top10_p_hold_planned_fc", "top10_validated",
           "top10_validated_multiplied", "trial_agree",
           "success_rate")


def _by(rows: list[dict], key: str) -> list[dict]:
    groups = defaultdict(list)
    for r in rows:
        groups[r[key]].append(r)
    out = []
    for name, rs in sorted(groups.items()):
        row = {key: name, "category": rs[0]["category"], "files": len(rs)}
        for m in METRICS:
            vals = [r[m] for r in rs if m in r and np.isfinite(r[m])]
            if vals:
                row[m] = float(np.mean(vals))
        out.append(row)
    return out


def _by_category(rows: list[dict]) -> list[dict]:
    objects = _by(rows, "object")
    groups = defaultdict(list)
    for o in objects:
        groups[o["category"]].append(o)
    return [{"category": c, "objects": len(os_), **_mean(os_)} for c, os_ in sorted(groups.items())]


def _mean(rows: list[dict]) -> dict:
    out = {}
    for m in METRICS:
        vals = [r[m] for r in rows if m in r]
        if vals:
            out[m] = float(np.mean(vals))
    if rows:
        out["width_beaten_formula"] = int(sum(r.get("auc_formula", 0) > r.get("auc_width", 1) for r in rows))
        if any("auc_p_hold" in r for r in rows):
            out["width_beaten_p_hold"] = int(sum(r.get("auc_p_hold", 0) > r.get("auc_width", 1) for r in rows))
    return out


def labelled_set(results: list[FileResult]) -> LabelledSet:
    """The closed poses of every file as one labelled set, grouped by object (``Category_id``)."""
    tables = [features.of_grasps(r.grasps) for r in results if r.grasps]
    table = {k: np.concatenate([t[k] for t in tables]) for k in features.TABLE}
    labels = np.concatenate([r.labels[r.closed] for r in results])
    groups = tuple(object_key(r.path)[1] for r in results for _ in range(int(r.closed.sum())))
    stems = tuple(r.path.stem for r in results for _ in range(int(r.closed.sum())))
    objects = {r.path.stem: object_properties(importer.read_for_rescoring(r.path)[1]) for r in results if r.grasps}
    hashes = {r.path.stem: file_digest(r.path) for r in results if r.grasps}  # in-sample told by the bytes
    return LabelledSet(table, labels, groups, stems, "panda", objects=objects, hashes=hashes)


def print_table(report: dict) -> None:
    cols = [m for m in METRICS if any(m in o for o in report["objects"])]
    head = f"{'object':48s}" + "".join(f"{c:>14s}" for c in cols)
    print(head)
    for o in report["objects"]:
        print(f"{o['object'][:48]:48s}" + "".join(f"{o[c]:14.3f}" if c in o else f"{'':14s}" for c in cols))
    print()
    for c in report["categories"]:
        print(f"{c['category'] + ' (' + str(c['objects']) + ')':48s}"
              + "".join(f"{c[k]:14.3f}" if k in c else f"{'':14s}" for k in cols))
    print(f"{'MEAN over objects':48s}" + "".join(f"{report['mean'][k]:14.3f}" if k in report["mean"] else f"{'':14s}"
                                            for k in cols))
    if report.get("intervals"):
        print("95% intervals over objects (a bootstrap drawing objects): " + ", ".join(
            f"{k} [{lo:.3f}, {hi:.3f}]" for k, (lo, hi) in report["intervals"].items()))
    print(f"objects where p_hold (a Panda grasp's stored score where the model applies) beats the width baseline: "
          f"{report['mean'].get('width_beaten_p_hold', 'n/a')} of {len(report['objects'])}; the rule's formula (the "
          f"stored score where no model applies): {report['mean'].get('width_beaten_formula')}")
    if "ece_p_hold" in report:
        print(f"ECE of p_hold over {report['closed_poses']} closed poses: {report['ece_p_hold']:.4f}; "
              f"p_hold >= 0.5 as a label agrees with FleX on {report['p_hold_label_agree']:.3f} of them")
    if "trial_n" in report:
        print(f"trial vs FleX: agree {report['trial_agree_pooled']:.3f} of {report['trial_n']} closed poses; "
              f"drops FleX holds {report['trial_drops_flex_holds']}, holds FleX drops "
              f"{report['trial_holds_flex_drops']}; reasons {report['trial_reasons']}")
        if "p_hold_trial_agree_pooled" in report:
            print(f"on the same poses: p_hold given the verdict >= 0.5 (the export's label after a trial) agrees "
                  f"{report['p_hold_trial_agree_pooled']:.3f}, p_hold >= 0.5 {report['p_hold_tried_agree_pooled']:.3f}")
    print(f"rejections by reason over {report['poses']} poses: {report['rejected']}")


def _typed(default: object, text: str) -> object:
    """A ``--trial-set`` value in the type of the setting's default (``none``: None, e.g. no friction cap)."""
    if text.lower() == "none":
        return None
    if isinstance(default, bool):
        return text.lower() in ("1", "true", "yes")
    return type(default)(text)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dev", type=Path, default=DEV)
    parser.add_argument("--poses", type=int, default=200, help="uniform sample of poses per file")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--objects", nargs="*", help="only these Category_id objects")
    parser.add_argument("--held-out", action="store_true", help="the held-out objects: the lead runs this ONCE")
    parser.add_argument("--model", type=Path, help="p_hold model TOML (default: the shipped one)")
    parser.add_argument("--trial", type=int, default=0, help="shake-trial this many closed poses per file")
    parser.add_argument("--trial-top", type=int, default=0,
                        help="trial each file's K best closed poses (grasp validate --top K) and rank again")
    parser.add_argument("--trial-set", nargs="*", default=[], help="the engine's settings overrides key=value")
    parser.add_argument("--engine", choices=ENGINES, default="pybullet", help="the trial of --trial")
    parser.add_argument("--trial-pose", choices=("planned", "original"),
                        help="start trials at the planner's re-centred pose or the file's own "
                             "[default: planned for pybullet, original for mujoco]")
    parser.add_argument("--code", help="re-scoring cache code (default: this tree's source_hash)")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--cache", type=Path, default=CACHE)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--cv", type=int, default=5, help="folds of the grouped CV of p_hold (tuning figures)")
    parser.add_argument("--no-cv", action="store_true", help="p_hold of --model (or the shipped one), no CV")
    parser.add_argument("--no-trees", action="store_true", help="fit the additive model alone (no interaction trees)")
    parser.add_argument("--write-model", type=Path, help="write the model fitted on every selected file (TOML)")
    parser.add_argument("--extra-features", nargs="*", default=[],
                        help="fit p_hold on the default features and these (planner.calibration.features.FEATURES)")
    args = parser.parse_args()
    files = dev_files(args.dev, args.held_out, args.objects)
    if args.held_out and (args.write_model or not args.no_cv):
        sys.exit("acronym_eval: --held-out measures the shipped (or --model) p_hold: add --no-cv, never fit on it")
    if args.no_cv:
        args.cv = 0
    code = args.code or source_hash()
    model = load_model(args.model) if args.model else default_model("panda")
    kind = MujocoSettings if args.engine == "mujoco" else ShakeSettings
    settings = kind(**{k: _typed(getattr(kind, k), v) for k, v in (kv.split("=", 1) for kv in args.trial_set)})
    trial_pose = args.trial_pose or ("original" if args.engine == "mujoco" else "planned")
    start = time.process_time()
    results = []
    for i, path in enumerate(files, 1):
        results.append(rescore_file(path, args.poses, args.seed, args.workers, args.cache, code))
        run_trials(results[-1], args.trial, args.seed, settings, args.cache, code, trial_pose)
        print(f"[{i}/{len(files)}] {path.stem}: {int(results[-1].closed.sum())} of {len(results[-1].rows)} closed",
              file=sys.stderr)
    oof = None
    if args.cv:
        data = labelled_set(results)
        source = (f"bench/acronym_eval.py --poses {args.poses} --seed {args.seed} --cv {args.cv}: fitted on the "
                  f"'tuning' objects of bench/acronym_split.toml ({len(files)} files of "
                  f"../shared/labelled/acronym_dev, ACRONYM FleX object_in_gripper labels, Panda), "
                  f"{len(data.labels)} closed poses; {'no trees' if args.no_trees else DEFAULT_TREES}; "
                  f"{' + '.join(args.extra_features) + '; ' if args.extra_features else ''}"
                  f"penalty chosen by nested grouped CV; figures: held out by {args.cv}-fold CV grouped by object; "
                  f"code {code}")
        cal = calibrate(data, folds=args.cv, source=source, trees=None if args.no_trees else DEFAULT_TREES,
                        features=(*DEFAULT_FEATURES, *args.extra_features))
        start_row = 0
        oof = {}
        for r in results:  # data's rows are the closed poses of results, in order
            n = int(r.closed.sum())
            oof[r.path.stem] = cal.cv.p[start_row:start_row + n]
            start_row += n
        if args.write_model:
            args.write_model.write_text(cal.model.to_toml())
            print(f"wrote {args.write_model}", file=sys.stderr)
        model = model or cal.model
    if args.trial_top:
        for r in results:
            run_top_trials(r, scores(r, model, RankingRule(), None if oof is None else oof[r.path.stem])["p_hold"],
                           args.trial_top, settings, args.cache, code, trial_pose)
    report = evaluate(results, model, RankingRule(), oof, "mujoco" if args.engine == "mujoco" else "validation")
    if oof is not None:
        report["cv"] = {"folds": args.cv, "note": "p_hold figures are out-of-fold (grouped by object)"}
    report["cpu_seconds"] = time.process_time() - start
    report["settings"] = {"poses": args.poses, "seed": args.seed, "side": "held_out" if args.held_out else "tuning",
                          "files": len(files), "code": code, "trial": args.trial, "trial_set": args.trial_set,
                          "engine": args.engine, "trial_pose": trial_pose,
                          "trial_top": args.trial_top, "extra_features": args.extra_features}
    if args.json:
        print(json.dumps(report, indent=1, default=float))
    else:
        print_table(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
