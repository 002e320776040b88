"""The PyBullet adapter: poses in and out, link frames, closest points, pictures."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from helpers import NUM_TOL, assert_close
from scipy.spatial.transform import Rotation

from planner.errors import SimulationError
from planner.geometry.solid import load_object
from planner.sim import MAX_LINKS, MESH_FACES, Sim, mesh_pieces, pb, pb_to_pose, pose_to_pb
from planner.specs.hands import DEFAULT_DISTANCE_OFFSET, load_hand

#: PyBullet stores poses in float32 in places; round trips agree to this.
FLOAT32_TOL = 1e-6


def a_pose(seed: int = 0) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    pose[:3, 3] = [0.1, -0.2, 0.3]
    return pose


def test_pose_conversions_round_trip() -> None:
    for seed in range(5):
        pose = a_pose(seed)
        assert_close(pb_to_pose(*pose_to_pb(pose)), pose, FLOAT32_TOL)


def test_a_placed_hand_reports_its_base_link_where_it_was_put() -> None:
    hand = load_hand("panda")
    with Sim() as sim:
        body = sim.load_urdf(hand.urdf)
        sim.set_pose(body, a_pose())
        assert_close(sim.link_pose(body, hand.root_link), a_pose(), FLOAT32_TOL)
        sim.set_joints(body, {"panda_finger_joint1": 0.03, "panda_finger_joint2": 0.03})
        assert_close(sim.joint_values(body, ["panda_finger_joint1"]), [0.03], NUM_TOL)
        assert sim.movable_joints(body) == ["panda_finger_joint1", "panda_finger_joint2"]
        assert sim.has_collision(body, "panda_leftfinger")
        lo, hi = sim.joint_limits(body, "panda_finger_joint1")
        assert (lo, hi) == pytest.approx((0.0, 0.04))


def test_closest_points_measure_the_gap_to_a_box() -> None:
    box = load_object("box")  # 5 x 4 x 8 cm
    with Sim() as sim:
        target = sim.add_static_mesh(box.mesh.vertices, box.mesh.faces)
        probe = sim.add_box((0.01, 0.01, 0.01), np.eye(4))
        shifted = np.eye(4)
        shifted[:3, 3] = [0.0, 0.0, 0.04 + 0.01 + 0.02]  # 2 cm above the box top
        sim.set_base_pose(probe, shifted)
        pairs = sim.closest(probe, target, 0.05)
        assert len(pairs) > 0
        # a box is a hull here, padded as a mesh is: 1 mm each, the hands' distance_offset in all
        assert pairs.min_distance + DEFAULT_DISTANCE_OFFSET == pytest.approx(0.02, abs=1e-6)
        assert_close(pairs.normal_b[np.argmin(pairs.distance)], [0.0, 0.0, 1.0], 1e-3)
        assert len(sim.closest(probe, target, 0.01)) == 0


def test_a_picture_has_the_size_asked_for() -> None:
    box = load_object("box")
    with Sim() as sim:
        sim.add_visual_mesh(box.mesh.vertices, box.mesh.faces, (0.8, 0.5, 0.2, 1.0))
        image = sim.render(np.array([0.3, -0.3, 0.2]), np.zeros(3), np.array([0.0, 0.0, 1.0]), (64, 48))
    assert image.shape == (48, 64, 3) and image.dtype == np.uint8 and image.std() > 0


def test_hull_bodies_keep_every_hull_or_refuse() -> None:
    # PyBullet keeps 127 links of a multibody and drops the rest silently (issue 26)
    tetra = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]])
    hulls = [tetra + [0.02 * i, 0.0, 0.0] for i in range(MAX_LINKS + 1)]
    with Sim() as sim:
        body = sim.add_static_hulls(hulls[:MAX_LINKS])
        assert pb.getNumJoints(body, physicsClientId=sim.client) == MAX_LINKS
        with pytest.raises(SimulationError):
            sim.add_static_hulls(hulls)


#: [m] how far the icosphere of 20,480 faces lies inside the sphere it approximates, and more.
SAGITTA = 2e-4


def test_a_mesh_beyond_pybullets_index_limit_collides_and_draws_whole() -> None:
    """PyBullet refuses a mesh shape of more than 2^19 indices (~175k faces) and answers a distance query
    whose reach holds many of a shape's triangles wrongly (this sphere in one shape, 7.5 mm from the probe,
    asked within 5 cm: 3 cm inside it): a large mesh goes in as slabs of at most MESH_FACES faces, every
    face in exactly one, and collides and draws as the whole."""
    import trimesh

    fine = trimesh.creation.icosphere(subdivisions=6, radius=0.03)  # 81,920 faces: in one shape, "inside" it
    assert len(fine.faces) > MESH_FACES
    pieces = mesh_pieces(fine.vertices, fine.faces)
    assert len(pieces) == -(-len(fine.faces) // MESH_FACES) and all(len(f) <= MESH_FACES for _, f in pieces)
    triangles = np.sort(np.concatenate([v[f] for v, f in pieces]).reshape(-1, 9), axis=0)
    assert np.array_equal(triangles, np.sort(fine.vertices[fine.faces].reshape(-1, 9), axis=0))
    plain = trimesh.creation.icosphere(subdivisions=5, radius=0.03)  # 20,480 faces: one shape
    directions = np.random.default_rng(0).normal(size=(24, 3))
    directions = np.r_[np.eye(3), -np.eye(3), directions / np.linalg.norm(directions, axis=1)[:, None]]
    with Sim() as sim:
        target, reference = (sim.add_static_mesh(m.vertices, m.faces) for m in (fine, plain))
        probe = sim.add_box((0.005, 0.005, 0.005), np.eye(4))
        for direction in directions:  # every slab, all round
            at = np.eye(4)
            at[:3, 3] = direction * (0.03 + 0.005 + 0.0075)
            sim.set_base_pose(probe, at)
            gap = sim.closest(probe, target, 0.05).min_distance
            assert gap == pytest.approx(sim.closest(probe, reference, 0.05).min_distance, abs=SAGITTA)
        sim.remove_body(probe)
        sim.remove_body(target)
        seen = []
        for sphere in (fine, plain):
            body = sim.add_visual_mesh(sphere.vertices, sphere.faces, (0.8, 0.5, 0.2, 1.0))
            image = sim.render(np.array([0.2, 0.0, 0.0]), np.zeros(3), np.array([0.0, 0.0, 1.0]), (96, 96))
            seen.append(int((np.abs(image.astype(int) - image[0, 0]).sum(axis=2) > 30).sum()))
            sim.remove_body(body)
    assert seen[1] > 500 and seen[0] == pytest.approx(seen[1], rel=0.05)


def _state(sim: Sim, uid: int) -> list:
    """Every joint's position and velocity and every link's frames and box, as PyBullet holds them."""
    c, n = sim.client, pb.getNumJoints(uid, physicsClientId=sim.client)
    return ([pb.getJointState(uid, i, physicsClientId=c)[:2] for i in range(n)]
            + [pb.getLinkState(uid, i, computeForwardKinematics=1, physicsClientId=c) for i in range(n)]
            + [pb.getAABB(uid, i, physicsClientId=c) for i in range(-1, n)])


@pytest.mark.parametrize("name", ["barrett", "allegro"])
def test_setting_joints_together_leaves_the_state_of_setting_each(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """``set_joints`` asks PyBullet once for all the joints it sets (each call updates every link's frames), and
    leaves the hand, to the bit, as one ``resetJointState`` per joint would, from moving joints too. Before: one
    call per joint."""
    hand, rng = load_hand(name), np.random.default_rng(0)
    with Sim() as sim:
        body = sim.load_urdf(hand.urdf)
        sim.set_pose(body, a_pose())
        for _ in range(20):
            values = {j.name: float(rng.uniform(j.lower, j.upper)) for j in hand.joints if rng.random() < 0.7}
            pb.resetJointStatesMultiDof(body.uid, list(body.joints.values()), [[0.3]] * len(body.joints),
                                        [[1.0]] * len(body.joints), physicsClientId=sim.client)
            sim.set_joints(body, values)
            got = _state(sim, body.uid)
            pb.resetJointStatesMultiDof(body.uid, list(body.joints.values()), [[0.3]] * len(body.joints),
                                        [[1.0]] * len(body.joints), physicsClientId=sim.client)
            for joint, value in values.items():
                pb.resetJointState(body.uid, body.joints[joint], value, physicsClientId=sim.client)
            assert got == _state(sim, body.uid)
        calls: list[str] = []
        for kind in ("resetJointState", "resetJointStatesMultiDof"):
            monkeypatch.setattr(pb, kind, _counted(calls, kind, getattr(pb, kind)))
        sim.set_joints(body, {j.name: j.lower for j in hand.joints})
        assert len(calls) == 1


def _counted(calls: list[str], kind: str, call: Callable) -> Callable:
    def counted(*args: object, **kwargs: object) -> object:
        calls.append(kind)
        return call(*args, **kwargs)
    return counted
