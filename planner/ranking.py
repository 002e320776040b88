"""The ranking rule: how a grasp's score is computed from its measures.

The rule is stored with the database (``meta.ranking``) so anyone reading it
knows what ``score`` and ``rank`` mean::

    score = epsilon * ((1 - reach_weight) + reach_weight * reachability)

with epsilon the L1 Ferrari-Canny epsilon and reachability the fraction of
sampled table placements at which an arm reaches the grasp and its
pre-grasp; grasps that are not force-closure score 0; when reachability was
not computed it counts as 1. ``reach_weight`` in [0, 1] is the user's
(``--reach-weight``): 0 ranks by epsilon alone, 1 makes unreachable grasps
score 0. Rank 1 is
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

    def __post_init__(self) -> None:
        if not 0.0 <= self.reach_weight <= 1.0:
            from planner.errors import InputError

            raise InputError(f"--reach-weight must be in [0, 1], got {self.reach_weight}")

    def score(self, epsilon: float, force_closure: bool, reachability: float | None = None) -> float:
        if not force_closure:
            return 0.0
        reach = 1.0 if reachability is None else reachability
        return epsilon * ((1.0 - self.reach_weight) + self.reach_weight * reach)

    def to_json(self) -> str:
        formula = ("score = epsilon * ((1 - reach_weight) + reach_weight * reachability); 0 unless force-closure;"
                   " reachability counts as 1 when not computed")
        return json.dumps({"formula": formula, **asdict(self)}, sort_keys=True)

    @classmethod
    def from_json(cls, text: str | None) -> RankingRule:
        if not text:
            return cls()
        data = json.loads(text)
        return cls(reach_weight=float(data.get("reach_weight", cls.reach_weight)))


ORDER_BY = "score DESC, epsilon DESC, volume DESC, seed, candidate, unit_id"

RERANK_SQL = f"""
WITH ranked AS (
    SELECT id, ROW_NUMBER() OVER (ORDER BY {ORDER_BY}) AS r FROM grasps WHERE object = ? AND hand = ?
)
UPDATE grasps SET rank = ranked.r FROM ranked WHERE grasps.id = ranked.id
"""
