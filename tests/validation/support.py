"""Builders of the validation tests."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from planner.geometry.solid import PreparedObject, prepare
from planner.plan.closing import Closed, CloseSettings, Grasper
from planner.record.contacts import HandContacts
from planner.record.grasp import Grasp
from planner.sim import Sim
from planner.specs.hands import HandSpec, load_hand
from planner.specs.objects import ObjectSpec
from planner.specs.preshapes import load_preshapes


def as_row(closed: Closed, preshape: str, obj: str = "box") -> Grasp:
    return as_row_of("panda", closed.pose, closed.closed_joints, closed.contacts, preshape, obj, closed.open_joints)


def as_row_of(hand: str, pose: np.ndarray, closed_joints: Mapping[str, float], contacts: HandContacts,
              preshape: str = "wide", obj: str = "box", open_joints: Mapping[str, float] | None = None) -> Grasp:
    """A stored grasp of ``hand`` with these joints and contacts (object frame)."""
    return Grasp(object=obj, hand=hand, preshape=preshape, candidate=0, seed=0, approach_point=np.zeros(3),
                 approach_dir=np.array([0, 0, -1.0]), roll=0.0, standoff=0.0, pose=pose,
                 open_joints=open_joints or {}, closed_joints=closed_joints, width=None, contacts=contacts,
                 epsilon=0.0, volume=0.0, force_closure=True, id=0, score=0.0, rank=1)


def close(setup, *, point=(0, 0, 0.04), direction=(0, 0, -1.0), roll=0.0, standoff=0.02, pose=None):  # type: ignore[no-untyped-def]
    hand, shapes, obj = setup
    with Sim() as sim:
        g = Grasper.for_mesh(sim, hand, obj.mesh)
        if pose is not None:
            return g.close_at(pose, shapes["wide"])
        return g.close(np.array(point), np.array(direction), roll, standoff, shapes["wide"], obj.torque_scale)


def top_down(hand: HandSpec, obj: PreparedObject) -> np.ndarray:
    """(4, 4) the Panda above ``obj`` (its approach along the object's -z),
    fingers closing along the object's y, the tool centre point on the centre of mass."""
    pose = np.diag([-1.0, 1.0, -1.0, 1.0])
    pose[:3, 3] = obj.com - pose[:3, :3] @ hand.tcp
    return pose


def pinch(hand: HandSpec, obj: PreparedObject, offset: tuple[float, float, float] = (0.0, 0.0, 0.0),
          contacts: str = "patch") -> Grasp:
    """The planner's own grasp of a box pinched from the top (closing along y)
    across its centre, or ``offset`` [m] from it; ``contacts``: how closing
    reads them (CloseSettings.contacts)."""
    wide = {p.name: p for p in load_preshapes(hand)}["wide"]
    pose = top_down(hand, obj)
    pose[:3, 3] += offset
    with Sim() as sim:
        closed = Grasper(sim, hand, sim.add_static_mesh(obj.mesh.vertices, obj.mesh.faces),
                         CloseSettings(contacts=contacts)).close_at(pose, wide)
    assert isinstance(closed, Closed), closed
    return as_row(closed, "wide", obj.name)


def backed_off(grasp: Grasp, hand: HandSpec, distance: float) -> Grasp:
    """The same grasp (same joints) with the hand moved back ``distance`` [m] along its approach."""
    pose = grasp.pose.copy()
    pose[:3, 3] -= pose[:3, :3] @ hand.approach * distance
    return replace(grasp, pose=pose)


def box(width: float) -> PreparedObject:
    """A 0.2 kg, 5 cm x ``width`` x 6 cm box, friction 0.5."""
    return box_of((0.05, width, 0.06), 0.2)


def box_of(dims: tuple[float, float, float], mass: float, friction: float = 0.5) -> PreparedObject:
    """A box of ``dims`` [m] and ``mass`` [kg], ``friction``."""
    return prepare(ObjectSpec(name="box_" + "x".join(f"{d * 1000:.0f}" for d in dims), kind="box", dims=dims,
                              mass=mass, friction=friction))


#: The Allegro's pinch of a 5 x 4 x 8 cm box from the planner's own sweep (`grasp generate box --hand allegro`,
#: 24 approaches x 2 rolls, its rank 3): the thumb touches 0.73 rad from its open preshape, the index curls to its
#: stop. Object frame; open and closed joints not listed are 0.
ALLEGRO_PINCH_POSE = [[0.0, -1.0, 0.0, 0.001862], [1.0, 0.0, 0.0, -0.0322], [0.0, 0.0, 1.0, -0.026198],
                      [0.0, 0.0, 0.0, 1.0]]
ALLEGRO_PINCH_OPEN = {"index_mcp": 0.3, "index_pip": 0.2, "thumb_rot": 1.396, "thumb_abd": 0.1, "thumb_mcp": 0.2}


def allegro_pinch(shift: float = 0.0) -> tuple[HandSpec, PreparedObject, Grasp]:
    """The Allegro, the box and its pinch (:data:`ALLEGRO_PINCH_POSE`), the box ``shift`` [m] further along the
    fingers (no planned contacts: the MuJoCo trial starts from the open preshape)."""
    hand = load_hand("allegro")
    obj = box_of((0.05, 0.04, 0.08), 0.2)
    pose = np.array(ALLEGRO_PINCH_POSE)
    pose[:3, 3] += pose[:3, :3] @ np.array([0.0, 0.0, shift])  # along the fingers, away from the box
    grasp = as_row_of("allegro", pose, {}, HandContacts(np.zeros((0, 3)), np.zeros((0, 3)), ()), preshape="pinch",
                      open_joints={j.name: ALLEGRO_PINCH_OPEN.get(j.name, 0.0) for j in hand.joints})
    return hand, obj, grasp
