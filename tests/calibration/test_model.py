"""The p_hold model: fit, monotone behaviour, invariances, round trips, grouped cross-validation."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from planner.calibration import features
from planner.calibration.metrics import expected_calibration_error, roc_auc
from planner.calibration.model import LogisticModel, cross_validate, fit, load_model, spline_basis
from planner.errors import InputError
from tests.helpers import assert_close

#: Predictions of models fitted on the same data differ by L-BFGS's stopping tolerance at most.
FIT_TOL = 1e-4


def synthetic(n: int, seed: int = 0, groups: int = 8) -> tuple[dict[str, np.ndarray], np.ndarray, list[str]]:
    """Grasps whose true log-odds are 4 (push - 0.5) + 2 epsilon / 0.1 - 1: labels drawn from them."""
    rng = np.random.default_rng(seed)
    table = {name: np.zeros(n) for name in features.MEASURES}
    table["push"] = rng.random(n)
    table["epsilon"] = rng.random(n) * 0.1
    table["force_closure"] = (table["epsilon"] > 0.01).astype(float)
    table["resist_worst"] = rng.exponential(20, n)
    table["resist_mean"] = table["resist_worst"] * 2
    table["open_margin"] = rng.random(n) * 0.03
    table["close_margin"] = np.full(n, np.inf)  # a finger not touching: inf
    table["width"] = rng.random(n) * 0.08
    table["n_contacts"] = rng.integers(2, 10, n).astype(float)
    table["links_touching"] = np.full(n, 2.0)
    table["settled_epsilon"] = np.full(n, np.nan)  # not measured
    z = 4 * (table["push"] - 0.5) + 20 * table["epsilon"] - 1
    y = (rng.random(n) < 1 / (1 + np.exp(-z))).astype(float)
    return table, y, [f"object{i % groups}" for i in range(n)]


def test_fit_recovers_a_logistic_truth_calibrated() -> None:
    table, y, _ = synthetic(6000)
    model = fit(table, y, "panda", l2=1e-4, splines=())  # linear terms: push's coefficient is the truth's slope
    push = model.columns.index("push")
    assert model.coef[push] / model.scale[push] == pytest.approx(4.0, rel=0.2)
    test_table, test_y, _ = synthetic(6000, seed=1)
    assert expected_calibration_error(test_y, model.predict(test_table)) < 0.03


def test_p_hold_rises_with_a_feature_whose_coefficient_is_positive() -> None:
    table, y, _ = synthetic(2000)
    model = fit(table, y, "panda")
    probe = {k: np.repeat(v[:1], 5) for k, v in table.items()}
    probe["push"] = np.linspace(0, 1, 5)
    p = model.predict(probe)
    assert np.all(np.diff(p) > 0) and np.all((0 <= p) & (p <= 1))


def test_fit_is_invariant_to_row_order_and_to_the_units_of_a_feature() -> None:
    table, y, _ = synthetic(1500)
    base = fit(table, y, "panda", l2=1e-2).predict(table)
    order = np.random.default_rng(3).permutation(len(y))
    shuffled = fit({k: v[order] for k, v in table.items()}, y[order], "panda", l2=1e-2).predict(table)
    assert_close(shuffled, base, FIT_TOL)
    # width in mm instead of m: standardisation makes the model the same
    mm = dict(table, width=table["width"] * 1000)
    assert_close(fit(mm, y, "panda", l2=1e-2).predict(mm), base, FIT_TOL)


def test_a_constant_feature_gets_no_weight_and_missing_measures_take_their_fill() -> None:
    table, y, _ = synthetic(1000)
    model = fit(table, y, "panda")
    links = model.columns.index("links_touching")
    assert model.coef[links] == pytest.approx(0.0, abs=1e-6)
    x = features.design(table, ["settled_epsilon", "close_margin"])
    assert np.all(x[:, 0] == features.FILL["settled_epsilon"]) and np.all(x[:, 1] == features.MARGIN_CAP)


def test_model_round_trips_through_toml_and_json(tmp_path) -> None:
    table, y, _ = synthetic(800)
    model = fit(table, y, "panda", source="synthetic")
    path = tmp_path / "panda.toml"
    path.write_text(model.to_toml())
    assert model.knots  # the default splines travel with the model
    for back in (load_model(path), LogisticModel.from_json(model.to_json())):
        assert back.features == model.features and back.source == "synthetic" and back.knots == model.knots
        assert back.bounds == model.bounds and model.bounds["push"][1] <= 1.0
        assert_close(back.predict(table), model.predict(table), 1e-12)


def test_the_domain_travels_with_the_model_and_says_where_an_object_lies_outside(tmp_path) -> None:
    table, y, _ = synthetic(400)
    model = replace(fit(table, y, "panda"), domain={"density": (150.0, 157.0), "friction": (1.0, 1.0),
                                                    "mass": (0.002, 0.5)})
    path = tmp_path / "panda.toml"
    path.write_text(model.to_toml())
    for back in (load_model(path), LogisticModel.from_json(model.to_json())):
        assert back.domain == model.domain
    assert model.outside({"density": 151.0, "friction": 1.0, "mass": 0.3}) == []
    assert model.outside({"density": 158.0, "friction": 1.01, "mass": 0.505}) == []  # within the slack
    assert model.outside({"density": 1320.0, "friction": 0.5, "mass": 0.3}) == [
        "density 1,320 kg/m^3 (labels: 150-157 kg/m^3)", "friction 0.5 (labels: 1)"]
    assert model.outside({"density": 150.0, "friction": 1.0, "mass": 0.9}) == ["mass 0.9 kg (labels: 0.002-0.5 kg)"]
    assert replace(model, domain={}).outside({"density": 1320.0, "friction": 0.5, "mass": 0.3}) == []  # not known
    assert "domain" not in replace(model, domain={}).to_dict()


def test_bad_models_are_refused_with_a_message() -> None:
    with pytest.raises(InputError, match="domain of friction"):
        LogisticModel("panda", ("push",), np.zeros(1), np.ones(1), np.zeros(1), 0.0, 0.0, domain={"friction": (1, 0.5)})
    with pytest.raises(InputError, match="domain of colour"):
        LogisticModel("panda", ("push",), np.zeros(1), np.ones(1), np.zeros(1), 0.0, 0.0, domain={"colour": (1, 2)})
    with pytest.raises(InputError, match="one per column"):
        LogisticModel("panda", ("push",), np.zeros(2), np.ones(1), np.zeros(1), 0.0, 0.0)
    with pytest.raises(InputError, match="unknown feature"):
        LogisticModel("panda", ("nonsense",), np.zeros(1), np.ones(1), np.zeros(1), 0.0, 0.0)
    with pytest.raises(InputError, match="bounds of width"):
        LogisticModel("panda", ("width",), np.zeros(1), np.ones(1), np.zeros(1), 0.0, 0.0, bounds={"width": (0.2, 0.1)})
    with pytest.raises(InputError, match="knots"):
        LogisticModel("panda", ("width",), np.zeros(2), np.ones(2), np.zeros(2), 0.0, 0.0,
                      knots={"width": (0.1, 0.0, 0.2)})


def test_inputs_beyond_the_fitting_data_are_held_at_its_ends() -> None:
    table, y, _ = synthetic(1500)
    model = fit(table, y, "panda")
    low, high = model.bounds["push"]
    assert low == table["push"].min() and high == table["push"].max()
    free = LogisticModel(**{**model.__dict__, "bounds": {}})
    assert_close(model.predict(table), free.predict(table), 1e-12)  # inside the data: the fit itself
    probe = {k: np.repeat(v[:1], 3) for k, v in table.items()}
    probe["push"] = np.array([high, 5.0, 50.0])  # far beyond: a line would go on rising
    p = model.predict(probe)
    assert p[1] == p[0] and p[2] == p[0]
    assert free.predict(probe)[2] > p[0]


@given(st.lists(st.floats(-5, 5), min_size=3, max_size=5, unique=True), st.floats(6, 50), st.floats(0.1, 3))
def test_a_spline_is_linear_beyond_its_outer_knots(knots, far, step) -> None:
    t = np.sort(np.array(knots))
    assume(np.all(np.diff(t) > 0.05))
    for x in (np.array([t[-1] + far, t[-1] + far + step, t[-1] + far + 2 * step]),
              np.array([t[0] - far - 2 * step, t[0] - far - step, t[0] - far])):
        b = spline_basis(x, t)
        assert_close(b[2] - b[1], b[1] - b[0], 1e-6 * max(1.0, float(np.abs(b).max())))  # equal steps: a line
    b = spline_basis(np.linspace(t[0] - 1, t[0], 5), t)
    assert_close(b, np.zeros_like(b), 0.0)  # below the first knot every spline column is 0


def test_splines_find_a_middle_optimum_a_line_cannot() -> None:
    rng = np.random.default_rng(5)
    table, _, _ = synthetic(6000)
    z = 2.0 - ((table["width"] - 0.04) / 0.015) ** 2  # a middle width holds best
    y = (rng.random(len(z)) < 1 / (1 + np.exp(-z))).astype(float)
    test, _, _ = synthetic(4000, seed=9)
    truth = 2.0 - ((test["width"] - 0.04) / 0.015) ** 2
    curved = fit(table, y, "panda", features=("width",), splines=("width",), l2=1e-4)
    line = fit(table, y, "panda", features=("width",), splines=(), l2=1e-4)
    assert "width" in curved.knots and curved.columns == ("width", "width~1", "width~2")
    assert np.corrcoef(curved.logit(test), truth)[0, 1] > 0.95 > np.corrcoef(line.logit(test), truth)[0, 1]
    parts = curved.terms(test)
    assert_close(curved.intercept + parts["width"], curved.logit(test), 1e-9)


def test_grouped_cross_validation_predicts_out_of_fold_and_close_to_the_truth() -> None:
    table, y, groups = synthetic(3000)
    cv = cross_validate(table, y, groups, "panda", folds=4, grid=(1e-3, 1e-1))
    assert len(set(cv.fold.tolist())) == 4 and cv.l2.shape == (4,)
    for f in range(4):  # a group's grasps are all in one fold
        assert len({groups[i] for i in np.flatnonzero(cv.fold == f)} &
                   {groups[i] for i in np.flatnonzero(cv.fold != f)}) == 0
    assert roc_auc(y, cv.p) > 0.75 and expected_calibration_error(y, cv.p) < 0.05


def test_one_penalty_given_is_not_chosen_by_an_inner_cross_validation(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """With one penalty there is nothing to choose: the inner grouped CV still fitted it once per fold (5 fits
    of each outer fold's training set, for the same answer)."""
    from planner.calibration import model as model_module

    table, y, groups = synthetic(400)
    calls = []
    real_fit = model_module.fit

    def counting_fit(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(kwargs.get("l2"))
        return real_fit(*args, **kwargs)

    monkeypatch.setattr(model_module, "fit", counting_fit)
    assert model_module.choose_l2(table, y, groups, "panda", grid=(0.3,)) == 0.3
    assert calls == []
    assert model_module.choose_l2(table, y, groups, "panda", grid=(0.3, 3.0), splines=()) in (0.3, 3.0)
    assert len(calls) == 2 * 5  # two penalties, five folds each


def test_a_fitted_model_names_its_label_files_and_they_travel_with_it(tmp_path) -> None:
    """A model's source named no files (the shipped one's: "46 files of ../shared/labelled/acronym_dev"), so an
    imported file's labels it was fitted on could not be told in-sample: the fit records them."""
    from planner.calibration.fitting import calibrate
    from planner.calibration.labels import LabelledSet

    table, y, groups = synthetic(400, groups=4)
    files = tuple(f"{g}_0.5.h5" for g in groups)
    model = calibrate(LabelledSet(table, y, tuple(groups), files, "panda"), folds=2, trees=None).model
    assert model.labels == tuple(sorted(set(files)))
    path = tmp_path / "panda.toml"
    path.write_text(model.to_toml())
    for back in (load_model(path), LogisticModel.from_json(model.to_json())):
        assert back.labels == model.labels
    assert "labels" not in replace(model, labels=()).to_dict()  # a model without them: the same JSON as before


def test_a_fitted_model_records_its_label_files_hashes_and_they_travel_with_it(tmp_path) -> None:
    """A model named its files alone: another file of one of those names was taken for it. The fit records each
    file's sha256 (``LabelledSet.hashes``) beside its name, in the names' order, through TOML and JSON."""
    from planner.calibration.fitting import calibrate
    from planner.calibration.labels import LabelledSet

    table, y, groups = synthetic(400, groups=4)
    files = tuple(f"{g}_0.5.h5" for g in groups)
    hashes = {name: f"{i:064x}" for i, name in enumerate(sorted(set(files), reverse=True))}
    model = calibrate(LabelledSet(table, y, tuple(groups), files, "panda", hashes=hashes), folds=2, trees=None).model
    assert model.label_hashes == tuple(hashes[name] for name in model.labels) and len(model.labels) == 4
    path = tmp_path / "panda.toml"
    path.write_text(model.to_toml(), encoding="ascii")
    for back in (load_model(path), LogisticModel.from_json(model.to_json())):
        assert back.label_hashes == model.label_hashes and back.labels == model.labels
    assert "label_hashes" not in replace(model, label_hashes=()).to_dict()  # none: the same JSON as before
    assert calibrate(LabelledSet(table, y, tuple(groups), files, "panda"), folds=2, trees=None).model.label_hashes == ()
    with pytest.raises(InputError, match="label_hashes"):
        replace(model, label_hashes=model.label_hashes[:3])
    with pytest.raises(InputError, match="label_hashes"):
        replace(model, label_hashes=("not a hash",) * 4)


def test_a_model_whose_label_files_have_any_names_reads_back_from_its_toml(tmp_path) -> None:
    """The label files' names were written as JSON strings: a name beyond U+FFFF (an emoji) became two surrogate
    escapes TOML refuses, so `grasp calibrate --model-out` wrote a model no one could read back."""
    table, y, groups = synthetic(200, groups=4)
    model = replace(fit(table, y, "panda", l2=1.0), labels=("mug😀.h5", "tasse_é.h5", 'a"b\\c.h5', "plain.h5"))
    path = tmp_path / "panda.toml"
    path.write_text(model.to_toml(), encoding="ascii")
    assert load_model(path).labels == model.labels
