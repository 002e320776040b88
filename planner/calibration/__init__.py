"""Calibration: a probability of holding per grasp (``p_hold``) fitted to
external labels, and how well it predicts them (issue 26).

- :mod:`~planner.calibration.features`: the stored analytic measures as the model's inputs;
- :mod:`~planner.calibration.model`: the logistic model's fit and grouped cross-validation;
- :mod:`~planner.calibration.logistic`: the fitted model as a value, its TOML/JSON and the shipped default;
- :mod:`~planner.calibration.basis`: the model's columns (inputs held within bounds, spline columns, knots);
- :mod:`~planner.calibration.trees`: the interaction term, trees boosted on the additive model's log-odds;
- :mod:`~planner.calibration.metrics`: ROC AUC, expected calibration error, reliability table, folds;
- :mod:`~planner.calibration.labels`: labelled grasp files (ACRONYM layout) -> measures and labels;
- :mod:`~planner.calibration.plot`: the reliability diagram (matplotlib, PNG).

Pure numpy/scipy except the plot, the labels' re-scoring and fitting the trees (scikit-learn).
"""
