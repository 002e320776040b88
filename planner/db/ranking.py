"""The ranking rule: how a grasp's score is computed from its measures.

The rule is stored with the database (``meta.ranking``) so anyone reading it
knows what ``score`` and ``rank`` mean::

    quality = (1 - robust_weight) * epsilon + robust_weight * robust_epsilon_quantile
    score   = quality * ((1 - reach_weight)   + reach_weight   * reachability)
                      * ((1 - success_weight) + success_weight * simulated_success)

with epsilon the L1 Ferrari-Canny epsilon, reachability the fraction of
sampled table placements at which an arm reaches the grasp and its
pre-grasp, simulated_success 1/0 from the shake test and
robust_epsilon_quantile the low quantile of epsilon under pose and friction
noise. Grasps that are not force-closure score 0. A measure that was not
computed for a grasp counts as neutral: reachability and success as 1, the
robust quantile as epsilon. Each weight lies in [0, 1]; 0 ignores the
measure, 1 lets it veto (an unreachable or failed grasp scores 0). Rank 1 is
the best grasp of an (object, hand); ties are broken by epsilon, then GWS
volume, then by the unit seed and candidate number (never by insertion
order, so the rank does not depend on which worker finished first).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class RankingRule:
    reach_weight: float = 0.5
    success_weight: float = 1.0
    robust_weight: float = 0.0

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not 0.0 <= value <= 1.0:
                from planner.errors import InputError

                raise InputError(f"--{name.replace('_', '-')} must be in [0, 1], got {value}")

    def score(self, epsilon: float, force_closure: bool, reachability: float | None = None,
              success: bool | None = None, robust_quantile: float | None = None) -> float:
        if not force_closure:
            return 0.0
        q = epsilon if robust_quantile is None else robust_quantile
        quality = (1.0 - self.robust_weight) * epsilon + self.robust_weight * q
        reach = 1.0 if reachability is None else reachability
        ok = 1.0 if success is None else float(success)
        return (quality * ((1.0 - self.reach_weight) + self.reach_weight * reach)
                * ((1.0 - self.success_weight) + self.success_weight * ok))

    def to_json(self) -> str:
        formula = ("score = ((1 - robust_weight) * epsilon + robust_weight * robust_quantile)"
                   " * ((1 - reach_weight) + reach_weight * reachability)"
                   " * ((1 - success_weight) + success_weight * simulated_success); 0 unless force-closure;"
                   " a measure not computed counts as neutral (reachability, success 1; robust quantile = epsilon)")
        return json.dumps({"formula": formula, **asdict(self)}, sort_keys=True)

    @classmethod
    def from_json(cls, text: str | None) -> RankingRule:
        if not text:
            return cls()
        data = json.loads(text)
        return cls(**{k: float(data.get(k, getattr(cls, k))) for k in ("reach_weight", "success_weight",
                                                                         "robust_weight")})

    def sql(self) -> tuple[str, tuple[float, ...]]:
        """The same formula as an SQL expression over grasps g, validation v, robust r."""
        expr = ("CASE WHEN g.force_closure = 1 THEN"
                " ((1.0 - ?) * g.epsilon + ? * COALESCE(r.quantile, g.epsilon))"
                " * ((1.0 - ?) + ? * COALESCE(g.reachability, 1.0))"
                " * ((1.0 - ?) + ? * COALESCE(v.success, 1.0)) ELSE 0.0 END")
        w = self
        return expr, (w.robust_weight, w.robust_weight, w.reach_weight, w.reach_weight, w.success_weight,
                      w.success_weight)


RESCORE_SQL = """
UPDATE grasps SET score = (
    SELECT {expr} FROM grasps g LEFT JOIN validation v ON v.grasp_id = g.id LEFT JOIN robust r ON r.grasp_id = g.id
    WHERE g.id = grasps.id)
WHERE {where}
"""


ORDER_BY = "score DESC, epsilon DESC, volume DESC, seed, candidate, unit_id"

RERANK_SQL = f"""
WITH ranked AS (
    SELECT id, ROW_NUMBER() OVER (ORDER BY {ORDER_BY}) AS r FROM grasps WHERE object = ? AND hand = ?
)
UPDATE grasps SET rank = ranked.r FROM ranked WHERE grasps.id = ranked.id
"""
