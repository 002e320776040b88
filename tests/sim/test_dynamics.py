"""Dynamic scenes: a free object's mass properties and pose, gravity as the
load, rigid hand contacts, gear couplings, collision filter groups."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import SIM_TOL, assert_close

from planner.geometry.decompose import convex_parts
from planner.geometry.solid import load_object
from planner.sim import Sim, pb
from planner.sim.dynamics import Dynamics, Shape, part_file
from planner.specs.hands import load_hand

#: Half a second of simulated time in steps of 1/480 s.
STEPS = 240


@pytest.fixture(scope="module")
def box():  # type: ignore[no-untyped-def]
    obj = load_object("box")
    parts = convex_parts(obj.mesh, obj.mesh_hash)
    return obj, Shape("parts", files=tuple(part_file(v, f) for v, f in zip(parts.vertices, parts.faces)))


def placed(x: float, y: float, z: float) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


@pytest.mark.parametrize("primitive", [False, True])
def test_the_object_frame_is_where_it_was_put(box, primitive: bool) -> None:  # type: ignore[no-untyped-def]
    obj, parts = box
    shape = Shape("box", obj.spec.dims) if primitive else parts
    with Sim() as sim:
        dyn = Dynamics(sim)
        uid = dyn.add_object(shape, obj.mass, obj.com, obj.inertia, obj.friction, placed(0.1, 0.2, 0.3))
        assert_close(dyn.object_pose(uid), placed(0.1, 0.2, 0.3), 1e-6)
        assert_close(dyn.centre_of_mass(uid), obj.com + [0.1, 0.2, 0.3], 1e-6)
        dyn.set_object_pose(uid, placed(-0.1, 0.0, 0.5))
        assert_close(dyn.object_pose(uid), placed(-0.1, 0.0, 0.5), 1e-6)


def test_gravity_accelerates_a_free_object_by_g(box) -> None:  # type: ignore[no-untyped-def]
    obj, parts = box
    g = np.array([0.0, 2.0, 0.0])  # [m/s^2]: a trial's load is a gravity vector in the hand frame
    with Sim() as sim:
        dyn = Dynamics(sim)  # no gravity until asked for
        uid = dyn.add_object(parts, obj.mass, obj.com, obj.inertia, obj.friction, np.eye(4))
        dyn.step(STEPS)
        assert_close(dyn.object_pose(uid), np.eye(4), 1e-12)
        dyn.set_gravity(g)
        dyn.step(STEPS)
        moved = dyn.object_pose(uid)[:3, 3]
    assert moved[1] == pytest.approx(0.5 * g[1] * (STEPS * dyn.dt) ** 2, rel=0.01)  # x = a t^2 / 2
    assert_close(moved[[0, 2]], [0.0, 0.0], 1e-9)


def test_the_hand_is_fixed_at_the_origin_with_rigid_contacts() -> None:
    hand = load_hand("panda")
    with Sim() as sim:
        dyn = Dynamics(sim)
        body = dyn.add_hand(hand.urdf)
        assert_close(sim.link_pose(body, hand.root_link), np.eye(4), 1e-9)
        finger = pb.getDynamicsInfo(body.uid, body.links["panda_leftfinger"], physicsClientId=sim.client)
        # the URDF's pads: stiffness 3e4 N/m (the fingers sank ~1 cm into objects), spinning 0.1 m
        assert finger[9] != 30000.0 and finger[7] == 0.0
        dyn.set_contact(body.uid, body.links["panda_leftfinger"], 0.004)
        finger = pb.getDynamicsInfo(body.uid, body.links["panda_leftfinger"], physicsClientId=sim.client)
        assert (finger[1], finger[7]) == (1.0, 0.004)  # lateral 1: the contact takes the object's mu


def test_the_hand_gets_the_moments_of_inertia_it_is_given_for_the_links_named() -> None:
    """PyBullet gives each link the moments of its collision shapes (not the URDF's, here pybullet_data's 1 kg
    m^2 placeholder); hand.toml's [dynamics.link_inertia] replaces those of the links it names, others stay."""
    hand = load_hand("pr2")
    with Sim() as sim:
        dyn = Dynamics(sim)
        plain = dyn.add_hand(hand.urdf)
        given = dyn.add_hand(hand.urdf, {"left_tip": (2e-5, 3e-5, 4e-5)})

        def moments(body, link):  # type: ignore[no-untyped-def]
            return pb.getDynamicsInfo(body.uid, body.links[link], physicsClientId=sim.client)[2]

        assert moments(given, "left_tip") == pytest.approx((2e-5, 3e-5, 4e-5), rel=1e-9)
        assert max(moments(plain, "left_tip")) < 1e-3  # the collision box's, not the URDF's 1 kg m^2
        assert moments(given, "right_tip") == moments(plain, "right_tip")


def test_a_gear_keeps_the_mimic_at_its_multiplier() -> None:
    # PyBullet's gear keeps q_parent + ratio q_child = 0; ratio -m would jam the Barrett's distal at a third
    hand = load_hand("barrett")
    with Sim() as sim:
        dyn = Dynamics(sim)
        body = dyn.add_hand(hand.urdf)
        dyn.gear(body, "bh_j32_joint", "bh_j33_joint", 1 / 3, 100.0, 0.8)
        dyn.velocity_motor(body, "bh_j33_joint", 0.0, 0.0)
        dyn.velocity_motor(body, "bh_j32_joint", 2.0, 5.0)
        dyn.step(STEPS // 2)
        q = dyn.joint_position(body, "bh_j32_joint"), dyn.joint_position(body, "bh_j33_joint")
    assert q[0] > 0.4
    assert q[1] == pytest.approx(q[0] / 3, abs=0.01)


def test_filter_groups_keep_trials_apart(box) -> None:  # type: ignore[no-untyped-def]
    obj, parts = box
    for same_group in (True, False):
        with Sim() as sim:
            dyn = Dynamics(sim)
            a = dyn.add_object(parts, obj.mass, obj.com, obj.inertia, obj.friction, np.eye(4))
            b = dyn.add_object(parts, obj.mass, obj.com, obj.inertia, obj.friction, placed(0.01, 0.0, 0.0))
            dyn.keep_apart([a], 0)
            dyn.keep_apart([b], 0 if same_group else 1)
            dyn.step(STEPS // 4)
            apart = np.linalg.norm(dyn.centre_of_mass(b) - dyn.centre_of_mass(a))
        # overlapping boxes of one group are pushed apart; of two groups they pass through each other
        assert (apart > 0.02) if same_group else apart == pytest.approx(0.01, abs=1e-9)


def test_overlap_and_touching_links(box) -> None:  # type: ignore[no-untyped-def]
    obj, parts = box
    hand = load_hand("panda")
    with Sim() as sim:
        dyn = Dynamics(sim)
        body = dyn.add_hand(hand.urdf)
        uid = dyn.add_object(parts, obj.mass, obj.com, obj.inertia, obj.friction, placed(0.0, 0.0, -1.0))
        assert dyn.overlap(body, uid) == 0.0 and dyn.touching_links(body, uid) == set()
        inside = np.diag([1.0, -1.0, -1.0, 1.0])
        inside[2, 3] = 0.04 + 0.05  # the box top 1 cm above the palm: the box in the hand frame
        dyn.set_object_pose(uid, np.linalg.inv(inside))
        assert dyn.overlap(body, uid) > 0.01 - SIM_TOL


def _diagonalises(inertia: np.ndarray, moments: list[float], quaternion: list[float]) -> None:
    from planner.sim import rotation_from_xyzw

    axes = rotation_from_xyzw(quaternion)
    assert_close(np.linalg.det(axes), 1.0, 1e-9)
    assert_close(axes.T @ inertia @ axes, np.diag(moments), 1e-9 * max(moments))


@pytest.mark.parametrize("moments", [(1.0, 2.0, 3.0), (2.0, 2.0, 5.0), (1.0, 4.0, 4.0), (3.0, 3.0, 3.0)])
def test_principal_inertia_is_a_right_handed_frame_that_diagonalises_the_tensor(moments) -> None:  # type: ignore[no-untyped-def]
    from scipy.spatial.transform import Rotation

    from planner.sim.dynamics import principal_inertia

    turn = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    inertia = 1e-4 * turn @ np.diag(moments) @ turn.T
    got, quaternion = principal_inertia(inertia)
    assert_close(np.array(got), 1e-4 * np.sort(moments), 1e-12)
    _diagonalises(inertia, got, quaternion)


def test_principal_inertia_does_not_depend_on_the_last_bits_of_its_input() -> None:
    """Equal moments (a cylinder's two, a sphere's three) have a whole plane
    or space of principal axes; the eigen solver may return any basis of it,
    and another BLAS kernel another one. The frame is chosen from the object
    axes instead, and every number is rounded, so inputs that differ by
    round-off give the very same frame."""
    from planner.sim.dynamics import principal_inertia

    rng = np.random.default_rng(5)
    for diag in ([2e-4, 2e-4, 5e-4], [3e-4, 3e-4, 3e-4], [1e-4, 2e-4, 3e-4]):
        inertia = np.diag(diag)
        first = principal_inertia(inertia)
        for _ in range(20):
            noise = rng.normal(size=(3, 3)) * 1e-19
            assert principal_inertia(inertia + noise + noise.T) == first
        _diagonalises(inertia, *first)


def test_an_object_of_more_than_16_convex_parts_collides_with_every_part() -> None:
    """PyBullet 3.2.7 builds at most 16 children from one createCollisionShapeArray and drops the rest without a
    word: the mug's 32 CoACD parts were 16 in the PyBullet trial and the settle, whose fingers then closed on air
    (`no_contact`) where the missing parts were."""
    import trimesh

    cubes = [trimesh.creation.box(extents=[0.01] * 3) for _ in range(20)]
    centres = [np.array([0.02 * (i % 5), 0.02 * (i // 5), 0.0]) for i in range(len(cubes))]
    files = tuple(part_file(c.vertices + p, c.faces) for c, p in zip(cubes, centres))
    inertia = np.eye(3) * 1e-5
    with Sim() as sim:
        dyn = Dynamics(sim)
        uid = dyn.add_object(Shape("parts", files=files), 0.2, np.mean(centres, axis=0), inertia, 0.5, np.eye(4))
        probe = pb.createCollisionShape(pb.GEOM_SPHERE, radius=0.001, physicsClientId=sim.client)
        missing = []
        for i, centre in enumerate(centres):
            ball = pb.createMultiBody(0, probe, -1, basePosition=list(centre + [0.0, 0.0, 0.007]),
                                      physicsClientId=sim.client)
            if not pb.getClosestPoints(uid, ball, 0.004, physicsClientId=sim.client):
                missing.append(i)
            pb.removeBody(ball, physicsClientId=sim.client)
    assert missing == []
