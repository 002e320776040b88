"""The python-fcl adapter: a body's URDF shapes mirrored in fcl agree with
PyBullet on known shapes (distances within PyBullet's margins and the
tessellation of its cylinders; overlap verdicts exactly)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planner.errors import ConfigError
from planner.geometry.solid import load_object
from planner.sim import Sim
from planner.sim import fcl as adapter
from planner.specs.hands import DEFAULT_DISTANCE_OFFSET, load_hand

#: PyBullet collides a URDF cylinder as a 32-sided hull and reports distances
#: through 1 mm margins per shape; fcl is exact: they agree to about this [m].
PYBULLET_TOL = 3e-4
#: fcl's own distances between exact shapes [m].
EXACT_TOL = 1e-7
#: fcl's signed distance between convex shapes [m]: GJK's apart, EPA's depth overlapping (libccd's tolerances).
EPA_TOL = 1e-6
#: A URDF <box> is a Bullet box shape whose margin lies inside its extents:
#: against a mesh only the mesh's 1 mm margin shows (meshes and URDF
#: cylinders add 1 mm each: DEFAULT_DISTANCE_OFFSET) [m].
BOX_OFFSET = 0.001

PROBE = """<?xml version="1.0"?>
<robot name="probe">
  <link name="base">
    <collision><geometry><box size="0.02 0.02 0.02"/></geometry></collision>
    <inertial><mass value="0.1"/><inertia ixx="1e-5" iyy="1e-5" izz="1e-5" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="stick">
    <collision><origin xyz="0 0 0.02"/><geometry><cylinder radius="0.01" length="0.04"/></geometry></collision>
    <inertial><mass value="0.1"/><inertia ixx="1e-5" iyy="1e-5" izz="1e-5" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="mount" type="fixed"><parent link="base"/><child link="stick"/><origin xyz="0 0 0.01"/></joint>
</robot>
"""


@pytest.fixture()
def probe(tmp_path: Path) -> Path:
    path = tmp_path / "probe.urdf"
    path.write_text(PROBE)
    return path


def pybullet_gap(sim: Sim, body: int, obj: int, offset: float = DEFAULT_DISTANCE_OFFSET) -> float:
    return sim.closest(body, obj, 0.1).min_distance + offset


@pytest.mark.parametrize("height", [0.003, 0.01, 0.025])
def test_box_and_cylinder_above_a_box_measure_the_known_gap(probe: Path, height: float) -> None:
    box = load_object("box")  # 5 x 4 x 8 cm, top face at z = 0.04
    with Sim() as sim:
        target = sim.add_static_mesh(box.mesh.vertices, box.mesh.faces)
        body = sim.load_urdf(probe)
        shapes = adapter.LinkShapes(sim, body, probe, ["base", "stick"])
        bvh = adapter.object_bvh(box.mesh.vertices, box.mesh.faces)
        pose = np.eye(4)
        pose[2, 3] = 0.04 + 0.01 + height  # the probe's box bottom `height` above the top face
        sim.set_pose(body, pose)
        shapes.update()
        assert shapes.distance(bvh) == pytest.approx(height, abs=EXACT_TOL)
        assert shapes.distance(bvh) == pytest.approx(pybullet_gap(sim, body.uid, target, BOX_OFFSET),
                                                     abs=PYBULLET_TOL)
        assert not shapes.collides(bvh)
        pose[2, 3] = 0.04  # half inside
        sim.set_pose(body, pose)
        shapes.update()
        assert shapes.collides(bvh) and pybullet_gap(sim, body.uid, target) < 0


def test_cylinder_on_its_side_beside_a_box(probe: Path) -> None:
    """The stick turned to lie along x, its curved side 7 mm from the box's +y face."""
    box = load_object("box")
    with Sim() as sim:
        target = sim.add_static_mesh(box.mesh.vertices, box.mesh.faces)
        body = sim.load_urdf(probe)
        shapes = adapter.LinkShapes(sim, body, probe, ["stick"])
        bvh = adapter.object_bvh(box.mesh.vertices, box.mesh.faces)
        pose = np.eye(4)
        pose[:3, :3] = Rotation.from_euler("y", 90, degrees=True).as_matrix()
        # the stick's centre at x = -0.02 (over the box), its side 7 mm past the +y face
        pose[:3, 3] = [-0.03 - 0.02, 0.02 + 0.01 + 0.007, 0.0]
        sim.set_pose(body, pose)
        shapes.update()
        assert shapes.distance(bvh) == pytest.approx(0.007, abs=EXACT_TOL)
        assert shapes.distance(bvh) == pytest.approx(pybullet_gap(sim, body.uid, target), abs=PYBULLET_TOL)


@pytest.mark.parametrize("name", ["panda", "barrett", "allegro", "pr2"])
def test_hands_agree_with_pybullet_near_the_mug(name: str) -> None:
    """Random hand poses and finger joints around the concave mug: the same
    overlap verdicts, distances within PyBullet's margins."""
    hand, mug = load_hand(name), load_object("mug")
    rng = np.random.default_rng(1)
    gaps = []
    with Sim() as sim:
        target = sim.add_static_mesh(mug.mesh.vertices, mug.mesh.faces)
        body = sim.load_urdf(hand.urdf)
        links = [n for n in hand.links if sim.has_collision(body, n)]
        shapes = adapter.LinkShapes(sim, body, hand.urdf, links)
        bvh = adapter.object_bvh(mug.mesh.vertices, mug.mesh.faces)
        for k in range(30):
            pose = np.eye(4)
            pose[:3, :3] = Rotation.random(random_state=k).as_matrix()
            pose[:3, 3] = rng.uniform(-0.12, 0.12, 3)
            sim.set_pose(body, pose)
            sim.set_joints(body, {j.name: rng.uniform(j.lower, j.upper) for j in hand.joints})
            shapes.update()
            reported = pybullet_gap(sim, body.uid, target)
            assert shapes.collides(bvh) == (reported <= 0), k
            distance = shapes.distance(bvh)
            if distance > 0 and np.isfinite(reported):
                gaps.append(distance - reported)
    assert gaps and np.max(np.abs(gaps)) < PYBULLET_TOL


def test_shapes_placed_relative_to_the_base_match_the_simulator(probe: Path) -> None:
    box = load_object("box")
    with Sim() as sim:
        body = sim.load_urdf(probe)
        shapes = adapter.LinkShapes(sim, body, probe, ["base", "stick"])
        relative = shapes.frames()  # base at the origin
        bvh = adapter.object_bvh(box.mesh.vertices, box.mesh.faces)
        for z in (0.0, 0.045, 0.052, 0.2):
            pose = np.eye(4)
            pose[2, 3] = z
            sim.set_pose(body, pose)
            shapes.update()
            assert shapes.collides_at(pose, relative, bvh) == shapes.collides(bvh)


PADS = """<?xml version="1.0"?>
<robot name="pads">
  <link name="base"/>
  <link name="left">
    <collision><geometry><box size="0.01 0.02 0.02"/></geometry></collision>
  </link>
  <link name="right">
    <collision><origin xyz="0.02 0 0" rpy="1.5707963267948966 0 0"/>
      <geometry><cylinder radius="0.005" length="0.02"/></geometry></collision>
    <collision><geometry><box size="0.01 0.02 0.02"/></geometry></collision>
  </link>
  <link name="bare"/>
  <joint name="l" type="prismatic"><parent link="base"/><child link="left"/><axis xyz="1 0 0"/>
    <limit lower="-0.1" upper="0.1" effort="1" velocity="1"/></joint>
  <joint name="r" type="prismatic"><parent link="base"/><child link="right"/><axis xyz="1 0 0"/>
    <limit lower="-0.1" upper="0.1" effort="1" velocity="1"/></joint>
  <joint name="b" type="fixed"><parent link="base"/><child link="bare"/></joint>
</robot>
"""


def at(x: float, y: float = 0.0) -> np.ndarray:
    out = np.eye(4)
    out[:2, 3] = x, y
    return out


@pytest.mark.parametrize("right, gap", [
    (at(0.013), 0.003),  # apart along x: the boxes' faces 3 mm apart
    (at(0.010), 0.0),  # touching
    (at(0.006), -0.004),  # overlapping 4 mm along x (20 mm along y and z): the depth
    (at(0.013, 0.024), np.hypot(0.003, 0.004)),  # apart across an edge
    (at(-0.033), 0.003),  # the right link's cylinder (radius 5 mm, 2 cm out along x) 3 mm from the left box
])
def test_the_gap_between_two_links_is_signed_and_exact(tmp_path: Path, right: np.ndarray, gap: float) -> None:
    """Two box pads (a URDF's primitives, made convex hulls) and a cylinder: fcl's distance apart, EPA's
    depth overlapping; the same whatever rigid motion moves both links."""
    urdf = tmp_path / "pads.urdf"
    urdf.write_text(PADS)
    pads = adapter.LinkGap(urdf, "left", "right")
    assert pads(np.eye(4), right) == pytest.approx(gap, abs=EPA_TOL)
    motion = np.eye(4)
    motion[:3, :3] = Rotation.from_euler("xyz", [0.3, -1.1, 2.0]).as_matrix()
    motion[:3, 3] = [0.4, -0.2, 1.5]
    assert pads(motion, motion @ right) == pytest.approx(gap, abs=EPA_TOL)


def test_a_link_without_collision_geometry_has_no_gap(tmp_path: Path) -> None:
    urdf = tmp_path / "pads.urdf"
    urdf.write_text(PADS)
    with pytest.raises(ConfigError, match="'left' and 'bare' need collision shapes"):
        adapter.LinkGap(urdf, "left", "bare")
