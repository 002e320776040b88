"""Physical validation: a dynamic PyBullet trial of stored grasps.

Everything happens in the hand frame: the hand's base is fixed at the world
origin and the object is placed at the inverse of the grasp pose, so one
gravity vector loads every trial of a world alike.

1. Flags, no physics: ``no_clearance`` if a touching finger's planned
   configuration leaves less than ``min_clearance`` of open travel at its
   contact (the open hand could not have been put around the object).
2. Close: the fingers start ``start_gap`` short of the planned grasp (at the
   contact) and close at the hand's speed under velocity motors limited to
   the hand's published ``effort`` (``[dynamics]`` of hand.toml): once
   blocked, each motor pushes with exactly its limit. Mimic joints are gear
   constraints sharing their motor's effort. A driven joint flagged
   ``breakaway`` (the Barrett's TorqueSwitch) follows the planner's closing
   rule: once its proximal link touches, the gear lets go, the proximal
   joint is braked and the distal closes on alone. Non-backdrivable fingers
   (worm gears) cannot be pushed open once closed (the open-side joint limit
   follows the finger). No gravity yet (the object rests as on a table).
   ``start_overlap`` if the open hand starts deeper than ``max_start_overlap``
   in the object's collision shape (true depth: collision margins removed).
3. Settle, then load: the object's weight acts along +-x, +-y, +-z of the
   hand frame in turn, the gravity vector moving smoothly (linearly over
   ``ramp_time``) from one direction to the next and held ``hold_time``.
4. Verdict: ``held`` if after every direction the centre of mass moved less
   than ``max_translation`` and the object turned less than ``max_rotation``
   relative to the hand since the fingers closed, and it still touches the
   hand; ``slipped`` if not. No finger on the object once the fingers have
   closed: ``squeezed_out`` if closing moved it by more than those
   thresholds, else ``no_contact`` (closed on air). A failed trial leaves
   the world at once.

Contacts are rigid (the URDF's soft contacts removed), with the object's own
friction (see :mod:`planner.sim.dynamics`) and, on soft links, the torsional
friction of :class:`~planner.specs.hands.ContactModel` (the same number the
analytic soft-finger model uses), except on a link whose planned contacts
are one point on a sharp edge or corner of its shape (no contact patch:
:mod:`planner.validation.pads`). One trial at a time (``batch`` 1, the
default) runs in one world that loads the hand once and is put back before
each grasp: the results of a fresh world per grasp, bit for bit. Several
trials can share a world (``batch``), each in its own collision filter
group: same verdicts on clear-cut grasps, not bit-identical for objects made
of several convex parts (Bullet's contact order depends on the other bodies).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from planner.errors import ConfigError
from planner.geometry.frames import angle_between
from planner.geometry.solid import PreparedObject
from planner.record.contacts import HandContacts
from planner.record.grasp import Grasp, Trial
from planner.sim import Body
from planner.sim.dynamics import Dynamics, Shape, fresh_world
from planner.specs.hands import HandSpec
from planner.validation import fingers as fg
from planner.validation.actuation import Breakaway, break_away, drive_fingers, hold_closed, joint_axes, set_contacts
from planner.validation.parts import trial_shape
from planner.validation.settings import ShakeSettings
from planner.validation.tolerances import GRAVITY, LOAD_DIRECTIONS

#: Why a trial ended as it did (``Trial.reason``).
REASONS = ("held", "slipped", "squeezed_out", "no_contact", "no_clearance", "start_overlap")


#: How the trial builds the object's collision shape, stored with each result so that a verdict of
#: another shape is tried again: 2, every convex part (until 2026-12-06 an object of more than 16 parts
#: kept its first 16 in PyBullet: planner.sim.dynamics.MAX_SHAPE_ARRAY).
OBJECT_SHAPE = 2


def recorded(settings: ShakeSettings, hand: HandSpec) -> str:
    """What decides a hand's trials, as stored with each result (JSON): the
    settings, the finger actuators and the torsion radii of the soft links."""
    torsion = {link: m.torsion_radius for link, m in sorted(hand.contacts.items()) if m.model == "soft"}
    return json.dumps({**asdict(settings), "object_shape": OBJECT_SHAPE, "hand": hand.name,
                       "actuators": asdict(hand.actuators),
                       "breakaway": [j.name for j in hand.joints if j.breakaway], "torsion_radius": torsion,
                       **fg.inertia(hand)}, sort_keys=True)


def trial(hand: HandSpec, obj: PreparedObject, grasp: Grasp, settings: ShakeSettings | None = None,
          friction: float | None = None, mass: float | None = None) -> Trial:
    """Shake-test one grasp. ``friction``/``mass`` override the object's (tests)."""
    return trials(hand, obj, [grasp], settings, friction, mass)[0]


#: Called with each trial's grasp and the contacts it settled into (object
#: frame, PyBullet's points) once the fingers have closed and the object has
#: come to rest, before any load; trials flagged before physics are skipped.
Settled = Callable[[Grasp, HandContacts], None]


def trials(hand: HandSpec, obj: PreparedObject, grasps: Sequence[Grasp], settings: ShakeSettings | None = None,
           friction: float | None = None, mass: float | None = None, on_settled: Settled | None = None) -> list[Trial]:
    """Shake-test grasps of one object, ``settings.batch`` per PyBullet world
    (consecutive chunks of ``grasps``: pass them in a fixed order so that the
    results do not depend on how work is split). ``on_settled``: see
    :data:`Settled` (measuring the grasp the squeeze settles into)."""
    s = settings or ShakeSettings()
    for j in hand.joints:
        if j.mimic is not None and j.offset != 0.0:
            raise ConfigError(f"hand '{hand.name}': mimic joint '{j.name}' has an offset; trials couple mimics "
                              "with gears, which keep q = multiplier x q[mimic] only")
    physical = _Physical(obj.friction if friction is None else friction, obj.mass if mass is None else mass)
    shape = trial_shape(obj, s.part_tolerance)
    return _worlds(hand, obj, shape, physical, grasps, s, on_settled)


@dataclass(frozen=True)
class _Physical:
    friction: float
    mass: float


@dataclass
class _Run:
    """One trial in a world: its hand, object, fingers and what was measured."""

    grasp: Grasp
    body: Body
    uid: int
    fingers: tuple[frozenset[int], ...]
    rates: dict[str, float]  # the grasp's closing rates (:func:`~planner.validation.fingers.closing_rates`)
    clutches: list[Breakaway] = field(default_factory=list)  # still engaged
    closed: np.ndarray = field(default_factory=lambda: np.eye(4))
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    touching: int = 0
    closing: tuple[float, float] = (0.0, 0.0)
    shaking: list[float] = field(default_factory=lambda: [0.0, 0.0])
    held: bool = True
    own_hand: bool = True  # the hand leaves the world with the trial (else it stays for the next grasp)
    own_object: bool = True  # the object leaves too (else it stays, left where it is: no other trial steps it)
    gone: bool = False  # left the world (:func:`_leave`)


def settled_contacts(hand: HandSpec, obj: PreparedObject, grasps: Sequence[Grasp],
                     settings: ShakeSettings | None = None) -> list[HandContacts]:
    """The contacts (object frame, PyBullet's points, normals into the
    object) each grasp settles into when the fingers close dynamically on the
    free object, without load: the first two phases of a trial (flags, close
    and settle), not the shake. Empty for a grasp flagged before physics.
    One grasp per world unless ``settings.batch`` says otherwise (pass 1 for
    results that do not depend on how grasps are grouped)."""
    s = settings or ShakeSettings()
    seen: dict[int, HandContacts] = {}

    def keep(grasp: Grasp, contacts: HandContacts) -> None:
        seen[id(grasp)] = contacts

    physical = _Physical(obj.friction, obj.mass)
    shape = trial_shape(obj, s.part_tolerance)
    _worlds(hand, obj, shape, physical, grasps, s, keep, load=False)
    empty = HandContacts(np.zeros((0, 3)), np.zeros((0, 3)), ())
    return [seen.get(id(g), empty) for g in grasps]


def _worlds(hand: HandSpec, obj: PreparedObject, shape: Shape, physical: _Physical, grasps: Sequence[Grasp],
            s: ShakeSettings, on_settled: Settled | None = None, load: bool = True) -> list[Trial]:
    """The trials of ``grasps``, ``s.batch`` to a world (consecutive chunks),
    or, one to a world (``batch`` 1), one after the other in one world
    (:func:`_in_turn`)."""
    if s.batch == 1:
        return _in_turn(hand, obj, shape, physical, grasps, s, on_settled, load)
    out: list[Trial] = []
    for i in range(0, len(grasps), s.batch):
        out += _world(hand, obj, shape, physical, grasps[i:i + s.batch], s, on_settled, load)
    return out


def _in_turn(hand: HandSpec, obj: PreparedObject, shape: Shape, physical: _Physical, grasps: Sequence[Grasp],
             s: ShakeSettings, on_settled: Settled | None = None, load: bool = True) -> list[Trial]:
    """One trial at a time in one world: the hand and the object are loaded
    once (PyBullet takes ~3 ms to make a hand, a third of a Barrett's settle,
    and ~1 ms to make the object), the object is parked after each grasp (its
    contacts gone: :meth:`Dynamics.park`) and the world put back to its state
    after loading before each grasp (:meth:`Dynamics.restore`: the object
    where it waits, :data:`PARKED`, still), and the grasp's gears and joint
    limits go after it (:meth:`Dynamics.undo_fingers`). The results are those
    of a fresh world per grasp (:func:`_world` with one grasp), to the last
    bit, in any order (measured on the Barrett's and the Panda's sweeps;
    tested; an object kept without parking it changed 189 of 300 of the
    mug's settled epsilons)."""
    out: list[Trial] = []
    with fresh_world(s.dt, s.solver_iterations) as dyn:
        body = dyn.add_hand(hand.urdf, hand.link_inertia)
        uid = _add_object(dyn, obj, shape, physical, PARKED)
        dyn.keep_apart([body.uid, uid], 0)
        loaded = dyn.save()
        for grasp in grasps:
            dyn.restore(loaded)
            run_or_flag = _set_up(dyn, hand, obj, shape, physical, grasp, 0, s, body, uid)
            flagged = isinstance(run_or_flag, Trial)
            out.append(run_or_flag if flagged else _simulate(dyn, hand, {0: run_or_flag}, s, on_settled, load)[0])
            dyn.park(uid, PARKED)
            dyn.undo_fingers()
    return out


def _world(hand: HandSpec, obj: PreparedObject, shape: Shape, physical: _Physical, grasps: Sequence[Grasp],
           s: ShakeSettings, on_settled: Settled | None = None, load: bool = True) -> list[Trial]:
    """The trials of ``grasps`` together in a fresh world, each its own hand
    and object in its own collision filter group."""
    results: dict[int, Trial] = {}
    with fresh_world(s.dt, s.solver_iterations) as dyn:
        runs: dict[int, _Run] = {}
        for k, grasp in enumerate(grasps):
            run_or_flag = _set_up(dyn, hand, obj, shape, physical, grasp, k, s)
            if isinstance(run_or_flag, Trial):
                results[k] = run_or_flag
            else:
                runs[k] = run_or_flag
        if runs:
            results |= _simulate(dyn, hand, runs, s, on_settled, load)
    return [results[k] for k in range(len(grasps))]


def _flag(reason: str) -> Trial:
    return Trial(False, 0, 0.0, 0.0, 0.0, 0.0, reason)


def _set_up(dyn: Dynamics, hand: HandSpec, obj: PreparedObject, shape: Shape, physical: _Physical, grasp: Grasp,
            bit: int, s: ShakeSettings, hand_body: Body | None = None, object_uid: int | None = None) -> _Run | Trial:
    """The hand with its fingers just short of the grasp, motors on, and the
    object; or the flag that stops the trial before any physics. A new hand
    and object (which a flag removes again), or ``hand_body`` and
    ``object_uid``, a hand and an object as loaded, in filter group ``bit``
    (which stay)."""
    own = hand_body is None
    body = dyn.add_hand(hand.urdf, hand.link_inertia) if hand_body is None else hand_body
    close = fg.synergy(hand, grasp.preshape)  # read once a grasp: the preshapes' file is looked at each time
    rates = fg.closing_rates(hand, grasp.preshape, close)
    dyn.set_joints(body, hand.full_configuration({j.name: grasp.closed_joints.get(j.name, j.lower)
                                                      for j in hand.driven}))
    axes = joint_axes(dyn.sim, hand, body)
    lever = fg.levers(hand, grasp, axes)
    if fg.clearance(hand, grasp, axes, close) < s.min_clearance:
        if own:
            dyn.remove(body.uid)
        return _flag("no_clearance")
    set_contacts(dyn, hand, body, grasp)
    dyn.set_joints(body, fg.start_joints(hand, grasp, rates, lever, s.start_gap))
    at = np.linalg.inv(np.asarray(grasp.pose, float))
    if object_uid is None:
        uid = _add_object(dyn, obj, shape, physical, at)
        dyn.keep_apart([body.uid, uid], bit)
    else:
        uid = object_uid
        dyn.set_object_pose(uid, at)
    if dyn.overlap(body, uid) - hand.distance_offset > s.max_start_overlap:
        if own:
            dyn.remove(body.uid)
        if object_uid is None:
            dyn.remove(uid)
        return _flag("start_overlap")
    clutches = drive_fingers(dyn, hand, body, rates, grasp.closed_joints, s.gear_erp)
    finger_links = tuple(frozenset(body.links[n] for n in f) for f in fg.fingers(hand, rates))
    return _Run(grasp, body, uid, finger_links, rates, clutches, own_hand=own, own_object=object_uid is None)


#: (4, 4) where the object of :func:`_in_turn`'s world waits between grasps: far from the hand, in no contact.
PARKED = np.diag([1.0, 1.0, 1.0, 1.0])
PARKED[:3, 3] = (0.0, 0.0, 100.0)


def _add_object(dyn: Dynamics, obj: PreparedObject, shape: Shape, physical: _Physical, pose: np.ndarray) -> int:
    """The object as a free body of the trial's mass and friction, its object frame at ``pose`` (4, 4)."""
    return dyn.add_object(shape, physical.mass, obj.com, obj.inertia * (physical.mass / obj.mass), physical.friction,
                          pose)


def _simulate(dyn: Dynamics, hand: HandSpec, runs: dict[int, _Run], s: ShakeSettings,
              on_settled: Settled | None = None, load: bool = True) -> dict[int, Trial]:
    """Close, settle and (``load``) shake the runs of one world; without
    ``load`` the verdicts say only whether a finger still touches (how far
    closing moved the object is not measured: the settle reads only the
    contacts, and the rotation's angle cost ~0.2 ms a grasp; a run without a
    finger on the object is ``no_contact``)."""
    start = {k: dyn.object_pose(r.uid) for k, r in runs.items()} if load else {}
    _close(dyn, hand, runs, _steps(s.close_time, s.dt))
    if not hand.actuators.backdrivable:
        for r in runs.values():
            hold_closed(dyn, hand, r.body, r.rates)
    dyn.step(_steps(s.settle_time, s.dt))
    active = []
    for k, r in runs.items():
        if load:
            r.closed, r.com = dyn.object_pose(r.uid), dyn.centre_of_mass(r.uid)
            r.closing = (float(np.linalg.norm(r.closed[:3, 3] - start[k][:3, 3])),
                         angle_between(start[k][:3, :3], r.closed[:3, :3]))
        if on_settled is not None:
            on_settled(r.grasp, HandContacts(*dyn.contact_points(r.body, r.uid)))
        links = dyn.touching_links(r.body, r.uid)
        r.touching = sum(1 for f in r.fingers if f & links)
        if r.touching:
            active.append(r)
        else:
            _leave(dyn, r)
    if not load:
        return {k: _verdict(r, s) for k, r in runs.items()}
    previous = np.zeros(3)
    for direction in LOAD_DIRECTIONS:
        if not active:  # every trial of the world has its verdict: nothing left to load
            break
        target = GRAVITY * s.load * direction
        ramp = _steps(s.ramp_time, s.dt)
        for i in range(ramp):
            f = (i + 1) / ramp
            dyn.set_gravity((1.0 - f) * previous + f * target)
            dyn.step()
        dyn.step(_steps(s.hold_time, s.dt))
        previous = target
        for r in list(active):
            if not _still_held(dyn, r, s):
                active.remove(r)
                _leave(dyn, r)
    dyn.set_gravity(np.zeros(3))
    return {k: _verdict(r, s) for k, r in runs.items()}


def _close(dyn: Dynamics, hand: HandSpec, runs: dict[int, _Run], steps: int) -> None:
    """Close for ``steps``; while a breakaway clutch is engaged, step by
    step, watching its finger's links."""
    for i in range(steps):
        engaged = [r for r in runs.values() if r.clutches]
        if not engaged:
            dyn.step(steps - i)
            return
        dyn.step()
        for r in engaged:
            break_away(dyn, hand, r.body, r.clutches, dyn.touching_links(r.body, r.uid))


def _still_held(dyn: Dynamics, r: _Run, s: ShakeSettings) -> bool:
    moved = float(np.linalg.norm(dyn.centre_of_mass(r.uid) - r.com))
    turned = angle_between(r.closed[:3, :3], dyn.object_pose(r.uid)[:3, :3])
    r.shaking = [max(r.shaking[0], moved), max(r.shaking[1], turned)]
    r.held = moved < s.max_translation and turned < s.max_rotation and bool(dyn.touching_links(r.body, r.uid))
    return r.held


def _leave(dyn: Dynamics, r: _Run) -> None:
    """A finished trial leaves the world (the others run on without it)."""
    if r.own_object:
        dyn.remove(r.uid)
    if r.own_hand:
        dyn.remove(r.body.uid)
    r.gone = True


def _verdict(r: _Run, s: ShakeSettings) -> Trial:
    if r.touching:
        reason = "held" if r.held else "slipped"
    else:  # no finger on the object once closed: pushed out, or closed on air
        pushed = r.closing[0] >= s.max_translation or r.closing[1] >= s.max_rotation
        reason = "squeezed_out" if pushed else "no_contact"
    return Trial(reason == "held", r.touching, *r.closing, *r.shaking, reason)


def _steps(seconds: float, dt: float) -> int:
    return max(1, int(round(seconds / dt)))
