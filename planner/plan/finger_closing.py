"""Closing the fingers, steps 4 and 5 of :mod:`planner.plan.closing`: the
part of :class:`~planner.plan.closing.Grasper` that knows the fingers'
kinematics (:class:`FingerClosing`).

Every finger DOF of the preshape's synergy closes until a link it moves
touches the object or the table, or one of its joints reaches a limit; a
breakaway joint's mimics then close on alone. A step never outruns the
measured gap: a link that only translates is bounded along its motion, any
other by an upper bound of its points' speed (once per DOF and link for
every configuration; the reference path recomputes a tighter one at every
step). A link's gap to the surface hulls is bracketed by its last answer and the steps since
(:class:`~planner.plan.obstacle_queries.HullBracket`): one shown far is asked only if it may bound its finger's
step, one shown near asks the exact mesh alone (issue 24: the same closings, ~0.6x the gap queries of the
Barrett's). A self-centring parallel jaw is re-centred afterwards.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from planner.plan.obstacle_queries import HullBracket
from planner.plan.tolerances import JOINT_LIMIT_SLACK, NEAR_SLACK
from planner.sim import Body, Closest, Sim
from planner.specs.hands import HandSpec
from planner.specs.preshapes import Preshape

if TYPE_CHECKING:
    from planner.plan.closing_types import CloseSettings


@dataclass
class _Dof:
    rates: dict[str, float]  # joint name -> dq/ds
    links: tuple[str, ...]  # links with geometry it moves
    active: bool = True
    after: dict[str, float] | None = None  # breakaway: the rates once ``trigger`` links are stopped
    trigger: frozenset[str] = frozenset()  # links whose contact breaks the coupling away


@dataclass(frozen=True)
class DofMotion:
    """A DOF's rates as closing reads them in every step (one per rates, per hand)."""

    limits: tuple[tuple[str, float, float, float], ...]  # (joint, rate, upper, lower) per joint the rates move
    prismatic: bool  # every joint prismatic: the cap is the whole remaining travel
    revolute_cap: float  # otherwise the cap: ``coarse_angle`` over the fastest rate
    translating: frozenset[str]  # moved links that only prismatic joints move (the directional bound)
    _speeds: dict[str, float] = field(default_factory=dict, compare=False)

    def room(self, q: dict[str, float]) -> float:
        """Closing left (units of s) before the first joint, at ``q``, reaches its limit."""
        return min((upper - q[j]) / r if r > 0 else (q[j] - lower) / -r for j, r, upper, lower in self.limits)

    def cap(self, room: float) -> float:
        """Largest closing step considered in one iteration (units of s): prismatic-only DOFs look at their whole
        remaining travel ``room`` at once (the directional bound makes that safe); revolute ones turn at most
        ``coarse_angle`` per step."""
        return max(room, JOINT_LIMIT_SLACK) if self.prismatic else self.revolute_cap

    def speeds(self, closing: FingerClosing, dof: _Dof) -> dict[str, float]:
        if not self._speeds:
            self._speeds.update(closing._speeds(dof))
        return self._speeds


class FingerClosing:
    """Closes the fingers of :class:`~planner.plan.closing.Grasper` (which
    holds the attributes below and answers the obstacle queries)."""

    sim: Sim
    hand: HandSpec
    body: Body
    geometry: tuple[str, ...]  # links with collision geometry
    settings: CloseSettings
    reference: bool
    _axes: dict[str, np.ndarray]
    _bounds: dict[tuple, dict[str, float]]
    _motions: dict[tuple, DofMotion]
    _radius: dict[str, float]  # link with geometry -> [m] its radius about its own frame (:meth:`_measure_arms`)
    _above: dict[str, tuple[str, float]]  # link -> (parent link, [m] bound of the distance between their frames)

    far_body: int | None  # the surface hulls (:mod:`planner.plan.obstacle_queries`; None: the reference path)
    table_body: int | None

    if TYPE_CHECKING:  # the queries of planner.plan.closing.Grasper
        def _obstacles(self, reach: float, link: str | None = None, near: bool = False) -> Closest: ...

        def _gap(self, closest: Closest) -> float: ...

        def _obstacle_gap(self, reach: float, link: str, bracket: HullBracket | None = None) -> float: ...

        def _translation_step(self, pairs: Closest, velocity: np.ndarray) -> tuple[bool, float]: ...

    def _dofs(self, preshape: Preshape) -> list[_Dof]:
        dofs: list[_Dof] = []
        for finger in self.hand.closing_dofs(preshape.close):
            moved = self._moved(finger.rates)
            dof = _Dof(dict(finger.rates), moved)
            if finger.after is not None:
                dof.after, dof.trigger = dict(finger.after), frozenset(moved) - frozenset(self._moved(finger.after))
            dofs.append(dof)
        return dofs

    def _moved(self, rates: dict[str, float]) -> tuple[str, ...]:
        moved = {link for name in rates for link in self.hand.joint(name).moves}
        return tuple(n for n in self.geometry if n in moved)

    def _close_fingers(self, preshape: Preshape, joints: dict[str, float], near_first: bool = False
                       ) -> dict[str, float]:
        """The closed joints (``near_first``: every finger expected near the object from the start)."""
        s = self.settings
        q = dict(joints)
        dofs = self._dofs(preshape)
        velocities: dict[tuple, np.ndarray | None] = {}  # the hand stays put while its fingers close: read once
        # translating links expected near the surface hulls at this step (ObstacleQueries._closest_near)
        near = {link for d in dofs for link in d.links} if near_first else set()
        live: list[_Dof] = []
        # what each link's query of the surface hulls would answer, bracketed (not on the reference path, nor with
        # a table): a far link is asked only when it may bound its finger's step
        bracketing = not self.reference and self.far_body is not None and self.table_body is None
        brackets: dict[str, HullBracket] = {}
        for _ in range(s.max_iterations):
            if not live:  # the live DOFs and what they move, read again only once one stops or breaks away
                live = [d for d in dofs if d.active]
                if not live:
                    break
                motions = [self._motion(d.rates) for d in live]  # the lists below run along ``live``
                speeds = [] if self.reference else [m.speeds(self, d) for d, m in zip(live, motions)]
                movers: dict[str, list[int]] = {}  # link -> the live DOFs that move it, in ``live``'s order
                for k, d in enumerate(live):
                    for link in d.links:
                        movers.setdefault(link, []).append(k)
                sharing = {link: len(ks) for link, ks in movers.items()}
                translating = frozenset().union(*(m.translating for m in motions))
            if self.reference:  # its bounds, of the configuration now
                speeds = [self._speeds(d) for d in live]
            rooms = [m.room(q) for m in motions]
            caps = [m.cap(room) for m, room in zip(motions, rooms)]
            pairs, gaps, later = {}, {}, {}
            for link, ks in movers.items():
                # several DOFs may move one link (a fingertip under three joints): their motions add up (the
                # DOFs that do not move it would add 0.0: left out, the same sum to the bit; one DOF's motion is
                # its sum's, 0 + x, to the bit)
                if len(ks) == 1:
                    k = ks[0]
                    reach = speeds[k][link] * caps[k] + s.contact_tol + s.gap
                else:
                    reach = sum(speeds[k][link] * caps[k] for k in ks) + s.contact_tol + s.gap
                if len(ks) == 1 and link in translating:
                    pairs[link] = self._obstacles(reach, link, link in near)  # the directional bound reads the pairs
                elif not bracketing or len(ks) > 1:
                    gaps[link] = self._obstacle_gap(reach, link)
                else:
                    bracket = brackets.get(link)
                    if bracket is None:
                        bracket = brackets[link] = HullBracket()
                    if bracket.low > s.near:  # far: asked only if it may bound
                        later[link] = reach
                    else:
                        gaps[link] = self._obstacle_gap(reach, link, bracket)
            steps, reread = [0.0] * len(live), False
            moving: list[tuple[int, str, np.ndarray]] = []  # (DOF along ``live``, link, velocity): directional bounds
            for k, (d, m, speed, ds, room) in enumerate(zip(live, motions, speeds, caps, rooms)):
                touched = set()
                for link in d.links:
                    velocity = None
                    if sharing[link] == 1 and link in m.translating:
                        key = (link, *d.rates.items())
                        if key not in velocities:
                            velocities[key] = self._translation(d, link)
                        velocity = velocities[key]
                    if velocity is not None:  # a translating link: directional bound
                        rate = float(np.linalg.norm(velocity))
                        hit, travel = self._translation_step(pairs[link], velocity / rate)
                        if hit:
                            touched.add(link)
                        ds = min(ds, travel / rate)
                        moving.append((k, link, velocity))
                        continue
                    if link in later:
                        continue
                    gap = gaps[link] if link in gaps else self._gap(pairs[link])
                    if gap <= s.contact_tol:
                        touched.add(link)
                    v = speed[link]
                    if v > 0 and math.isfinite(gap):
                        ds = min(ds, (gap - s.gap) / (sharing[link] * v))
                for link in d.links:  # far links, once the others have bounded the step
                    if link not in later or self._beside(brackets[link].low, speed[link], min(ds, room)):
                        continue
                    gap = self._obstacle_gap(later[link], link, brackets[link])
                    if gap <= s.contact_tol:
                        touched.add(link)
                    v = speed[link]
                    if v > 0 and math.isfinite(gap):
                        ds = min(ds, (gap - s.gap) / v)
                if touched and d.after is not None and touched <= d.trigger:
                    # breakaway: the touching links stop, the rest of the finger closes on
                    d.rates, d.links, d.after = d.after, self._moved(d.after), None
                    reread = True
                    continue
                if touched or room <= JOINT_LIMIT_SLACK:
                    d.active = False
                    reread = True
                    continue
                steps[k] = min(ds, room)
            near = {link for k, link, velocity in moving
                    if live[k].active and self._near_after(pairs[link], velocity * steps[k])}
            moved = {}
            for d, step in zip(live, steps):
                if d.active:
                    for j, r in d.rates.items():
                        q[j] += r * step
                        moved[j] = q[j]
            self.sim.set_joints(self.body, moved)
            for link, bracket in brackets.items():  # a stopped finger's links keep theirs
                ks = movers.get(link)
                if ks:
                    bracket.moved(speeds[ks[0]][link] * steps[ks[0]] if len(ks) == 1
                                  else sum(speeds[k][link] * steps[k] for k in ks))
            if reread:
                live = []
        return q

    def _beside(self, low: float, speed: float, step: float) -> bool:
        """Can a link whose gap is at least ``low`` [m] (by its bracket), moving at most ``speed`` [m per unit s],
        neither touch nor bound its finger's ``step`` (units of s; its gap's bound is no smaller to the bit)?"""
        s = self.settings
        return low > s.contact_tol and (speed <= 0 or (low - s.gap) / speed >= step)

    def _near_after(self, pairs: Closest, moved: np.ndarray) -> bool:
        """Will a link whose ``pairs`` these were be near the surface hulls once it has moved by ``moved`` (3,) [m]?
        Each pair's gap then, to first order, is its gap less its approach along its normal: a guess (which of
        :meth:`~planner.plan.closing.Grasper._obstacles`' two ways to ask is the cheaper), never the answer."""
        if len(pairs) == 0:
            return False
        guess = float(np.min(pairs.distance + pairs.normal_b @ moved)) + self.hand.distance_offset
        return guess <= self.settings.near - NEAR_SLACK

    def _motion(self, rates: dict[str, float]) -> DofMotion:
        """What closing reads of a DOF's ``rates`` in every step, looked up once per hand."""
        key = tuple(rates.items())
        found = self._motions.get(key)
        if found is None:
            specs = [self.hand.joint(j) for j in rates]
            translating = frozenset(link for link in self._moved(rates)
                                    if (movers := [j for j in specs if link in j.moves])
                                    and all(j.kind == "prismatic" for j in movers))
            found = self._motions[key] = DofMotion(
                tuple((j.name, r, j.upper, j.lower) for j, r in zip(specs, rates.values())),
                all(j.kind == "prismatic" for j in specs),
                min(self.settings.coarse_angle / abs(r) for r in rates.values()), translating)
        return found

    def _translation(self, dof: _Dof, link: str) -> np.ndarray | None:
        """World velocity of ``link`` per unit closing if only prismatic joints move it."""
        movers = [self.hand.joint(j) for j in dof.rates if link in self.hand.joint(j).moves]
        if not movers or any(j.kind != "prismatic" for j in movers):
            return None
        root = self.sim.link_pose(self.body, self.hand.root_link)
        velocity = sum(dof.rates[j.name] * (root[:3, :3] @ self.axis_in_root(j.name)) for j in movers)
        return velocity if np.linalg.norm(velocity) > 0 else None

    def axis_in_root(self, joint: str) -> np.ndarray:
        """(3,) unit axis of a prismatic finger joint in the hand frame (constant)."""
        if joint not in self._axes:
            self._axes[joint] = self.sim.joint_axis_in_base(self.body, joint)
        return self._axes[joint]

    def _speeds(self, dof: _Dof) -> dict[str, float]:
        """Upper bound of each moved link's point speed [m per unit s], valid
        in every configuration: computed once per DOF (the reference path
        recomputes a tighter one at every step)."""
        if self.reference:
            return self._speeds_now(dof)
        key = tuple(sorted(dof.rates.items()))
        if key not in self._bounds:
            speeds = dict.fromkeys(dof.links, 0.0)
            for name, rate in dof.rates.items():
                joint = self.hand.joint(name)
                for link in joint.moves:
                    if link in speeds:
                        speeds[link] += abs(rate) * (1.0 if joint.kind == "prismatic" else self._arm(joint.child,
                                                                                                     link))
            self._bounds[key] = speeds
        return self._bounds[key]

    def _arm(self, top: str, link: str) -> float:
        """Largest distance [m] from the origin of link ``top`` (a joint's
        child frame, on its axis) to any point of ``link`` below it, in any
        configuration: the link's radius about its own frame plus the distances
        between the frames up the chain (triangle inequality), each measured
        once with the hand (:meth:`_measure_arms`), so that the bound, and every
        closing, is the same whichever pose the grasper closed first."""
        total = self._radius[link]
        while link != top:
            link, offset = self._above[link]
            total += offset
        return total

    def _measure_arms(self) -> None:
        """Measure what :meth:`_arm` adds up, once per grasper (moves the hand; the caller puts it back).

        A link's radius: the largest distance from its frame to a corner of its box in its own frame
        (PyBullet's box, margins included), read with the hand placed so that the link's frame is the world
        frame; a box read in another frame would be larger, by how the link is turned. A frame's offset: its
        distance to its parent link's frame with every finger joint at its lower limit (constant for a revolute
        or fixed joint), plus the whole travel of a prismatic one."""
        self.sim.set_pose(self.body, np.eye(4))
        self.sim.set_joints(self.body, {j.name: j.lower for j in self.hand.joints})
        frames = {link: self.sim.link_pose(self.body, link) for link in self.body.links}
        self._radius, self._above = {}, {}
        for link in self.geometry:
            self.sim.set_pose(self.body, np.linalg.inv(frames[link]))
            lo, hi = self.sim.link_aabb(self.body, link)
            corners = np.array(np.meshgrid(*zip(lo, hi))).T.reshape(-1, 3)
            self._radius[link] = float(np.max(np.linalg.norm(corners, axis=1)))
        for link, index in self.body.links.items():
            if index >= 0:
                joint = self.sim.parent_joint(self.body, link)
                offset = float(np.linalg.norm(frames[link][:3, 3] - frames[joint.parent][:3, 3])) + joint.travel
                self._above[link] = (joint.parent, offset)

    def _speeds_now(self, dof: _Dof) -> dict[str, float]:
        """Upper bound of each moved link's point speed [m per unit s] in the current configuration."""
        speeds = dict.fromkeys(dof.links, 0.0)
        for name, rate in dof.rates.items():
            joint = self.hand.joint(name)
            if joint.kind == "prismatic":
                for link in joint.moves:
                    if link in speeds:
                        speeds[link] += abs(rate)
                continue
            frame = self.sim.link_pose(self.body, joint.child)
            origin, axis = frame[:3, 3], frame[:3, :3] @ self.body.joint_axes[name]
            for link in joint.moves:
                if link in speeds:
                    lo, hi = self.sim.link_aabb(self.body, link)
                    corners = np.array(np.meshgrid(*zip(lo, hi))).T.reshape(-1, 3) - origin
                    radius = np.max(np.linalg.norm(np.cross(corners, axis), axis=1))
                    speeds[link] += abs(rate) * radius
        return speeds

    def _centre(self, pose: np.ndarray, q: dict[str, float]) -> tuple[np.ndarray, dict[str, float]]:
        """Shift a self-centring parallel jaw so its two fingers are symmetric."""
        master, slave = self.hand.jaw  # type: ignore[misc]  # centring hands are parallel jaws
        axis = pose[:3, :3] @ self.body.joint_axes[master.name]
        qa, qb = q[master.name], q[slave.name]
        shifted = pose.copy()
        shifted[:3, 3] += 0.5 * (qa - qb) * axis
        out = dict(q)
        out[master.name] = out[slave.name] = 0.5 * (qa + qb)
        return shifted, out
