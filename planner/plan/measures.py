"""The analytic measures of a closed grasp: epsilon, weight resistance and
feasibility with its reasons (issue 15). Inputs: the contacts and the hand's
joint frames at the closed configuration (object frame, from closing), the
hand spec, the preshape (its closing synergy) and the object.

Feasibility, each a number and a reason (stored per grasp):

* ``open_margin`` [m]: the smallest travel a touching finger has left towards
  its OPEN limit, at its contacts (revolute: angle x the distance from the
  joint axis to its farthest contact). Below :data:`MIN_OPEN_MARGIN`:
  ``open_limit`` (no clearance: the open hand cannot be placed around the
  object, no squeeze travel); a parallel jaw whose fingers are both there
  also gets ``too_wide`` (the object fills the gripper's maximum opening).
* ``close_margin`` [m]: the same towards the CLOSED limit; below
  :data:`MIN_CLOSE_MARGIN`: ``at_close_stop`` (the finger cannot squeeze).
* ``push``: over finger contact regions, the smallest cosine between the
  contact normal and the direction closing moves the contact (the best
  contact of each region counts): 1 = pads pressed square on the object.
  Below :data:`MIN_PUSH`: ``back_or_side_contact`` (the finger touches with
  its back or side, where the hand cannot push).
* weight resistance, worst direction below :data:`MIN_RESISTANCE` g:
  ``cannot_hold_weight`` (the patches are too small, or the fingers too weak,
  to hold the object's weight at its friction in some direction).

The load on the grip (no flag): ``torque_per_mu`` [N m], the torque of the
object's weight about the grip axis (its mass x g x the grip measure
``gravity_arm``) over the object's friction coefficient: what the pads'
friction must resist as a torque, per unit of friction (Coulomb: the same
grip slips at twice the torque on half the friction). None where the grip
measures are not computed.

Motors (hand.toml ``[dynamics] effort``): one per driven joint, its mimics
geared to it; a Barrett finger that broke away (its distal joint closed on
past the 1:3 coupling) drives its distal joint alone while its proximal joint
is held by the clutch. Joints that do not close (the Barrett spread) are
held: by the worm gear (unbounded) on a non-backdrivable hand, else by the
motor's effort. Each motor's torque is bounded by its effort, push-only in
the closing sense (the grip a worm gear can build is the motor's).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping, MutableMapping, Sequence
from contextlib import contextmanager
from dataclasses import asdict, replace
from typing import TYPE_CHECKING

import numpy as np

from planner.plan.contacts import contact_models
from planner.record.contacts import HandContacts
from planner.record.measures import JointFrames, Measures
from planner.record.tolerances import MIN_CLOSE_MARGIN, MIN_OPEN_MARGIN
from planner.specs.hands import STILL, HandSpec
from planner.specs.preshapes import Preshape

if TYPE_CHECKING:  # the quality stage imports scipy.optimize, the object trimesh: loaded where used, so that
    # reading stored Measures (`grasp best`) needs neither
    from planner import quality
    from planner.geometry.solid import PreparedObject
    from planner.plan.grip import Grip
    from planner.plan.squeeze import Squeeze
    from planner.quality.resistance import HandDrive, ResistanceProgram
    from planner.record.grasp import Grasp

#: cos 72.5 deg: contact normal and closing motion further apart than this is
#: the back or side of a finger.
MIN_PUSH = 0.3
#: [g] a grasp that cannot hold its object's weight in some direction.
MIN_RESISTANCE = 1.0


def hand_drive(hand: HandSpec, shape: Preshape, closed: Mapping[str, float], frames: JointFrames) -> HandDrive:
    """The motors at the closed grasp (see the module docstring)."""
    from planner.quality.resistance import HandDrive, drive_rows

    act = hand.actuators
    hold = np.inf if not act.backdrivable else act.effort
    broken = hand.broken_away(closed)
    motors: list[tuple[dict[str, float], int, float]] = []
    for joint in hand.driven:
        rate = shape.close.get(joint.name, 0.0)
        coupled = hand.coupling(joint.name)
        if rate == 0.0:
            motors.append((coupled, 0, hold))
        elif joint.name in broken:
            motors.append(({name: 1.0 for name in coupled if name != joint.name}, int(np.sign(rate)), act.effort))
            motors.append(({joint.name: 1.0}, 0, np.inf if not act.backdrivable else act.effort))
        else:
            motors.append((coupled, int(np.sign(rate)), act.effort))
    t, sense, limit = drive_rows(frames.names, motors)
    types = tuple(hand.joint(n).kind for n in frames.names)
    return HandDrive(frames.origins, frames.axes, types, t, sense, limit)


def _axes(frames: JointFrames) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    return {name: (frames.origins[i], frames.axes[i]) for i, name in enumerate(frames.names)}


def measure(contacts: HandContacts, frames: JointFrames, hand: HandSpec, shape: Preshape,
            closed: Mapping[str, float], obj: PreparedObject, width: float | None = None,
            directions: np.ndarray | None = None, grip: Grip | None = None,
            local_sdf: np.ndarray | None = None, resist: quality.Resistance | None = None,
            squeeze: Squeeze | None = None) -> Measures:
    """Weight resistance and feasibility of a closed grasp (object frame);
    ``directions`` (k, 3) of the weight (None: the 14 of :data:`planner.geometry.gravity.SPHERE14`);
    ``grip``: its grip measures (:mod:`planner.plan.grip`), stored with the rest (None: not measured);
    ``local_sdf``: the object around it (:mod:`planner.plan.local_sdf`; None: not measured);
    ``resist``: its weight resistance when already solved, with other grasps' (:func:`resistances` of its
    :func:`resistance_program`; None: solved here, by HiGHS); ``squeeze``: what its squeeze ends in
    (:mod:`planner.plan.squeeze`; None: the hand does not squeeze)."""
    from planner.geometry.gravity import SPHERE14
    from planner.quality.resistance import solve, summarise

    directions = SPHERE14 if directions is None else directions
    if resist is None:
        resist = summarise(solve(resistance_program(contacts, frames, hand, shape, closed, obj), directions))
    push, open_margin, close_margin, both_open = _fingers(contacts, frames, hand, shape, closed)
    reasons = []
    if open_margin < MIN_OPEN_MARGIN:
        reasons.append("open_limit")
        if hand.centering and both_open:
            reasons.append("too_wide")
    if close_margin < MIN_CLOSE_MARGIN:
        reasons.append("at_close_stop")
    if push < MIN_PUSH:
        reasons.append("back_or_side_contact")
    if resist.worst < MIN_RESISTANCE:
        reasons.append("cannot_hold_weight")
    grips = {} if grip is None else {k: float(v) for k, v in asdict(grip).items()}
    if grip is not None:
        grips["torque_per_mu"] = torque_per_mu(obj.mass, obj.friction, grip.gravity_arm)
    squeezes = {} if squeeze is None else {"squeezed_force_closure": squeeze.force_closure,
                                           "squeezed_epsilon": squeeze.epsilon, "squeeze_turn": squeeze.turn}
    return Measures(resist.worst, resist.mean, open_margin, close_margin, push, tuple(reasons), **grips,
                    local_sdf=local_sdf, **squeezes)


#: Grasps waiting in :func:`measured_later` are solved together once this many wait (and at the end): 14 x
#: 4,096 programs keep the batch's per-call cost thin, and bound the queue (a Barrett grasp's program and standard
#: form are ~28 KB, 6 times its record: a unit of 1,000,000 candidates, ~1,000,000 grasps, would queue ~28 GB).
WAITING = 4096


#: One grasp waiting in :func:`measured_later`: (its index in the grasps, its :func:`resistance_program`, its
#: :func:`measure` but ``resist``) and optionally where its ``local_sdf`` is to be read, (the unit's
#: :class:`~planner.plan.local_sdf.LocalSurface`, the grasp's pose (4, 4)): then its :func:`measure` but ``resist``
#: and ``local_sdf``.
Waiting = tuple


class _Waiting(list):  # type: ignore[type-arg]
    """The grasps waiting for their measures: ``fill`` called whenever :data:`WAITING` of them wait."""

    def __init__(self, fill: Callable[[], None]) -> None:
        super().__init__()
        self._fill = fill

    def append(self, item: Waiting) -> None:
        super().append(item)
        if len(self) >= WAITING:
            self._fill()


@contextmanager
def measured_later(grasps: list[Grasp], timing: MutableMapping[str, float]) -> Iterator[list[Waiting]]:
    """A list for the sweep's closed grasps to wait in (:data:`Waiting`). Once :data:`WAITING` wait, and on
    leaving, also on an error (a failed unit stores the grasps it has), ``grasps[index]`` gets those measures, the
    weight resistances of all waiting solved together (:func:`resistances`) and their ``local_sdf`` read together
    (:func:`~planner.plan.local_sdf.measured_together`; one at a time, in order, should that fail), their time
    added to ``timing["quality"]`` [s]. Should one fail, the grasps from the first left without measures on are
    dropped (measured one at a time, the sweep stopped at it) and the error raised."""
    from planner.plan.local_sdf import measured_together

    def fill() -> None:
        start, filled = time.perf_counter(), 0
        try:
            found = resistances([item[1] for item in pending])
            asked = [item[3] if len(item) > 3 else None for item in pending]
            try:
                sdf = measured_together(asked)
            except Exception:  # noqa: BLE001 - read again one at a time below, where the failing grasp raises
                sdf = None
            for k, (item, resist) in enumerate(zip(pending, found)):
                given = {} if len(item) < 4 else {"local_sdf": measured_together([asked[k]])[0] if sdf is None
                                                  else sdf[k]}
                grasps[item[0]] = replace(grasps[item[0]], measures=item[2](resist=resist, **given))
                filled += 1
        except BaseException:
            del grasps[pending[filled][0]:]
            raise
        finally:
            del pending[:]
            timing["quality"] += time.perf_counter() - start

    pending = _Waiting(fill)
    try:
        yield pending
    finally:
        fill()


def torque_per_mu(mass: float, friction: float, gravity_arm: float) -> float:
    """[N m] the weight's torque about the grip axis over the friction coefficient: ``mass`` [kg] x g x
    ``gravity_arm`` [m] / ``friction``."""
    from planner.quality.tolerances import GRAVITY

    return float(mass * GRAVITY * gravity_arm / friction)


def resistance_program(contacts: HandContacts, frames: JointFrames, hand: HandSpec, shape: Preshape,
                       closed: Mapping[str, float], obj: PreparedObject) -> ResistanceProgram:
    """The weight-resistance program of a closed grasp (object frame; :func:`planner.quality.resistance.program`
    with the hand's motors and the object's friction, mass and centre of mass)."""
    from planner.quality.resistance import ResistanceProgram, program
    from planner.quality.tolerances import GRAVITY, RESISTANCE_CAP

    if len(contacts) == 0:
        return ResistanceProgram(np.zeros((6, 0)), np.zeros((0, 0)), np.zeros(0), obj.mass * GRAVITY, RESISTANCE_CAP)
    models, torsion = contact_models(contacts, hand, obj.friction)
    links = sorted(set(contacts.links))
    index = np.array([links.index(link) for link in contacts.links])
    moves = [hand.joint(name).moves for name in frames.names]
    affects = np.array([[link in m for m in moves] for link in contacts.links], bool)
    return program(contacts.points, contacts.frames, mu=obj.friction, center=obj.com, mass=obj.mass,
                   drive=hand_drive(hand, shape, closed, frames), contact_links=index,
                   joint_affects=affects.reshape(len(contacts), -1), model=models, torsion=torsion)


def resistances(programs: Sequence[ResistanceProgram], directions: np.ndarray | None = None
                ) -> list[quality.Resistance]:
    """The weight resistance of each of ``programs`` along ``directions`` (k, 3) (None: the 14 of
    :data:`planner.geometry.gravity.SPHERE14`), all solved together (:mod:`planner.quality.resistance_batch`:
    the answers of HiGHS one grasp at a time, to ~1e-10 g; less than half its cost on a Panda or PR2 unit, a
    little less on a Barrett one)."""
    from planner.geometry.gravity import SPHERE14
    from planner.quality.resistance import summarise
    from planner.quality.resistance_batch import solve_many

    return [summarise(r) for r in solve_many(programs, SPHERE14 if directions is None else directions)]


def _fingers(contacts: HandContacts, frames: JointFrames, hand: HandSpec, shape: Preshape,
             closed: Mapping[str, float]) -> tuple[float, float, float, bool]:
    """(push, open margin [m], close margin [m], every finger DOF within the open margin)."""
    pushes, open_m, close_m, near_open = [], [np.inf], [np.inf], []
    axes = _axes(frames)
    for dof in hand.closing_dofs(shape.close, closed):
        v = hand.contact_velocity(dof.rates, contacts.points, contacts.links, axes)
        speed = np.linalg.norm(v, axis=1)
        on = speed > STILL
        if not on.any():
            continue
        cos = np.einsum("ij,ij->i", contacts.normals[on], v[on]) / speed[on]
        owner = np.where(contacts.region[on] >= 0, contacts.region[on], -1 - np.flatnonzero(on))
        pushes += [float(cos[owner == r].max()) for r in np.unique(owner)]
        mine_open = hand.travel(dof.rates, closed, speed[on].max(), "open")
        close_m.append(hand.travel(dof.rates, closed, speed[on].max(), "closed"))
        open_m.append(mine_open)
        near_open.append(mine_open < MIN_OPEN_MARGIN)
    return (min(pushes, default=0.0), float(min(open_m)), float(min(close_m)),
            bool(near_open) and all(near_open))
