"""The ranking rule: how a grasp's score follows from its measures.

The rule is :meth:`RankingRule.scores`, written once, over arrays of
measures; :data:`FORMULA` says the same in words (it is stored with every
database in ``meta.ranking`` and shown in the README). The database never
computes a score itself: it reads the measures, calls the rule and writes
the scores back (:mod:`planner.db.store`), then ranks by :data:`ORDER_BY`.

epsilon is the L1 Ferrari-Canny epsilon, reachability the fraction of sampled
table placements at which an arm reaches the grasp and its pre-grasp,
simulated success 1/0 from the shake test and the robust quantile the low
quantile of epsilon under pose and friction noise. Each weight lies in
[0, 1]; 0 ignores the measure, 1 lets it veto (an unreachable or failed
grasp scores 0). Rank 1 is the best grasp of an (object, hand); ties are
broken by epsilon, then GWS volume, then by the unit seed and candidate
number (never by insertion order, so the rank does not depend on which
worker finished first).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike

from planner.errors import InputError

#: The rule of :meth:`RankingRule.scores` in words, as ``meta.ranking`` stores it.
FORMULA = ("score = ((1 - robust_weight) * epsilon + robust_weight * robust_quantile)"
           " * ((1 - reach_weight) + reach_weight * reachability)"
           " * ((1 - success_weight) + success_weight * simulated_success); 0 unless force-closure;"
           " a measure not computed counts as neutral (reachability, success 1; robust quantile = epsilon)")

#: The rank order: score first, then the tie-breaks (columns of ``grasps``).
ORDER_BY = "score DESC, epsilon DESC, volume DESC, seed, candidate, unit_id"


@dataclass(frozen=True)
class RankingRule:
    """The weights of the rule, each in [0, 1]."""

    reach_weight: float = 0.5
    success_weight: float = 1.0
    robust_weight: float = 0.0

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not 0.0 <= value <= 1.0:
                raise InputError(f"--{name.replace('_', '-')} must be in [0, 1], got {value}")

    def scores(self, epsilon: ArrayLike, force_closure: ArrayLike, reachability: ArrayLike | None = None,
               success: ArrayLike | None = None, robust_quantile: ArrayLike | None = None) -> np.ndarray:
        """(n,) scores of n grasps from (n,) measures; NaN (or None for a whole
        measure) means not computed, which is neutral."""
        eps = np.asarray(epsilon, float)
        quantile = _neutral(robust_quantile, eps)
        quality = (1.0 - self.robust_weight) * eps + self.robust_weight * quantile
        reach = _neutral(reachability, np.ones_like(eps))
        ok = _neutral(success, np.ones_like(eps))
        score = (quality * ((1.0 - self.reach_weight) + self.reach_weight * reach)
                 * ((1.0 - self.success_weight) + self.success_weight * ok))
        return np.where(np.asarray(force_closure, bool), score, 0.0)

    def to_json(self) -> str:
        return json.dumps({"formula": FORMULA, **asdict(self)}, sort_keys=True)

    @classmethod
    def from_json(cls, text: str | None) -> RankingRule:
        if not text:
            return cls()
        data = json.loads(text)
        return cls(**{k: float(data.get(k, getattr(cls, k))) for k in ("reach_weight", "success_weight",
                                                                         "robust_weight")})


def _neutral(values: ArrayLike | None, instead: np.ndarray) -> np.ndarray:
    """``values`` as floats with NaN (not computed) replaced by ``instead``."""
    if values is None:
        return instead
    array = np.asarray(values, float)
    return np.where(np.isnan(array), instead, array)
