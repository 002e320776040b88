"""The measures record: the analytic measures of one closed grasp, and the
hand's joint frames at it. How they are computed, and what each
feasibility reason means, is :mod:`planner.plan.measures`'.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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

    resist_worst: float
    resist_mean: float
    open_margin: float
    close_margin: float
    push: float
    reasons: tuple[str, ...]
    settled_epsilon: float | None = None

    @property
    def feasible(self) -> bool:
        return not self.reasons

    def to_json(self) -> dict:
        return {"resist_worst": self.resist_worst, "resist_mean": self.resist_mean,
                "open_margin": _finite(self.open_margin), "close_margin": _finite(self.close_margin),
                "push": self.push, "feasibility": list(self.reasons), "settled_epsilon": self.settled_epsilon}


def _finite(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


@dataclass(frozen=True)
class JointFrames:
    """Every finger joint of the hand at the closed grasp, object frame.

    names : q joint names (hand spec order); origins : (q, 3) [m]; axes : (q, 3) unit.
    """

    names: tuple[str, ...]
    origins: np.ndarray
    axes: np.ndarray
