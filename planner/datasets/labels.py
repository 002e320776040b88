"""The success label an export writes (ACRONYM's and GraspGen's
``object_in_gripper``, the tables' ``label``), and where each row's label
came from.

A label is one of five things, each named per grasp in ``label_source``:

- ``file_label``: the label the file the grasp was imported from gives it
  (``grasp import`` of a labelled file: ACRONYM's FleX labels, a user's
  real-robot outcomes), exported as the file gave it;
- ``p_hold_trial``: p_hold updated by the verdict of the grasp's dynamic
  trial (the hand's model's update for that trial's engine,
  :mod:`planner.calibration.update`) thresholded at :data:`P_HOLD_SUCCESS`:
  against ACRONYM's FleX labels on held-out objects it agrees more often
  than either the verdict or p_hold alone (bench/RESULTS.md);
- ``trial``: the grasp's dynamic trial (``grasp validate``): MuJoCo's
  verdict where it tried the grasp, else PyBullet's
  (:data:`~planner.record.fields.TRIAL_PRECEDENCE`: the one that agrees best
  with external labels first);
- ``p_hold``: the calibrated probability of holding (:mod:`planner.calibration`)
  thresholded at :data:`P_HOLD_SUCCESS`;
- ``force_closure``: whether the planned contacts are force closure. This is
  a closure flag, not a success label: on the mug, 18 of 18 sampled grasps
  that are not force closure as planned held in the shake trial.

``--label best`` (the default) takes, per grasp, the best one available in
that order; ``--label file_label``, ``--label p_hold_trial``, ``--label trial`` or ``--label
p_hold`` export only the grasps that have it; ``--label force_closure``
writes the flag for every grasp.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from planner.errors import InputError
from planner.record import fields
from planner.record.grasp import Grasp

P_HOLD_TRIAL, TRIAL, P_HOLD, FORCE_CLOSURE, MIXED = "p_hold_trial", "trial", "p_hold", "force_closure", "mixed"
FILE_LABEL = "file_label"
BEST = "best"
#: What ``grasp export --label`` takes.
CHOICES = (BEST, FILE_LABEL, P_HOLD_TRIAL, TRIAL, P_HOLD, FORCE_CLOSURE)
#: p_hold at or above this is a success label (the probability's own midpoint:
#: a calibrated p_hold of 0.5 is a coin toss).
P_HOLD_SUCCESS = 0.5


def check(choice: str) -> str:
    if choice not in CHOICES:
        raise InputError(f"--label must be one of {', '.join(CHOICES)}; got '{choice}'")
    return choice


def has_label(choice: str, grasp: Grasp) -> bool:
    """Whether ``grasp`` is exported under ``choice`` (file_label, p_hold_trial, trial, p_hold: only grasps that
    have one)."""
    if choice == FILE_LABEL:
        return grasp.file_label is not None
    if choice == P_HOLD_TRIAL:
        return grasp.p_hold_trial is not None
    if choice == TRIAL:
        return grasp.trial is not None
    if choice == P_HOLD:
        return grasp.p_hold is not None
    return True


def labels(columns: Mapping[str, np.ndarray], choice: str) -> tuple[np.ndarray, list[str]]:
    """((n,) int64 0/1 labels, n sources) of a batch's columns
    (``file_label_success`` -1 where no file gave one,
    ``validation_success`` and ``mujoco_success`` -1 where not validated,
    ``p_hold`` and ``p_hold_trial`` NaN where absent); a trial label is the
    verdict of the first trial in :data:`~planner.record.fields.TRIAL_PRECEDENCE`
    that tried the grasp (MuJoCo's, then PyBullet's)."""
    success = np.full(len(np.asarray(columns["force_closure"])), -1)
    for group in reversed(fields.TRIAL_PRECEDENCE):
        verdict = np.asarray(columns[f"{fields.GROUPS[group].prefix}success"])
        success = np.where(verdict >= 0, verdict, success)
    p_hold = np.asarray(columns["p_hold"], float)
    p_trial = np.asarray(columns["p_hold_trial"], float)
    closure = np.asarray(columns["force_closure"])
    given = np.asarray(columns["file_label_success"])
    if choice == BEST:
        source = np.where(given >= 0, FILE_LABEL, np.where(~np.isnan(p_trial), P_HOLD_TRIAL, np.where(
            success >= 0, TRIAL, np.where(np.isnan(p_hold), FORCE_CLOSURE, P_HOLD))))
    else:
        source = np.full(len(closure), choice)
    value = np.select([source == FILE_LABEL, source == P_HOLD_TRIAL, source == TRIAL, source == P_HOLD],
                      [given, np.nan_to_num(p_trial) >= P_HOLD_SUCCESS, success,
                       np.nan_to_num(p_hold) >= P_HOLD_SUCCESS], closure)
    return value.astype(np.int64), source.tolist()


def file_source(sources: Iterable[str]) -> str:
    """One file's ``label_source`` attribute: the one source of every row, or ``mixed``."""
    found = set(sources)
    return found.pop() if len(found) == 1 else MIXED
