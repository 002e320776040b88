"""The hand in a trial's world: its contacts, finger motors, gear couplings,
breakaway clutches and worm-gear ratchet, as the hand's ``[dynamics]``,
``[[joints]]`` and ``[contact]`` tables describe them (the world is the hand
frame)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from planner.record.grasp import Grasp
from planner.sim import Body, Sim
from planner.sim.dynamics import Dynamics
from planner.specs.hands import Actuators, HandSpec
from planner.validation.pads import has_patch, link_planes
from planner.validation.tolerances import GEAR_FACTOR, HOLD_FACTOR


def set_contacts(dyn: Dynamics, hand: HandSpec, body: Body, grasp: Grasp) -> None:
    """Every link: the object's own friction; soft links (pads) also resist
    a moment about the normal of up to mu x torsion_radius x normal force,
    unless the grasp's planned contacts on that link are one point on a sharp
    edge or corner of its shape (no contact patch:
    :mod:`planner.validation.pads`). Call with the fingers at the grasp's
    closed configuration (link poses)."""
    to_hand = np.linalg.inv(np.asarray(grasp.pose, float))
    points = grasp.contacts.points @ to_hand[:3, :3].T + to_hand[:3, 3]
    normals = grasp.contacts.normals @ to_hand[:3, :3].T
    by_link: dict[str, list[int]] = {}  # each link's contacts, in their order (the rows a mask would take)
    for i, link in enumerate(grasp.contacts.links):
        by_link.setdefault(link, []).append(i)
    for name, index in body.links.items():
        model = hand.contacts.get(name)
        radius = model.torsion_radius if model is not None and model.model == "soft" else 0.0
        on = by_link.get(name)
        if radius > 0.0 and on:
            to_link = np.linalg.inv(dyn.sim.link_pose(body, name))
            patch = has_patch(link_planes(hand.urdf, name), points[on] @ to_link[:3, :3].T + to_link[:3, 3],
                              normals[on] @ to_link[:3, :3].T)
            radius = radius if patch else 0.0
        dyn.set_contact(body.uid, index, radius)


def joint_axes(sim: Sim, hand: HandSpec, body: Body) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(point, unit direction) of every finger joint's axis in the world (= hand) frame now."""
    out = {}
    for j in hand.joints:
        frame = sim.link_pose(body, j.child)  # PyBullet's link frame is the URDF joint frame
        out[j.name] = (frame[:3, 3], frame[:3, :3] @ body.joint_axes[j.name])
    return out


@dataclass
class Breakaway:
    """One finger's breakaway clutch (a driven joint flagged ``breakaway``:
    the BH8's TorqueSwitch) while it is still engaged. ``trigger``: indices of
    the links only the driven joint moves (the proximal link); ``rest``: the
    links its mimics move (the distal link); ``gears``: the mimics' gear
    constraints."""

    driven: str
    gears: tuple[int, ...]
    trigger: frozenset[int]
    rest: frozenset[int]


def drive_fingers(dyn: Dynamics, hand: HandSpec, body: Body, rates: Mapping[str, float],
                  hold: Mapping[str, float], gear_erp: float) -> list[Breakaway]:
    """Finger motors at the hand's ``[dynamics]``: every closing joint a
    velocity motor (the fastest at ``closing_speed``, the others in
    proportion to their ``rates``), a driven joint's ``effort`` shared with
    its mimics in proportion to their multipliers (sum of m_i x effort_i =
    effort: the statics of one motor behind a gear train) and gear
    constraints keeping them together; joints that do not close hold their
    ``hold`` value (a spread set by the preshape). Returns the engaged
    breakaway clutches (:func:`break_away`)."""
    act: Actuators = hand.actuators
    fastest = max([abs(rates[j.name]) for j in hand.driven] + [0.0])
    clutches = []
    for j in hand.driven:
        members = [(j.name, 1.0)] + [(m.name, m.multiplier) for m in hand.joints if m.mimic == j.name]
        norm = sum(m * m for _, m in members)
        gears = []
        for name, m in members:
            if name != j.name:
                gears.append(dyn.gear(body, j.name, name, m, GEAR_FACTOR * act.effort, gear_erp))
            rate = rates[name]
            if rate == 0.0:
                dyn.position_motor(body, name, float(hold.get(name, 0.0)), HOLD_FACTOR * act.effort)
            else:
                dyn.velocity_motor(body, name, act.closing_speed * rate / fastest, act.effort * abs(m) / norm)
        mimics = {link for name, _ in members[1:] if rates[name] != 0.0 for link in hand.joint(name).moves}
        if j.breakaway and rates[j.name] != 0.0 and mimics:
            clutches.append(Breakaway(j.name, tuple(gears), frozenset(body.links[n] for n in j.moves
                                                                      if n not in mimics and n in body.links),
                                      frozenset(body.links[n] for n in mimics if n in body.links)))
    return clutches


def break_away(dyn: Dynamics, hand: HandSpec, body: Body, clutches: list[Breakaway], touching: set[int]) -> None:
    """The planner's closing rule (``breakaway`` in hand.toml), in the trial:
    once a finger's proximal link touches the object while its distal link
    does not, the clutch slips: the gears go, the proximal joint stays where
    it is (braked: the worm gear holds it) and the distal joint closes on
    alone with its own share of the motor's effort until it touches or
    reaches its limit. A finger whose distal link touches first stalls as a
    whole (its clutch is dropped from ``clutches``)."""
    for c in list(clutches):
        if touching & c.rest:
            clutches.remove(c)
        elif touching & c.trigger:
            clutches.remove(c)
            for cid in c.gears:
                dyn.release(cid)
            dyn.velocity_motor(body, c.driven, 0.0, HOLD_FACTOR * hand.actuators.effort)


def hold_closed(dyn: Dynamics, hand: HandSpec, body: Body, rates: Mapping[str, float]) -> None:
    """Non-backdrivable fingers (worm gears): the open-side limit of every
    closing joint (a mimic too: its gear may have broken away) moves to where
    the finger is now, so no load can open it; the motor keeps pushing."""
    for j in hand.joints:
        rate = rates[j.name]
        if rate != 0.0:
            q = dyn.joint_position(body, j.name)
            dyn.set_limits(body, j.name, *((q, j.upper) if rate > 0 else (j.lower, q)))
