"""p_hold given a dynamic trial's verdict: ``p_hold_trial``.

A trial's verdict (held 1 / dropped 0) is evidence about holding, and so is
p_hold; neither alone agrees best with external labels. A hand's model may
carry, per trial engine (the record's trial groups: ``mujoco``,
``validation`` = PyBullet), a :class:`TrialUpdate`, a logistic regression
of the label on both::

    logit p_hold_trial = slope * logit p_hold + verdict * held + intercept

fitted by maximum likelihood on labelled grasps that the trial tried, with
p_hold *out of fold* (the model fitted without the grasp's object), so the
update learns how far each is to be trusted on objects the model has not
seen. ``slope`` < 1 shrinks an over-confident p_hold; ``verdict`` is what
the trial's verdict adds (log-odds). Where ``verdict`` > 0 (a verdict that
agrees with the labels), a held verdict never lowers p_hold and a dropped
one never raises it: ``p_hold_trial`` is at least p_hold after "held" and at
most p_hold after "dropped". The logistic's slope below 1 would otherwise
put a grasp that held below an untried one of the same p_hold near 1, where
the fitting data hold no grasp to tell them apart (the shrinkage is a
statement about p_hold everywhere, not about the verdict). :func:`fit_update` fits one;
:meth:`TrialUpdate.apply` applies it. Numpy only to apply; scipy to fit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from planner.calibration.basis import _sigmoid
from planner.errors import InputError

#: p_hold is clipped to [EPS, 1 - EPS] before its logit (a p_hold of exactly 0 or 1 has none).
EPS = 1e-6


def logit(p: np.ndarray) -> np.ndarray:
    q = np.clip(np.asarray(p, float), EPS, 1 - EPS)
    return np.log(q / (1 - q))


@dataclass(frozen=True)
class TrialUpdate:
    """How one engine's verdict updates p_hold (module docstring).

    engine: the trial group (``mujoco`` or ``validation``); slope, verdict,
    intercept: the coefficients (log-odds); grasps: the labelled trialled
    grasps it was fitted on; agreement: on those grasps, the share whose
    label ``p_hold_trial >= 0.5`` equals (in-sample: the three coefficients
    are all it fits).
    """

    engine: str
    slope: float
    verdict: float
    intercept: float
    grasps: int = 0
    agreement: float = math.nan

    def __post_init__(self) -> None:
        if not all(math.isfinite(v) for v in (self.slope, self.verdict, self.intercept)):
            raise InputError(f"trial update ({self.engine}): coefficients must be finite, got "
                             f"{self.slope}, {self.verdict}, {self.intercept}")

    def apply(self, p_hold: np.ndarray, held: np.ndarray) -> np.ndarray:
        """(n,) p_hold_trial of grasps with ``p_hold`` (n,) and verdicts ``held`` (n,) 0/1."""
        h = np.asarray(held, float)
        z = self.slope * logit(p_hold) + self.verdict * h + self.intercept
        q = _sigmoid(z)
        if self.verdict <= 0:
            return q
        p = np.asarray(p_hold, float)
        return np.where(h > 0.5, np.maximum(q, p), np.minimum(q, p))  # held never lowers, dropped never raises

    def to_dict(self) -> dict:
        return {"slope": self.slope, "verdict": self.verdict, "intercept": self.intercept, "grasps": self.grasps,
                **({"agreement": self.agreement} if math.isfinite(self.agreement) else {})}

    @classmethod
    def from_dict(cls, engine: str, data: Mapping) -> TrialUpdate:
        return cls(str(engine), float(data["slope"]), float(data["verdict"]), float(data["intercept"]),
                   int(data.get("grasps", 0)), float(data.get("agreement", math.nan)))


def fit_update(engine: str, p_hold: np.ndarray, held: np.ndarray, labels: np.ndarray) -> TrialUpdate:
    """The update of ``engine`` maximising the likelihood of ``labels`` (n,)
    0/1 given out-of-fold ``p_hold`` (n,) and the trial's verdicts ``held``
    (n,) 0/1: the p_hold model's own loss (:func:`planner.calibration.model._loss`)
    on the columns (logit p_hold, held), with a tiny L2 penalty, 1e-6, on
    slope and verdict that keeps them finite where the labels separate."""
    y = np.asarray(labels, float)
    h = np.asarray(held, float)
    if not len(y) == len(h) == len(np.asarray(p_hold)) or len(y) == 0:
        raise InputError(f"trial update ({engine}): {len(y)} labels, {len(h)} verdicts and "
                         f"{len(np.asarray(p_hold))} p_hold values; need the same number, at least one")
    if not np.all(np.isin(h, (0.0, 1.0))) or not np.all(np.isin(y, (0.0, 1.0))):
        raise InputError(f"trial update ({engine}): verdicts and labels must be 0 or 1")
    from scipy.optimize import minimize  # fitting only

    from planner.calibration.model import _loss  # the model's module imports this one

    z = np.column_stack([logit(p_hold), h])
    w = minimize(_loss, np.array([0.0, 1.0, 0.0]), args=(z, y, 1e-6), jac=True, method="L-BFGS-B").x
    update = TrialUpdate(engine, float(w[1]), float(w[2]), float(w[0]), len(y))
    agreement = float(np.mean((update.apply(p_hold, h) >= 0.5) == (y == 1)))
    return TrialUpdate(engine, update.slope, update.verdict, update.intercept, len(y), agreement)
