"""The p_hold model as a value: :class:`LogisticModel` (standardised
columns, coefficients, intercept; its held-out figures and reliability
table), applied to a measure table, stored as TOML or JSON
(:func:`load_model`), and the shipped default per hand
(:func:`default_model`). Fitting it is :mod:`planner.calibration.model`'s.
Numpy only.
"""

from __future__ import annotations

import functools
import json
import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from planner.assets import project_dir
from planner.calibration.basis import _sigmoid, clip, columns, expand  # noqa: F401 - _sigmoid re-exported
from planner.calibration.features import FEATURES, PRODUCTS, design
from planner.calibration.metrics import Reliability
from planner.calibration.trees import Trees
from planner.calibration.update import TrialUpdate
from planner.errors import InputError

#: The folder of shipped models.
FOLDER = "calibration"
#: The name of the trees' part of the log-odds in :meth:`LogisticModel.terms`.
INTERACTIONS = "interactions"
#: The trees' integer arrays (written as integers in TOML).
TREE_INTS = ("roots", "feature", "left", "right")
#: The object properties a model's domain spans, with their units: the range of the labelled objects it was
#: fitted on (:attr:`LogisticModel.domain`). An object outside it gets a p_hold the labels never tested.
DOMAIN = {"density": "kg/m^3", "friction": "", "mass": "kg"}
#: Relative slack of :meth:`LogisticModel.outside` (the stored values' rounding).
DOMAIN_SLACK = 0.02


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
    feature without bounds is used as it is); trees: the boosted
    interaction term over the clipped inputs and the inputs of
    ``tree_features`` (features only the trees read, after the others: the
    cells of ``local_sdf``); tree_turns: orders of the trees' inputs in
    which a grasp is the same grasp (the hand turned onto itself,
    :attr:`~planner.specs.hand_spec.HandSpec.cell_turns`): the trees were
    grown on every grasp in each order and their term is the mean over the
    orders, the inputs' own included (:mod:`~planner.calibration.trees`;
    None: the model is additive alone); updates: per trial group (``mujoco``,
    ``validation``), how that trial's verdict updates p_hold into
    ``p_hold_trial`` (:mod:`~planner.calibration.update`; none: a verdict of
    that engine is used as it is); domain: per property of :data:`DOMAIN`,
    (low, high) over the labelled objects it was fitted on (empty: not
    known, a model stored before 2026-12-05): :meth:`outside` says where an
    object's p_hold is extrapolated; labels: the names of the label files it
    was fitted on (empty: not recorded, a model made before 2026-12-07); label_hashes: the sha256 (hex) of
    each one's bytes, in their order (empty: not recorded: a file is matched by its name): an imported file's
    labels among them are in-sample (``grasp import``, ``report`` and ``best`` say so).
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
    trees: Trees | None = None
    updates: Mapping[str, TrialUpdate] = field(default_factory=dict)
    domain: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    tree_features: tuple[str, ...] = ()
    tree_turns: tuple[tuple[int, ...], ...] = ()
    labels: tuple[str, ...] = ()
    label_hashes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "tree_features", tuple(self.tree_features))
        object.__setattr__(self, "labels", tuple(str(name) for name in self.labels))
        object.__setattr__(self, "label_hashes", tuple(str(h).lower() for h in self.label_hashes))
        if self.label_hashes and (len(self.label_hashes) != len(self.labels)
                                  or not all(re.fullmatch("[0-9a-f]{64}", h) for h in self.label_hashes)):
            raise InputError("calibration model: label_hashes must be one sha256 (64 hex digits) per file of labels")
        object.__setattr__(self, "tree_turns", tuple(tuple(int(i) for i in t) for t in self.tree_turns))
        width = len(self.features) + len(self.tree_features)
        if any(sorted(t) != list(range(width)) for t in self.tree_turns):
            raise InputError(f"calibration model: each of tree_turns must order the trees' {width} inputs")
        odd = [k for k, b in self.domain.items() if k not in DOMAIN or len(b) != 2 or not 0 < b[0] <= b[1]]
        if odd:
            raise InputError(f"calibration model: domain of {', '.join(map(str, odd))} must be one of "
                             f"{', '.join(DOMAIN)} as (low, high) with 0 < low <= high")
        object.__setattr__(self, "domain", {k: (float(b[0]), float(b[1])) for k, b in self.domain.items()})
        if any(u.engine != k for k, u in self.updates.items()):
            raise InputError("calibration model: each trial update must be keyed by its own engine")
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
        unknown = [f for f in (*self.features, *self.tree_features) if f not in FEATURES and f not in PRODUCTS]
        if unknown:
            raise InputError(f"calibration model: unknown feature(s) {', '.join(unknown)}; "
                             f"available: {', '.join([*FEATURES, *PRODUCTS])}")
        if not np.all(self.scale > 0):
            raise InputError("calibration model: every scale must be > 0")
        inputs = len(self.features) + len(self.tree_features)
        if self.trees is not None and len(self.trees.feature) and self.trees.feature.max() >= inputs:
            raise InputError(f"calibration model: trees split on input {int(self.trees.feature.max())}, the model "
                             f"has {inputs} inputs")

    @property
    def columns(self) -> tuple[str, ...]:
        """The model's input columns: each feature, and ``feature~j`` for the j-th spline column of a spline one."""
        return columns(self.features, self.knots)

    def inputs(self, table: Mapping[str, np.ndarray]) -> np.ndarray:
        """(n, len(features)) the features' inputs, each clipped to its bounds."""
        return clip(design(table, self.features), self.features, self.bounds)

    def tree_inputs(self, table: Mapping[str, np.ndarray], x: np.ndarray | None = None) -> np.ndarray:
        """(n, len(features) + len(tree_features)) what the trees read: :meth:`inputs` (``x``, if given)
        and the inputs of :attr:`tree_features`."""
        x = self.inputs(table) if x is None else x
        return np.hstack([x, design(table, self.tree_features)]) if self.tree_features else x

    def _z(self, x: np.ndarray) -> np.ndarray:
        return (expand(x, self.features, self.knots) - self.mean) / self.scale

    def logit(self, table: Mapping[str, np.ndarray]) -> np.ndarray:
        """(n,) log-odds of holding of the grasps of a measure table."""
        x = self.inputs(table)
        additive = self.intercept + self._z(x) @ self.coef
        return additive if self.trees is None else additive + self._tree_term(self.tree_inputs(table, x))

    def _tree_term(self, inputs: np.ndarray) -> np.ndarray:
        """(n,) the trees' part of the log-odds: their mean over the grasps' views (:attr:`tree_turns`)."""
        assert self.trees is not None
        views = [inputs, *(inputs[:, list(t)] for t in self.tree_turns)]
        return np.mean([self.trees.evaluate(v) for v in views], axis=0)

    def terms(self, table: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Each feature's part of the log-odds, (n,) per feature name: the
        sum over its columns of coef x standardised column; and, for a
        model with trees, ``interactions``: the trees' part. With
        ``intercept`` they add up to :meth:`logit` (``grasp best --explain``
        prints them)."""
        x = self.inputs(table)
        part = self._z(x) * self.coef
        owner = np.array([c.partition("~")[0] for c in self.columns])
        out = {name: part[:, owner == name].sum(axis=1) for name in self.features}
        if self.trees is not None:
            out[INTERACTIONS] = self._tree_term(self.tree_inputs(table, x))
        return out

    def standardised(self, table: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Each feature's standardised input ``(x - mean) / scale``, (n,) per feature name (a spline's: its input's)."""
        z = self._z(self.inputs(table))
        cols = self.columns
        return {name: z[:, cols.index(name)] for name in self.features}

    def predict(self, table: Mapping[str, np.ndarray]) -> np.ndarray:
        """(n,) p_hold in [0, 1]."""
        return _sigmoid(self.logit(table))

    def given_trial(self, p_hold: np.ndarray, verdicts: Mapping[str, np.ndarray]) -> np.ndarray:
        """(n,) p_hold_trial: ``p_hold`` (n,) updated by the verdict of the
        first trial in :data:`~planner.record.fields.TRIAL_PRECEDENCE` that
        tried each grasp (``verdicts``: group -> (n,) 1 held, 0 dropped,
        NaN or < 0 not tried); NaN where none tried it, where that trial's
        engine has no update, or where p_hold is NaN."""
        from planner.record.fields import TRIAL_PRECEDENCE

        p = np.asarray(p_hold, float)
        out, done = np.full(len(p), np.nan), np.zeros(len(p), bool)
        for group in TRIAL_PRECEDENCE:
            v = np.asarray(verdicts.get(group, np.full(len(p), np.nan)), float)
            tried = ~done & (v >= 0)
            update = self.updates.get(group)
            if update is not None and tried.any():
                out[tried] = update.apply(p[tried], v[tried])
            done |= tried
        return np.where(np.isnan(p), np.nan, out)

    def outside(self, properties: Mapping[str, float]) -> list[str]:
        """:func:`outside` of the model's domain."""
        return outside(self.domain, properties)

    def to_dict(self) -> dict:
        return {"hand": self.hand, "features": list(self.features), "mean": self.mean.tolist(),
                "scale": self.scale.tolist(), "coef": self.coef.tolist(), "intercept": self.intercept,
                "l2": self.l2, "source": self.source, "figures": dict(self.figures),
                "knots": {k: list(v) for k, v in self.knots.items()},
                "bounds": {k: list(v) for k, v in self.bounds.items()},
                **({"held_out": _table(self.held_out)} if self.held_out is not None else {}),
                **({"trees": self.trees.to_dict()} if self.trees is not None else {}),
                **({"updates": {k: u.to_dict() for k, u in self.updates.items()}} if self.updates else {}),
                **({"domain": {k: list(v) for k, v in self.domain.items()}} if self.domain else {}),
                **({"tree_features": list(self.tree_features)} if self.tree_features else {}),
                **({"tree_turns": [list(t) for t in self.tree_turns]} if self.tree_turns else {}),
                **({"labels": list(self.labels)} if self.labels else {}),
                **({"label_hashes": list(self.label_hashes)} if self.label_hashes else {})}

    @classmethod
    def from_dict(cls, data: Mapping) -> LogisticModel:
        try:
            return cls(str(data["hand"]), tuple(data["features"]), np.asarray(data["mean"], float),
                       np.asarray(data["scale"], float), np.asarray(data["coef"], float), float(data["intercept"]),
                       float(data["l2"]), str(data.get("source", "")),
                       {k: float(v) for k, v in dict(data.get("figures", {})).items()},
                       _reliability(data["held_out"]) if "held_out" in data else None,
                       {str(k): tuple(float(x) for x in v) for k, v in dict(data.get("knots", {})).items()},
                       {str(k): tuple(float(x) for x in v) for k, v in dict(data.get("bounds", {})).items()},
                       Trees.from_dict(data["trees"]) if "trees" in data else None,
                       {str(k): TrialUpdate.from_dict(k, v) for k, v in dict(data.get("updates", {})).items()},
                       {str(k): tuple(float(x) for x in v) for k, v in dict(data.get("domain", {})).items()},
                       tuple(str(f) for f in data.get("tree_features", ())),
                       tuple(tuple(int(i) for i in t) for t in data.get("tree_turns", ())),
                       tuple(str(name) for name in data.get("labels", ())),
                       tuple(str(h) for h in data.get("label_hashes", ())))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"calibration model: missing or bad field ({exc})") from None

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> LogisticModel:
        return cls.from_dict(json.loads(text))

    def to_toml(self) -> str:
        """The model as TOML (coefficients and how they were made; no data)."""
        lines = [f"# p_hold model for the {self.hand}: planner/calibration/logistic.py reads it.", ""]
        lines += [f'hand = "{self.hand}"', f"features = {json.dumps(list(self.features))}",
                  *([f"tree_features = {json.dumps(list(self.tree_features))}"] if self.tree_features else []),
                  *([f"tree_turns = {json.dumps([list(t) for t in self.tree_turns])}"] if self.tree_turns else []),
                  f"mean = {_floats(self.mean)}", f"scale = {_floats(self.scale)}", f"coef = {_floats(self.coef)}",
                  f"intercept = {self.intercept!r}", f"l2 = {self.l2!r}", f"source = {json.dumps(self.source)}",
                  *([f"labels = [{', '.join(map(_toml_string, self.labels))}]"] if self.labels else []),
                  *([f"label_hashes = {json.dumps(list(self.label_hashes))}"] if self.label_hashes else []), "",
                  "[figures]"]
        lines += [f"{k} = {float(v)!r}" for k, v in sorted(self.figures.items())]
        if self.knots:
            lines += ["", "[knots]  # restricted cubic spline knots per feature (the feature's input units)"]
            lines += [f'"{k}" = {_floats(np.asarray(v, float))}' for k, v in self.knots.items()]
        if self.bounds:
            lines += ["", "[bounds]  # (low, high) of each feature's inputs in the fitting data; inputs clipped to it"]
            lines += [f'"{k}" = {_floats(np.asarray(v, float))}' for k, v in self.bounds.items()]
        if self.domain:
            lines += ["", "[domain]  # (low, high) over the labelled objects: " +
                      ", ".join(f"{k} [{u}]" if u else k for k, u in DOMAIN.items())]
            lines += [f'"{k}" = {_floats(np.asarray(v, float))}' for k, v in self.domain.items()]
        if self.held_out is not None:
            lines += ["", "[held_out]  # reliability table of the cross-validated predictions (nan: empty bin)"]
            lines += [f"{k} = {_floats(np.asarray(v, float))}" for k, v in _table(self.held_out, nan=True).items()]
        if self.trees is not None:
            lines += ["", "[trees]  # the interaction term: trees boosted over the clipped inputs (trees.py)"]
            lines += [f"{k} = {json.dumps(v) if k in TREE_INTS else _floats(np.asarray(v, float))}"
                      for k, v in self.trees.to_dict().items()]
        for engine, u in self.updates.items():
            lines += ["", f"[updates.{engine}]  # p_hold given this trial's verdict (update.py)"]
            lines += [f"{k} = {float(v)!r}" if k != "grasps" else f"{k} = {int(v)}" for k, v in u.to_dict().items()]
        return "\n".join(lines) + "\n"


def properties(item: object) -> dict[str, float]:
    """The :data:`DOMAIN` properties of anything that has them as attributes (a stored object's row, a prepared
    object): what :func:`outside` reads and a fitted model's domain spans."""
    return {name: float(getattr(item, name)) for name in DOMAIN}


def outside(domain: Mapping[str, tuple[float, float]], properties: Mapping[str, float]) -> list[str]:
    """Where an object (``properties``: names of :data:`DOMAIN` -> value)
    lies outside a model's ``domain`` (:attr:`LogisticModel.domain`), one text
    per property, e.g. ``density 1,322 kg/m^3 (labels: 150 kg/m^3)``; [] inside
    (within :data:`DOMAIN_SLACK`) or where the domain is not known."""
    out = []
    for name, (low, high) in domain.items():
        value = properties.get(name)
        if value is None or low * (1 - DOMAIN_SLACK) <= value <= high * (1 + DOMAIN_SLACK):
            continue
        unit = f" {DOMAIN[name]}" if DOMAIN[name] else ""
        span = _short(low) if high <= low * (1 + DOMAIN_SLACK) else f"{_short(low)}-{_short(high)}"
        out.append(f"{name} {_short(value)}{unit} (labels: {span}{unit})")
    return out


def _short(v: float) -> str:
    """Three significant digits, without an exponent from 1e-3 to 1e6 (1320, 0.5, 0.0017)."""
    return f"{v:,.0f}" if 1e3 <= abs(v) < 1e6 else f"{v:.3g}"


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


def _toml_string(text: str) -> str:
    """``text`` as an ASCII TOML basic string: JSON's escapes write a character beyond U+FFFF (a file name's emoji)
    as two surrogates, which TOML refuses (the model written could not be read back): here one ``\\U`` escape."""
    return '"' + "".join(c if " " <= c < "\x7f" and c not in '"\\' else
                         f"\\u{ord(c):04x}" if ord(c) < 0x10000 else f"\\U{ord(c):08x}" for c in text) + '"'


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
    """The shipped model of ``hand`` (``calibration/<hand>.toml``), None if there is none or it is switched off."""
    if os.environ.get(SHIPPED_ENV, "1") == "0":
        return None
    return _shipped(hand)


def default_domain(hand: str) -> dict[str, tuple[float, float]]:
    """The shipped model's domain ({} if no model or none recorded), read from its ``[domain]`` table alone:
    the whole file (its trees) takes ~0.1 s to parse, a start-up cost ``grasp best`` does not otherwise pay."""
    if os.environ.get(SHIPPED_ENV, "1") == "0":
        return {}
    return dict(_shipped_domain(hand))


@functools.cache
def _shipped_domain(hand: str) -> tuple[tuple[str, tuple[float, float]], ...]:
    import tomllib

    path = project_dir(FOLDER) / f"{hand}.toml"
    text = path.read_text() if path.is_file() else ""
    start = text.find("\n[domain]")
    if start < 0:
        return ()
    end = text.find("\n[", start + 1)
    table = tomllib.loads(text[start:end if end >= 0 else len(text)])["domain"]
    return tuple((str(k), (float(v[0]), float(v[1]))) for k, v in table.items())


@functools.cache
def _shipped(hand: str) -> LogisticModel | None:
    """The shipped model file of ``hand``, read once per process."""
    path = project_dir(FOLDER) / f"{hand}.toml"
    return load_model(path) if path.is_file() else None
