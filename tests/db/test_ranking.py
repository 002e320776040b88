"""The ranking rule: the vectorised rule equals its plain definition, weights
act as documented, measures not computed are neutral."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from helpers import NUM_TOL, assert_close
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.db.ranking import FORMULA, RankingRule
from planner.errors import InputError

README = Path(__file__).parents[2] / "README.md"


def reference(rule: RankingRule, eps: float, fc: bool, reach: float | None, ok: bool | None,
              quantile: float | None) -> float:
    """The rule as FORMULA states it, one grasp at a time."""
    if not fc:
        return 0.0
    q = eps if quantile is None else quantile
    quality = (1 - rule.robust_weight) * eps + rule.robust_weight * q
    reach_factor = (1 - rule.reach_weight) + rule.reach_weight * (1.0 if reach is None else reach)
    success_factor = (1 - rule.success_weight) + rule.success_weight * (1.0 if ok is None else float(ok))
    return quality * reach_factor * success_factor


weight = st.floats(0.0, 1.0)
grasp = st.tuples(st.floats(0.0, 0.5), st.booleans(), st.none() | st.floats(0.0, 1.0), st.none() | st.booleans(),
                  st.none() | st.floats(0.0, 0.5))


@settings(max_examples=200, deadline=None)
@given(weights=st.tuples(weight, weight, weight), grasps=st.lists(grasp, min_size=1, max_size=12))
def test_vectorised_rule_equals_the_plain_definition(weights: tuple, grasps: list) -> None:
    rule = RankingRule(*weights)
    nan = math.nan
    eps, fc, reach, ok, quantile = zip(*grasps)
    got = rule.scores(eps, fc, [nan if r is None else r for r in reach], [nan if s is None else s for s in ok],
                      [nan if q is None else q for q in quantile])
    assert_close(got, [reference(rule, *g) for g in grasps], NUM_TOL)


def test_robust_weight_moves_the_score_towards_the_robust_quantile() -> None:
    eps, quantile = np.array([0.1, 0.1]), np.array([0.02, np.nan])
    only_robust = RankingRule(reach_weight=0.0, success_weight=0.0, robust_weight=1.0)
    assert_close(only_robust.scores(eps, [True, True], robust_quantile=quantile), [0.02, 0.1])
    half = RankingRule(reach_weight=0.0, success_weight=0.0, robust_weight=0.5)
    assert_close(half.scores(eps, [True, True], robust_quantile=quantile), [0.06, 0.1])
    assert_close(RankingRule(robust_weight=0.0).scores(eps, [True, True], robust_quantile=quantile), [0.1, 0.1])


def test_measures_not_computed_are_neutral() -> None:
    rule = RankingRule(reach_weight=0.7, success_weight=0.6, robust_weight=0.4)
    eps, fc = [0.08], [True]
    plain = rule.scores(eps, fc)
    assert_close(plain, rule.scores(eps, fc, [1.0], [1.0], eps))  # as if reached, held, robust = epsilon
    assert_close(plain, rule.scores(eps, fc, [np.nan], [np.nan], [np.nan]))
    assert rule.scores(eps, fc, [0.5])[0] < plain[0] and rule.scores(eps, fc, success=[0.0])[0] < plain[0]


def test_a_veto_weight_zeroes_failed_or_unreachable_grasps_and_non_closure_scores_zero() -> None:
    rule = RankingRule(reach_weight=1.0, success_weight=1.0)
    assert_close(rule.scores([0.1, 0.1, 0.1], [True, True, True], [0.0, 1.0, 1.0], [1.0, 0.0, 1.0]), [0, 0, 0.1])
    assert_close(RankingRule().scores([0.3], [False], [1.0], [1.0]), [0.0])


@pytest.mark.parametrize("weights", [(-0.1, 1, 0), (0.5, 1.5, 0), (0.5, 1, 2)])
def test_weights_outside_zero_one_are_refused(weights: tuple) -> None:
    with pytest.raises(InputError, match="must be in \\[0, 1\\]"):
        RankingRule(*weights)


def test_the_stored_rule_round_trips_and_says_its_formula() -> None:
    rule = RankingRule(0.25, 0.5, 0.75)
    assert RankingRule.from_json(rule.to_json()) == rule
    assert RankingRule.from_json(None) == RankingRule()
    assert FORMULA in rule.to_json()


def test_the_readme_shows_the_one_formula() -> None:
    assert " ".join(FORMULA.split()) in " ".join(README.read_text().split())
