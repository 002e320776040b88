"""Robust epsilon: deterministic for a seed, the quantile below the mean."""

from __future__ import annotations

import numpy as np

from planner.validation.robust import NoiseSettings, epsilon_samples, robust_epsilon, summarise


def test_robust_epsilon_is_deterministic(setup, firm) -> None:  # type: ignore[no-untyped-def]
    hand, _, obj = setup
    noise = NoiseSettings(samples=4)
    values_a = epsilon_samples(hand, obj, firm, np.random.default_rng(3), noise)
    values_b = epsilon_samples(hand, obj, firm, np.random.default_rng(3), noise)
    a, b = summarise(values_a, noise.quantile), summarise(values_b, noise.quantile)
    assert a.mean == b.mean and np.array_equal(values_a, values_b) and a.samples == len(values_a) == 4
    assert 0.0 <= a.quantile <= a.mean
    assert robust_epsilon(hand, obj, firm, np.random.default_rng(3), noise) == a


def test_summary_of_known_samples() -> None:
    r = summarise(np.array([0.0, 0.1, 0.2, 0.3, 0.4]), 0.25)
    assert (r.mean, r.quantile, r.samples) == (0.2, 0.1, 5)
