"""Dynamic scenes: a free object's mass properties, poses, forces and a held hand."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import SIM_TOL, assert_close

from planner.geometry.decompose import convex_parts
from planner.geometry.solid import load_object
from planner.sim import Sim
from planner.sim.dynamics import Dynamics
from planner.specs.hands import load_hand

#: One second of simulated time in steps of 1/240 s.
STEPS = 240


@pytest.fixture(scope="module")
def box():  # type: ignore[no-untyped-def]
    obj = load_object("box")
    return obj, convex_parts(obj.mesh, obj.mesh_hash)


def placed(x: float, y: float, z: float) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


def test_the_object_frame_is_where_it_was_put(box) -> None:  # type: ignore[no-untyped-def]
    obj, parts = box
    with Sim() as sim:
        dyn = Dynamics(sim)
        uid = dyn.add_object(parts.vertices, parts.faces, obj.mass, obj.com, obj.inertia, obj.friction,
                             placed(0.1, 0.2, 0.3))
        assert_close(dyn.object_pose(uid), placed(0.1, 0.2, 0.3), 1e-6)
        dyn.set_object_pose(uid, placed(-0.1, 0.0, 0.5))
        assert_close(dyn.object_pose(uid), placed(-0.1, 0.0, 0.5), 1e-6)


def test_a_push_accelerates_the_free_object_by_force_over_mass(box) -> None:  # type: ignore[no-untyped-def]
    obj, parts = box
    force = 0.5  # [N]
    with Sim() as sim:
        dyn = Dynamics(sim)  # no gravity until a trial asks for it
        uid = dyn.add_object(parts.vertices, parts.faces, obj.mass, obj.com, obj.inertia, obj.friction, np.eye(4))
        for _ in range(STEPS):
            dyn.push(uid, np.array([force, 0.0, 0.0]))
            dyn.step()
        moved = dyn.object_pose(uid)[:3, 3]
    expected = 0.5 * force / obj.mass * (STEPS * dyn.dt) ** 2  # x = a t^2 / 2
    assert moved[0] == pytest.approx(expected, rel=0.02)
    assert_close(moved[1:], [0.0, 0.0], SIM_TOL)


def test_a_held_hand_stays_put_and_follows_its_hold(box) -> None:  # type: ignore[no-untyped-def]
    hand = load_hand("panda")
    with Sim() as sim:
        dyn = Dynamics(sim)
        body = sim.load_urdf(hand.urdf, fixed=False)
        cid = dyn.hold(body, placed(0.0, 0.0, 0.5), 2000.0)
        dyn.drive(body, {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}, 20.0)
        dyn.step(STEPS // 2)
        assert_close(sim.link_pose(body, hand.root_link)[:3, 3], [0.0, 0.0, 0.5], SIM_TOL)
        assert_close(sim.joint_values(body, ["panda_finger_joint1"]), [0.02], SIM_TOL)
        dyn.move_hold(cid, placed(0.0, 0.05, 0.5), 2000.0)
        dyn.step(STEPS // 2)
        assert_close(sim.link_pose(body, hand.root_link)[:3, 3], [0.0, 0.05, 0.5], SIM_TOL)


def test_overlap_and_touching_links(box) -> None:  # type: ignore[no-untyped-def]
    obj, parts = box
    hand = load_hand("panda")
    with Sim() as sim:
        dyn = Dynamics(sim)
        uid = dyn.add_object(parts.vertices, parts.faces, obj.mass, obj.com, obj.inertia, obj.friction, np.eye(4))
        body = sim.load_urdf(hand.urdf, fixed=True)
        sim.set_pose(body, placed(0.0, 0.0, 1.0))
        assert dyn.overlap(body, uid) == 0.0 and dyn.touching_links(body, uid) == set()
        inside = np.diag([1.0, -1.0, -1.0, 1.0])
        inside[2, 3] = 0.04 + 0.05  # the palm 1 cm into the box top
        sim.set_pose(body, inside)
        assert dyn.overlap(body, uid) > 0.005
