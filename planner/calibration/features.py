"""The analytic measures a probability of holding is fitted on, as one table.

A *measure table* maps each name of :data:`MEASURES` to an ``(n,)`` float
array over n grasps (NaN: not measured). It is built from grasp records
(:func:`of_grasps`) or from stored columns (the database reads the same
names), so the fitted model sees the very numbers the store holds.

:func:`design` turns a table into the model's ``(n, k)`` inputs, one column
per entry of :data:`FEATURES`: each a monotone transform of one measure, with
a neutral value where it was not measured (:data:`FILL`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from planner.errors import InputError
from planner.plan.local_sdf import CLIP as LOCAL_CLIP
from planner.specs.hand_spec import LOCAL_CELLS

if TYPE_CHECKING:
    from planner.record.grasp import Grasp

#: The raw measures read per grasp (units: epsilon, volume dimensionless; resist_* [g]; margins, width [m];
#: counts; force_closure 0/1; settled_epsilon dimensionless; depth [m], see :func:`contact_depth`; the grip
#: measures of :mod:`planner.plan.grip`: pad_area, jaw_fill [m^2], pad_alignment, opposition (cosines),
#: palm_gap, com_lever, com_height, gravity_arm [m]; torque_per_mu [N m], :mod:`planner.plan.measures`; the
#: squeeze's, :mod:`planner.plan.squeeze`: squeezed_force_closure 0/1, squeezed_epsilon, squeeze_turn [rad]);
#: the cells of ``local_sdf`` are :data:`LOCAL`.
MEASURES = ("epsilon", "volume", "force_closure", "resist_worst", "resist_mean", "open_margin", "close_margin",
            "push", "width", "n_contacts", "links_touching", "settled_epsilon", "depth", "pad_area", "pad_alignment",
            "opposition", "jaw_fill", "palm_gap", "com_lever", "com_height", "gravity_arm", "torque_per_mu",
            "squeezed_force_closure", "squeezed_epsilon", "squeeze_turn")

#: The cells of the measure ``local_sdf`` [m] (:mod:`planner.plan.local_sdf`), one table entry each (the
#: trees read them, :attr:`planner.calibration.logistic.LogisticModel.tree_features`); NaN: not measured.
LOCAL = tuple(f"local_sdf_{i:02d}" for i in range(LOCAL_CELLS))
#: Every name of a measure table.
TABLE = (*MEASURES, *LOCAL)

#: The stored columns (declared fields, :mod:`planner.record.fields`) a measure table is built from:
#: every measure but ``depth``, which comes from the pose, the approach direction and the contacts, and
#: ``local_sdf`` for its cells.
COLUMNS = (*(m for m in MEASURES if m != "depth"), "local_sdf", "pose", "approach_dir", "contacts")

#: [m] margins above this are all "plenty of travel" (an untouched finger's margin is inf).
MARGIN_CAP = 0.04
#: [g] weight resistance is compared on a log scale: log1p(min(resist, cap)).
RESIST_CAP = 1e4
#: [m^2] areas are compared on a log scale in units of this (1 mm^2): log1p(area / AREA_UNIT).
AREA_UNIT = 1e-6

#: feature name -> (measure, transform); transforms are monotone so a coefficient's sign reads as a direction.
FEATURES: dict[str, tuple[str, str]] = {
    "epsilon": ("epsilon", "identity"),
    "force_closure": ("force_closure", "identity"),
    "log_resist_worst": ("resist_worst", "log_resist"),
    "log_resist_mean": ("resist_mean", "log_resist"),
    "open_margin": ("open_margin", "margin"),
    "close_margin": ("close_margin", "margin"),
    "push": ("push", "identity"),
    "width": ("width", "identity"),
    "n_contacts": ("n_contacts", "identity"),
    "links_touching": ("links_touching", "identity"),
    "settled_epsilon": ("settled_epsilon", "identity"),
    "depth": ("depth", "identity"),
    "log_pad_area": ("pad_area", "log_area"),
    "pad_alignment": ("pad_alignment", "identity"),
    "opposition": ("opposition", "identity"),
    "log_jaw_fill": ("jaw_fill", "log_area"),
    "palm_gap": ("palm_gap", "identity"),
    "com_lever": ("com_lever", "identity"),
    "com_height": ("com_height", "identity"),
    "gravity_arm": ("gravity_arm", "identity"),
    "torque_per_mu": ("torque_per_mu", "identity"),
    "squeezed_force_closure": ("squeezed_force_closure", "identity"),
    "squeezed_epsilon": ("squeezed_epsilon", "identity"),
    "squeeze_turn": ("squeeze_turn", "identity"),
    **{name: (name, "identity") for name in LOCAL},
}

#: Products of two features' inputs (after transform and fill): the curvature a linear model lacks where a
#: middle value is best (neither the narrowest closed width nor the deepest contact always holds best).
PRODUCTS: dict[str, tuple[str, str]] = {
    "depth^2": ("depth", "depth"),
    "width^2": ("width", "width"),
    "width*depth": ("width", "depth"),
}

#: Value of a feature whose measure was not computed (NaN): the "nothing known" end of its scale.
FILL = {"epsilon": 0.0, "force_closure": 0.0, "log_resist_worst": 0.0, "log_resist_mean": 0.0,
        "open_margin": MARGIN_CAP, "close_margin": MARGIN_CAP, "push": 0.0, "width": 0.0, "n_contacts": 0.0,
        "links_touching": 0.0, "settled_epsilon": 0.0, "depth": 0.0, "log_pad_area": 0.0, "pad_alignment": 0.0,
        "opposition": 0.0, "log_jaw_fill": 0.0, "palm_gap": 0.05, "com_lever": 0.0,
        "com_height": 0.0, "gravity_arm": 0.0, "torque_per_mu": 0.0,
        "squeezed_force_closure": 0.0, "squeezed_epsilon": 0.0, "squeeze_turn": 0.0,  # a hand that does not squeeze
        **dict.fromkeys(LOCAL, LOCAL_CLIP)}  # a cell not measured: nothing of the object near


def _transform(kind: str, x: np.ndarray) -> np.ndarray:
    if kind == "log_resist":
        return np.log1p(np.clip(x, 0.0, RESIST_CAP))
    if kind == "log_area":
        return np.log1p(np.maximum(x, 0.0) / AREA_UNIT)
    if kind == "margin":
        return np.clip(x, 0.0, MARGIN_CAP)  # inf (no finger touching) -> the cap
    return x


def _input(table: Mapping[str, np.ndarray], name: str) -> np.ndarray:
    if name in PRODUCTS:
        a, b = PRODUCTS[name]
        return _input(table, a) * _input(table, b)
    measure, kind = FEATURES[name]
    if measure not in table and measure in LOCAL:  # a table of the other measures alone: not measured
        return np.full(len(np.asarray(table["epsilon"])), FILL[name])
    raw = np.asarray(table[measure], float)
    return np.where(np.isnan(raw), FILL[name], _transform(kind, raw))


def design(table: Mapping[str, np.ndarray], names: Sequence[str]) -> np.ndarray:
    """(n, len(names)) inputs of the features ``names`` (keys of :data:`FEATURES` or :data:`PRODUCTS`)."""
    unknown = [n for n in names if n not in FEATURES and n not in PRODUCTS]
    if unknown:
        raise InputError(f"unknown calibration feature(s) {', '.join(unknown)}; "
                         f"available: {', '.join([*FEATURES, *PRODUCTS])}")
    if not names:
        return np.zeros((len(np.asarray(table["epsilon"])), 0))
    return np.stack([_input(table, name) for name in names], axis=1)


def contact_depth(pose: np.ndarray, approach: np.ndarray, points: Sequence[np.ndarray]) -> np.ndarray:
    """(n,) [m] how far along the approach the contacts lie from the hand
    frame's origin (the palm side): the mean over a grasp's contacts of
    (point - origin) . approach; small = the object sits deep in the hand.
    ``pose`` (n, 4, 4), ``approach`` (n, 3) unit, ``points`` n arrays (k_i, 3),
    all in the object frame; NaN for a grasp without contacts."""
    out = np.full(len(points), np.nan)
    for i, p in enumerate(points):
        p = np.asarray(p, float).reshape(-1, 3)
        if len(p):
            out[i] = float(np.mean((p - pose[i, :3, 3]) @ approach[i]))
    return out


def of_grasps(grasps: Sequence[Grasp]) -> dict[str, np.ndarray]:
    """The measure table of grasp records (NaN where a measure was not
    computed): each measure read by its declared field
    (:func:`planner.record.fields.values`), ``depth`` from the pose, the
    approach direction and the contacts."""
    from planner.record import fields

    out = {name: np.array([np.nan if v is None else float(v) for v in fields.values(fields.by_name(name), grasps)],
                          float) for name in MEASURES if name != "depth"}
    out["depth"] = contact_depth(np.array([g.pose for g in grasps], float).reshape(-1, 4, 4),
                                 np.array([g.approach_dir for g in grasps], float).reshape(-1, 3),
                                 [g.contacts.points for g in grasps])
    out.update(local_cells(list(fields.values(fields.by_name("local_sdf"), grasps))))
    return out


def local_cells(values: Sequence[np.ndarray | None]) -> dict[str, np.ndarray]:
    """The table entries of :data:`LOCAL` from n grasps' ``local_sdf`` ((LOCAL_CELLS,) or None: NaN)."""
    cells = np.full((len(values), LOCAL_CELLS), np.nan)
    for i, v in enumerate(values):
        if v is not None:
            cells[i] = v
    return {name: cells[:, j] for j, name in enumerate(LOCAL)}


def of_columns(col: Mapping[str, Sequence[object]]) -> dict[str, np.ndarray]:
    """The measure table of stored columns (None -> NaN): the names of
    :data:`MEASURES` but ``depth``, which comes from ``pose``, ``approach_dir``
    (flat JSON lists) and ``contacts`` (JSON ``[{point, ...}]``)."""
    import json

    out = {name: np.array([np.nan if v is None else v for v in col[name]], float)
           for name in MEASURES if name != "depth"}
    n = len(col["pose"])

    def parsed(texts: Sequence[object]) -> list:  # one parser call for the whole batch (exports read 100,000s)
        return json.loads("[" + ",".join(map(str, texts)) + "]") if n else []

    poses = np.array(parsed(col["pose"]), float).reshape(n, 4, 4)
    approach = np.array(parsed(col["approach_dir"]), float).reshape(n, 3)
    points = [np.array([c["point"] for c in items], float) for items in parsed(col["contacts"])]
    out["depth"] = contact_depth(poses, approach, points)
    local = [None if v is None else np.asarray(json.loads(str(v)), float) for v in col["local_sdf"]]
    out.update(local_cells(local))
    return out
