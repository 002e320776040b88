"""The worlds the MuJoCo trial (:mod:`planner.validation.mujoco_trial`) runs
in: the object as the trial collides it (:func:`solid`), the engine its
settings ask for, and a per-process cache of built worlds, one per hand,
object (its mesh, centre of mass and inertia), mass and engine (building one costs a few ms, more with many parts;
each trial then starts from a fresh state in it)."""

from __future__ import annotations

import numpy as np

from planner.geometry.solid import PreparedObject
from planner.sim.mujoco_world import Engine, Solid, World, build
from planner.specs.hands import HandSpec
from planner.validation.mujoco_settings import MujocoSettings

#: Worlds kept per process.
KEPT = 8
WORLDS: dict[tuple, World] = {}


def solid(obj: PreparedObject, mass: float, tolerance: float) -> Solid:
    """The object as the trial collides it: the PyBullet trial's shape
    (:func:`planner.validation.parts.trial_shape`: primitives, else convex
    parts simplified to ``tolerance``), at ``mass`` [kg]."""
    from planner.validation.parts import PRIMITIVES, simplified_parts

    inertia = np.asarray(obj.inertia, float) * (mass / obj.mass)
    com = np.asarray(obj.com, float)
    if obj.spec.kind in PRIMITIVES:
        return Solid(obj.spec.kind, tuple(obj.spec.dims), (), mass, com, inertia)
    hulls = tuple(v for v, _ in simplified_parts(obj, tolerance))
    return Solid("hulls", (), hulls, mass, com, inertia)


def world_for(hand: HandSpec, obj: PreparedObject, s: MujocoSettings, mass: float) -> World:
    """The world a trial of ``hand`` on ``obj`` at ``mass`` [kg] runs in with
    settings ``s`` as the hand runs them (:meth:`MujocoSettings.for_hand`): built once per process and kept (the
    last :data:`KEPT`)."""
    s = s.for_hand(hand.name)
    engine = Engine(s.timestep, s.iterations, s.impratio, s.contact_time, 1.0, s.contact_time, s.multiccd,
                    bool(s.islands), s.cone)
    soft = tuple(sorted(link for link, c in hand.contacts.items() if c.model == "soft" and c.torsion_radius > 0))
    inertia = tuple(sorted(hand.link_inertia.items()))
    # its centre of mass and inertia too: one mesh may be two objects, each with its own (a URDF's, a sidecar's)
    key = (hand.name, str(hand.urdf), soft, inertia, obj.mesh_hash, obj.spec.kind, tuple(obj.spec.dims), mass,
           tuple(np.ravel(obj.com).tolist()), tuple(np.ravel(obj.inertia).tolist()), s.part_tolerance, engine)
    if key not in WORLDS:
        if len(WORLDS) >= KEPT:
            WORLDS.pop(next(iter(WORLDS)))
        WORLDS[key] = build(hand, solid(obj, mass, s.part_tolerance), engine)
    return WORLDS[key]
