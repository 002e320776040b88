"""The finger mechanics of the MuJoCo trial's closing (:mod:`planner.validation.mujoco_trial`): the
servo targets the closing joints follow, the breakaway clutch and worm gears (the Barrett's).

Each closing joint is a position servo whose force is limited to its motor's effort, following a
:class:`Target` that moves at the hand's closing speed: once a finger is blocked it squeezes with the
motor's effort. A breakaway clutch (:func:`break_away`) lets the distal joint close on alone once the
proximal link is stopped. A worm-gear finger (not backdrivable) is its motor's (:func:`worm_target`):
the target leads it by at most the servo's lag and no push of the object turns it back; once closed,
no load opens it (:func:`hold_closed`). Angles in rad, lengths in m, times in s.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from planner.sim.mujoco_world import World
from planner.specs.hands import HandSpec
from planner.validation.mujoco_settings import MujocoSettings
from planner.validation.tolerances import DEFAULT_LEVER

#: [s] the finger servos' damping over their stiffness: the servo lags a
#: moving target by this times its speed (0.5 mm at the Panda's 5 cm/s).
SERVO_TIME = 0.01
#: A breakaway clutch (the BH8's TorqueSwitch) disengages at a force, not at a touch (the BH8 manual,
#: "TorqueSwitch operation": the force that disengages it is a setting; the inner link then holds its
#: position): here once the proximal link touches and its motor pushes with this share of its effort
#: (1: stalled), a grip the worm gear then holds. Slipping at the first touch left the link touching with
#: no force (the object loose in a cage of fingers: ``no_contact``); at 0.5 the Barrett's figures of
#: bench/mujoco_protocols.py move by one grasp in 150.
BREAKAWAY = 1.0
#: How far [servo lags] behind its furthest closing a worm-gear finger's open-side limit trails while it closes
#: (the worm gear lets no push of the object turn it back; the slack keeps the limit off while it moves on).
RATCHET = 0.5


@dataclass(frozen=True)
class Target:
    """A closing joint's servo target: from ``start`` at time ``since`` [s into closing], moving at
    ``speed`` (signed) [rad/s or m/s] to ``end`` [rad or m], where it stays."""

    start: float
    speed: float
    end: float
    since: float

    def at(self, t: float) -> float:
        target = self.start + self.speed * (t - self.since)
        return min(target, self.end) if self.speed > 0 else max(target, self.end)


@dataclass
class Clutch:
    """A breakaway driven joint still engaged: its mimics, the links only
    it moves (``trigger``) and the links its mimics move (``rest``)."""

    driven: str
    mimics: tuple[str, ...]
    trigger: frozenset[str]
    rest: frozenset[str]


def break_away(w: World, hand: HandSpec, rates: Mapping[str, float], s: MujocoSettings, clutches: list[Clutch],
               touching: set[str], moving: dict[str, Target], t: float, fastest: float) -> None:
    """The planner's closing rule (``breakaway`` in hand.toml): a finger
    whose distal links touch first stalls as a whole (its clutch is
    dropped); once only its proximal link touches and its motor pushes
    with :data:`BREAKAWAY` of its effort, the gears go, the
    proximal joint is braked where it is (its servo leaves the closing
    targets, ``moving``) and each distal joint closes on alone, from
    where it is at its geared speed (as the motor turns on behind the
    slipping clutch), with its share of the motor's effort; ``t`` [s]:
    the time into closing; ``fastest``: the largest closing rate."""
    effort = hand.actuators.effort * s.effort_scale
    for c in list(clutches):
        if touching & c.rest:
            clutches.remove(c)
        elif touching & c.trigger and abs(w.motor_force(c.driven)) >= BREAKAWAY * effort:
            clutches.remove(c)
            del moving[c.driven]
            held = w.joint_position(c.driven)
            w.drive(c.driven, held, 0.0, 0.0, 0.0)
            w.set_limits(c.driven, held, held)
            norm = 1.0 + sum(hand.joint(m).multiplier ** 2 for m in c.mimics)
            for m in c.mimics:
                joint = hand.joint(m)
                share = effort * abs(joint.multiplier) / norm
                w.couple(m, False)
                rate = rates[m]
                moving[m] = Target(w.joint_position(m), hand.actuators.closing_speed * rate / fastest,
                                   joint.upper if rate > 0 else joint.lower, t)
                kp = share / (s.servo_lag / DEFAULT_LEVER)
                w.drive(m, moving[m].at(t), kp, kp * SERVO_TIME, share)


def worm_target(w: World, hand: HandSpec, name: str, target: Target, at: float, t: float, lead: float,
                moving: dict[str, Target], floor: dict[str, float]) -> float:
    """The target of worm-gear joint ``name`` at ``t`` [s into closing] (the trial's closing): ``at`` held to
    ``lead`` ahead of the joint (the motor stalls there: ``moving`` restarts from it), and the joint's
    open-side limit kept :data:`RATCHET` leads behind the furthest it has closed (moved as it closes on)."""
    q = w.joint_position(name)
    sign = 1.0 if target.speed > 0 else -1.0
    if sign * (at - q) > lead:
        at = q + sign * lead
        moving[name] = Target(at, target.speed, target.end, t)
    back = q - sign * RATCHET * lead
    if name not in floor or sign * (back - floor[name]) > 0:
        floor[name] = back
        joint = hand.joint(name)
        w.set_limits(name, *((back, joint.upper) if sign > 0 else (joint.lower, back)))
    return at


def hold_closed(w: World, hand: HandSpec, rates: Mapping[str, float]) -> None:
    """Worm-gear fingers: no load can open a closing joint past where it is now."""
    for j in hand.joints:
        rate = rates[j.name]
        if rate != 0.0:
            q = w.joint_position(j.name)
            w.set_limits(j.name, *((q, j.upper) if rate > 0 else (j.lower, q)))
