"""The one grasp record, from the sweep to the database to every export.

A :class:`Grasp` is made by the planner (:mod:`planner.plan.unit`) with what
the sweep found and what the quality and reachability stages measured; the
database (:mod:`planner.db.store`) stores it and returns it with what it adds
(``id``, ``unit_id``, ``score``, ``rank``) and with the results of physical
validation (:class:`Trial`, :class:`RobustEpsilon`) where they exist. The
exporters turn lists of them into columns (:mod:`planner.datasets.columns`),
``grasp best --json`` prints :meth:`Grasp.to_json`. Each stored attribute
is declared where it is defined (:func:`~planner.record.field.stored`: kind,
unit, schema version, doc); :mod:`planner.record.fields` collects them.

Frames: the object frame is the frame of the scaled mesh file; the grasp pose
is the hand frame (the hand's ``root_link``) in the object frame. Lengths in
metres, angles in radians, joint values in radians or metres.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, fields, replace

import numpy as np

from planner.record.contacts import HandContacts
from planner.record.field import stored, stored_numbers
from planner.record.measures import Measures


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
    """The outcome of one dynamic shake trial: PyBullet's
    (:func:`planner.validation.shake.trial`, the record's ``validation``) or
    MuJoCo's, an independent protocol
    (:func:`planner.validation.mujoco_trial.trial`, the record's ``mujoco``).

    Motions are the object's relative to the hand, as ACRONYM stores them:
    while the fingers closed and settled, and the largest during the loads
    (centre of mass [m], rotation [rad]). ``fingers_in_contact``: distinct
    fingers touching after closing. ``reason``: ``held``, ``slipped``,
    ``squeezed_out``, ``no_contact``, ``no_clearance`` or ``start_overlap``
    (the last two are flags: not simulated, motions 0), or MuJoCo's
    ``diverged`` (no verdict, motions 0; never stored); empty when unknown
    (imported files, older databases). Docs say ``{engine}`` where the
    declaration of each group (:mod:`planner.record.fields`) names its engine.
    """

    success: bool = stored("bool", "", 2, "1 if the object stayed in the hand in the {engine} trial",
                           ranked="success")
    fingers_in_contact: int = stored("int", "", 2, "fingers touching the object after shaking")
    closing_linear: float = stored("real", "m", 2, "object motion during closing")
    closing_angular: float = stored("real", "rad", 2, "object rotation during closing")
    shaking_linear: float = stored("real", "m", 2, "object motion during shaking")
    shaking_angular: float = stored("real", "rad", 2, "object rotation during shaking")
    reason: str = stored("text", "", 3, "why the trial ended as it did ('' = unknown)", default="")


@dataclass(frozen=True)
class RobustEpsilon:
    """Epsilon over noisy copies of a grasp (:mod:`planner.validation.robust`)."""

    mean: float = stored("real", "", 2, "robust epsilon: mean over pose / friction noise samples")
    quantile: float = stored("real", "", 2, "robust epsilon: low quantile over the samples", ranked="robust_quantile")
    samples: int = stored("int", "", 2, "noise samples behind the robust values")


@dataclass(frozen=True)
class FileLabel:
    """A success label the file a grasp was imported from gives its pose (ACRONYM's
    ``grasps/qualities/flex/object_in_gripper``: FleX's verdict in ACRONYM's own files, a real robot's outcomes
    in a user's): kept as the file says it, beside what this project measures, and exported again."""

    success: bool = stored("bool", "", 16, "1 if the file the grasp was imported from labels it held (its "
                           "`grasps/qualities/flex/object_in_gripper`: FleX's verdict in ACRONYM's files, a user's "
                           "outcomes), 0 dropped")
    source: str = stored("text", "", 16, "the file and dataset the label was read from")


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
        width: [m] distance between the fingers at the closed joints (:mod:`planner.plan.width`), else None.
        contacts: the contacts, object frame.
        epsilon, volume: Ferrari-Canny L1 epsilon and GWS volume (0 unless force closure).
        reachability: fraction of sampled table placements an arm reaches (None: not computed).
        manipulability: the best arm manipulability over those placements.
        squeezed_from_turn: [rad] where the grasp is where the squeeze (:mod:`planner.plan.squeeze`) of a planned
            grasp that is not force closure ends force closure (the hand closed again at the turned pose, a grasp
            of its own beside its parent, with the parent's candidate fields): how far the hand turned from the
            parent's pose; None: the hand closed where it was planned (every grasp of another hand, of an import).
        table_plane: (4,) the table the grasp was planned on (:class:`planner.geometry.support.Support`):
            [nx, ny, nz] the unit normal out of the table and the height [m], object frame (the table top
            is ``n . x = height``); None: planned on the object alone.
        id, unit_id, score, p_hold, p_hold_trial, rank: set by the database (rank 1 = best of its object and hand).
        validation, mujoco, robust: physical validation results, where they
            exist: the PyBullet trial, the MuJoCo trial (another engine and
            protocol) and the robust epsilon.
        file_label: the success label of the file the grasp was imported from (``grasp import``), where it gave
            one; None: none given.
        measures: weight resistance and feasibility (None: not measured, e.g.
            a grasp stored before schema version 3).
        end_kept: True where the grasp's squeeze's end is kept as a grasp of its own beside it (the same unit and
            candidate): the sweep's (:mod:`planner.plan.keeping`) and, read from a database, whether that end is
            stored there (not a column: :func:`planner.db.ranking.end_kept_sql`); the end then stands for it in the
            rank (:data:`planner.db.ranking.FIRST`). None: not known (an import's record before it is stored, one
            made by hand): no end stands for it.
        p_hold: calibrated probability in [0, 1] that the grasp holds
            (:mod:`planner.calibration`), set by the database where it writes
            the scores (the hand's model applied to the record's measures);
            None where no model applies.
        p_hold_trial: p_hold updated by the verdict of the grasp's trial
            (:attr:`trial`), set by the database likewise
            (:meth:`planner.calibration.logistic.LogisticModel.given_trial`);
            None where no trial tried it or the model has no update for
            that trial's engine.
    """

    object: str = stored("text", "", 1, "object name (key of the `objects` table)")
    hand: str = stored("text", "", 1, "hand name")
    preshape: str = stored("text", "", 1, "preshape name")
    candidate: int = stored("int", "", 1, "candidate number in the unit's enumeration (to replay it)")
    seed: int = stored("int", "", 1, "the unit's seed")
    approach_point: np.ndarray = stored("vector", "m", 1, "where the approach ray meets the object, object frame",
                                        shape=(3,))
    approach_dir: np.ndarray = stored("vector", "", 1, "unit approach direction, object frame", shape=(3,))
    roll: float = stored("real", "rad", 1, "roll of the hand about the approach direction")
    standoff: float = stored("real", "m", 1, "back-off after first contact, before closing")
    pose: np.ndarray = stored("vector", "m", 1, "grasp pose, row-major 4x4: the hand frame (`root_link`) in the "
                              "object frame", shape=(4, 4))
    open_joints: Joints = stored("joints", "rad or m", 1, "JSON `{joint: value}` of the preshape")
    closed_joints: Joints = stored("joints", "rad or m", 1, "JSON `{joint: value}` of the closed hand")
    width: float | None = stored("real", "m", 1, "distance between the fingers at the closed joints: a "
                                 "self-centring parallel jaw's opening (the Panda), the gap between the pads a hand "
                                 "names in `width_links` (the PR2's fingertips; negative: they overlap); null for the "
                                 "other hands", required=False)
    contacts: HandContacts = stored("contacts", "m", 1, "JSON `[{point, normal, link}]`, object frame, normals "
                                    "into the object")
    epsilon: float = stored("real", "", 1, "Ferrari-Canny L1 epsilon (0 unless force-closure)", ranked="epsilon")
    volume: float = stored("real", "", 1, "volume of the grasp wrench space (0 unless generated with `--volume`)")
    force_closure: bool = stored("bool", "", 1, "1 if force-closure, else 0", ranked="force_closure")
    reachability: float | None = stored("real", "", 1, "fraction of sampled table placements an arm reaches",
                                        required=False, ranked="reachability", default=None)
    manipulability: float | None = stored("real", "", 1, "best arm manipulability over the reachable placements",
                                          required=False, default=None)
    table_plane: np.ndarray | None = stored("vector", "m", 6, "[nx, ny, nz, height]: the table top the grasp was "
                                            "planned on, object frame (`n . x = height`, n out of the table); null: "
                                            "planned on the object alone", required=False, shape=(4,), default=None)
    squeezed_from_turn: float | None = stored("real", "rad", 15, "where the grasp is the end of a self-centring "
                                              "parallel jaw's squeeze (`planner/plan/squeeze.py`) of the planned "
                                              "grasp of the same unit and candidate, whose contacts are not force "
                                              "closure: the angle the hand turned from that planned pose (it "
                                              "closes there from its parent's opening: its open joints are a "
                                              "pre-grasp posture; it carries its parent's candidate fields, the ray "
                                              "its parent was planned along: send its pose, never rebuild it from "
                                              "the ray); null: closed where it was planned", required=False,
                                              default=None)
    id: int | None = stored("int", "", 1, "`grasps.id` in the database", key=True, default=None)
    unit_id: int | None = stored("int", "", 1, "the unit of work that produced the grasp", default=None)
    score: float | None = stored("real", "", 1, "ranking score (`meta.ranking` says how)", default=None)
    p_hold: float | None = stored("real", "", 5, "calibrated probability that the grasp holds (the hand's "
                                  "`grasp calibrate` model, or the shipped one; null: no model)", required=False,
                                  ranked="p_hold", default=None)
    p_hold_trial: float | None = stored("real", "", 8, "p_hold updated by the verdict of the trial that tried the "
                                        "grasp (MuJoCo's, else PyBullet's), as the hand's model says "
                                        "(`planner/calibration/update.py`); null: not tried, or the model has no "
                                        "update for that trial's engine", required=False, ranked="p_hold_trial",
                                        default=None)
    rank: int | None = stored("int", "", 1, "1 = best grasp of its (object, hand)", required=False, default=None)
    validation: Trial | None = None
    mujoco: Trial | None = None
    robust: RobustEpsilon | None = None
    file_label: FileLabel | None = None
    measures: Measures | None = None
    end_kept: bool | None = None

    @property
    def trial(self) -> Trial | None:
        """The dynamic trial whose verdict labels and ranks the grasp: the
        first in :data:`planner.record.fields.TRIAL_PRECEDENCE` that tried it
        (MuJoCo's, then PyBullet's); None if none did."""
        from planner.record.fields import TRIAL_PRECEDENCE  # fields declares itself from this module

        return next((t for t in (getattr(self, name) for name in TRIAL_PRECEDENCE) if t is not None), None)

    def __post_init__(self) -> None:
        if self.pose.shape != (4, 4) or self.approach_point.shape != (3,) or self.approach_dir.shape != (3,):
            raise ValueError("Grasp.pose must be (4, 4), approach_point and approach_dir (3,)")
        if self.table_plane is not None and np.shape(self.table_plane) != (4,):
            raise ValueError("Grasp.table_plane must be (4,) [nx, ny, nz, height] or None")
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

    def as_stored(self) -> Grasp:
        """The record as the database gives it back: every ``vector`` (the
        pose, the approach ray, the table plane) rounded as stored
        (:data:`~planner.record.field.VECTOR_DIGITS` decimals), the contacts
        as their stored text (:data:`~planner.record.contacts.STORED_DIGITS`);
        joint values and measures are stored exactly. What is computed from
        this record gives what the same computation gives on the stored grasp,
        to the last bit: it matters for the settle, whose dynamics turn a
        nanometre of the pose into another settled epsilon."""
        vectors = {f.name: np.reshape(stored_numbers(getattr(self, f.name)), f.metadata["stored"]["shape"])
                   for f in fields(self) if "stored" in f.metadata and f.metadata["stored"]["kind"] == "vector"
                   and getattr(self, f.name) is not None}
        c = self.contacts
        return replace(self, contacts=HandContacts.stored(c.json_text(), c.count, c.touching), **vectors)

    def to_json(self) -> dict:
        """The grasp as ``grasp best --json`` prints it: every field of
        :func:`planner.record.fields.record_fields` by its flat name (null
        when absent), ``joints``, the closed joints again (its name
        before the declaration), and ``end_kept``: whether the squeeze's end
        of this grasp is stored beside it and ranks for it (the derived
        attribute that ranks it after every force-closure grasp)."""
        from planner.record.fields import getter, json_value, record_fields

        out = {f.name: json_value(f, getter(f)(self)) for f in record_fields()}
        return {**out, "joints": out["closed_joints"], "end_kept": bool(self.end_kept)}


#: The record's field names, in order.
FIELDS = tuple(Grasp.__dataclass_fields__)
