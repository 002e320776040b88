"""The interaction trees of p_hold: their evaluation against scikit-learn's and a plain one, what they add
to the additive model, their files, and bad trees refused."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.calibration import features
from planner.calibration.logistic import INTERACTIONS, LogisticModel, load_model
from planner.calibration.metrics import roc_auc
from planner.calibration.model import cross_validate, fit
from planner.calibration.trees import LEAF, Trees, TreeSettings, _Margin, fit_trees
from planner.errors import InputError
from tests.calibration.test_model import synthetic
from tests.helpers import assert_close

#: Sums of float64 leaf values in another order differ by round-off only.
SUM_TOL = 1e-9


def xor_truth(table: dict[str, np.ndarray]) -> np.ndarray:
    """Log-odds of a world where a narrow grasp holds only when pushed square and a wide one only when not:
    no sum of one part per feature can say it."""
    return np.where((table["width"] < 0.04) == (table["push"] > 0.5), 2.5, -2.5)


def labelled(n: int, seed: int) -> tuple[dict[str, np.ndarray], np.ndarray]:
    table, _, _ = synthetic(n, seed=seed)
    rng = np.random.default_rng(seed + 100)
    return table, (rng.random(n) < 1 / (1 + np.exp(-xor_truth(table)))).astype(float)


FEATS = ("push", "width", "epsilon")


def test_trees_find_an_interaction_the_additive_model_cannot() -> None:
    table, y = labelled(4000, 0)
    test, test_y = labelled(3000, 1)
    additive = fit(table, y, "panda", features=FEATS, l2=1e-3)
    boosted = fit(table, y, "panda", features=FEATS, l2=1e-3, trees=TreeSettings())
    assert additive.trees is None and boosted.trees is not None
    assert roc_auc(test_y, additive.predict(test)) < 0.6
    assert roc_auc(test_y, boosted.predict(test)) > 0.8


def test_the_term_is_scikit_learns_and_the_plain_walk_agrees() -> None:
    from sklearn.ensemble import GradientBoostingClassifier

    table, y = labelled(1500, 2)
    x = features.design(table, FEATS)
    margin = np.linspace(-1, 1, len(y))
    s = TreeSettings(n_trees=30)
    trees = fit_trees(x, y, margin, s)
    gb = GradientBoostingClassifier(init=_Margin(x, margin), n_estimators=s.n_trees, max_depth=s.depth,
                                    learning_rate=s.learning_rate, min_samples_leaf=s.min_leaf,
                                    subsample=s.subsample, random_state=s.seed).fit(x, y)
    assert_close(margin + trees.evaluate(x), gb.decision_function(x), 1e-6)
    assert trees.depth == s.depth and len(trees.roots) == s.n_trees


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.5, 1.5), st.floats(-0.05, 0.15), st.floats(-0.1, 0.2)), min_size=1,
                max_size=30))
def test_the_fast_evaluation_is_the_plain_one(rows: list[tuple[float, float, float]]) -> None:
    trees = _fitted().trees
    x = np.array(rows)
    assert_close(trees.evaluate(x), trees.evaluate_reference(x), SUM_TOL)


_CACHE: dict[str, LogisticModel] = {}


def _fitted() -> LogisticModel:
    if "m" not in _CACHE:
        table, y = labelled(1500, 3)
        _CACHE["m"] = fit(table, y, "panda", features=FEATS, l2=1e-3, trees=TreeSettings(n_trees=40))
    return _CACHE["m"]


def test_terms_add_up_to_the_logit_and_files_keep_the_trees(tmp_path: Path) -> None:
    model = _fitted()
    table, _ = labelled(200, 4)
    parts = model.terms(table)
    assert set(parts) == {*FEATS, INTERACTIONS}
    assert_close(model.intercept + sum(parts.values()), model.logit(table), SUM_TOL)
    path = tmp_path / "m.toml"
    path.write_text(model.to_toml())
    for again in (load_model(path), LogisticModel.from_json(model.to_json())):
        assert again.trees is not None
        assert_close(again.predict(table), model.predict(table), 0.0)
    assert LogisticModel.from_json(replace(model, trees=None).to_json()).trees is None


def test_bad_trees_are_refused_in_one_line() -> None:
    good = _fitted()
    t = good.trees.to_dict()
    out_of_range = dict(t, left=[len(t["left"]) + 5 if v != LEAF else v for v in t["left"]])
    with pytest.raises(InputError, match="children"):
        Trees.from_dict(out_of_range)
    too_many = dict(t, feature=[7 if v != LEAF else v for v in t["feature"]])
    with pytest.raises(InputError, match="trees split on input 7"):
        replace(good, trees=Trees.from_dict(too_many))
    with pytest.raises(InputError, match="learning_rate"):
        TreeSettings(learning_rate=0.0)


def test_cross_validation_with_trees_is_out_of_fold() -> None:
    table, y = labelled(2000, 5)
    groups = [f"object{i % 6}" for i in range(len(y))]
    cv = cross_validate(table, y, groups, "panda", features=FEATS, folds=3, grid=(1e-3,),
                        trees=TreeSettings(n_trees=40))
    assert roc_auc(y, cv.p) > 0.8


def test_trees_read_features_the_additive_part_does_not(tmp_path: Path) -> None:
    # a world where a grasp holds only where the object fills one cell of local_sdf (< 0: inside) and the
    # closed width is small: only trees that read that cell can tell
    cells = ("local_sdf_12", "local_sdf_40")

    def world(n: int, seed: int) -> tuple[dict[str, np.ndarray], np.ndarray]:
        table, _, _ = synthetic(n, seed=seed)
        rng = np.random.default_rng(seed + 7)
        for name in features.LOCAL:
            table[name] = rng.uniform(-0.02, 0.02, n)
        logit = np.where((table[cells[0]] < 0) & (table["width"] < 0.05), 2.5, -2.5)
        return table, (rng.random(n) < 1 / (1 + np.exp(-logit))).astype(float)

    table, y = world(4000, 5)
    test, test_y = world(3000, 6)
    plain = fit(table, y, "panda", features=FEATS, l2=1e-3, trees=TreeSettings(n_trees=100))
    seeing = fit(table, y, "panda", features=FEATS, l2=1e-3, trees=TreeSettings(n_trees=100, extra=cells))
    assert plain.tree_features == () and seeing.tree_features == cells
    assert roc_auc(test_y, seeing.predict(test)) > roc_auc(test_y, plain.predict(test)) + 0.1
    assert seeing.trees is not None and (seeing.trees.feature >= len(FEATS)).any()  # it splits on a cell
    path = tmp_path / "m.toml"
    path.write_text(seeing.to_toml())
    for again in (load_model(path), LogisticModel.from_json(seeing.to_json())):
        assert again.tree_features == cells
        assert_close(again.predict(test), seeing.predict(test), 0.0)
    # a table without the cells (a grasp whose hand declares no grid) reads them as "nothing near"
    bare = {k: v for k, v in test.items() if k not in features.LOCAL}
    filled = dict(bare, **{k: np.full(len(test_y), features.FILL[k]) for k in features.LOCAL})
    assert_close(seeing.predict(bare), seeing.predict(filled), 0.0)
    beyond = dict(seeing.trees.to_dict(), feature=[len(FEATS) + len(cells) if v != LEAF else v
                                                     for v in seeing.trees.feature.tolist()])
    with pytest.raises(InputError, match=f"trees split on input {len(FEATS) + len(cells)}, the model has 5 inputs"):
        replace(seeing, trees=Trees.from_dict(beyond))


def test_the_turned_hand_sees_the_same_grasp(tmp_path: Path) -> None:
    # the Panda turned half about its approach swaps its fingers: a world where a grasp holds where the
    # object fills either of two cells the turn swaps; the trees grow on both views and read their mean
    from planner.calibration.model import tree_turns
    from planner.specs.hands import load_hand

    (turn,) = load_hand("panda").cell_turns
    a = 12
    b = turn[a]

    def world(n: int, seed: int) -> tuple[dict[str, np.ndarray], np.ndarray]:
        table, _, _ = synthetic(n, seed=seed)
        rng = np.random.default_rng(seed + 7)
        for name in features.LOCAL:
            table[name] = rng.uniform(-0.02, 0.02, n)
        logit = np.where(np.minimum(table[features.LOCAL[a]], table[features.LOCAL[b]]) < -0.01, 2.5, -2.5)
        return table, (rng.random(n) < 1 / (1 + np.exp(-logit))).astype(float)

    table, y = world(3000, 5)
    model = fit(table, y, "panda", features=FEATS, l2=1e-3, trees=TreeSettings(n_trees=60, extra=features.LOCAL))
    (order,) = model.tree_turns
    assert order == tree_turns("panda", len(FEATS), features.LOCAL)[0]
    assert order[:len(FEATS)] == tuple(range(len(FEATS)))
    assert order[len(FEATS) + a] == len(FEATS) + b and order[len(FEATS) + b] == len(FEATS) + a
    test, test_y = world(2000, 6)
    turned = dict(test, **{features.LOCAL[i]: test[features.LOCAL[j]] for i, j in enumerate(turn)})
    assert_close(model.predict(turned), model.predict(test), SUM_TOL)  # the same grasp, the same p_hold
    assert roc_auc(test_y, model.predict(test)) > 0.8
    assert fit(table, y, "barrett", features=FEATS, l2=1e-3,
               trees=TreeSettings(n_trees=5, extra=features.LOCAL)).tree_turns == ()  # no grid, no turn
    assert tree_turns("panda", len(FEATS), features.LOCAL[:10]) == ()  # their twins are not read
    path = tmp_path / "m.toml"
    path.write_text(model.to_toml())
    for again in (load_model(path), LogisticModel.from_json(model.to_json())):
        assert again.tree_turns == model.tree_turns
        assert_close(again.predict(test), model.predict(test), 0.0)
    with pytest.raises(InputError, match="each of tree_turns must order the trees' 78 inputs"):
        replace(model, tree_turns=((0,) * (len(FEATS) + 75),))


def test_a_walk_stays_at_a_leaf_reached_early_and_nan_goes_right() -> None:
    """Three trees of depth 2, 1 and 0 (a root that is a leaf): every grasp reaches its leaf of each whatever
    the depth walked; a NaN input is not <= any threshold (goes right), as in scikit-learn's float32 walk."""
    # tree 0: node 0 splits input 1 at 0.5 -> node 1 (splits input 0 at 0.0 -> leaves 3, 4) | leaf 2
    # tree 1: node 5 splits input 0 at 1.0 -> leaves 6 | 7;  tree 2: node 8 a leaf
    trees = Trees(roots=np.array([0, 5, 8]), feature=np.array([1, 0, LEAF, LEAF, LEAF, 0, LEAF, LEAF, LEAF]),
                  threshold=np.array([0.5, 0.0, -2, -2, -2, 1.0, -2, -2, -2]),
                  left=np.array([1, 3, LEAF, LEAF, LEAF, 6, LEAF, LEAF, LEAF]),
                  right=np.array([2, 4, LEAF, LEAF, LEAF, 7, LEAF, LEAF, LEAF]),
                  value=np.array([0, 0, 4.0, 1.0, 2.0, 0, 16.0, 32.0, 64.0]))
    x = np.array([[-1.0, 0.0], [0.5, 0.5], [2.0, 0.7], [np.nan, 0.0], [0.0, np.nan]])
    want = np.array([1 + 16 + 64, 2 + 16 + 64, 4 + 32 + 64, 2 + 32 + 64, 4 + 16 + 64], float)
    assert trees.depth == 2
    np.testing.assert_array_equal(trees.evaluate(x), want)
    np.testing.assert_array_equal(trees.evaluate_reference(x), want)
    np.testing.assert_array_equal(trees.evaluate(np.asfortranarray(x)), want)
    assert trees.evaluate(np.zeros((0, 2))).shape == (0,)
