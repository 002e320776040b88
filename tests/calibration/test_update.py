"""p_hold given a trial's verdict: the fit recovers a known update, the update
orders as it should, the model applies the verdict of the trial that comes
first, and the update survives TOML and JSON."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.calibration.logistic import LogisticModel, load_model
from planner.calibration.update import TrialUpdate, fit_update, logit
from planner.errors import InputError


def simulated(n: int, slope: float, verdict: float, intercept: float, seed: int) -> tuple[np.ndarray, ...]:
    """(p_hold, held, labels) drawn from a known update."""
    rng = np.random.default_rng(seed)
    p = rng.uniform(0.02, 0.98, n)
    held = (rng.uniform(size=n) < p).astype(float)  # a verdict that follows p_hold, as a trial does
    truth = TrialUpdate("mujoco", slope, verdict, intercept).apply(p, held)
    return p, held, (rng.uniform(size=n) < truth).astype(float)


def test_the_fit_recovers_a_known_update() -> None:
    p, held, y = simulated(40_000, 0.8, 2.0, -1.5, seed=3)
    u = fit_update("mujoco", p, held, y)
    assert abs(u.slope - 0.8) < 0.08 and abs(u.verdict - 2.0) < 0.12 and abs(u.intercept - (-1.5)) < 0.12
    assert u.grasps == 40_000
    assert u.agreement == pytest.approx(np.mean((u.apply(p, held) >= 0.5) == (y == 1)))


@settings(max_examples=60, deadline=None)
@given(st.floats(0.01, 0.99), st.floats(0.01, 0.99), st.floats(0.1, 2.0), st.floats(0.1, 4.0), st.floats(-3, 3))
def test_the_update_rises_with_p_hold_and_with_holding(p1: float, p2: float, slope: float, verdict: float,
                                                       intercept: float) -> None:
    u = TrialUpdate("mujoco", slope, verdict, intercept)
    lo, hi = sorted((p1, p2))
    for held in (0.0, 1.0):
        a, b = u.apply(np.array([lo, hi]), np.array([held, held]))
        assert a <= b + 1e-12
    dropped, kept = u.apply(np.array([p1, p1]), np.array([0.0, 1.0]))
    assert dropped < kept and 0.0 < dropped < 1.0
    assert dropped <= p1 <= kept  # an informative verdict: held never lowers p_hold, dropped never raises it


def test_a_held_grasp_near_certainty_stays_above_an_untried_one_of_the_same_p_hold() -> None:
    u = TrialUpdate("mujoco", 0.85, 2.0, -1.5)
    p = np.array([0.99999, 0.99999])
    held, dropped = u.apply(p, np.array([1.0, 0.0]))
    assert held == pytest.approx(0.99999) and dropped < 0.9999
    assert u.apply(np.array([0.3]), np.array([1.0]))[0] > 0.3  # below the crossing the logistic itself lifts it
    inverse = TrialUpdate("mujoco", 1.0, -1.0, 0.0)  # a verdict against the labels: no such bound
    assert inverse.apply(np.array([0.5]), np.array([1.0]))[0] < 0.5


def model_with(updates: dict[str, TrialUpdate]) -> LogisticModel:
    return LogisticModel("panda", ("epsilon",), np.array([0.0]), np.array([1.0]), np.array([0.0]), 0.0, 0.0,
                         updates=updates)


def test_the_verdict_of_the_first_trial_in_precedence_updates_p_hold() -> None:
    mujoco = TrialUpdate("mujoco", 1.0, 2.0, -1.0)
    pybullet = TrialUpdate("validation", 0.5, 1.0, 0.0)
    p = np.array([0.6, 0.6, 0.6, 0.6, np.nan])
    verdicts = {"mujoco": np.array([1, -1, np.nan, 0, 1]), "validation": np.array([0, 1, -1, 1, 1])}
    q = model_with({"mujoco": mujoco, "validation": pybullet}).given_trial(p, verdicts)
    expected = [mujoco.apply(p[:1], [1])[0], pybullet.apply(p[:1], [1])[0], math.nan, mujoco.apply(p[:1], [0])[0],
                math.nan]
    assert np.allclose(q, expected, equal_nan=True)
    # MuJoCo tried the first and fourth: without its update they stay without p_hold_trial (not PyBullet's instead)
    q = model_with({"validation": pybullet}).given_trial(p, verdicts)
    assert np.isnan(q[[0, 2, 3, 4]]).all() and q[1] == pytest.approx(pybullet.apply(p[:1], [1])[0])
    assert np.isnan(model_with({}).given_trial(p, verdicts)).all()


def test_updates_survive_toml_and_json(tmp_path) -> None:
    m = model_with({"mujoco": TrialUpdate("mujoco", 0.85, 1.99, -1.52, 9200, 0.865)})
    path = tmp_path / "m.toml"
    path.write_text(m.to_toml())
    for back in (load_model(path), LogisticModel.from_json(m.to_json())):
        assert back.updates == m.updates
    assert model_with({}).to_dict().get("updates") is None


def test_bad_updates_are_refused() -> None:
    with pytest.raises(InputError, match="finite"):
        TrialUpdate("mujoco", math.nan, 1.0, 0.0)
    with pytest.raises(InputError, match="keyed by its own engine"):
        model_with({"validation": TrialUpdate("mujoco", 1.0, 1.0, 0.0)})
    with pytest.raises(InputError, match="0 or 1"):
        fit_update("mujoco", np.array([0.5]), np.array([2.0]), np.array([1.0]))
    assert np.isfinite(logit(np.array([0.0, 1.0]))).all()
