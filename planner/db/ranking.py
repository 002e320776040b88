"""The ranking rule: how a grasp's score follows from its measures.

The rule is :meth:`RankingRule.scores`, written once, over arrays of
measures; :data:`FORMULA` says the same in words (it is stored with every
database in ``meta.ranking`` and shown in the README). The database never
computes a score itself: it reads the measures, calls the rule and writes
the scores back (:mod:`planner.db.store`), then ranks by :data:`ORDER_BY`.

The analytic part (:meth:`RankingRule.analytic`) stands on its own, from the
measures of :mod:`planner.plan.measures` and epsilon:

* gate: 0 for a grasp with no clearance (a touching finger within
  ``min_open_margin`` of its open limit) or a finger at its closing stop;
* press: the fingers squeeze the object, ``push`` (1 = pads square on it);
* hold: weight resistance, worst direction, capped: min(resist_worst, cap) / cap;
* epsilon (Ferrari-Canny with contact patches, or its robust quantile), with
  weight ``eps_weight``: it orders grasps that press and hold alike and, at
  weight 1, can outweigh a small difference of press;
* settled: the epsilon of the contacts the grasp settles into under a
  dynamic closing (hands with ``settle``, :mod:`planner.plan.settle`; 0
  when not measured), with weight ``settled_weight``: for a hand whose
  closing moves the object it decides the order.

Where a calibrated probability of holding applies (a p_hold model for the
hand: fitted by ``grasp calibrate`` and stored, or the project's shipped one,
:mod:`planner.calibration`), the analytic score *is* ``p_hold``: the model
has learnt from external labels how much each of those measures counts.

A pressed grasp that does not hold its weight yet still ranks above one that
is not pressed (half weight): squeezing settles it. Reachability (fraction of
table placements an arm reaches) and simulated success (1/0 from the shake
test) then multiply, each with its weight in [0, 1] (0 ignores the measure, 1
lets it veto); simulated success only refines the order. Rank 1 is the best
grasp of an (object, hand). Every grasp whose planned contacts are force
closure ranks above every grasp whose contacts are not, whatever their
scores (issue 26: a score that rewards what one simulator's closing happens to
do must not lift a grasp that is not force closure as planned); within each
of the two, by score; ties are broken by epsilon, then GWS volume, then by
the unit seed and candidate number (never by insertion order).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from planner.errors import InputError

if TYPE_CHECKING:
    from planner.grasp import Grasp

#: The rule of :meth:`RankingRule.scores` in words, as ``meta.ranking`` stores it.
FORMULA = ("analytic = p_hold where a calibrated model applies to the hand, else"
           " gate * (press * (1 + hold) / 2 + eps_weight * quality + settled_weight * settled);"
           " gate = [open_margin >= min_open_margin] * [close_margin >= 1e-4 m];"
           " press = clip(push, 0, 1); hold = min(resist_worst, cap) / cap;"
           " quality = (1 - robust_weight) * epsilon + robust_weight * robust_quantile;"
           " settled = settled_epsilon (0 when not measured);"
           " score = analytic * ((1 - reach_weight) + reach_weight * reachability)"
           " * ((1 - success_weight) + success_weight * simulated_success);"
           " a measure not computed counts as neutral (reachability, success 1; robust quantile = epsilon);"
           " grasps stored without the analytic measures (before schema v3): gate 1, press 1,"
           " hold = force_closure;"
           " rank: force-closure grasps first, then by score")

#: The rank order: score first, then the tie-breaks (columns of ``grasps``).
ORDER_BY = "force_closure DESC, score DESC, epsilon DESC, volume DESC, seed, candidate, unit_id"

#: [m] a finger this close to its closing stop cannot squeeze (the gate).
CLOSE_STOP = 1e-4

#: The measures the rule reads (each an (n,) array; NaN or None = not computed).
MEASURES = ("epsilon", "force_closure", "reachability", "success", "robust_quantile", "resist_worst", "push",
            "open_margin", "close_margin", "settled_epsilon", "p_hold")


@dataclass(frozen=True)
class RankingRule:
    """The weights and thresholds of the rule.

    reach_weight, success_weight, robust_weight in [0, 1]; cap [g] > 0, the
    weight resistance that counts as holding; min_open_margin [m] >= 0, the
    clearance the gate asks for; eps_weight >= 0, epsilon's weight;
    settled_weight >= 0, the settled epsilon's weight. cap, min_open_margin,
    eps_weight and settled_weight were chosen by cross-validation grouped by
    object on the tuning objects (bench/RESULTS.md; third round, 2026-11-23:
    one rule for both hands, every fold chose cap 5 g, min_open_margin 2 mm,
    eps_weight 3, settled_weight 100: where measured, the settled epsilon
    decides the order and the rest breaks its ties).
    """

    reach_weight: float = 0.5
    success_weight: float = 1.0
    robust_weight: float = 0.0
    cap: float = 5.0
    min_open_margin: float = 0.002
    eps_weight: float = 3.0
    settled_weight: float = 100.0

    def __post_init__(self) -> None:
        for name in ("reach_weight", "success_weight", "robust_weight"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise InputError(f"--{name.replace('_', '-')} must be in [0, 1], got {value}")
        if not self.cap > 0 or self.min_open_margin < 0 or self.eps_weight < 0 or self.settled_weight < 0:
            raise InputError(f"ranking rule: cap must be > 0 g, min_open_margin, eps_weight and settled_weight >= 0; "
                             f"got {self}")

    def analytic(self, measures: Mapping[str, ArrayLike | None]) -> np.ndarray:
        """(n,) analytic scores from the measures (see :data:`MEASURES`): p_hold
        where given (not NaN), else the rule's formula."""
        eps = _column(measures, "epsilon")
        n = len(eps)
        fc = _column(measures, "force_closure", np.zeros(n))
        measured = ~np.isnan(_column(measures, "resist_worst", np.full(n, np.nan)))
        hold = np.where(measured, np.minimum(np.maximum(_column(measures, "resist_worst", np.zeros(n)), 0.0),
                                             self.cap) / self.cap, fc > 0)
        press = np.clip(_column(measures, "push", np.ones(n)), 0.0, 1.0)
        open_margin = _column(measures, "open_margin", np.full(n, np.inf))
        close_margin = _column(measures, "close_margin", np.full(n, np.inf))
        gate = (open_margin >= self.min_open_margin) & (close_margin >= CLOSE_STOP)
        settled = _column(measures, "settled_epsilon", np.zeros(n))
        quantile = _column(measures, "robust_quantile", eps)
        quality = (1.0 - self.robust_weight) * eps + self.robust_weight * quantile
        rule = np.where(gate, press * (1.0 + hold) / 2.0 + self.eps_weight * quality + self.settled_weight * settled,
                        0.0)
        p_hold = _column(measures, "p_hold", np.full(n, np.nan))
        return np.where(np.isnan(p_hold), rule, p_hold)

    def scores(self, measures: Mapping[str, ArrayLike | None]) -> np.ndarray:
        """(n,) final scores: the analytic score times reachability and
        simulated success, each weighted (absent = neutral)."""
        analytic = self.analytic(measures)
        ones = np.ones_like(analytic)
        reach = _column(measures, "reachability", ones)
        ok = _column(measures, "success", ones)
        return (analytic * ((1.0 - self.reach_weight) + self.reach_weight * reach)
                * ((1.0 - self.success_weight) + self.success_weight * ok))

    def to_json(self) -> str:
        return json.dumps({"formula": FORMULA, **asdict(self)}, sort_keys=True)

    @classmethod
    def from_json(cls, text: str | None) -> RankingRule:
        """The stored rule; a rule stored by an older version keeps its weights
        and takes today's defaults for what it did not have."""
        if not text:
            return cls()
        data = json.loads(text)
        return cls(**{k: float(data.get(k, getattr(cls, k))) for k in cls.__dataclass_fields__})


def _column(measures: Mapping[str, ArrayLike | None], name: str, instead: np.ndarray | None = None) -> np.ndarray:
    """Measure ``name`` as floats, NaN / None (not computed) replaced by ``instead``."""
    values = measures.get(name)
    if values is None:
        if instead is None:
            raise InputError(f"ranking rule: the measure '{name}' is required")
        return np.asarray(instead, float)
    array = np.array([np.nan if v is None else v for v in values], float) if isinstance(values, (list, tuple)) \
        else np.asarray(values, float)
    return array if instead is None else np.where(np.isnan(array), instead, array)


def rank_order(scores: np.ndarray, force_closure: np.ndarray) -> np.ndarray:
    """(n,) indices best first, as :data:`ORDER_BY` ranks (before its
    tie-breaks, which are left to a stable sort: the given order): force
    closure first, then by score."""
    s, fc = np.asarray(scores, float), np.asarray(force_closure, float) > 0
    return np.lexsort((np.arange(len(s)), -s, ~fc))


def rule_measures(grasps: Sequence[Grasp]) -> dict[str, np.ndarray]:
    """The rule's measures of grasp records (validation and robust rows
    included; p_hold as the records carry it)."""
    nan = np.nan

    def measured(name: str) -> np.ndarray:
        return np.array([nan if g.measures is None or getattr(g.measures, name) is None
                         else getattr(g.measures, name) for g in grasps], float)

    return {"epsilon": np.array([g.epsilon for g in grasps], float),
            "force_closure": np.array([g.force_closure for g in grasps], float),
            "reachability": np.array([nan if g.reachability is None else g.reachability for g in grasps], float),
            "success": np.array([nan if g.validation is None else g.validation.success for g in grasps], float),
            "robust_quantile": np.array([nan if g.robust is None else g.robust.quantile for g in grasps], float),
            "p_hold": np.array([nan if g.p_hold is None else g.p_hold for g in grasps], float),
            **{name: measured(name) for name in ("resist_worst", "push", "open_margin", "close_margin",
                                                 "settled_epsilon")}}
