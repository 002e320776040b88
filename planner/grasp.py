"""The one grasp record, from the sweep to the database to every export.

A :class:`Grasp` is made by the planner (:mod:`planner.plan.unit`) with what
the sweep found and what the quality and reachability stages measured; the
database (:mod:`planner.db.store`) stores it and returns it with what it adds
(``id``, ``unit_id``, ``score``, ``rank``) and with the results of physical
validation (:class:`Trial`, :class:`RobustEpsilon`) where they exist. The
exporters turn lists of them into columns (:mod:`planner.datasets.columns`),
``grasp best --json`` prints :meth:`Grasp.to_json`.

Frames: the object frame is the frame of the scaled mesh file; the grasp pose
is the hand frame (the hand's ``root_link``) in the object frame. Lengths in
metres, angles in radians, joint values in radians or metres.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from planner.plan.contacts import HandContacts
from planner.plan.measures import Measures


class Joints(Mapping[str, float]):
    """Finger joint values by name [rad or m] (immutable). The stored form is
    compact JSON text; read back from the database, a Joints keeps that text
    and decodes it on first use, so an export that copies it never decodes."""

    __slots__ = ("_values", "_text")

    def __init__(self, values: Mapping[str, float]) -> None:
        self._values: dict[str, float] | None = dict(values)
        self._text: str | None = None

    @classmethod
    def stored(cls, text: str) -> Joints:
        out = cls.__new__(cls)
        out._values, out._text = None, text
        return out

    def _dict(self) -> dict[str, float]:
        if self._values is None:
            self._values = json.loads(self._text or "{}")
        return self._values

    def __getitem__(self, name: str) -> float:
        return self._dict()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._dict())

    def __len__(self) -> int:
        return len(self._dict())

    def __repr__(self) -> str:
        return f"Joints({self._dict()!r})"

    def json_text(self) -> str:
        """The stored form: ``{"joint": value, ...}`` as compact JSON."""
        if self._text is None:
            self._text = json.dumps(self._dict(), separators=(",", ":"))
        return self._text


@dataclass(frozen=True)
class Trial:
    """The outcome of one dynamic shake trial (:func:`planner.validation.shake.trial`).

    Motions are the object's relative to the hand, as ACRONYM stores them:
    while the fingers closed and settled, and the largest during the loads
    (centre of mass [m], rotation [rad]). ``fingers_in_contact``: distinct
    fingers touching after closing. ``reason``: ``held``, ``slipped``,
    ``squeezed_out``, ``no_contact``, ``no_clearance`` or ``start_overlap``
    (the last two are flags: not simulated, motions 0); empty when unknown
    (imported files, older databases).
    """

    success: bool
    fingers_in_contact: int
    closing_linear: float  # [m]
    closing_angular: float  # [rad]
    shaking_linear: float  # [m]
    shaking_angular: float  # [rad]
    reason: str = ""


@dataclass(frozen=True)
class RobustEpsilon:
    """Epsilon over noisy copies of a grasp (:mod:`planner.validation.robust`)."""

    mean: float
    quantile: float  # the low quantile of the samples
    samples: int  # how many noisy copies


@dataclass(frozen=True)
class Grasp:
    """One grasp: the hand closed on the object, its contacts and measures.

    Attributes:
        object, hand, preshape: names.
        candidate: its number in the object's enumeration (:mod:`planner.plan.sweep`).
        seed: the seed of the unit of work that found it.
        approach_point: (3,) [m] where the approach ray meets the object, object frame.
        approach_dir: (3,) unit approach direction, object frame.
        roll: [rad] about the approach direction; standoff: [m] back-off before closing.
        pose: (4, 4) hand frame in the object frame [m].
        open_joints / closed_joints: finger joint values by name [rad or m].
        width: [m] distance between the fingers of a parallel jaw, else None.
        contacts: the contacts, object frame.
        epsilon, volume: Ferrari-Canny L1 epsilon and GWS volume (0 unless force closure).
        reachability: fraction of sampled table placements an arm reaches (None: not computed).
        manipulability: the best arm manipulability over those placements.
        id, unit_id, score, rank: set by the database (rank 1 = best of its object and hand).
        validation, robust: physical validation results, where they exist.
        measures: weight resistance and feasibility (None: not measured, e.g.
            a grasp stored before schema version 3).
        p_hold: calibrated probability in [0, 1] that the grasp holds
            (:mod:`planner.calibration`), set by the database from the stored
            measures and the hand's model; None where no model applies.
    """

    object: str
    hand: str
    preshape: str
    candidate: int
    seed: int
    approach_point: np.ndarray
    approach_dir: np.ndarray
    roll: float
    standoff: float
    pose: np.ndarray
    open_joints: Joints
    closed_joints: Joints
    width: float | None
    contacts: HandContacts
    epsilon: float
    volume: float
    force_closure: bool
    reachability: float | None = None
    manipulability: float | None = None
    id: int | None = None
    unit_id: int | None = None
    score: float | None = None
    rank: int | None = None
    validation: Trial | None = None
    robust: RobustEpsilon | None = None
    measures: Measures | None = None
    p_hold: float | None = None

    def __post_init__(self) -> None:
        if self.pose.shape != (4, 4) or self.approach_point.shape != (3,) or self.approach_dir.shape != (3,):
            raise ValueError("Grasp.pose must be (4, 4), approach_point and approach_dir (3,)")
        for name in ("open_joints", "closed_joints"):  # any mapping of joint values is taken as Joints
            if not isinstance(getattr(self, name), Joints):
                object.__setattr__(self, name, Joints(getattr(self, name)))

    @classmethod
    def restored(cls, values: tuple) -> Grasp:
        """A record read back from the database, which wrote it: the value of
        every field, in field order and in its stored type, so ``__init__``
        and its checks are skipped (an export reads 100,000s of records)."""
        if len(values) != len(FIELDS):
            raise TypeError(f"Grasp.restored needs the {len(FIELDS)} fields {FIELDS}, got {len(values)} values")
        out = object.__new__(cls)
        out.__dict__.update(zip(FIELDS, values))
        return out

    def to_json(self) -> dict:
        """The grasp as ``grasp best --json`` prints it."""
        return {"object": self.object, "hand": self.hand, "preshape": self.preshape, "pose": self.pose.tolist(),
                "joints": dict(self.closed_joints), "open_joints": dict(self.open_joints), "width": self.width,
                "epsilon": self.epsilon, "volume": self.volume, "force_closure": self.force_closure,
                "reachability": self.reachability, "manipulability": self.manipulability,
                "contacts": self.contacts.to_json(), "rank": self.rank, "score": self.score,
                "candidate": self.candidate, "seed": self.seed, "p_hold": self.p_hold,
                **(self.measures.to_json() if self.measures is not None else dict.fromkeys(MEASURE_KEYS))}


#: The keys ``to_json`` gives the analytic measures (None when not measured).
MEASURE_KEYS = ("resist_worst", "resist_mean", "open_margin", "close_margin", "push", "feasibility", "settled_epsilon")


#: The record's field names, in order.
FIELDS = tuple(Grasp.__dataclass_fields__)
