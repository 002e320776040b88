"""ROC AUC, expected calibration error, reliability table and grouped folds: known answers and properties."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.calibration.metrics import expected_calibration_error, grouped_folds, reliability, roc_auc

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
