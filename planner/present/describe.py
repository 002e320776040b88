"""A grasp as ``grasp best`` prints it: the frames people use, units on everything.

Two points of the hand are given, both as positions and with the hand's
orientation: the **hand base** (the hand's ``root_link`` frame, the pose the
database stores: ACRONYM's and MoveIt's "grasp pose" of the Panda is this
frame) and the **tool centre point** (``tcp`` of hand.toml: the point between
the fingers that the approach aims at). The approach direction is the hand's
approach axis (``approach`` of hand.toml) in the same frame. Every pose is in
the object frame (the frame of the scaled mesh file); with an object pose,
in the world frame too. Quaternions are (x, y, z, w).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from planner.geometry.gravity import DIRECTIONS
from planner.geometry.quaternion import canonical_xyzw
from planner.plan.measures import MIN_RESISTANCE
from planner.record import fields
from planner.record.grasp import Grasp
from planner.record.tolerances import RESISTANCE_CAP
from planner.specs.hands import HandFrame

if TYPE_CHECKING:
    from planner.calibration.model import LogisticModel
    from planner.db.ranking import RankingRule


@dataclass(frozen=True)
class Frames:
    """Where a grasp puts the hand, in one frame.

    Attributes:
        frame: ``object`` or ``world``.
        base: (3,) [m] the hand base (``root_link``) position.
        tcp: (3,) [m] the tool centre point.
        quaternion: (4,) the hand's orientation, x y z w.
        approach: (3,) unit, the direction the hand moves in to grasp.
    """

    frame: str
    base: np.ndarray
    tcp: np.ndarray
    quaternion: np.ndarray
    approach: np.ndarray

    def to_json(self) -> dict:
        # + 0.0: a negative zero is written 0.0, as the text lines say it (:func:`_fixed`)
        return {"frame": self.frame, "hand_base_m": (self.base + 0.0).tolist(), "tcp_m": (self.tcp + 0.0).tolist(),
                "quaternion_xyzw": (self.quaternion + 0.0).tolist(), "approach": (self.approach + 0.0).tolist()}


def frames(grasp: Grasp, hand: HandFrame, world: np.ndarray | None = None) -> Frames:
    """The grasp's frames in the object frame, or in the world when
    ``world`` (4, 4), the object's pose in the world, is given."""
    pose = np.asarray(grasp.pose, float) if world is None else np.asarray(world, float) @ np.asarray(grasp.pose)
    rotation = pose[:3, :3]
    return Frames("object" if world is None else "world", pose[:3, 3].copy(), rotation @ hand.tcp + pose[:3, 3],
                  canonical_xyzw(rotation), rotation @ hand.approach)


def _fixed(x: float, digits: int) -> str:
    """``x`` with ``digits`` decimals, a value that rounds to zero without the sign of a tiny negative
    ("-0.000" read as a coordinate a hair below zero, or a sign bug, beside the "0.000" of the same axis)."""
    text = f"{x:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def times_weight(resist: float) -> str:
    """A weight resistance [multiples of the weight] as said: one at the measure's cap is a bound, not a value
    (a Barrett grasp "holds 50.0 times its weight", worst and mean, read as measured)."""
    if resist >= RESISTANCE_CAP:
        return f"at least {RESISTANCE_CAP:.0f}"
    if resist < MIN_RESISTANCE <= round(resist, 1):  # 0.96 said "1.0" beside the flag cannot_hold_weight
        return f"{math.floor(resist * 100) / 100:.2f}"
    return f"{resist:.1f}"


def xyz(v: np.ndarray, digits: int = 3) -> str:
    """``v`` (n,) as "(x, y, z)" with ``digits`` decimals, no sign on a value that rounds to zero."""
    return "(" + ", ".join(_fixed(x, digits) for x in v) + ")"


def frame_lines(f: Frames, hand: HandFrame) -> list[str]:
    return [f"{f.frame} frame: hand base ({hand.root_link}) at {xyz(f.base)} m, tool centre point at "
            f"{xyz(f.tcp)} m, orientation xyzw {xyz(f.quaternion, 4)}, approach direction {xyz(f.approach)}"]


def describe(grasp: Grasp, hand: HandFrame, world: np.ndarray | None = None,
             arm: Mapping[str, Mapping[str, float]] | None = None, up: str = "+z") -> list[str]:
    """The lines ``grasp best`` prints for one grasp (with ``world`` and the
    ``arm`` joint solutions by stage when it was reached at an object pose); ``up``: the object's
    (:mod:`planner.specs.up`), said where it is not its frame's +z."""
    g, m = grasp, grasp.measures
    score = "n/a" if g.score is None else score_text(g.score)
    reach = "not computed" if g.reachability is None else f"{g.reachability:.2f} of table placements"
    width = "n/a (not a parallel jaw)" if g.width is None else f"{g.width * 1000:.1f} mm"
    volume = f"{g.volume:.3g}" if g.volume else "0 (computed only with --volume, for force closure)"
    p_hold = ("n/a (no calibrated model for the hand)" if g.p_hold is None
              else f"{probability(g.p_hold)} (calibrated probability of holding)")
    if g.p_hold_trial is not None and g.trial is not None:
        p_hold += (f", {probability(g.p_hold_trial)} given its trial's verdict "
                   f"({'held' if g.trial.success else 'dropped'})")
    rank = f"#{g.rank}" if g.rank is not None else "#- (planned now with the table, not stored)"
    head = f"{rank} {g.object}/{g.hand} preshape {g.preshape}: p_hold {p_hold}; score {score} (ranking rule, " \
           "higher is better)"
    lines = [head, *(f"    {line}" for line in frame_lines(frames(g, hand), hand))]
    if world is not None:
        lines += [f"    {line}" for line in frame_lines(frames(g, hand, world), hand)]
    if g.table_plane is not None:
        n = g.table_plane
        lines.append(f"    planned on a table: its top is n . x = {n[3]:.4f} m in the object frame, n = "
                     f"{xyz(n[:3])} (the hand keeps off it)")
    elif up != "+z":
        lines.append(f"    the object's up is its frame's {up} (com_height, gravity_arm and the MuJoCo trial's weight "
                     "read it; poses stay in the file's frame)")
    if g.squeezed_from_turn is not None:
        lines.append(f"    the end of a parallel jaw's squeeze: candidate {g.candidate}'s planned grasp (not force "
                     f"closure) with the hand turned {math.degrees(g.squeezed_from_turn):.1f} deg about its contacts "
                     "until the pads lie flush, closed again here (force closure as planned at this pose)")
    squeezed = m is not None and bool(m.squeezed_force_closure) and not g.force_closure
    closure = "force closure" if g.force_closure else "NOT force closure as planned, force closure once squeezed" \
        if squeezed else "NOT force closure"
    lines.append(f"    finger width {width}; epsilon {g.epsilon:.4f} (Ferrari-Canny L1, {closure}); GWS volume "
                 f"{volume}; {len(g.contacts)} contacts; reachability {reach}")
    if m is not None:
        settled = "" if m.settled_epsilon is None else f"; settled epsilon {m.settled_epsilon:.4f}"
        capped = " (the measure's cap)" if m.resist_worst >= RESISTANCE_CAP else ""
        lines.append(f"    holds {times_weight(m.resist_worst)} times its weight{capped} in the worst of {DIRECTIONS} "
                     f"directions (mean {times_weight(m.resist_mean)}); push {m.push:.2f} (1 = pads square on); "
                     f"feasibility {','.join(m.reasons) or 'ok'}{settled}")
    if squeezed and m is not None:  # where it ranks (planner.db.ranking.FIRST): say why, where it says NOT fc
        lines.append(f"    not force closure as planned, but force closure once the jaw's squeeze turns the object "
                     f"{math.degrees(m.squeeze_turn or 0.0):.1f} deg between the pads, flush against them (squeezed "
                     f"epsilon {m.squeezed_epsilon or 0.0:.4f}; the pose above is the planned one): "
                     + (f"that squeeze's end is {'stored' if g.rank is not None else 'planned now too'} as a grasp "
                        f"of its own, candidate {g.candidate} too, force "
                        "closure as planned at the turned pose (`grasp best` calls it the end of a parallel jaw's "
                        "squeeze): it stands for this one, which ranks after every force-closure grasp" if g.end_kept
                        else "it ranks with the force-closure grasps, above every grasp that is neither (no end of "
                        "its squeeze stands for it: none is stored beside it, or the database was ranked before one "
                        "did; its next write ranks it again)"))
    elif not g.force_closure:
        lines.append("    not force closure as planned: it ranks after every force-closure grasp of the object (and "
                     "every one force closure once a parallel jaw's squeeze turns the object, but for those whose "
                     "squeeze's end stands for them: with them, by score; so it shows only where the object has fewer "
                     "that rank first than asked for); its p_hold is how often labelled grasps "
                     "with these measures held (a thin pinch often turns the object into line as it closes); "
                     "`grasp validate` tries it")
    held_by = []
    for name, trial in (("shake trial (PyBullet)", g.validation), ("MuJoCo trial", g.mujoco)):
        if trial is not None:
            verdict = "held" if trial.success else "dropped"
            why = "" if trial.reason == verdict else f" ({trial.reason or 'no reason stored'})"
            lines.append(f"    {name}: {verdict}{why}")
            held_by += [name] if trial.success else []
    if g.file_label is not None:  # an imported file's own label (FleX's, a user's outcomes)
        lines.append(f"    label of the file it was imported from ({g.file_label.source}): "
                     f"{'held' if g.file_label.success else 'dropped'}")
    if m is not None and "cannot_hold_weight" in m.reasons:
        lines += _weight_lines(g, m.resist_worst, held_by, up)
    for stage, joints in (arm or {}).items():
        lines.append(f"    arm at {stage} [rad]: " + ", ".join(f"{k} {_fixed(v, 4)}" for k, v in joints.items()))
    return lines


def _weight_lines(g: Grasp, worst: float, held_by: list[str], up: str) -> list[str]:
    """Why a grasp flagged ``cannot_hold_weight`` can still hold (and p_hold say so): the flag is the worst of
    the 14 directions its weight may take about the hand, a trial and the labels p_hold was fitted on load one,
    the object's down. Nothing where a trial dropped it (its verdict says what is true)."""
    down = "the table's down" if g.table_plane is not None else f"the object's down, {'-+'[up[0] == '-']}{up[1]}"
    if held_by:
        return [f"    its weight: the {held_by[-1]} held it loaded along one direction ({down}); cannot_hold_weight is "
                f"the worst of {DIRECTIONS} directions, where the fingers' force limits hold {times_weight(worst)} "
                "times its weight: hold it as it stands, do not turn it"]
    if g.validation is not None or g.mujoco is not None:
        return []
    said = ("p_hold says how often labelled grasps with these measures held loaded along their object's down: both "
            "can be true (held as it stands, not turned over)" if g.p_hold is not None else "it may still hold as it "
            "stands")
    return [f"    its weight: cannot_hold_weight says that with its weight turned to the worst of {DIRECTIONS} "
            f"directions about the hand the fingers' force limits hold {times_weight(worst)} times it (a static "
            f"bound); {said}; not tried yet: `grasp validate` loads it along {down}, at its own mass and friction"]


def p_hold_terms(grasp: Grasp, model: LogisticModel) -> dict[str, dict[str, float]]:
    """The model's log-odds of ``grasp`` feature by feature: for each feature
    its input ``x`` (the measure as the model reads it, e.g. log1p of an area
    in mm^2), whether it enters as a spline, and its ``part`` of the log-odds;
    and the ``intercept``, the trees' ``interactions`` (a model with trees),
    ``logit`` (their sum) and ``p_hold`` = 1 / (1 + e^-logit)."""
    from planner.calibration import features
    from planner.calibration.logistic import INTERACTIONS

    table = features.of_grasps([grasp])
    x = features.design(table, model.features)[0]
    parts = model.terms(table)
    logit = float(model.logit(table)[0])
    extra = {INTERACTIONS: float(parts[INTERACTIONS][0])} if INTERACTIONS in parts else {}
    return {"features": {name: {"x": float(x[i]), "spline": float(name in model.knots), "part": float(parts[name][0])}
                         for i, name in enumerate(model.features)},
            "total": {"intercept": float(model.intercept), **extra, "logit": logit,
                      "p_hold": float(model.predict(table)[0])}}


def explain_json(grasp: Grasp, rule: RankingRule, model: LogisticModel | None = None) -> dict:
    """``grasp best --json --explain``'s ``frames.explain``: every term of the
    rule (:meth:`~planner.db.ranking.RankingRule.terms`) and, where the
    grasp has a p_hold, the model's terms (:func:`p_hold_terms`)."""
    from planner.db.ranking import rule_measures

    out: dict = {k: float(v[0]) for k, v in rule.terms(rule_measures([grasp])).items()}
    if model is not None and grasp.p_hold is not None:
        out["p_hold_terms"] = p_hold_terms(grasp, model)
    return out


def explain(grasp: Grasp, rule: RankingRule, model: LogisticModel | None = None) -> list[str]:
    """Why ``grasp`` scores what it does: the ranking rule's terms
    (:meth:`~planner.db.ranking.RankingRule.terms`), each with the measure it
    comes from and the rule's own weights and thresholds; where a calibrated
    model gave the grasp its p_hold, the analytic score is p_hold, shown
    term by term of the model's log-odds (coefficient x standardised
    feature), and the formula's value beside it."""
    from planner.db.ranking import rule_measures

    m = {k: float(v[0]) for k, v in rule_measures([grasp]).items()}
    t = {k: float(v[0]) for k, v in rule.terms(rule_measures([grasp])).items()}
    calibrated = not math.isnan(t["p_hold"])
    mm = lambda v: "not measured" if math.isnan(v) else f"{v * 1000:.1f} mm"  # noqa: E731
    lines = [f"    gate {t['gate']:.0f}: open margin {mm(m.get('open_margin', math.nan))} (needs >= "
             f"{rule.min_open_margin * 1000:.1f} mm), close margin {mm(m.get('close_margin', math.nan))}"]
    if t["gate"] == 0:
        lines.append(f"    -> {'formula' if calibrated else 'analytic'} 0: a finger has no clearance or sits at its "
                     "closing stop")
    else:
        lines += [f"    press {t['press']:.3f} (push) x (1 + hold {t['hold']:.3f} (min(holds, {rule.cap:g} g) / "
                  f"{rule.cap:g} g)) / 2 = {t['press'] * (1 + t['hold']) / 2:.4f}",
                  f"    + eps_weight {rule.eps_weight:g} x quality {t['quality']:.4f} (epsilon) = "
                  f"{rule.eps_weight * t['quality']:.4f}",
                  f"    + settled_weight {rule.settled_weight:g} x settled epsilon {t['settled']:.4f} = "
                  f"{rule.settled_weight * t['settled']:.4f}"]
    if calibrated:
        lines.append(f"    (the formula: {t['formula']:.4f}; not used: the hand has a calibrated p_hold model)")
        lines.append("    analytic = p_hold = 1 / (1 + exp(-logit)), logit = intercept + each feature's part "
                     "(a line, or a spline where marked ~, of the feature's input x)"
                     + (" + the interactions of its trees:" if model is not None and model.trees is not None else ":"))
        if model is None:
            lines.append("    (the model that made it is no longer the hand's: its terms cannot be shown)")
        else:
            pt = p_hold_terms(grasp, model)
            lines += [f"      {name}{'~' if v['spline'] else ''}: x {v['x']:.4g} -> {v['part']:+.4f}"
                      for name, v in pt["features"].items()]
            total = pt["total"]
            if "interactions" in total:
                lines.append(f"      interactions (the model's trees over these inputs together): "
                             f"{total['interactions']:+.4f}")
            lines.append(f"      intercept {total['intercept']:+.4f}; logit {total['logit']:+.4f} -> p_hold "
                         f"{total['p_hold']:.4f} (stored {t['p_hold']:.4f})")
    if not math.isnan(t["p_hold_trial"]):
        update = None if model is None else model.updates.get(_tried_group(m))
        how = ("" if update is None else f" (1 / (1 + exp(-({update.slope:.4f} x logit {update.verdict:+.4f} x held "
               f"{update.intercept:+.4f}))), held never below p_hold, dropped never above)")
        lines.append(f"    analytic = p_hold_trial = {t['p_hold_trial']:.4f}: p_hold updated by the trial's verdict as "
                     f"the model's update for that trial says{how}; the verdict does not multiply again")
    reach = m.get("reachability", math.nan)
    # the verdict the rule reads: the first trial in precedence that tried the grasp (MuJoCo's, then PyBullet's)
    tried = [(f"{fields.GROUPS[group].engine} trial", m.get(name, math.nan))
             for group, name in zip(fields.TRIAL_PRECEDENCE, fields.TRIAL_SUCCESS)]
    trial_name, success = next(((name, v) for name, v in tried if not math.isnan(v)), ("", math.nan))
    lines += [f"    = analytic {t['analytic']:.4f}; x reach factor {t['reach_factor']:.3f} ((1 - {rule.reach_weight:g})"
              f" + {rule.reach_weight:g} x reachability {'not computed: 1' if math.isnan(reach) else f'{reach:.2f}'})"
              f" x success factor {t['success_factor']:.3f} ("
              f"{_success_text(success, trial_name, not math.isnan(t['p_hold_trial']))})"
              f" = score {t['score']:.4f}"]
    return lines


def _tried_group(m: Mapping[str, float]) -> str:
    """The trial group whose verdict the rule reads (the first in precedence that tried the grasp)."""
    return next((group for group, name in zip(fields.TRIAL_PRECEDENCE, fields.TRIAL_SUCCESS)
                 if not math.isnan(m.get(name, math.nan))), "")


def _success_text(success: float, trial: str, in_p_hold_trial: bool) -> str:
    if math.isnan(success):
        return "trials not run: 1"
    return f"{trial} {success:.0f}" + (", counted in p_hold_trial: 1" if in_p_hold_trial else "")


def score_text(score: float) -> str:
    """A score with four decimals, except just below 1, where p_hold-based scores crowd and four decimals would
    print a row of equal 1.0000: ``1 - 2.3e-05``, so the printed order is the rank order."""
    return f"1 - {1.0 - score:.3g}" if 0.99995 <= score < 1.0 else f"{score:.4f}"


def probability(p: float) -> str:
    """``p`` with three decimals, never rounded to certainty: ``>0.999`` and
    ``<0.001`` where the model is that sure (it is calibrated to about that:
    bench/RESULTS.md), ``0.000`` and ``1.000`` only for exactly 0 and 1."""
    if 0.999 < p < 1.0:
        return ">0.999"
    if 0.0 < p < 0.001:
        return "<0.001"
    return f"{p:.3f}"

