"""A second, independent dynamic trial: another engine (MuJoCo) and another
protocol than :mod:`planner.validation.shake` (PyBullet).

What is independent of the PyBullet trial: the engine (soft contacts,
elliptic friction cones, a Newton solver), the closing control and the load.
What is shared: the hand (its URDF, finger motors and their published
effort, mimic gearing, the Barrett's breakaway clutch and worm gears, the
pads' torsional friction: :class:`~planner.specs.hands.HandSpec`), the
object (its convex parts, mass, inertia, friction) and the record
(:class:`~planner.record.grasp.Trial`).

The protocol (settings: :class:`~planner.validation.mujoco_settings.MujocoSettings`),
in the object's frame at rest (the world; the object is free, the hand's root
welded to a moving target, hand gravity-compensated as an arm would carry it):

1. The hand at the grasp pose with its fingers at the grasp's *open preshape*
   (not near the planned contacts); ``start_overlap`` if that open hand is
   deeper than ``max_start_overlap`` in the object.
2. Close without gravity: each closing joint's position servo follows a
   target moving at the hand's closing speed to the closed limit. The
   fingers' travel in free space is skipped: while no finger is near the
   object nothing touches it and it stays at rest, so closing starts where a
   moving finger first comes within ``free_travel_gap`` of the object (found
   by conservative advancement: :meth:`~planner.sim.mujoco_world.World.clearance`),
   the fingers there at their closing speed, on the closing clock (the
   Barrett's closing was half free travel, 475 -> 230 steps a trial); not
   when the open hand already touches the object (it is then pushed while
   the fingers travel). The servo's
   force is limited to the motor's effort (a mimic is geared to its master
   by an equality constraint, so one motor's effort is shared as by a gear
   train), reached ``servo_lag`` behind the target: once a finger is
   blocked it squeezes with the motor's effort. A worm-gear finger (not
   backdrivable: the Barrett) is its motor's: the target leads it by at
   most that lag (the motor stalls where the object holds the finger and
   goes on from there at the closing speed once it is free, instead of
   running on and snapping the finger after it), and no push of the object
   turns it back (its open-side limit follows it). A joint the preshape does
   not close (a spread) is held where it was set. A breakaway clutch (the
   Barrett's TorqueSwitch) lets go as the planner's closing rule says: the
   proximal joint is held where it touched, the distal one closes on at its
   geared speed; a worm-gear finger cannot be opened once closed. Holds are
   joint limits as stiff as the contacts (a servo as stiff as a brake is
   unstable at the trial's time step). Closing ends when every
   finger has stalled; the object then settles.
3. Load and shake: gravity ramps on (the object's down, -``obj.up``: the
   object frame's -z unless told; on a table the table's; or along the
   approach); the hand lifts against it, rotates back and forth about the
   two axes across its approach through the tool centre point, and moves up
   and down along gravity; then holds still.
4. Verdict: ``held`` if the object still touches a finger and moved less
   than ``max_translation`` and ``max_rotation`` relative to the hand since
   the fingers closed; ``slipped`` if not (a trial stops as soon as no
   finger touches, or the object has moved ``drop_factor`` times either
   threshold: on the tuning poses none came back from there). No finger on the object once closed: ``squeezed_out``
   if closing moved it by more than those thresholds, else ``no_contact``.

At every check (every :data:`CHECK_EVERY` of closing and loading, and after
each phase) the trial reads whether MuJoCo's state has diverged (MuJoCo then
resets it: hand and object at the origin, so any later reading is of another
world): the trial ends at once as ``diverged``, no verdict (motions 0; ``grasp
validate`` does not store it, so the grasp stays untried).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from planner.geometry.frames import UP, resting_up
from planner.geometry.solid import PreparedObject
from planner.record.grasp import Grasp, Trial
from planner.sim.mujoco_world import VERSION, World
from planner.specs.hands import HandSpec
from planner.validation import fingers as fg
from planner.validation.mujoco_fingers import (
    BREAKAWAY,
    RATCHET,
    SERVO_TIME,
    Clutch,
    Target,
    break_away,
    hold_closed,
    worm_target,
)
from planner.validation.mujoco_load import down_along, load_path, motion, steps
from planner.validation.mujoco_settings import DIVERGED, Engine, MujocoSettings
from planner.validation.mujoco_worlds import world_for
from planner.validation.tolerances import DEFAULT_LEVER, GRAVITY

#: (4, 4) the identity, copied (np.eye's call cost more than the copy)
_EYE = np.eye(4)
#: Why a MuJoCo trial ended as it did (``Trial.reason``).
REASONS = ("held", "slipped", "squeezed_out", "no_contact", "start_overlap", DIVERGED)
#: [s] how often a trial reads its contacts while loaded (an early verdict once no finger touches) and
#: whether its state diverged (while closing and loaded).
CHECK_EVERY = 0.05
#: [m] how far the free-travel skip looks for the object (a finger farther away advances by this).
PROBE_REACH = 0.05
#: The share of the time to the gap each advance of the skip takes (under 1: the speed bound is first order).
ADVANCE = 0.8
#: [s] the least free travel worth skipping (less: closing starts at rest, as without the skip; more
#: than the servo's lag, so the fingers are at their steady closing speed where closing starts).
MIN_SKIP = 3 * SERVO_TIME
#: The most clearance probes one skip takes (then it starts where it got to).
MAX_PROBES = 40
#: Servo lags a finger takes to come to rest at its closed limit once its target has stopped there.
SETTLE_LAGS = 5


def recorded(settings: MujocoSettings, hand: HandSpec) -> str:
    """What decides a hand's MuJoCo trials, as stored with each result (JSON): ``settings`` as the hand runs them
    (:meth:`MujocoSettings.for_hand`)."""
    settings = settings.for_hand(hand.name)
    torsion = {link: m.torsion_radius for link, m in sorted(hand.contacts.items()) if m.model == "soft"}
    worm = {} if hand.actuators.backdrivable else {"worm_gear": {"motor_stalls_with_finger": True, "ratchet": RATCHET}}
    # a hand whose fingers may need longer than max_close_time to close (the Allegro at 0.5 rad/s, until
    # 2026-12-06): its trials close over the whole travel, unlike those stored before (every shipped hand now
    # closes within max_close_time and records as before)
    slow = {"closing": "whole_travel"} if closing_time(settings, [
        Target(j.lower, hand.actuators.closing_speed, j.upper, 0.0) for j in hand.driven]) > settings.max_close_time \
        else {}
    # until 2026-12-07 a multiccd recorded False ran with multi-contact all the same (MuJoCo 4 ignored the setting):
    # a trial run without it says so, apart from those (validate re-tries them)
    off = {} if settings.multiccd else {"multiccd_flag": "disable"}
    # islands: on in every trial until 2026-12-07, where a trial records nothing of them (as before); off, it says so
    # and the cone: elliptic in every trial until 2026-12-07, where a trial records nothing of it (as before)
    fields = {k: v for k, v in asdict(settings).items()
              if not (k == "islands" and v) and not (k == "cone" and v == Engine.cone)}
    return json.dumps({"engine": "mujoco", "mujoco": VERSION, **fields, **off, "hand": hand.name,
                       "actuators": asdict(hand.actuators), "breakaway": [j.name for j in hand.joints if j.breakaway],
                       "breakaway_effort": BREAKAWAY, "torsion_radius": torsion, **worm, **slow, **fg.inertia(hand)},
                      sort_keys=True)


def trial(hand: HandSpec, obj: PreparedObject, grasp: Grasp, settings: MujocoSettings | None = None,
          friction: float | None = None, mass: float | None = None) -> Trial:
    """Shake-test one grasp in MuJoCo. ``friction``/``mass`` override the object's."""
    return trials(hand, obj, [grasp], settings, friction, mass)[0]


def trials(hand: HandSpec, obj: PreparedObject, grasps: Sequence[Grasp], settings: MujocoSettings | None = None,
           friction: float | None = None, mass: float | None = None) -> list[Trial]:
    """Shake-test grasps of one object in MuJoCo, one after the other in one
    world (each from a fresh state: the results do not depend on the order)."""
    s = (settings or MujocoSettings()).for_hand(hand.name)
    world = world_for(hand, obj, s, obj.mass if mass is None else mass)
    mu = contact_friction(obj.friction if friction is None else friction, s)
    known: dict[str, tuple[dict[str, float], tuple[frozenset[str], ...]]] = {}  # a preshape's rates and fingers
    return [_Run(world, hand, g, s, mu, obj.up, known).run() for g in grasps]


def contact_friction(mu: float, s: MujocoSettings) -> float:
    """The hand-object contacts' friction in a trial of an object of friction ``mu``: ``friction_scale`` times
    it, at most ``friction_cap``."""
    scaled = mu * s.friction_scale
    return scaled if s.friction_cap is None else min(scaled, s.friction_cap)


def closing_time(s: MujocoSettings, targets: Iterable[Target]) -> float:
    """[s] how long closing may last on the closing clock: ``max_close_time``, or longer where a finger's
    whole travel at its closing speed takes longer (then that travel, the servo's lag and ``stall_time``).
    The Allegro's flexion joints travel up to 1.9 rad: at 0.5 rad/s (until 2026-12-06), 3.8 s, and cut at
    1.5 s a finger that reaches the object in the last half of its travel never touched it (``no_contact``);
    at its 7 rad/s 0.27 s. The Panda's 4 cm at 5 cm/s (0.8 s) and the Barrett's 2.4 rad at 2.4 rad/s (1 s)
    end within 1.5 s as before."""
    travel = max([abs(t.end - t.start) / abs(t.speed) for t in targets if t.speed != 0.0] + [0.0])
    return max(s.max_close_time, travel + SETTLE_LAGS * SERVO_TIME + s.stall_time)


class _Diverged(Exception):
    """MuJoCo's state diverged: the trial ends without a verdict."""


@dataclass
class _Run:
    """One grasp's trial in a world."""

    world: World
    hand: HandSpec
    grasp: Grasp
    s: MujocoSettings
    mu: float
    up: np.ndarray = field(default_factory=lambda: UP)  # (3,) the object's up as it stands, object frame
    #: preshape -> its closing rates and fingers, worked out once for a hand's trials (they depend on nothing else)
    known: dict[str, tuple[dict[str, float], tuple[frozenset[str], ...]]] = field(default_factory=dict)
    rates: dict[str, float] = field(init=False)
    fingers: tuple[frozenset[str], ...] = field(init=False)
    pose: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        preshape = self.grasp.preshape
        if preshape not in self.known:
            rates = fg.closing_rates(self.hand, preshape)
            self.known[preshape] = (rates, fg.fingers(self.hand, rates))
        rates, self.fingers = self.known[preshape]
        self.rates = dict(rates)  # the run's own (read only today)
        self.pose = np.asarray(self.grasp.pose, float)

    # -- phases ----------------------------------------------------------------------
    def run(self) -> Trial:
        w, s = self.world, self.s
        start = self._open_joints()
        w.reset(self.pose, start)
        w.set_friction(self.mu, {link: self.mu * c.torsion_radius * s.torsion_scale
                                 for link, c in self.hand.contacts.items()
                                 if c.model == "soft"})
        if w.depth() > s.max_start_overlap:
            return Trial(False, 0, 0.0, 0.0, 0.0, 0.0, "start_overlap")
        try:
            return self._simulate(start)
        except _Diverged:
            return Trial(False, 0, 0.0, 0.0, 0.0, 0.0, DIVERGED)

    def _simulate(self, start: Mapping[str, float]) -> Trial:
        w, s = self.world, self.s
        before = self._relative()
        self._close(start)
        w.step(steps(s.settle_time, s.timestep))
        self._check()
        closed = self._relative()
        closing = motion(before, closed)
        touching = self._touching()
        if not touching:
            pushed = closing[0] >= s.max_translation or closing[1] >= s.max_rotation
            return Trial(False, 0, *closing, 0.0, 0.0, "squeezed_out" if pushed else "no_contact")
        held, shaking = self._load(closed)
        self._check()
        touching = self._touching()
        return Trial(held, touching, *closing, *shaking, "held" if held else "slipped")

    def _open_joints(self) -> dict[str, float]:
        return fg.open_start(self.hand, self.grasp, self.rates)

    def _close(self, start: Mapping[str, float]) -> None:
        w, s, hand = self.world, self.s, self.hand
        effort = hand.actuators.effort * s.effort_scale
        fastest = max([abs(self.rates[j.name]) for j in hand.driven] + [1e-12])
        moving: dict[str, Target] = {}  # the joints whose servo follows a moving target
        clutches = []
        for j in hand.driven:
            rate = self.rates[j.name]
            lag = s.servo_lag if j.kind == "prismatic" else s.servo_lag / DEFAULT_LEVER
            if rate == 0.0:  # set by the preshape, held there (its motor idle)
                w.set_limits(j.name, start[j.name], start[j.name])
                continue
            moving[j.name] = Target(start[j.name], hand.actuators.closing_speed * rate / fastest,
                                    j.upper if rate > 0 else j.lower, 0.0)
            kp = effort / lag
            w.drive(j.name, start[j.name], kp, kp * SERVO_TIME, effort)
            mimics = tuple(m.name for m in hand.joints if m.mimic == j.name and self.rates[m.name] != 0.0)
            if j.breakaway and mimics:
                rest = frozenset(link for m in mimics for link in hand.joint(m).moves)
                clutches.append(Clutch(j.name, mimics, frozenset(j.moves) - rest, rest))
        dt = s.timestep
        every = steps(CHECK_EVERY, dt)
        lever = {j.name: 1.0 if j.kind == "prismatic" else DEFAULT_LEVER for j in hand.joints}
        # Worm-gear fingers (not backdrivable): the motor turns the finger, so it cannot run ahead of a finger
        # the object holds back (its target leads the joint by at most the servo's lag, where the servo pushes
        # with the motor's effort, and goes on at the closing speed from there once the finger is free), and
        # no push of the object turns a finger back (its open-side limit follows it, RATCHET behind)
        worm = not hand.actuators.backdrivable
        lead = {j.name: s.servo_lag / lever[j.name] for j in hand.joints}
        floor: dict[str, float] = {}
        still = 0.0
        first = self._skip_free_travel(moving) if s.free_travel_gap > 0 else 0
        ctrl, motor, qvel, dof = w.servo_io()  # every step: views, not a method call per joint
        step, stall = w.stepper(), s.stall_speed
        for i in range(first, steps(closing_time(s, moving.values()), dt)):
            t = (i + 1) * dt
            done = True
            for name, target in moving.items():
                at = target.at(t)
                if worm:
                    at = worm_target(w, hand, name, target, at, t, lead[name], moving, floor)
                ctrl[motor[name]] = at
                done &= at == target.end
            step()
            if (i + 1) % every == 0:
                self._check()
            if clutches:
                break_away(w, hand, self.rates, s, clutches, w.touching_links(), moving, t, fastest)
            stalled = True
            for name in moving:
                if not abs(qvel.item(dof[name])) * lever[name] < stall:
                    stalled = False
                    break
            still = still + dt if stalled and (done or i * dt > s.stall_time) else 0.0
            if still >= s.stall_time:
                break
        if not hand.actuators.backdrivable:
            hold_closed(w, hand, self.rates)

    def _free_path(self, moving: Mapping[str, Target], t: float) -> tuple[dict[str, float], dict[str, float]]:
        """(positions, speeds) of every closing joint at ``t`` [s] into closing when nothing has touched:
        each servo :data:`SERVO_TIME` behind its target (its steady lag), a mimic geared to its master."""
        q, v = {}, {}
        for name, target in moving.items():
            q[name] = target.at(max(0.0, t - SERVO_TIME))
            v[name] = 0.0 if q[name] == target.end else target.speed
        for j in self.hand.joints:
            if j.mimic in moving and j.name not in moving:
                q[j.name] = j.multiplier * q[j.mimic] + j.offset
                v[j.name] = j.multiplier * v[j.mimic]
        return q, v

    def _skip_free_travel(self, moving: Mapping[str, Target]) -> int:
        """The closing step to start from: the fingers' travel in free space skipped up to where a
        moving finger comes within ``free_travel_gap`` of the object (conservative advancement with
        :meth:`~planner.sim.mujoco_world.World.clearance`'s speed bound: over the skipped travel no
        moving point came nearer than the gap), the fingers placed there at their closing speeds.
        Nothing is skipped (0) when the hand touches the object at the start (the object is not at rest:
        its push goes on while the fingers travel) or a finger is already within the gap."""
        w, s, dt = self.world, self.s, self.s.timestep
        if w.touching_links() or not moving:
            return 0
        end = max(abs(t.end - t.start) / abs(t.speed) for t in moving.values()) + SERVO_TIME
        t, placed = 0.0, 0.0
        for _ in range(MAX_PROBES):
            q, v = self._free_path(moving, t)
            w.set_fingers(q, {}, probe=True)
            gap, speed = w.clearance(v, PROBE_REACH)
            if gap < s.free_travel_gap:
                break
            placed = t
            if gap < 1.5 * s.free_travel_gap or t >= end or speed == 0.0:
                break
            t = min(end, t + ADVANCE * (gap - s.free_travel_gap) / speed)
        first = int(placed / dt)  # whole steps: the targets stay on the closing clock
        if first * dt < MIN_SKIP:  # not worth it: from rest, as without the skip
            w.set_fingers(self._free_path(moving, 0.0)[0], {})
            return 0
        q, v = self._free_path(moving, first * dt)
        w.set_fingers(q, v)
        return first

    def _load(self, closed: np.ndarray) -> tuple[bool, tuple[float, float]]:
        """Gravity, lift, shake, hold; (held, (largest motion [m], rotation [rad]) relative to the hand)."""
        w, s, dt = self.world, self.s, self.s.timestep
        down = down_along(s.down, self.pose[:3, :3] @ self.hand.approach, resting_up(self.grasp.table_plane, self.up))
        weight = 0.0 if s.down == "none" else GRAVITY
        worst = [0.0, 0.0]
        every = steps(CHECK_EVERY, dt)
        path = w.targets(load_path(s, self.pose, self.hand.tcp, self.hand.approach, down))
        ramp = steps(s.ramp_time, dt)
        gone = (s.drop_factor * s.max_translation, s.drop_factor * s.max_rotation) if s.drop_factor else None
        for begin in range(0, len(path), every):  # a check after each `every` steps and after the last
            end = min(begin + every, len(path))
            for i in range(begin, min(end, ramp + 1)):
                w.set_gravity(weight * min(1.0, (i + 1) / ramp) * down)
                w.follow(path[i])
                w.step()
            if end > ramp + 1:
                w.follow_path(path[max(begin, ramp + 1):end])
            self._check()
            moved = motion(closed, self._relative())
            worst = [max(worst[0], moved[0]), max(worst[1], moved[1])]
            if not self._touching() or (gone and (moved[0] >= gone[0] or moved[1] >= gone[1])):
                return False, (worst[0], worst[1])
        final = motion(closed, self._relative())
        held = final[0] < s.max_translation and final[1] < s.max_rotation
        return held, (worst[0], worst[1])

    # -- reading ---------------------------------------------------------------------
    def _check(self) -> None:
        if self.world.diverged():
            raise _Diverged

    def _relative(self) -> np.ndarray:
        """(4, 4) the object's centre-of-mass frame in the hand frame now."""
        w = self.world
        frame = w.object_pose()
        frame[:3, 3] = w.centre_of_mass()
        hand = w.hand_pose()
        inverse = _EYE.copy()
        inverse[:3, :3] = hand[:3, :3].T
        inverse[:3, 3] = -hand[:3, :3].T @ hand[:3, 3]
        return inverse @ frame

    def _touching(self) -> int:
        links = self.world.touching_links()
        return sum(1 for f in self.fingers if f & links)
