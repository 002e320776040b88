"""The model's columns from its feature inputs: each input held within the
range of the fitting data (:func:`clip`, :func:`fitting_bounds`), and a
spline feature's restricted cubic spline columns (:func:`spline_basis`) on
knots at Harrell's quantiles (:func:`choose_knots`), side by side
(:func:`expand`, named by :func:`columns`). Pure numpy.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

#: Knots per spline feature unless told otherwise (:func:`choose_knots`).
KNOTS = 4
#: Knots at these quantiles of a feature's training inputs (Harrell's for 4 knots).
KNOT_QUANTILES = {3: (0.10, 0.50, 0.90), 4: (0.05, 0.35, 0.65, 0.95), 5: (0.05, 0.275, 0.50, 0.725, 0.95)}
#: A feature whose spread is below this is constant in the data: its scale is 1 (coefficient ~0 by the penalty).
MIN_SCALE = 1e-12


def columns(features: Sequence[str], knots: Mapping[str, Sequence[float]]) -> tuple[str, ...]:
    """Column names of :func:`expand`: each feature, then ``feature~1`` .. for its spline columns."""
    out: list[str] = []
    for f in features:
        out.append(f)
        out += [f"{f}~{j}" for j in range(1, len(knots[f]) - 1)] if f in knots else []
    return tuple(out)


def spline_basis(x: np.ndarray, knots: Sequence[float]) -> np.ndarray:
    """(n, len(knots) - 2) restricted cubic spline columns of ``x`` (n,)
    (Harrell, Regression Modeling Strategies, sec. 2.4.5): for inner knot
    j, ``(x - t_j)+^3 - (x - t_{k-1})+^3 (t_k - t_j) / (t_k - t_{k-1})
    + (x - t_k)+^3 (t_{k-1} - t_j) / (t_k - t_{k-1})``, divided by
    ``(t_k - t_1)^2`` to keep it in x's units; with x itself they span the
    cubic splines on the knots that are linear beyond the outer ones."""
    t = np.asarray(knots, float)
    x = np.asarray(x, float)[:, None]
    k = len(t)

    def cube(v: np.ndarray) -> np.ndarray:
        return np.maximum(v, 0.0) ** 3

    inner = t[:k - 2][None, :]
    span = t[k - 1] - t[k - 2]
    out = (cube(x - inner) - cube(x - t[k - 2]) * (t[k - 1] - inner) / span
           + cube(x - t[k - 1]) * (t[k - 2] - inner) / span)
    return out / (t[k - 1] - t[0]) ** 2


def clip(x: np.ndarray, features: Sequence[str], bounds: Mapping[str, tuple[float, float]]) -> np.ndarray:
    """(n, len(features)) the inputs ``x`` each held within its feature's ``bounds`` (NaN stays NaN)."""
    out = np.array(x, float, copy=True)
    for i, f in enumerate(features):
        if f in bounds:
            out[:, i] = np.clip(out[:, i], *bounds[f])
    return out


def fitting_bounds(x: np.ndarray, features: Sequence[str]) -> dict[str, tuple[float, float]]:
    """Each feature's (low, high) over the fitting inputs ``x`` (n, len(features)), NaN ignored."""
    out = {}
    for i, f in enumerate(features):
        v = x[:, i][np.isfinite(x[:, i])]
        if len(v):
            out[f] = (float(v.min()), float(v.max()))
    return out


def expand(x: np.ndarray, features: Sequence[str], knots: Mapping[str, Sequence[float]]) -> np.ndarray:
    """(n, len(columns)) model columns of the feature inputs ``x`` (n, len(features))."""
    parts = []
    for i, f in enumerate(features):
        parts.append(x[:, i:i + 1])
        if f in knots:
            parts.append(spline_basis(x[:, i], knots[f]))
    return np.hstack(parts) if parts else np.zeros((len(x), 0))


def choose_knots(x: np.ndarray, features: Sequence[str], splines: Sequence[str], count: int = KNOTS
                 ) -> dict[str, tuple[float, ...]]:
    """Knots of each spline feature at Harrell's quantiles of its inputs
    ``x`` (n, len(features)); a feature with too few distinct values there
    stays linear."""
    out = {}
    for i, f in enumerate(features):
        if f not in splines:
            continue
        t = np.unique(np.quantile(x[:, i], KNOT_QUANTILES[count]))
        if len(t) == count and np.all(np.diff(t) > MIN_SCALE):
            out[f] = tuple(float(v) for v in t)
    return out


def _sigmoid(z: np.ndarray) -> np.ndarray:
    """The logistic function, overflow-free."""
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(z, float)))
