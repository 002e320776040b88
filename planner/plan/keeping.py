"""A unit's closed grasps kept as records (:class:`Keeper`): each one's quality, squeeze and grip measured now, its
weight resistance and ``local_sdf`` left waiting to be found with others'
(:func:`~planner.plan.measures.measured_later`), its :class:`~planner.record.grasp.Grasp` appended; and where a
self-centring parallel jaw's squeeze (:mod:`planner.plan.squeeze`) of a grasp whose planned contacts are not force
closure ends force closure, that end too, as a grasp of its own.

The squeeze's end is where the closing of a real jaw on a free object ends (the object turned between the pads until
the wall lies flat on both): the turned hand and its squeeze's last closing there, opened as its parent was (its
open joints, a posture to approach in), whose contacts ARE force closure as planned. It is kept beside its parent,
which stays as planned, with the parent's candidate fields (preshape, candidate, approach ray, roll, standoff; the
two share the unit and the candidate number) and how far it turned (``squeezed_from_turn``); every measure is
computed at it as at any grasp of the sweep (its own squeeze: force closure as planned, not turned). Only the sweep
keeps it: the importer's re-scoring (:mod:`planner.datasets.importer`) keeps exactly the poses it is given.
"""

from __future__ import annotations

import logging
from collections import Counter
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from planner import quality
from planner.errors import DegenerateGraspError
from planner.geometry.solid import PreparedObject
from planner.plan import grip
from planner.plan.closing import Closed, Grasper
from planner.plan.contacts import HandContacts, grasp_quality
from planner.plan.local_sdf import LocalSurface
from planner.plan.measures import measure, resistance_program
from planner.plan.squeeze import Squeeze, squeezed
from planner.plan.sweep import Candidate, SweepSettings
from planner.plan.width import closed_width
from planner.record.grasp import Grasp
from planner.specs.hands import HandSpec

log = logging.getLogger(__name__)

#: Rejection reason of a grasp whose quality :mod:`planner.quality` cannot compute.
QUALITY_FAILED = "quality_failed"

#: (approach point [m], approach direction, roll [rad], standoff [m]) of a candidate, object frame: its record's.
Ray = tuple[np.ndarray, np.ndarray, float, float]


@dataclass
class Keeper:
    """What keeps one unit's grasps: its ``hand``, ``obj``, ``settings`` and ``seed``; the ``grasper`` that closed
    them (the squeeze closes again in it); the exact surface ``gripping`` (grip measures), the ``local`` surface
    (``local_sdf``); ``up`` (3,) the object's up (object frame; on a table, the table's); the unit's ``grasps``
    and ``waiting`` (:func:`~planner.plan.measures.measured_later`'s list, where their resistances wait)."""

    hand: HandSpec
    obj: PreparedObject
    settings: SweepSettings
    seed: int
    grasper: Grasper
    gripping: grip.GripSurface
    local: LocalSurface
    up: np.ndarray
    grasps: list[Grasp]
    waiting: list

    def keep(self, cand: Candidate, closed: Closed, ray: Ray, q: quality.Quality) -> int:
        """Keep the grasp ``closed`` of candidate ``cand`` (its approach ``ray``) whose contacts' quality is ``q``,
        and its squeeze's end where that is force closure and ``q`` is not (the module docstring); returns how many
        force-closure grasps were kept (what counts towards the unit's budget)."""
        squeeze = squeezed(self.grasper, closed, cand.preshape, q, self.score)
        self._append(cand, closed, ray, q, squeeze, None)
        end = self._end(closed, squeeze, q)
        if end is None:
            return int(q.force_closure)
        again = squeezed(self.grasper, end[0], cand.preshape, end[1], self.score)  # force closure: not turned
        self._append(cand, end[0], ray, end[1], again, squeeze.turn)  # type: ignore[union-attr]
        self.grasps[-2] = replace(self.grasps[-2], end_kept=True)  # the end stands for it in the rank
        return int(q.force_closure) + 1

    def score(self, contacts: HandContacts) -> quality.Quality | None:
        """The quality of the squeeze's turned closings (no volume, rejections not counted)."""
        return scored(contacts, self.hand, self.obj, self.settings.cone_edges, Counter(), False)

    def _end(self, closed: Closed, squeeze: Squeeze | None, q: quality.Quality
             ) -> tuple[Closed, quality.Quality] | None:
        """The squeeze's end kept as a grasp and its quality (the sweep's, with a volume where it asks for one),
        or None: the planned contacts force closure, no squeeze, one not ending force closure, or one whose turned
        hand opened as its parent was would overlap the object or the table, or on a table, backed off to the
        pre-grasp, would touch the table.

        The end is the squeeze's last closing (its contacts, joints and quality) with its parent's opening as its open
        joints (as the sweep opens an antipodal candidate's hand): the squeeze's closing began only
        :data:`~planner.plan.squeeze.REOPEN` wider than the one before, no posture to approach in (an export's
        pre-grasp posture, the trials' start, the pre-grasp's reach and table checks). Until
        :data:`~planner.plan.sweep.ALGORITHM_VERSION` 26 the hand closed once more there from that opening: a second
        closing per end (~5% of a mug's unit) that ended where the squeeze's had, within 0.14 mm (median 1e-6 m) on
        the mug, teddy, duck and random_007, with the same contacts and epsilons within noise."""
        if q.force_closure or squeeze is None or not squeeze.force_closure or squeeze.end is None:
            return None
        opened = self.hand.full_configuration({j.name: closed.open_joints[j.name] for j in self.hand.driven})
        pose = squeeze.end.pose
        backed = pregrasp(pose, self.hand, self.settings.pregrasp_distance)
        if self.grasper.overlaps_at(pose, opened) or (self.settings.table_plane is not None
                                                      and self.grasper.on_table_at(backed, opened)):
            return None
        end = replace(squeeze.end, open_joints={j.name: opened[j.name] for j in self.hand.driven})
        if not self.settings.volume and squeeze.quality is not None:
            return end, squeeze.quality  # what the squeeze scored it: the sweep's quality, no volume
        again = scored(end.contacts, self.hand, self.obj, self.settings.cone_edges, Counter(), self.settings.volume)
        return None if again is None or not again.force_closure else (end, again)

    def _append(self, cand: Candidate, closed: Closed, ray: Ray, q: quality.Quality, squeeze: Squeeze | None,
                turned: float | None) -> None:
        hand, obj = self.hand, self.obj
        width = closed_width(hand, closed.closed_joints)
        at = (closed.contacts, closed.frames, hand, cand.preshape, closed.closed_joints, obj)
        gripped = grip.measure(hand, self.gripping, closed.contacts, closed.link_poses or {}, obj.com, self.up)
        later = partial(measure, *at, width, grip=gripped, squeeze=squeeze)  # type: ignore[arg-type]
        waiting = resistance_program(*at)  # type: ignore[arg-type]
        point, direction, roll, standoff = ray
        table = self.settings.table_plane
        self.grasps.append(Grasp(
            object=obj.name, hand=hand.name, preshape=cand.preshape.name, candidate=cand.index, seed=self.seed,
            approach_point=point, approach_dir=direction, roll=roll, standoff=standoff, pose=closed.pose,
            open_joints=closed.open_joints, closed_joints=closed.closed_joints, width=width,
            contacts=closed.contacts, epsilon=q.epsilon, volume=q.volume, force_closure=q.force_closure,
            measures=None, table_plane=None if table is None else np.array(table, float), squeezed_from_turn=turned))
        # once recorded: a record that fails leaves none; its local_sdf read with the others' (measured_later)
        self.waiting.append((len(self.grasps) - 1, waiting, later, (self.local, closed.pose)))


def pregrasp(pose: np.ndarray, hand: HandSpec, distance: float) -> np.ndarray:
    """(4, 4) the hand backed off ``distance`` [m] along its approach from ``pose`` (4, 4)."""
    out = np.array(pose, float)
    out[:3, 3] -= (out[:3, :3] @ hand.approach) * distance
    return out


def scored(contacts: HandContacts, hand: HandSpec, obj: PreparedObject, cone_edges: int, rejected: Counter,
           volume: bool = True) -> quality.Quality | None:
    """:func:`grasp_quality`, or None with :data:`QUALITY_FAILED` counted in
    ``rejected`` when :mod:`planner.quality` cannot analyse these contacts
    (a ``HullError`` or another ``DegenerateGraspError``): one grasp is
    rejected, not its whole unit."""
    try:
        return grasp_quality(contacts, hand, obj, cone_edges, volume)
    except DegenerateGraspError as exc:
        rejected[QUALITY_FAILED] += 1
        log.debug("%s/%s: grasp rejected, quality not computable: %s", obj.name, hand.name, exc)
        return None
