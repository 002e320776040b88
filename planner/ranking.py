"""The ranking rule: how a grasp's score is computed from its measures.

The rule is stored with the database (``meta.ranking``) so anyone reading it
knows what ``score`` and ``rank`` mean. For now the score is the L1
Ferrari-Canny epsilon; grasps that are not force-closure score 0. Rank 1 is
the best grasp of an (object, hand); ties are broken by epsilon, then GWS
volume, then by the unit seed and candidate number (never by insertion
order, so the rank does not depend on which worker finished first).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class RankingRule:
    epsilon_weight: float = 1.0

    def score(self, epsilon: float, force_closure: bool) -> float:
        return self.epsilon_weight * epsilon if force_closure else 0.0

    def to_json(self) -> str:
        return json.dumps({"formula": "score = epsilon_weight * epsilon (0 unless force-closure)", **asdict(self)},
                          sort_keys=True)


ORDER_BY = "score DESC, epsilon DESC, volume DESC, seed, candidate, unit_id"

RERANK_SQL = f"""
WITH ranked AS (
    SELECT id, ROW_NUMBER() OVER (ORDER BY {ORDER_BY}) AS r FROM grasps WHERE object = ? AND hand = ?
)
UPDATE grasps SET rank = ranked.r FROM ranked WHERE grasps.id = ranked.id
"""
