"""ROC AUC, expected calibration error, reliability table and grouped folds: known answers and properties."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.calibration.metrics import (
    expected_calibration_error,
    group_interval,
    grouped_folds,
    object_figures,
    reliability,
    roc_auc,
)

#: ECE of a perfectly calibrated synthetic set of N_CALIBRATED grasps: sampling noise of ~10 bins of ~1e4
#: grasps each is ~sqrt(p (1 - p) / 1e4) <= 0.005.
N_CALIBRATED = 100_000
ECE_NOISE = 0.01


def test_a_perfectly_calibrated_set_has_ece_near_zero() -> None:
    rng = np.random.default_rng(0)
    p = rng.random(N_CALIBRATED)
    y = (rng.random(N_CALIBRATED) < p).astype(float)
    assert expected_calibration_error(y, p) < ECE_NOISE


def test_a_constant_overconfident_prediction_has_ece_of_its_gap() -> None:
    y = np.array([1, 0, 1, 0], float)  # observed 0.5
    assert abs(expected_calibration_error(y, np.full(4, 0.9)) - 0.4) < 1e-12


def test_reliability_bins_count_every_grasp_once_and_edges_go_to_the_last_bin() -> None:
    p = np.array([0.0, 0.05, 0.1, 0.95, 1.0])
    r = reliability(np.array([0, 0, 1, 1, 1], float), p)
    assert r.count.sum() == 5 and r.count[0] == 2 and r.count[1] == 1 and r.count[-1] == 2
    assert np.isnan(r.predicted[5]) and r.observed[-1] == 1.0


@given(st.lists(st.floats(0, 1), min_size=5, max_size=60), st.integers(0, 2**32 - 1))
@settings(max_examples=40, deadline=None)
def test_auc_is_invariant_under_monotone_maps_and_flips_with_the_score(scores: list[float], seed: int) -> None:
    rng = np.random.default_rng(seed)
    x = np.array(scores)
    y = (rng.random(len(x)) < 0.5).astype(float)
    if y.min() == y.max():
        y[0] = 1 - y[0]
    auc = roc_auc(y, x)
    assert abs(roc_auc(y, 2.0 * x) - auc) < 1e-12  # an exact monotone map (no ties made or broken)
    assert abs(roc_auc(y, -x) - (1 - auc)) < 1e-12


def test_rejected_poses_scored_minus_infinity_rank_lowest() -> None:
    y = np.array([1, 1, 0, 0], float)
    assert roc_auc(y, np.array([0.2, 0.1, -np.inf, -np.inf])) == 1.0


@given(st.lists(st.sampled_from("abcdefg"), min_size=7, max_size=80), st.integers(2, 4))
@settings(max_examples=40, deadline=None)
def test_grouped_folds_partition_the_rows_and_never_split_a_group(groups: list[str], k: int) -> None:
    if len(set(groups)) < k:
        groups = groups + list("abcdefg")
    folds = grouped_folds(groups, k)
    rows = np.sort(np.concatenate(folds))
    assert np.array_equal(rows, np.arange(len(groups)))
    owner = {}
    for f, test in enumerate(folds):
        for i in test:
            assert owner.setdefault(groups[i], f) == f


# -- intervals over objects -------------------------------------------------------------------------------------
#: Relative tolerance of a bootstrap interval's half-width against the normal theory's 1.96 sigma / sqrt(n)
#: (2,000 draws of 400 objects: the percentiles' own noise is a few percent).
HALF_WIDTH_TOL = 0.15


def test_the_interval_of_a_mean_over_objects_matches_normal_theory_and_shrinks_with_more_objects() -> None:
    values = np.random.default_rng(1).normal(0.8, 0.05, 400)
    lo, hi = group_interval(lambda picked: float(values[picked].mean()), len(values), np.random.default_rng(0))
    expected = 1.96 * values.std() / np.sqrt(len(values))
    assert lo < values.mean() < hi
    assert abs((hi - lo) / 2 - expected) < HALF_WIDTH_TOL * expected
    few = values[:25]
    lo_few, hi_few = group_interval(lambda picked: float(few[picked].mean()), len(few), np.random.default_rng(0))
    assert hi_few - lo_few > 3 * (hi - lo)  # sqrt(400 / 25) = 4 times wider in theory


def test_the_same_figure_on_every_object_has_no_spread_and_no_objects_give_nan() -> None:
    lo, hi = group_interval(lambda picked: 0.7, 12, np.random.default_rng(0))
    assert lo == hi == 0.7
    assert all(np.isnan(group_interval(lambda picked: 0.7, 0, np.random.default_rng(0))))
    assert all(np.isnan(group_interval(lambda picked: float("nan"), 5, np.random.default_rng(0))))


def test_the_interval_draws_objects_not_grasps() -> None:
    """Ten objects of 1,000 grasps each, p >= 0.5 right on every grasp of five objects and wrong on every grasp of
    the other five: over grasps the agreement would look sure (0.5 +- 0.01); over objects it is not."""
    groups = np.repeat([f"o{i}" for i in range(10)], 1000)
    labels = np.tile([1.0, 0.0], 5000)
    right = np.repeat(np.arange(10) < 5, 1000)
    p = np.where(right, labels, 1.0 - labels) * 0.8 + 0.1
    files = groups.copy()
    got = object_figures(labels, p, groups, files, np.ones(len(p), bool), 10, np.random.default_rng(0))
    assert got["agreement_lo"] < 0.3 and got["agreement_hi"] > 0.7
    assert got["auc_mean_lo"] < 0.3 and got["auc_mean_hi"] > 0.7


def test_a_perfect_prediction_has_a_point_interval_and_every_figure_has_both_ends() -> None:
    rng = np.random.default_rng(3)
    groups = np.repeat(["a", "b", "c", "d"], 50)
    labels = (rng.random(200) < 0.5).astype(float)
    got = object_figures(labels, labels, groups, groups, np.ones(200, bool), 10, np.random.default_rng(0))
    assert set(got) == {f"{n}_{e}" for n in ("auc_mean", "top10", "ece", "agreement") for e in ("lo", "hi")}
    assert got["auc_mean_lo"] == got["auc_mean_hi"] == 1.0
    assert got["agreement_lo"] == got["agreement_hi"] == 1.0
    assert got["top10_lo"] == got["top10_hi"] == 1.0
