"""The hand in a trial's world: its contacts, finger motors, gear couplings
and worm-gear ratchet, as the hand's ``[dynamics]`` and ``[contact]``
tables describe them (the world is the hand frame)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from planner.sim import Body, Sim
from planner.sim.dynamics import Dynamics
from planner.specs.hands import DynamicsSpec, HandSpec
from planner.validation.tolerances import GEAR_FACTOR, HOLD_FACTOR


def set_contacts(dyn: Dynamics, hand: HandSpec, body: Body) -> None:
    """Every link: the object's own friction; soft links (pads) also resist
    a moment about the normal of up to mu x torsion_radius x normal force."""
    for name, index in body.links.items():
        model = hand.contacts.get(name)
        dyn.set_contact(body.uid, index, model.torsion_radius if model is not None and model.model == "soft" else 0.0)


def joint_axes(sim: Sim, hand: HandSpec, body: Body) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(point, unit direction) of every finger joint's axis in the world (= hand) frame now."""
    out = {}
    for j in hand.joints:
        frame = sim.link_pose(body, j.child)  # PyBullet's link frame is the URDF joint frame
        out[j.name] = (frame[:3, 3], frame[:3, :3] @ body.joint_axes[j.name])
    return out


def drive_fingers(dyn: Dynamics, hand: HandSpec, body: Body, rates: Mapping[str, float],
                  hold: Mapping[str, float], gear_erp: float) -> None:
    """Finger motors at the hand's ``[dynamics]``: every closing joint a
    velocity motor (the fastest at ``closing_speed``, the others in
    proportion to their ``rates``), a driven joint's ``effort`` shared with
    its mimics in proportion to their multipliers (sum of m_i x effort_i =
    effort: the statics of one motor behind a gear train) and gear
    constraints keeping them together; joints that do not close hold their
    ``hold`` value (a spread set by the preshape)."""
    act: DynamicsSpec = hand.dynamics  # type: ignore[assignment]
    fastest = max([abs(rates[j.name]) for j in hand.driven] + [0.0])
    for j in hand.driven:
        members = [(j.name, 1.0)] + [(m.name, m.multiplier) for m in hand.joints if m.mimic == j.name]
        norm = sum(m * m for _, m in members)
        for name, m in members:
            if name != j.name:
                dyn.gear(body, j.name, name, m, GEAR_FACTOR * act.effort, gear_erp)
            rate = rates[name]
            if rate == 0.0:
                dyn.position_motor(body, name, float(hold.get(name, 0.0)), HOLD_FACTOR * act.effort)
            else:
                dyn.velocity_motor(body, name, act.closing_speed * rate / fastest, act.effort * abs(m) / norm)


def hold_closed(dyn: Dynamics, hand: HandSpec, body: Body, rates: Mapping[str, float]) -> None:
    """Non-backdrivable fingers (worm gears): the open-side limit of every
    closing driven joint moves to where the finger is now, so no load can
    open it (its mimics follow through the gear); the motor keeps pushing."""
    for j in hand.driven:
        rate = rates[j.name]
        if rate != 0.0:
            q = dyn.joint_position(body, j.name)
            dyn.set_limits(body, j.name, *((q, j.upper) if rate > 0 else (j.lower, q)))
