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

from planner.db.ranking import FORMULA, MEASURES, RankingRule
from planner.errors import InputError

README = Path(__file__).parents[2] / "README.md"


def reference(rule: RankingRule, g: tuple) -> float:
    """The rule as FORMULA states it, one grasp at a time."""
    eps, fc, reach, ok, quantile, resist, push, open_margin, close_margin, settled, p_hold, mujoco_ok, p_trial = g
    gate = (open_margin is None or open_margin >= rule.min_open_margin) and (close_margin is None
                                                                           or close_margin >= 1e-4)
    press = 1.0 if push is None else min(max(push, 0.0), 1.0)
    hold = float(fc) if resist is None else min(resist, rule.cap) / rule.cap
    q = eps if quantile is None else quantile
    quality = (1 - rule.robust_weight) * eps + rule.robust_weight * q
    settled_term = rule.settled_weight * (0.0 if settled is None else settled)
    analytic = (press * (1 + hold) / 2 + rule.eps_weight * quality + settled_term) if gate else 0.0
    if p_hold is not None:  # a calibrated model applies: the analytic score is p_hold
        analytic = p_hold
    verdict = mujoco_ok if mujoco_ok is not None else ok  # MuJoCo's where it tried the grasp, else PyBullet's
    if p_trial is not None:  # p_hold updated by the verdict: the verdict does not count again
        analytic, verdict = p_trial, None
    reach_factor = (1 - rule.reach_weight) + rule.reach_weight * (1.0 if reach is None else reach)
    success_factor = (1 - rule.success_weight) + rule.success_weight * (1.0 if verdict is None else float(verdict))
    return analytic * reach_factor * success_factor


def measures(grasps: list) -> dict:
    """Columns of the rule's measures, None -> NaN."""
    nan = math.nan
    cols = list(zip(*grasps))
    return {name: [nan if v is None else float(v) for v in col] for name, col in zip(ORDER, cols)}


#: The measures in the order of :func:`reference`'s tuples.
ORDER = ("epsilon", "force_closure", "reachability", "success", "robust_quantile", "resist_worst", "push",
         "open_margin", "close_margin", "settled_epsilon", "p_hold", "mujoco_success", "p_hold_trial")


def test_the_rule_reads_the_declared_ranked_fields() -> None:
    assert sorted(MEASURES) == sorted(ORDER)


weight = st.floats(0.0, 1.0)
maybe = st.none() | st.floats(0.0, 40.0)
grasp = st.tuples(st.floats(0.0, 0.5), st.booleans(), st.none() | st.floats(0.0, 1.0), st.none() | st.booleans(),
                  st.none() | st.floats(0.0, 0.5), maybe, st.none() | st.floats(-1.0, 1.0),
                  st.none() | st.floats(0.0, 0.02), st.none() | st.floats(0.0, 0.02), st.none() | st.floats(0.0, 0.5),
                  st.none() | st.floats(0.0, 1.0), st.none() | st.booleans(), st.none() | st.floats(0.0, 1.0))


@settings(max_examples=200, deadline=None)
@given(weights=st.tuples(weight, weight, weight), cap=st.floats(0.5, 20.0), margin=st.floats(0.0, 0.01),
       settled_weight=st.floats(0.0, 30.0), grasps=st.lists(grasp, min_size=1, max_size=12))
def test_vectorised_rule_equals_the_plain_definition(weights: tuple, cap: float, margin: float, settled_weight: float,
                                                     grasps: list) -> None:
    rule = RankingRule(*weights, cap=cap, min_open_margin=margin, settled_weight=settled_weight)
    assert_close(rule.scores(measures(grasps)), [reference(rule, g) for g in grasps], NUM_TOL)


def test_the_analytic_part_presses_then_holds_then_breaks_ties_by_epsilon() -> None:
    rule = RankingRule(reach_weight=0.0, success_weight=0.0, eps_weight=1.0)
    m = {"epsilon": [0.1, 0.2, 0.0, 0.3, 0.2], "force_closure": [1, 1, 0, 1, 1], "resist_worst": [20, 20, 0, 2, 20],
         "push": [1.0, 1.0, 1.0, 1.0, 0.2], "open_margin": [0.01] * 5, "close_margin": [0.01] * 5}
    s = rule.analytic(m)
    assert s[1] > s[0] > s[3] > s[2] > 0  # holding beats epsilon; a pressed non-holding grasp still ranks
    assert s[4] < s[2]  # unpressed (back of a finger) ranks below pressed
    no_room = rule.analytic({**m, "open_margin": [0.001] * 5})
    assert (no_room == 0).all()


def test_by_default_the_settled_epsilon_weighs_like_press_and_hold_and_epsilon_breaks_ties() -> None:
    rule = RankingRule(reach_weight=0.0, success_weight=0.0)
    m = {"epsilon": [0.3, 0.05, 0.05, 0.1], "force_closure": [1, 1, 1, 1], "resist_worst": [20, 0.5, 20, 20],
         "push": [1.0, 0.4, 1.0, 1.0], "open_margin": [0.01] * 4, "close_margin": [0.01] * 4,
         "settled_epsilon": [0.0, 0.3, 0.1, 0.1]}
    s = rule.analytic(m)
    # a settled epsilon of 0.3 lifts a weak press and hold (0.22) above a full one that settled into nothing,
    # one of 0.1 does not outweigh a full press and hold; equal otherwise, epsilon decides
    assert s[3] > s[2] > s[1] > s[0] > 0
    assert_close(s, [1.0 + 0.1 * 0.3, 0.4 * 1.1 / 2 + 0.1 * 0.05 + 3 * 0.3, 1.0 + 0.1 * 0.05 + 0.3, 1.0 + 0.01 + 0.3])
    unmeasured = rule.analytic({**m, "settled_epsilon": [np.nan] * 4})
    assert unmeasured[0] > unmeasured[3] > unmeasured[2] > unmeasured[1]  # the planned measures alone


def test_robust_weight_moves_the_tie_break_towards_the_robust_quantile() -> None:
    base = {"epsilon": [0.1, 0.1], "force_closure": [1, 1], "robust_quantile": [0.02, np.nan]}
    only_robust = RankingRule(reach_weight=0.0, success_weight=0.0, robust_weight=1.0, eps_weight=1.0)
    assert_close(only_robust.scores(base), [1.0 + 0.02, 1.0 + 0.1])
    assert_close(RankingRule(eps_weight=1.0, reach_weight=0.0).scores(base), [1.1, 1.1])


def test_measures_not_computed_are_neutral() -> None:
    rule = RankingRule(reach_weight=0.7, success_weight=0.6, robust_weight=0.4)
    m = {"epsilon": [0.08], "force_closure": [1], "resist_worst": [10.0], "push": [0.9],
         "open_margin": [0.01], "close_margin": [0.01]}
    plain = rule.scores(m)
    assert_close(plain, rule.scores({**m, "reachability": [1.0], "success": [1.0], "robust_quantile": [0.08]}))
    assert_close(plain, rule.scores({**m, "reachability": [np.nan], "success": [np.nan]}))
    assert rule.scores({**m, "reachability": [0.5]})[0] < plain[0]
    assert rule.scores({**m, "success": [0.0]})[0] < plain[0]


def test_a_veto_weight_zeroes_failed_or_unreachable_grasps() -> None:
    rule = RankingRule(reach_weight=1.0, success_weight=1.0)
    m = {"epsilon": [0.1] * 3, "force_closure": [1] * 3, "reachability": [0.0, 1.0, 1.0], "success": [1.0, 0.0, 1.0]}
    got = rule.scores(m)
    assert got[0] == got[1] == 0 and got[2] > 0


def test_a_grasp_takes_the_mujoco_verdict_where_there_is_one_else_pybullets() -> None:
    # PyBullet and MuJoCo trials: held/held, held/dropped, dropped/held, only MuJoCo held, only MuJoCo dropped,
    # only PyBullet dropped, none
    rule = RankingRule(reach_weight=0.0, success_weight=1.0)
    nan = np.nan
    m = {"epsilon": [0.1] * 7, "force_closure": [1] * 7, "success": [1.0, 1.0, 0.0, nan, nan, 0.0, nan],
         "mujoco_success": [1.0, 0.0, 1.0, 1.0, 0.0, nan, nan]}
    got = rule.terms(m)["success_factor"]
    assert got.tolist() == [1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0]


def test_grasps_without_analytic_measures_rank_by_force_closure_then_epsilon() -> None:
    s = RankingRule().analytic({"epsilon": [0.1, 0.2, 0.0], "force_closure": [1, 1, 0]})
    assert s[1] > s[0] > s[2]


@pytest.mark.parametrize("weights", [(-0.1, 1, 0), (0.5, 1.5, 0), (0.5, 1, 2)])
def test_weights_outside_zero_one_are_refused(weights: tuple) -> None:
    with pytest.raises(InputError, match="must be in \\[0, 1\\]"):
        RankingRule(*weights)


def test_the_stored_rule_round_trips_and_says_its_formula() -> None:
    rule = RankingRule(0.25, 0.5, 0.75, cap=7.0, min_open_margin=0.002, eps_weight=0.3)
    assert RankingRule.from_json(rule.to_json()) == rule
    old = '{"formula": "...", "reach_weight": 0.25, "success_weight": 0.5, "robust_weight": 0.75}'
    assert RankingRule.from_json(old) == RankingRule(0.25, 0.5, 0.75)
    assert RankingRule.from_json(None) == RankingRule()
    assert FORMULA in rule.to_json()


def test_the_readme_shows_the_one_formula() -> None:
    assert " ".join(FORMULA.split()) in " ".join(README.read_text().split())


@given(st.lists(st.tuples(st.floats(-10, 10), st.booleans()), min_size=1, max_size=40))
@settings(max_examples=60, deadline=None)
def test_every_force_closure_grasp_ranks_above_every_other(grasps: list[tuple[float, bool]]) -> None:
    from planner.db.ranking import rank_order

    scores = np.array([s for s, _ in grasps])
    fc = np.array([f for _, f in grasps])
    order = rank_order(scores, fc)
    ranked_fc = fc[order]
    assert not np.any(~ranked_fc[:-1] & ranked_fc[1:])  # never a non-closure grasp before a closure one
    for part in (ranked_fc, ~ranked_fc):  # within each, by score
        assert np.all(np.diff(scores[order][part]) <= 0)


def test_p_hold_replaces_the_formula_where_given_and_nowhere_else() -> None:
    rule = RankingRule()
    m = {"epsilon": [0.1, 0.1], "force_closure": [1, 1], "p_hold": [0.3, np.nan]}
    got = rule.analytic(m)
    assert got[0] == 0.3 and got[1] == rule.analytic({"epsilon": [0.1], "force_closure": [1]})[0]


def test_a_grasp_force_closure_after_the_squeeze_ranks_with_the_force_closure_ones() -> None:
    """Force closure as planned or as squeezed (planner.plan.squeeze) ranks first; a squeeze not measured (None,
    NaN: a hand that does not squeeze, a grasp stored before) counts as not force closure."""
    from planner.db.ranking import rank_order, ranks_first

    m = {"force_closure": [0, 1, 0, 0, 0], "squeezed_force_closure": [1, 1, 0, None, np.nan]}
    first = ranks_first(m)
    assert first.tolist() == [True, True, False, False, False]
    assert rank_order(np.array([0.1, 0.2, 0.9, 0.8, 0.7]), first).tolist() == [1, 0, 2, 3, 4]
    assert ranks_first({"force_closure": [1, 0]}).tolist() == [True, False]  # the squeeze not given at all


def test_a_grasp_whose_squeezes_end_is_kept_ranks_with_those_that_are_neither() -> None:
    """Force closure only once squeezed ranks first unless that squeeze's end is kept as a grasp of its own
    (planner.db.ranking.FIRST, END_KEPT): the end, force closure as planned, stands for it (issue 26). Not known
    (None, NaN, not given): no end stands for it, as for an import's grasp."""
    from planner.db.ranking import END_KEPT, rank_order, ranks_first

    m = {"force_closure": [0, 0, 0, 1, 0], "squeezed_force_closure": [1, 1, 1, 1, 0],
         END_KEPT: [True, None, np.nan, True, True]}
    first = ranks_first(m)
    assert first.tolist() == [False, True, True, True, False]
    assert rank_order(np.array([0.9, 0.1, 0.2, 0.3, 0.8]), first).tolist() == [3, 2, 1, 0, 4]
    assert ranks_first({"force_closure": [0], "squeezed_force_closure": [1]}).tolist() == [True]


def _sweep(rows: list[tuple[bool, float, bool | None, bool]], first_candidate: int) -> list:
    """Records as a sweep hands them over: per row (force closure as planned, epsilon, squeezed force closure or
    None: not measured, whether its squeeze's end is kept: then the end follows, the same candidate, its parent
    marked as the keeper marks it)."""
    from dataclasses import replace

    from helpers import made_up

    from planner.plan.measures import Measures

    out = []
    for i, (fc, eps, squeezed, end) in enumerate(rows):
        measures = Measures(3.0, 4.0, 0.01, 0.01, 1.0, (), squeezed_force_closure=squeezed)
        g = replace(made_up(first_candidate + i, eps if fc else 0.0, fc=fc), measures=measures)
        if end and squeezed and not fc:
            out += [replace(g, end_kept=True),
                    replace(g, epsilon=eps / 2, force_closure=True, squeezed_from_turn=0.3,
                            measures=replace(measures, squeezed_force_closure=False))]
        else:
            out.append(g)
    return out


ROWS = st.lists(st.tuples(st.booleans(), st.floats(0.0, 0.2), st.sampled_from([None, False, True]), st.booleans()),
                min_size=1, max_size=8)


@given(ROWS, ROWS, st.integers(0, 3))
@settings(max_examples=25, deadline=None)
def test_the_database_and_the_records_rank_alike(tmp_path_factory: pytest.TempPathFactory, swept: list,
                                                 imported: list, overlap: int) -> None:
    """On random small databases (a sweep's unit with parents and their ends, an import's unit with the same
    candidate numbers and no ends, squeezes not measured): the SQL order (grasps.rank, FIRST_SQL) and the records'
    (Database.scored: rank_order of ranks_first) put the same (first, score) in the same places, and a record read
    back knows whether its squeeze's end is stored."""
    import dataclasses
    import json
    import sqlite3

    from planner.db.ranking import FIRST_SQL, first_of
    from planner.db.store import UnitRow, open_db

    path = tmp_path_factory.mktemp("rank") / "g.db"
    units = [_sweep(swept, 0), [dataclasses.replace(g, end_kept=None) for g in _sweep(imported, overlap)
                                if g.squeezed_from_turn is None]]
    with open_db(path) as db:
        for chunk, grasps in enumerate(units):
            db.write_unit(UnitRow("thing", "panda", "h" * 16, json.dumps({}), 5, chunk, None), None, grasps,
                          RankingRule())
        back = db.best("thing", "panda", 100)
        ordered = db.scored([g for u in units for g in u], "panda")
    python = [(f, g.score) for g, f in zip(ordered, first_of(ordered))]
    with sqlite3.connect(path) as conn:
        sql = [(bool(f), s) for f, s in conn.execute(f"SELECT {FIRST_SQL}, score FROM grasps ORDER BY rank")]
    assert sql == python
    kept = {(g.candidate, g.unit_id) for g in back if g.squeezed_from_turn is not None}
    assert [g.end_kept for g in back] == [g.squeezed_from_turn is None and (g.candidate, g.unit_id) in kept
                                          for g in back]
    assert sum(g.end_kept for g in back) == sum(bool(g.end_kept) for g in units[0])
