"""A calibrated probability of holding, ``p_hold``, from the analytic measures.

The model is a logistic regression on standardised features
(:mod:`planner.calibration.features`) with an L2 penalty on the
coefficients (not the intercept), fitted by L-BFGS on the mean log-loss::

    z = (x - mean) / scale;   p_hold = 1 / (1 + exp(-(intercept + z . coef)))

A feature with knots enters as a restricted cubic spline (Harrell's: cubic
between its knots, linear beyond the outer ones, so a new object's values
outside the training range are extrapolated by a line, not a cubic): its
input x and one column per inner knot (:func:`spline_basis`), each with its
own coefficient. Beyond the range of the fitting data (``bounds``) an
input is held at the nearest end: a line fitted on nothing out there would
otherwise drive p_hold to 0 or 1 with certainty it never earned. The model stays additive, one term per feature (a
generalised additive model), so ``--explain`` still gives each feature's
part of the log-odds.

:func:`fit` fits one; :func:`cross_validate` gives out-of-fold predictions
over folds grouped by object, choosing the penalty inside each training
fold (nested), so the figures it yields are held-out ones. A model is a
frozen value stored as TOML (the shipped default, ``calibration/<hand>.toml``
beside ``hands/``) or as JSON in a database (:mod:`planner.db.store`).
"""

from __future__ import annotations

import functools
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from planner.assets import project_dir
from planner.calibration.features import FEATURES, PRODUCTS, design
from planner.calibration.metrics import Reliability, grouped_folds
from planner.errors import InputError

#: The features a model uses unless told otherwise.
DEFAULT_FEATURES = ("epsilon", "force_closure", "log_resist_worst", "log_resist_mean", "open_margin", "close_margin",
                    "push", "width", "n_contacts", "links_touching", "settled_epsilon", "depth", "log_pad_area",
                    "pad_alignment", "opposition", "log_jaw_fill", "palm_gap", "com_lever")
#: The features that enter as splines unless told otherwise (:func:`spline_basis`), with this many knots.
DEFAULT_SPLINES = ("epsilon", "log_resist_worst", "open_margin", "push", "width", "depth", "log_pad_area",
                   "pad_alignment", "opposition", "log_jaw_fill", "palm_gap", "com_lever")
KNOTS = 4
#: Knots at these quantiles of a feature's training inputs (Harrell's for 4 knots).
KNOT_QUANTILES = {3: (0.10, 0.50, 0.90), 4: (0.05, 0.35, 0.65, 0.95), 5: (0.05, 0.275, 0.50, 0.725, 0.95)}
#: L2 penalties tried by cross-validation (per grasp of the mean log-loss, on standardised features).
L2_GRID = (1e-4, 1e-3, 1e-2, 1e-1, 1.0)
#: A feature whose spread is below this is constant in the data: its scale is 1 (coefficient ~0 by the penalty).
MIN_SCALE = 1e-12
#: The folder of shipped models.
FOLDER = "calibration"


@dataclass(frozen=True)
class LogisticModel:
    """A fitted p_hold model for one hand.

    features: names (keys of :data:`~planner.calibration.features.FEATURES`);
    knots: per spline feature, its knots (ascending, >= 3; inputs' units);
    the model's k *columns* (:attr:`columns`) are each feature's input and,
    for a spline feature, its spline columns; mean, scale: (k,)
    standardisation of the columns; coef: (k,) per standardised column;
    intercept; l2: the penalty it was fitted with;
    source: how it was made (data, split, command), free text kept with it;
    figures: its held-out (cross-validated) figures; held_out: the held-out
    reliability table (None: not known), drawn by ``grasp report``;
    bounds: per feature, (low, high) of its inputs in the fitting data
    (inputs' units): a grasp's input is clipped to them before use (a
    feature without bounds is used as it is).
    """

    hand: str
    features: tuple[str, ...]
    mean: np.ndarray
    scale: np.ndarray
    coef: np.ndarray
    intercept: float
    l2: float
    source: str = ""
    figures: Mapping[str, float] = field(default_factory=dict)
    held_out: Reliability | None = None
    knots: Mapping[str, tuple[float, ...]] = field(default_factory=dict)
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        wrong = [f for f, b in self.bounds.items() if f not in self.features or len(b) != 2 or not b[0] <= b[1]]
        if wrong:
            raise InputError(f"calibration model: bounds of {', '.join(wrong)} must belong to a feature and be "
                             "(low, high) with low <= high")
        object.__setattr__(self, "bounds", {f: (float(b[0]), float(b[1])) for f, b in self.bounds.items()})
        bad = [f for f, t in self.knots.items() if f not in self.features or len(t) < 3 or np.any(np.diff(t) <= 0)]
        if bad:
            raise InputError(f"calibration model: knots of {', '.join(bad)} must belong to a feature and be >= 3 "
                             "increasing values")
        object.__setattr__(self, "knots", {f: tuple(float(v) for v in t) for f, t in self.knots.items()})
        k = len(self.columns)
        for name in ("mean", "scale", "coef"):
            a = np.asarray(getattr(self, name), float)
            if a.shape != (k,):
                raise InputError(f"calibration model: {name} must have {k} entries (one per column), got {a.shape}")
            object.__setattr__(self, name, a)
        unknown = [f for f in self.features if f not in FEATURES and f not in PRODUCTS]
        if unknown:
            raise InputError(f"calibration model: unknown feature(s) {', '.join(unknown)}; "
                             f"available: {', '.join([*FEATURES, *PRODUCTS])}")
        if not np.all(self.scale > 0):
            raise InputError("calibration model: every scale must be > 0")

    @property
    def columns(self) -> tuple[str, ...]:
        """The model's input columns: each feature, and ``feature~j`` for
        the j-th spline column of a spline feature."""
        return columns(self.features, self.knots)

    def _z(self, table: Mapping[str, np.ndarray]) -> np.ndarray:
        x = clip(design(table, self.features), self.features, self.bounds)
        return (expand(x, self.features, self.knots) - self.mean) / self.scale

    def logit(self, table: Mapping[str, np.ndarray]) -> np.ndarray:
        """(n,) log-odds of holding of the grasps of a measure table."""
        return self.intercept + self._z(table) @ self.coef

    def terms(self, table: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Each feature's part of the log-odds, (n,) per feature name: the
        sum over its columns of coef x standardised column; with
        ``intercept`` they add up to :meth:`logit` (``grasp best --explain``
        prints them)."""
        part = self._z(table) * self.coef
        owner = np.array([c.partition("~")[0] for c in self.columns])
        return {name: part[:, owner == name].sum(axis=1) for name in self.features}

    def standardised(self, table: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Each feature's standardised input ``(x - mean) / scale``, (n,) per
        feature name (its first column: the input itself, for a spline feature)."""
        z = self._z(table)
        cols = self.columns
        return {name: z[:, cols.index(name)] for name in self.features}

    def predict(self, table: Mapping[str, np.ndarray]) -> np.ndarray:
        """(n,) p_hold in [0, 1]."""
        return _sigmoid(self.logit(table))

    def to_dict(self) -> dict:
        return {"hand": self.hand, "features": list(self.features), "mean": self.mean.tolist(),
                "scale": self.scale.tolist(), "coef": self.coef.tolist(), "intercept": self.intercept,
                "l2": self.l2, "source": self.source, "figures": dict(self.figures),
                "knots": {k: list(v) for k, v in self.knots.items()},
                "bounds": {k: list(v) for k, v in self.bounds.items()},
                **({"held_out": _table(self.held_out)} if self.held_out is not None else {})}

    @classmethod
    def from_dict(cls, data: Mapping) -> LogisticModel:
        try:
            return cls(str(data["hand"]), tuple(data["features"]), np.asarray(data["mean"], float),
                       np.asarray(data["scale"], float), np.asarray(data["coef"], float), float(data["intercept"]),
                       float(data["l2"]), str(data.get("source", "")),
                       {k: float(v) for k, v in dict(data.get("figures", {})).items()},
                       _reliability(data["held_out"]) if "held_out" in data else None,
                       {str(k): tuple(float(x) for x in v) for k, v in dict(data.get("knots", {})).items()},
                       {str(k): tuple(float(x) for x in v) for k, v in dict(data.get("bounds", {})).items()})
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"calibration model: missing or bad field ({exc})") from None

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> LogisticModel:
        return cls.from_dict(json.loads(text))

    def to_toml(self) -> str:
        """The model as TOML (coefficients and how they were made; no data)."""
        lines = [f"# p_hold model for the {self.hand}: planner/calibration/model.py reads it.", ""]
        lines += [f'hand = "{self.hand}"', f"features = {json.dumps(list(self.features))}",
                  f"mean = {_floats(self.mean)}", f"scale = {_floats(self.scale)}", f"coef = {_floats(self.coef)}",
                  f"intercept = {self.intercept!r}", f"l2 = {self.l2!r}", f"source = {json.dumps(self.source)}", "",
                  "[figures]"]
        lines += [f"{k} = {float(v)!r}" for k, v in sorted(self.figures.items())]
        if self.knots:
            lines += ["", "[knots]  # restricted cubic spline knots per feature (the feature's input units)"]
            lines += [f'"{k}" = {_floats(np.asarray(v, float))}' for k, v in self.knots.items()]
        if self.bounds:
            lines += ["", "[bounds]  # (low, high) of each feature's inputs in the fitting data; inputs clipped to it"]
            lines += [f'"{k}" = {_floats(np.asarray(v, float))}' for k, v in self.bounds.items()]
        if self.held_out is not None:
            lines += ["", "[held_out]  # reliability table of the cross-validated predictions (nan: empty bin)"]
            lines += [f"{k} = {_floats(np.asarray(v, float))}" for k, v in _table(self.held_out, nan=True).items()]
        return "\n".join(lines) + "\n"


def _table(r: Reliability, nan: bool = False) -> dict[str, list]:
    def vals(a: np.ndarray) -> list:
        return [float(v) if nan or math.isfinite(v) else None for v in a]

    return {"edges": vals(r.edges), "predicted": vals(r.predicted), "observed": vals(r.observed),
            "count": vals(r.count)}


def _reliability(data: Mapping) -> Reliability:
    def arr(name: str) -> np.ndarray:
        return np.array([math.nan if v is None else v for v in data[name]], float)

    return Reliability(arr("edges"), arr("predicted"), arr("observed"), arr("count"))


def _floats(a: np.ndarray) -> str:
    return "[" + ", ".join("nan" if math.isnan(v) else repr(float(v)) for v in a) + "]"


def _sigmoid(z: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(z, float)))  # overflow-free logistic


def load_model(path: Path) -> LogisticModel:
    """A model TOML file."""
    import tomllib

    try:
        data = tomllib.loads(Path(path).read_text())
    except OSError as exc:
        raise InputError(f"{path}: cannot read calibration model ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not a calibration model TOML ({exc})") from None
    return LogisticModel.from_dict(data)


#: Set to "0" to switch the shipped models off (scores by the rule's formula: tests, comparisons).
SHIPPED_ENV = "GRASP_SHIPPED_MODELS"


def default_model(hand: str) -> LogisticModel | None:
    """The shipped model of ``hand`` (``calibration/<hand>.toml``), None if
    there is none or ``$GRASP_SHIPPED_MODELS`` is "0"."""
    if os.environ.get(SHIPPED_ENV, "1") == "0":
        return None
    return _shipped(hand)


@functools.cache
def _shipped(hand: str) -> LogisticModel | None:
    """The shipped model file of ``hand``, read once per process."""
    path = project_dir(FOLDER) / f"{hand}.toml"
    return load_model(path) if path.is_file() else None


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


def fit(table: Mapping[str, np.ndarray], labels: np.ndarray, hand: str, *,
        features: Sequence[str] = DEFAULT_FEATURES, l2: float = 1e-2, source: str = "",
        splines: Sequence[str] = DEFAULT_SPLINES) -> LogisticModel:
    """The model minimising mean log-loss + ``l2``/2 |coef|^2 on grasps with
    ``labels`` (n,) 0/1; the ``splines`` among ``features`` get knots from
    these grasps (:func:`choose_knots`)."""
    y = np.asarray(labels, float)
    raw = design(table, features)
    knots = choose_knots(raw, features, splines)
    x = expand(raw, features, knots)
    if len(y) != len(x) or len(y) == 0:
        raise InputError(f"calibration: {len(y)} labels for {len(x)} grasps; need at least one of each")
    if l2 < 0:
        raise InputError(f"calibration: l2 must be >= 0, got {l2}")
    mean = x.mean(axis=0)
    spread = x.std(axis=0)
    scale = np.where(spread > MIN_SCALE, spread, 1.0)
    z = (x - mean) / scale
    w0 = np.zeros(z.shape[1] + 1)
    rate = float(np.clip(y.mean(), 1e-6, 1 - 1e-6))
    w0[0] = math.log(rate / (1 - rate))
    from scipy.optimize import minimize  # fitting only: reading and applying a model needs numpy alone

    res = minimize(_loss, w0, args=(z, y, l2), jac=True, method="L-BFGS-B", options={"maxiter": 2000})
    return LogisticModel(hand, tuple(features), mean, scale, res.x[1:], float(res.x[0]), float(l2), source,
                         knots=knots, bounds=fitting_bounds(raw, features))


def _loss(w: np.ndarray, z: np.ndarray, y: np.ndarray, l2: float) -> tuple[float, np.ndarray]:
    """Mean log-loss + l2/2 |coef|^2 and its gradient; w = (intercept, coef...)."""
    s = w[0] + z @ w[1:]
    # log(1 + e^s) - y s, stable for large |s|
    loss = np.mean(np.logaddexp(0.0, s) - y * s) + 0.5 * l2 * float(w[1:] @ w[1:])
    r = (_sigmoid(s) - y) / len(y)
    grad = np.concatenate([[r.sum()], z.T @ r + l2 * w[1:]])
    return float(loss), grad


@dataclass(frozen=True)
class CrossValidation:
    """Out-of-fold predictions: p (n,) each grasp's p_hold from the model fitted
    without its object's fold; fold (n,) the fold of each grasp; l2 (folds,)
    the penalty each fold's inner cross-validation chose."""

    p: np.ndarray
    fold: np.ndarray
    l2: np.ndarray


def _subset(table: Mapping[str, np.ndarray], rows: np.ndarray) -> dict[str, np.ndarray]:
    return {k: np.asarray(v)[rows] for k, v in table.items()}


def log_loss(labels: np.ndarray, p: np.ndarray) -> float:
    q = np.clip(p, 1e-12, 1 - 1e-12)
    return float(-np.mean(labels * np.log(q) + (1 - labels) * np.log(1 - q)))


def choose_l2(table: Mapping[str, np.ndarray], labels: np.ndarray, groups: Sequence[str], hand: str, *,
              features: Sequence[str] = DEFAULT_FEATURES, folds: int = 5, grid: Sequence[float] = L2_GRID,
              splines: Sequence[str] = DEFAULT_SPLINES) -> float:
    """The penalty of ``grid`` with the least grouped-CV log-loss (ties: the larger)."""
    k = min(folds, len(set(groups)))
    if k < 2:
        return float(max(grid))
    tests = grouped_folds(groups, k)
    best, best_loss = float(max(grid)), math.inf
    for l2 in sorted(grid, reverse=True):
        p = np.empty(len(labels))
        for test in tests:
            train = np.setdiff1d(np.arange(len(labels)), test)
            p[test] = fit(_subset(table, train), labels[train], hand, features=features, l2=l2,
                          splines=splines).predict(_subset(table, test))
        loss = log_loss(labels, p)
        if loss < best_loss - 1e-9:
            best, best_loss = float(l2), loss
    return best


def cross_validate(table: Mapping[str, np.ndarray], labels: np.ndarray, groups: Sequence[str], hand: str, *,
                   features: Sequence[str] = DEFAULT_FEATURES, folds: int = 5,
                   grid: Sequence[float] = L2_GRID, splines: Sequence[str] = DEFAULT_SPLINES) -> CrossValidation:
    """Out-of-fold p_hold over ``folds`` folds grouped by ``groups`` (n,) (object ids)."""
    y = np.asarray(labels, float)
    groups = list(groups)
    tests = grouped_folds(groups, folds)
    p, fold, chosen = np.empty(len(y)), np.empty(len(y), int), []
    for f, test in enumerate(tests):
        train = np.setdiff1d(np.arange(len(y)), test)
        sub = _subset(table, train)
        l2 = choose_l2(sub, y[train], [groups[i] for i in train], hand, features=features, folds=folds, grid=grid,
                       splines=splines)
        chosen.append(l2)
        p[test] = fit(sub, y[train], hand, features=features, l2=l2, splines=splines).predict(_subset(table, test))
        fold[test] = f
    return CrossValidation(p, fold, np.array(chosen))
