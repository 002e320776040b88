"""The measures record: the analytic measures of one closed grasp, and the
hand's joint frames at it. How they are computed, and what each
feasibility reason means, is :mod:`planner.plan.measures`'.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.record.field import stored

#: The feasibility reasons a grasp can carry (:attr:`Measures.reasons`).
REASONS = ("open_limit", "too_wide", "at_close_stop", "back_or_side_contact", "cannot_hold_weight")


@dataclass(frozen=True)
class Measures:
    """The analytic measures of one grasp (:mod:`planner.plan.measures`).

    resist_worst, resist_mean: weight resistance [g] over 14 gravity
    directions of the object frame (axes and diagonals); open_margin,
    close_margin [m] (inf when no finger touches); push (cosine, 0 when no
    finger touches); reasons: the feasibility flags that apply;
    settled_epsilon: Ferrari-Canny epsilon of the contacts the grasp settles
    into when the fingers close dynamically on the free object
    (:mod:`planner.plan.settle`; 0 if the object is pushed out or the trial
    is flagged; None: not measured, the hand's ``settle`` off).
    """

    resist_worst: float = stored("real", "g", 3, "weight resistance, worst of 14 gravity directions (object frame)",
                                 required=False, ranked="resist_worst")
    resist_mean: float = stored("real", "g", 3, "weight resistance, mean over the 14 directions", required=False)
    open_margin: float = stored("margin", "m", 3, "smallest travel a touching finger has left towards its open limit",
                                required=False, ranked="open_margin")
    close_margin: float = stored("margin", "m", 3, "smallest travel a touching finger has left towards its closing "
                                 "stop", required=False, ranked="close_margin")
    push: float = stored("real", "", 3, "smallest cosine between a finger region's contact normal and its closing "
                         "motion", required=False, ranked="push")
    reasons: tuple[str, ...] = stored("reasons", "", 3, "feasibility reasons, comma-separated ('' = feasible)",
                                      required=False, column="feasibility")
    settled_epsilon: float | None = stored("real", "", 4, "Ferrari-Canny epsilon of the contacts after a dynamic "
                                           "closing (hands with `settle`)", required=False, ranked="settled_epsilon",
                                           default=None)

    @property
    def feasible(self) -> bool:
        return not self.reasons

    def to_json(self) -> dict:
        """The measures as ``grasp best --json`` prints them (:func:`planner.record.fields.json_value`)."""
        from planner.record.fields import group, json_value

        return {f.name: json_value(f, getattr(self, f.attr.partition(".")[2])) for f in group("measures")}


@dataclass(frozen=True)
class JointFrames:
    """Every finger joint of the hand at the closed grasp, object frame.

    names : q joint names (hand spec order); origins : (q, 3) [m]; axes : (q, 3) unit.
    """

    names: tuple[str, ...]
    origins: np.ndarray
    axes: np.ndarray
