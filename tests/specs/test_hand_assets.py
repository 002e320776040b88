"""Every hand folder in ``hands/``: its description loads, PyBullet and
yourdfpy agree on its kinematics, its preshapes load, and it closes on a
sphere, a box and a cylinder of its size to a force-closure grasp.

Plus known answers of the hands authored here (Barrett, Allegro-style).
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import NUM_TOL, assert_close

from planner.geometry.solid import PreparedObject, prepare
from planner.plan import sampling
from planner.plan.closing import Closed, Grasper
from planner.plan.unit import grasp_quality
from planner.sim import Sim
from planner.specs.hands import HandSpec, hand_names, load_hand
from planner.specs.objects import ObjectSpec
from planner.specs.preshapes import load_preshapes

HANDS = hand_names()
SEED = 0
#: PyBullet's and yourdfpy's forward kinematics of one URDF [m, rotation entries]:
#: both are exact up to float32 storage inside PyBullet.
FK_TOL = 1e-5
#: Characteristic radius [m] of the test objects per hand (about a third of
#: the opening); a hand added later gets the default until it is listed.
OBJECT_RADIUS = {"panda": 0.025, "pr2": 0.02, "barrett": 0.04, "allegro": 0.03}
DEFAULT_RADIUS = 0.03
RAYS = 12
CONE_EDGES = 8


def test_every_shipped_hand_is_found() -> None:
    assert {"panda", "barrett", "allegro", "pr2"} <= set(HANDS)


def fingers(hand: HandSpec) -> dict[str, str]:
    """Finger of each moving link: the outermost finger joint that moves it."""
    out: dict[str, str] = {}
    for joint in sorted(hand.joints, key=lambda j: -len(j.moves)):
        for link in joint.moves:
            out.setdefault(link, joint.name)
    return out


@pytest.mark.parametrize("name", HANDS)
def test_hand_description_is_complete(name: str) -> None:
    import yourdfpy

    hand = load_hand(name)
    robot = yourdfpy.URDF.load(str(hand.urdf), load_meshes=False, build_collision_scene_graph=False)
    # a movable joint missing from hand.toml would never be set (stays at 0)
    assert {j.name for j in robot.robot.joints if j.type != "fixed"} == {j.name for j in hand.joints}
    with Sim() as sim:
        body = sim.load_urdf(hand.urdf)
        geometry = {link for link in hand.links if sim.has_collision(body, link)}
    # a link that can touch but is not a contact link rejects every grasp it touches
    assert geometry == set(hand.contact_links)
    assert np.isclose(np.linalg.norm(hand.approach), 1.0)
    assert all(j.lower < j.upper for j in hand.joints)
    assert any(j.close != 0 for j in hand.driven)


@pytest.mark.parametrize("name", HANDS)
def test_pybullet_and_yourdfpy_kinematics_agree(name: str) -> None:
    import yourdfpy

    hand = load_hand(name)
    robot = yourdfpy.URDF.load(str(hand.urdf), load_meshes=False, build_collision_scene_graph=False)
    rng = np.random.default_rng(SEED)
    with Sim() as sim:
        body = sim.load_urdf(hand.urdf)
        for _ in range(3):
            driven = {j.name: float(rng.uniform(j.lower, j.upper)) for j in hand.driven}
            robot.update_cfg(driven)  # yourdfpy fills in the mimics itself
            sim.set_joints(body, hand.full_configuration(driven))
            root = np.linalg.inv(sim.link_pose(body, hand.root_link))
            for link in hand.links:
                assert_close(root @ sim.link_pose(body, link), robot.get_transform(link, hand.root_link), FK_TOL)


@pytest.mark.parametrize("name", HANDS)
def test_preshapes_load_within_limits(name: str) -> None:
    hand = load_hand(name)
    shapes = load_preshapes(hand)
    assert shapes
    for shape in shapes:
        assert set(shape.joints) == {j.name for j in hand.joints}
        for joint in hand.joints:
            assert joint.lower - NUM_TOL <= shape.joints[joint.name] <= joint.upper + NUM_TOL
        assert shape.tags and shape.taxonomy


def sized_objects(radius: float) -> dict[str, PreparedObject]:
    """A sphere of ``radius`` [m], and a box and a cylinder of about its size."""
    r = radius
    specs = [ObjectSpec(name="sphere", kind="sphere", dims=(r,), mass=0.2),
             ObjectSpec(name="box", kind="box", dims=(1.6 * r, 1.2 * r, 2.4 * r), mass=0.2),
             ObjectSpec(name="cylinder", kind="cylinder", dims=(0.8 * r, 3.0 * r), mass=0.2)]
    return {s.name: prepare(s) for s in specs}


@pytest.mark.parametrize("name", HANDS)
def test_hand_closes_to_force_closure(name: str) -> None:
    hand = load_hand(name)
    shapes = load_preshapes(hand)
    finger_of = fingers(hand)
    multi = len(set(finger_of.values())) > 1
    for obj in sized_objects(OBJECT_RADIUS.get(name, DEFAULT_RADIUS)).values():
        rays = sampling.sample(obj.mesh, sampler="surface", count=RAYS, rng=np.random.default_rng(SEED))
        with Sim() as sim:
            grasper = Grasper(sim, hand, sim.add_static_mesh(obj.mesh.vertices, obj.mesh.faces))
            found = _first_force_closure(grasper, shapes, rays, obj, finger_of, multi)
        assert found is not None, f"{name}: no force-closure grasp of the {obj.name}"


def _first_force_closure(grasper, shapes, rays, obj, finger_of, multi):  # type: ignore[no-untyped-def]
    for shape in shapes:
        for standoff in shape.standoffs:
            for i in range(len(rays)):
                closed = grasper.close(rays.points[i], rays.directions[i], 0.0, standoff, shape, obj.torque_scale)
                if not isinstance(closed, Closed):
                    continue
                touching = {finger_of[link] for link in closed.contacts.links if link in finger_of}
                if multi and len(touching) < 2:
                    continue
                if grasp_quality(closed.contacts, grasper.hand, obj, CONE_EDGES).force_closure:
                    return closed
    return None


# -- known answers of the authored hands -------------------------------------------------------
def _fk(name: str, driven: dict[str, float], link: str, point: tuple[float, float, float]) -> np.ndarray:
    """(3,) position [m] in the hand frame of ``point`` given in ``link``'s frame."""
    import yourdfpy

    hand = load_hand(name)
    robot = yourdfpy.URDF.load(str(hand.urdf), load_meshes=False, build_collision_scene_graph=False)
    robot.update_cfg({k: float(v) for k, v in driven.items()})
    return (robot.get_transform(link, hand.root_link) @ np.array([*point, 1.0]))[:3]


BARRETT_TIP = (0.056, 0.0, 0.0)  # end of the distal link, its own frame


def _barrett_tips(spread: float, flex: float) -> np.ndarray:
    q = {"bh_j11_joint": spread, "bh_j12_joint": flex, "bh_j22_joint": flex, "bh_j32_joint": flex}
    return np.array([_fk("barrett", q, f"bh_finger_{k}3_link", BARRETT_TIP) for k in (1, 2, 3)])


def test_barrett_spread_mirrors_fingers_one_and_two() -> None:
    for spread in (0.0, 1.0472, 1.5708, 3.14159):
        f1, f2, f3 = _barrett_tips(spread, 0.5)
        assert_close(f2, f1 * [-1, 1, 1], NUM_TOL)  # mirror images in the x = 0 plane
        assert_close(f3[0], 0.0, NUM_TOL)  # finger 3 is fixed in the y-z plane
    y = _barrett_tips(0.0, 0.0)[:, 1]
    assert y[0] < 0 and y[1] < 0 and y[2] > 0  # spread 0: fingers 1 and 2 oppose finger 3
    y = _barrett_tips(3.14159, 0.0)[:, 1]
    assert np.all(y > 0)  # spread pi: all three side by side


def test_barrett_open_span_matches_datasheet() -> None:
    # fully open (flat) hand: ~0.33 m between fingertips (datasheet ~0.335 m)
    tips = _barrett_tips(0.0, 0.0)
    assert 0.30 < np.linalg.norm(tips[0] - tips[2]) < 0.35
    # closing lifts the fingers from the palm plane towards the approach axis
    assert np.all(_barrett_tips(0.0, 1.0)[:, 2] > tips[:, 2])


def test_barrett_distal_follows_a_third_of_the_proximal() -> None:
    hand = load_hand("barrett")
    q = hand.full_configuration({"bh_j11_joint": 0.3, "bh_j12_joint": 1.2, "bh_j22_joint": 0.6, "bh_j32_joint": 2.4})
    assert q["bh_j21_joint"] == q["bh_j11_joint"]
    assert_close([q["bh_j13_joint"], q["bh_j23_joint"], q["bh_j33_joint"]], np.array([1.2, 0.6, 2.4]) * 0.3333)


def test_allegro_is_sixteen_independent_joints_curling_towards_the_approach() -> None:
    hand = load_hand("allegro")
    assert len(hand.driven) == len(hand.joints) == 16
    straight = {j.name: 0.0 for j in hand.driven} | {"thumb_rot": 0.263}
    tip = _fk("allegro", straight, "middle_tip", (0, 0, 0))
    assert_close(tip, [0.0, 0.0, 0.0007 + 0.0164 + 0.054 + 0.0384 + 0.0267], NUM_TOL)  # straight up the z axis
    curled = straight | {"middle_mcp": 0.8, "middle_pip": 0.8, "middle_dip": 0.8}
    assert _fk("allegro", curled, "middle_tip", (0, 0, 0)) @ hand.approach > 0.05


def test_allegro_opposed_thumb_meets_the_index_in_front_of_the_palm() -> None:
    # pinch preshape, index curled 1 rad per joint, thumb 0.7 rad: the 12 mm
    # fingertip spheres overlap about 8 cm in front of the palm face
    pinch = {s.name: s for s in load_preshapes(load_hand("allegro"))}["pinch"]
    q = dict(pinch.joints) | {"index_mcp": 1.0, "index_pip": 1.0, "index_dip": 1.0, "thumb_mcp": 0.7, "thumb_ip": 0.7}
    thumb = _fk("allegro", q, "thumb_tip", (0, 0, 0))
    index = _fk("allegro", q, "index_tip", (0, 0, 0))
    assert np.linalg.norm(thumb - index) < 2 * 0.012
    assert thumb[0] > 0.05 and index[0] > 0.05
