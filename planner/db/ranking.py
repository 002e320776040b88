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
  weight ``eps_weight``: it orders grasps that press and hold alike;
* settled: the epsilon of the contacts the grasp settles into under a
  dynamic closing (hands with ``settle``, :mod:`planner.plan.settle`; 0
  when not measured), with weight ``settled_weight``: for a hand whose
  closing moves the object it weighs about as much as press and hold.

Where a calibrated probability of holding applies (a p_hold model for the
hand: fitted by ``grasp calibrate`` and stored, or the project's shipped one,
:mod:`planner.calibration`), the analytic score *is* ``p_hold``: the model
has learnt from external labels how much each of those measures counts.
Where a trial tried the grasp and the model says how that trial's verdict
updates p_hold (:mod:`planner.calibration.update`), it is ``p_hold_trial``
and the verdict does not multiply again.

A pressed grasp that does not hold its weight yet still ranks above one that
is not pressed (half weight): squeezing settles it. Reachability (fraction of
table placements an arm reaches) and simulated success then multiply, each
with its weight in [0, 1] (0 ignores the measure, 1 lets it veto); simulated
success only refines the order. Simulated success is the verdict of the
dynamic trial that agrees best with external labels among those that tried
the grasp (:data:`planner.record.fields.TRIAL_PRECEDENCE`: MuJoCo's, then
PyBullet's shake trial), neutral if none tried it. Rank 1 is the best
grasp of an (object, hand). Every grasp whose contacts are force closure, as
planned or as a self-centring parallel jaw's squeeze ends in (:data:`FIRST`;
only the Panda squeezes), ranks above every grasp whose contacts are neither,
whatever their scores (issue 26: a score that rewards what one simulator's
closing happens to do must not lift a grasp that is not force closure),
but for a grasp force closure only once squeezed whose squeeze's end is
stored as a grasp of its own: the end, force closure as planned, stands for
it, and it ranks with the others; within each of the two, by score; ties are broken by epsilon, then GWS
volume, then by the unit seed and candidate number, a planned grasp before its squeeze's end (never by
insertion order).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from planner.errors import InputError
from planner.record import fields
from planner.record.first import END_KEPT, FIRST, first_measures, first_of, ranks_first  # noqa: F401 - the rule
from planner.record.tolerances import MIN_CLOSE_MARGIN, MIN_OPEN_MARGIN

if TYPE_CHECKING:
    from planner.record.grasp import Grasp


def end_kept_sql(table: str = "grasps") -> str:
    """:data:`END_KEPT` of a row of ``table`` (``grasps`` or its alias) in SQL, 1 or 0: a squeeze's end of the same
    unit and candidate is stored beside the grasp (the index ``grasps_candidate`` finds it; looked up only for a grasp
    closed where planned and force closure once squeezed, the only kind whose end is kept)."""
    return (f"CASE WHEN {table}.squeezed_from_turn IS NULL AND {table}.squeezed_force_closure = 1 THEN EXISTS (SELECT"
            f" 1 FROM grasps e WHERE e.unit_id = {table}.unit_id AND e.candidate = {table}.candidate AND"
            " e.squeezed_from_turn IS NOT NULL) ELSE 0 END")


def first_sql(table: str = "grasps") -> str:
    """:data:`FIRST` as SQL over a row of ``table`` (``grasps`` or its alias): 1 for a grasp that ranks first, else
    0 (NULL: 0)."""
    taken_back = {"": "", END_KEPT: f" * (1 - {end_kept_sql(table)})"}
    return f"MAX({', '.join(f'COALESCE({table}.{c}, 0){taken_back[back]}' for c, back in FIRST.items())})"


#: :func:`first_sql` of the ``grasps`` table itself.
FIRST_SQL = first_sql()
#: The last tie-break: a planned grasp before its squeeze's end (:mod:`planner.plan.keeping`: the same unit and
#: candidate; it ties only where both score and epsilon alike).
SQUEEZED_LAST = "squeezed_from_turn IS NOT NULL"
#: The rank order: a 1 in :data:`FIRST` first, then score, then the tie-breaks (columns of ``grasps``).
ORDER_BY = f"{FIRST_SQL} DESC, score DESC, epsilon DESC, volume DESC, seed, candidate, unit_id, {SQUEEZED_LAST}"

#: The measures the rule reads (each an (n,) array; NaN or None = not computed), by
#: the names the declaration gives them (:func:`planner.record.fields.ranked_fields`).
MEASURES = tuple(f.ranked for f in fields.ranked_fields())


def _short(value: float) -> str:
    """A number as the formula writes it, in short scientific form: ``1e-4``."""
    mantissa, exponent = f"{value:.15e}".split("e")
    return f"{mantissa.rstrip('0').rstrip('.')}e{int(exponent)}"


#: The words of :data:`FORMULA` on :data:`END_KEPT` (:func:`ranked_with_ends` looks for them).
ENDS_RANKED = "(but for one whose squeeze's end is stored as a grasp of its own, which stands for it)"
#: The rule of :meth:`RankingRule.scores` in words, as ``meta.ranking`` stores it.
FORMULA = ("analytic = p_hold_trial where the hand's calibrated model updates p_hold by the verdict of the trial"
           " that tried the grasp (then simulated_success counts as neutral: the verdict is in p_hold_trial),"
           " else p_hold where a calibrated model applies to the hand, else"
           " gate * (press * (1 + hold) / 2 + eps_weight * quality + settled_weight * settled);"
           f" gate = [open_margin >= min_open_margin] * [close_margin >= {_short(MIN_CLOSE_MARGIN)} m];"
           " press = clip(push, 0, 1); hold = min(resist_worst, cap) / cap;"
           " quality = (1 - robust_weight) * epsilon + robust_weight * robust_quantile;"
           " settled = settled_epsilon (0 when not measured);"
           " score = analytic * ((1 - reach_weight) + reach_weight * reachability)"
           " * ((1 - success_weight) + success_weight * simulated_success);"
           " simulated_success = mujoco_success where the MuJoCo trial tried the grasp, else success"
           " (PyBullet's trial);"
           " a measure not computed counts as neutral (reachability, success 1; robust quantile = epsilon);"
           " grasps stored without the analytic measures (before schema v3): gate 1, press 1,"
           " hold = force_closure;"
           f" rank: grasps force closure as planned or after a parallel jaw's squeeze first {ENDS_RANKED}, then by"
           " score")


def ranked_with_ends(ranking: str | None) -> bool:
    """Whether a database whose ``meta.ranking`` is ``ranking`` (JSON; None: none stored yet, a new database
    ranked by :data:`ORDER_BY`) was ranked with stored squeezes' ends standing for their parents: an earlier
    version's ranks keep each such parent among the grasps that rank first until the next write ranks them
    again, and its records read back say so (:attr:`planner.record.grasp.Grasp.end_kept` False), as they rank."""
    return ranking is None or ENDS_RANKED in str(json.loads(ranking).get("formula", ""))


@dataclass(frozen=True)
class RankingRule:
    """The weights and thresholds of the rule.

    reach_weight, success_weight, robust_weight in [0, 1]; cap [g] > 0, the
    weight resistance that counts as holding; min_open_margin [m] >= 0, the
    clearance the gate asks for; eps_weight >= 0, epsilon's weight;
    settled_weight >= 0, the settled epsilon's weight. cap and
    min_open_margin were chosen by cross-validation grouped by object on the
    tuning objects (bench/RESULTS.md; third round, 2026-11-23, against this
    project's PyBullet trial); eps_weight 0.1 and settled_weight 3 on 22
    random objects of their own (2026-12-03, bench/barrett_rule.py: the
    Barrett's grasps against the MuJoCo trial, an independent protocol, and
    the parallel-jaw formula against ACRONYM's FleX labels): the settled
    epsilon, the planned epsilon and the press and hold now share the order
    instead of the settled epsilon deciding it (weight 100 before).
    """

    reach_weight: float = 0.5
    success_weight: float = 1.0
    robust_weight: float = 0.0
    cap: float = 5.0
    min_open_margin: float = MIN_OPEN_MARGIN
    eps_weight: float = 0.1
    settled_weight: float = 3.0

    def __post_init__(self) -> None:
        for name in ("reach_weight", "success_weight", "robust_weight"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise InputError(f"--{name.replace('_', '-')} must be in [0, 1], got {value}")
        if not self.cap > 0 or self.min_open_margin < 0 or self.eps_weight < 0 or self.settled_weight < 0:
            raise InputError(f"ranking rule: cap must be > 0 g, min_open_margin, eps_weight and settled_weight >= 0; "
                             f"got {self}")

    def terms(self, measures: Mapping[str, ArrayLike | None]) -> dict[str, np.ndarray]:
        """Every term of the rule, (n,) each, in the order :data:`FORMULA`
        builds them: ``gate``, ``press``, ``hold``, ``quality``, ``settled``,
        ``formula`` (the formula's analytic score), ``p_hold`` (NaN where no
        calibrated model applies), ``p_hold_trial`` (NaN where the model
        does not update p_hold by a trial's verdict), ``analytic``
        (p_hold_trial where given, else p_hold where given, else the
        formula's), ``reach_factor``, ``success_factor`` (neutral where
        p_hold_trial is given) and ``score``
        (``grasp best --explain`` prints them; :meth:`analytic` and
        :meth:`scores` are read off them)."""
        eps = _column(measures, "epsilon")
        n = len(eps)
        fc = _column(measures, "force_closure", np.zeros(n))
        measured = ~np.isnan(_column(measures, "resist_worst", np.full(n, np.nan)))
        hold = np.where(measured, np.minimum(np.maximum(_column(measures, "resist_worst", np.zeros(n)), 0.0),
                                             self.cap) / self.cap, fc > 0).astype(float)
        press = np.clip(_column(measures, "push", np.ones(n)), 0.0, 1.0)
        open_margin = _column(measures, "open_margin", np.full(n, np.inf))
        close_margin = _column(measures, "close_margin", np.full(n, np.inf))
        gate = ((open_margin >= self.min_open_margin) & (close_margin >= MIN_CLOSE_MARGIN)).astype(float)
        settled = _column(measures, "settled_epsilon", np.zeros(n))
        quantile = _column(measures, "robust_quantile", eps)
        quality = (1.0 - self.robust_weight) * eps + self.robust_weight * quantile
        formula = np.where(gate > 0, press * (1.0 + hold) / 2.0 + self.eps_weight * quality
                           + self.settled_weight * settled, 0.0)
        p_hold = _column(measures, "p_hold", np.full(n, np.nan))
        p_trial = _column(measures, "p_hold_trial", np.full(n, np.nan))
        updated = ~np.isnan(p_trial)
        analytic = np.where(updated, p_trial, np.where(np.isnan(p_hold), formula, p_hold))
        ones = np.ones(n)
        reach = (1.0 - self.reach_weight) + self.reach_weight * _column(measures, "reachability", ones)
        tried = np.full(n, np.nan)  # the verdict of the first trial in precedence that tried it; NaN: none did
        for name in reversed(fields.TRIAL_SUCCESS):
            tried = _column(measures, name, tried)
        tried = np.where(updated, np.nan, tried)  # counted in p_hold_trial already
        success = (1.0 - self.success_weight) + self.success_weight * np.where(np.isnan(tried), 1.0, tried)
        return {"gate": gate, "press": press, "hold": hold, "quality": quality, "settled": settled,
                "formula": formula, "p_hold": p_hold, "p_hold_trial": p_trial, "analytic": analytic,
                "reach_factor": reach,
                "success_factor": success, "score": analytic * reach * success}

    def analytic(self, measures: Mapping[str, ArrayLike | None]) -> np.ndarray:
        """(n,) analytic scores from the measures (see :data:`MEASURES`): p_hold
        where given (not NaN), else the rule's formula."""
        return self.terms(measures)["analytic"]

    def scores(self, measures: Mapping[str, ArrayLike | None]) -> np.ndarray:
        """(n,) final scores: the analytic score times reachability and
        simulated success, each weighted (absent = neutral)."""
        return self.terms(measures)["score"]

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


def rank_order(scores: np.ndarray, first: np.ndarray) -> np.ndarray:
    """(n,) indices best first, as :data:`ORDER_BY` ranks (before its tie-breaks, which are left to a stable
    sort: the given order): the grasps ``first`` (n,) (:func:`ranks_first`; > 0: first) first, then by score."""
    s, fc = np.asarray(scores, float), np.asarray(first, float) > 0
    return np.lexsort((np.arange(len(s)), -s, ~fc))


def rule_measures(grasps: Sequence[Grasp]) -> dict[str, np.ndarray]:
    """The rule's measures of grasp records (validation and robust rows included):
    each declared ranked field as an (n,) float array, NaN where absent."""
    return {f.ranked: np.array([np.nan if v is None else v for v in fields.values(f, grasps)], float)
            for f in fields.ranked_fields()}
