"""The squeeze of a self-centring parallel jaw on a free object (issue 26): where the wall would turn flush.

Closing (:mod:`planner.plan.closing`) holds the object still, so two rigid flat pads closing on a wall that is
tilted to them (a bowl's or a mug's wall, a knife's blade, a hat's brim, pinched at a slant) each touch it at one
of their EDGES, the two edges on opposite sides of the wall: the points do not face each other, the squeeze
makes a couple that friction resists only over the wall's thickness, and the planned contacts are not force
closure (a 9.7 mm pinch of a bowl's wall: epsilon 0 with 8 well-opposed contacts). The real gripper holds no
object still: a squeeze the contacts cannot resist turns the free object between the pads until the wall lies
flat against both (Goldberg's squeeze grasp, "Orienting polygonal parts without sensors", 1993: a parallel jaw
turns a part to a local minimum of its width). ACRONYM's FleX records how far: its held Panda grasps turn the
object by a median 0.2-0.4 rad while closing, on every category of the dev set.

So where the planned contacts are not force closure, the hand (the object's frame stays the world frame) turns
about the contacts' centre by the rotation that brings the jaw's closing axis onto the wall's normal (the
difference of the two fingers' mean contact normals), the jaw a little more open than it closed
(:data:`REOPEN`), and closes again; at most :data:`TURNS` times, until the contacts are force closure. Where
that jaw would overlap the object at the whole turn, the object turns part of the way (:data:`SHARES`); a turn
it cannot make at all or a closing that fails there ends the squeeze where it is. A pad on a concave face (a mug's
inner wall or handle, curved across the pad) touches it at one of its two edges, where the face's normal leans
further than the wall's: the turn overshoots, the pad touches at its other edge, and the next turn points back the
way it came (until ALGORITHM_VERSION 28 the mug's failing squeezes flipped so three times, 76 of 81). Where a turn
turns back (:data:`REVERSED`), the flush pose lies between the last two closings: the squeeze bisects that bracket
(:func:`bracketed`, :func:`midway`) instead, with no more closings. On a table (the grasper's), it is
the object that turns, not the hand: a turn that would take the object resting there through the table top
(deeper than :data:`SINK`) is one it cannot make (:func:`through_table`).

The grasp stays as planned: the squeeze's outcome is stored beside it as measures (:class:`Squeeze`: its force
closure, epsilon and turn; replacing the planned pose by the squeezed one lost what the slanted pose says about
holding, bench/RESULTS.md 2026-12-07). Where the squeeze ends force closure, the sweep also keeps its end (the
turned hand and the contacts of its last closing, force closure as planned there) as a grasp of its own
(:mod:`planner.plan.keeping`). Only a self-centring parallel jaw squeezes (:func:`squeezes`: the Panda):
its two fingers close together about the hand's centre, so the object, pressed from both sides, may turn freely
between them. The PR2's jaw is declared not self-centring (its pads are not mirror images; a finger stops where
it touches), the Barrett and the Allegro are no parallel jaws (the Barrett settles dynamically:
:mod:`planner.plan.settle`): they get None.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from planner.plan.closing import Grasper
from planner.plan.closing_types import Closed
from planner.plan.tolerances import TABLE_CLEARANCE
from planner.quality import Quality
from planner.record.contacts import HandContacts
from planner.specs.hand_spec import HandSpec
from planner.specs.preshapes import Preshape

__all__ = ["REOPEN", "REVERSED", "SINK", "TURNS", "Squeeze", "bracketed", "midway", "squeezed", "squeezes",
           "through_table", "turn"]

#: Turns of the squeeze at most: one brings the wall flush where the pads touched a flat wall; a curved one
#: may take a second or third (the pads then touch it elsewhere).
TURNS = 3
#: [m] the jaw's fingers back off this far each (an opening of twice as much beyond the closed one) before they
#: close again at the turned pose: the object turns in a jaw that presses on it, not in the open hand.
REOPEN = 0.001
#: Shares of the whole turn tried in turn: where the jaw cannot turn all the way (a finger would enter the object
#: elsewhere: a mug's wall curves across the pads), the object turns part of the way.
SHARES = (1.0, 0.5, 0.25)
#: A turn whose cosine with the way back to the pose of the closing before is above this turns back: the flush pose
#: lies between the two (a turn about another axis, below it, is taken as a turn: the wall curves the other way).
REVERSED = 0.7
#: [rad] a smaller turn is no turn (the wall already lies along the closing axis).
MIN_TURN = 1e-4

#: [m] how far below the table top it rests on the object turned by the squeeze may reach (a turn that takes it
#: deeper goes through the table: the table stops it).
SINK = 1e-4

#: (4, 4), (4, 4): two poses of the hand (object frame), the whole turn at the first towards the second, at the
#: second towards the first: the flush pose lies between them (:func:`bracketed`).
Bracket = tuple[np.ndarray, np.ndarray]

#: contacts -> their quality (epsilon and force closure; None: not computable).
Score = Callable[[HandContacts], "Quality | None"]


@dataclass(frozen=True)
class Squeeze:
    """What the squeeze of a planned grasp ends in.

    force_closure: whether its contacts are force closure (the planned ones' where they already were);
    epsilon: their Ferrari-Canny epsilon (L1, dimensionless; the planned one where they already were force
    closure, or where the squeeze could not turn); turn [rad] >= 0: the angle of the hand's rotation from the
    planned pose to the squeezed one (0: not turned); end: the last closing at a turned pose and its ``quality``
    (None: not turned, or no closing at a turned pose was scored): where the squeeze ends force closure and the
    planned contacts were not, the sweep keeps it as a grasp of its own (:mod:`planner.plan.keeping`).
    """

    force_closure: bool
    epsilon: float
    turn: float
    end: Closed | None = None
    quality: Quality | None = None


def squeezes(hand: HandSpec) -> bool:
    """Whether ``hand`` squeezes (the module docstring): a self-centring parallel jaw."""
    return bool(hand.centering) and hand.jaw is not None


def turn(contacts: HandContacts, sides: tuple[frozenset[str], frozenset[str]], pose: np.ndarray,
         axis: np.ndarray, share: float = 1.0) -> np.ndarray | None:
    """(4, 4) the hand ``pose`` (object frame) turned about its contacts' centre so that the closing ``axis``
    (3,) (hand frame, unit) lies along the wall's normal: the difference of the mean contact normals of the
    two fingers' links ``sides`` (``share`` < 1: that share of the way); None when a finger has no contact, the
    axis already lies along it, or the normals give no wall's normal (opposite means cancelling, or not finite)."""
    whole = turning(contacts, sides, pose, axis)
    return None if whole is None else turned(pose, *whole, share)


def turning(contacts: HandContacts, sides: tuple[frozenset[str], frozenset[str]], pose: np.ndarray,
            axis: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """What :func:`turn` turns ``pose`` by, whatever the share: ((3,) [rad] the whole turn's rotation vector, object
    frame; (3,) [m] the contacts' centre it turns about), or None where :func:`turn` gives None. Read once a closing:
    every share of the turn, :func:`turned`, is made from it (the same values as reading it again)."""
    on = [np.array([link in side for link in contacts.links]) for side in sides]
    if not all(s.any() for s in on):
        return None
    wall = contacts.normals[on[1]].mean(axis=0) - contacts.normals[on[0]].mean(axis=0)
    along = pose[:3, :3] @ axis
    if not np.all(np.isfinite(wall)) or np.linalg.norm(wall) == 0.0:  # a NaN normal turned the hand to NaN
        return None
    wall = wall / np.linalg.norm(wall) * np.sign(wall @ along or 1.0)
    cross = np.cross(along, wall)
    angle = float(np.arctan2(np.linalg.norm(cross), along @ wall))
    if angle < MIN_TURN:
        return None
    return cross / np.linalg.norm(cross) * angle, contacts.points[on[0] | on[1]].mean(axis=0)


def turned(pose: np.ndarray, whole: np.ndarray, centre: np.ndarray, share: float = 1.0) -> np.ndarray:
    """(4, 4) the hand ``pose`` (4, 4) turned by ``share`` of the rotation vector ``whole`` (3,) [rad] about
    ``centre`` (3,) [m] (object frame; :func:`turning`)."""
    rotation = Rotation.from_rotvec(whole * share).as_matrix()
    out = np.eye(4)
    out[:3, :3] = rotation @ pose[:3, :3]
    out[:3, 3] = rotation @ (pose[:3, 3] - centre) + centre
    return out


def through_table(grasper: Grasper, planned: np.ndarray, pose: np.ndarray) -> bool:
    """Would the squeeze that turns the hand from ``planned`` (4, 4) to ``pose`` (4, 4) (object frame) take the
    object through the grasper's table? The hand and the table stay where they are, the object turns by the
    inverse (object frame -> planned @ pose^-1); its vertices may reach :data:`SINK` below the table top (closing's
    raised one less :data:`~planner.plan.tolerances.TABLE_CLEARANCE`) or below its own lowest point at rest, the
    lower of the two. False without a table."""
    if grasper.table is None or grasper.mesh is None:
        return False
    normal = grasper.table[:3, 2]
    at_rest = np.asarray(grasper.mesh.vertices, float) @ normal
    top = float(normal @ grasper.table[:3, 3]) - TABLE_CLEARANCE
    moved = planned @ np.linalg.inv(pose)
    heights = (np.asarray(grasper.mesh.vertices, float) @ moved[:3, :3].T + moved[:3, 3]) @ normal
    return bool(heights.min() < min(top, float(at_rest.min())) - SINK)


def squeezed(grasper: Grasper, closed: Closed, preshape: Preshape, planned: Quality, score: Score
             ) -> Squeeze | None:
    """The squeeze of the grasp ``closed`` whose contacts' quality is ``planned`` (the module docstring), each
    turned closing scored by ``score``; None for a hand that does not squeeze (:func:`squeezes`). The grasper's
    world is left as it was (closing places the hand anew for every grasp), and its count of the seconds spent
    reading contacts (the sweep's ``contacts`` stage, taken out of ``closing``: the squeeze's time is the caller's
    to count); ``closed`` is not changed."""
    hand = grasper.hand
    if not squeezes(hand):
        return None
    if planned.force_closure:
        return Squeeze(True, float(planned.epsilon), 0.0)
    seconds = grasper.contact_seconds
    try:
        return _squeezed(grasper, closed, preshape, planned, score)
    finally:
        grasper.contact_seconds = seconds


def _squeezed(grasper: Grasper, closed: Closed, preshape: Preshape, planned: Quality, score: Score) -> Squeeze:
    """:func:`squeezed` of a grasp that squeezes, not force closure as planned."""
    hand = grasper.hand
    master, slave = hand.jaw  # type: ignore[misc]
    sides = (frozenset(master.moves) - frozenset(slave.moves), frozenset(slave.moves))
    axis = grasper.axis_in_root(master.name)
    axis = axis / np.linalg.norm(axis)
    quality, start = planned, closed.pose
    before: np.ndarray | None = None  # (4, 4) the pose of the closing before this one
    bracket: Bracket | None = None
    for _ in range(TURNS):
        joints = dict(closed.closed_joints)
        joints[master.name] += -np.sign(master.close) * REOPEN
        joints = hand.full_configuration({j.name: joints[j.name] for j in hand.driven})
        by = turning(closed.contacts, sides, closed.pose, axis)
        if by is None:
            break
        whole = turned(closed.pose, *by)
        bracket = bracketed(bracket, before, closed.pose, whole)
        middle = [] if bracket is None else [midway(*bracket)]  # where that overlaps, or no bracket: the turn's shares
        shares = (whole if share == 1.0 else turned(closed.pose, *by, share) for share in SHARES)  # whole: made once
        tried = itertools.chain(middle, shares)
        pose = next((p for p in tried if not (grasper.overlaps_at(p, joints) or through_table(grasper, start, p))),
                    None)
        if pose is None:
            break
        if not any(pose is m for m in middle):
            bracket = None  # turned as far as it could along the turn: no bisection (yet)
        again = grasper.close_from(pose, preshape, joints, near=True)  # the jaw opened a millimetre
        if not isinstance(again, Closed) or (better := score(again.contacts)) is None:
            break
        before, closed, quality = closed.pose, again, better
        if quality.force_closure:
            break
    turned_by = Rotation.from_matrix(closed.pose[:3, :3] @ start[:3, :3].T).magnitude()
    end = None if quality is planned else closed
    return Squeeze(bool(quality.force_closure), float(quality.epsilon), float(turned_by), end,
                   None if end is None else quality)


def bracketed(bracket: Bracket | None, before: np.ndarray | None, pose: np.ndarray, whole: np.ndarray
              ) -> Bracket | None:
    """The bracket of the flush pose once the squeeze has closed at ``pose`` (4, 4), where the whole turn would take
    the hand to ``whole`` (4, 4): ``bracket`` (None: none yet) halved where ``pose`` is its middle (the flush pose
    lies on the side ``whole`` turns to), or a new one from ``before`` (4, 4; None: the first closing) to ``pose``
    where ``whole`` turns back the way it came (cosine above :data:`REVERSED`), else None. At a bracket's middle
    too, a turn about another axis (the cosine with either end's not above :data:`REVERSED`: on the quick start's
    mug 11 of 327 until ALGORITHM_VERSION 29, which halved the bracket by that cosine's sign) is taken as a turn."""
    way = rotvec(pose, whole)  # read once: each cosine below is of the turn from ``pose`` to ``whole``
    toward = 0.0
    if bracket is not None:
        toward = _cosine(way, rotvec(pose, bracket[1]))
        if abs(toward) > REVERSED:
            return (pose, bracket[1]) if toward > 0.0 else (bracket[0], pose)
    if before is None:
        return None
    # after a closing at a bracket's middle, ``before`` is the bracket's end (the same array): its cosine is read
    back = toward if bracket is not None and before is bracket[1] else _cosine(way, rotvec(pose, before))
    return (before, pose) if back > REVERSED else None


def rotvec(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(3,) [rad] the rotation vector (object frame) that turns the pose ``source`` (4, 4) onto ``target`` (4, 4)."""
    return Rotation.from_matrix(target[:3, :3] @ source[:3, :3].T).as_rotvec()


def cosine(pose: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """The cosine between the turns from ``pose`` to ``a`` and from ``pose`` to ``b`` (all (4, 4)); 0 where either
    does not turn."""
    return _cosine(rotvec(pose, a), rotvec(pose, b))


def _cosine(u: np.ndarray, v: np.ndarray) -> float:
    """The cosine between the rotation vectors ``u`` (3,) and ``v`` (3,) [rad]; 0 where either is 0."""
    norms = float(np.linalg.norm(u) * np.linalg.norm(v))
    return float(u @ v) / norms if norms > 0.0 else 0.0


def midway(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(4, 4) the pose half way from ``a`` (4, 4) to ``b`` (4, 4): half the rotation, the mean position."""
    out = np.eye(4)
    out[:3, :3] = Rotation.from_rotvec(rotvec(a, b) / 2.0).as_matrix() @ a[:3, :3]
    out[:3, 3] = (a[:3, 3] + b[:3, 3]) / 2.0
    return out
