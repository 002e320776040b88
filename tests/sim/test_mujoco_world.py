"""The MuJoCo world: every hand's model compiles and its fingers close under
their motors, mimic joints follow their masters, the object sits where it
was put with its mass, and the hand follows its weld target."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest
from helpers import assert_close

from planner.sim.mujoco_world import Solid, World, build
from planner.specs.hands import hand_names, load_hand

#: [rad or m] a joint within this of where its coupling puts it (the gear is a stiff equality constraint).
GEAR_TOL = 1e-3
#: [m] the hand's root within this of its weld target at rest.
WELD_TOL = 1e-3


def far_away(distance: float = 1.0) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = (distance, 0.0, 0.0)
    return pose


def cube(mass: float = 0.2) -> Solid:
    side = 0.04
    return Solid("box", (side, side, side), (), mass, np.zeros(3), np.eye(3) * mass * side ** 2 / 6)


@pytest.mark.parametrize("name", hand_names())
def test_every_hand_compiles_and_its_fingers_close_under_their_motors(name: str) -> None:
    hand = load_hand(name)
    world = build(hand, cube())
    closing = {j.name: j for j in hand.driven if j.close != 0.0}
    start = {j.name: (j.lower if j.close > 0 else j.upper) for j in hand.joints if j.mimic is None}
    world.reset(far_away(), hand.full_configuration(start))
    for name_, j in closing.items():
        lag = 0.002 if j.kind == "prismatic" else 0.04
        kp = hand.actuators.effort / lag
        world.drive(name_, j.upper if j.close > 0 else j.lower, kp, 0.01 * kp, hand.actuators.effort)
    world.step(1000)  # 2 s
    for name_, j in closing.items():
        closed = j.upper if j.close > 0 else j.lower
        assert abs(world.joint_position(name_) - closed) < 0.05 * (j.upper - j.lower), name_
    for j in hand.joints:
        if j.mimic is not None:
            expected = j.multiplier * world.joint_position(j.mimic) + j.offset
            assert abs(world.joint_position(j.name) - expected) < GEAR_TOL, j.name
    assert world.touching_links() == set()  # the hand is a metre away


def test_a_released_gear_lets_the_mimic_move_alone() -> None:
    hand = load_hand("barrett")
    world = build(hand, cube())
    world.reset(far_away(), hand.full_configuration({}))
    world.couple("bh_j13_joint", False)
    world.drive("bh_j12_joint", 0.0, 5000.0, 50.0, 100.0)  # the proximal joint braked
    world.drive("bh_j13_joint", 0.7, 50.0, 0.5, 1.0)
    world.step(500)
    assert world.joint_position("bh_j13_joint") > 0.6 and abs(world.joint_position("bh_j12_joint")) < 0.01


def test_the_object_sits_where_it_was_put_and_falls_with_gravity() -> None:
    world = build(load_hand("panda"), cube(0.3))
    pose = far_away(0.2)
    world.reset(far_away(), {}, pose)
    assert_close(world.object_pose(), pose, 1e-9)
    assert_close(world.model.body_mass[world.object_body], 0.3, 1e-9)
    world.set_gravity(np.array([0.0, 0.0, -9.81]))
    world.step(250)  # 0.5 s of free fall: 1.226 m
    assert_close(world.object_pose()[2, 3], -0.5 * 9.81 * 0.5 ** 2, 0.01)


def test_the_hand_follows_its_weld_target() -> None:
    world = build(load_hand("panda"), cube())
    world.reset(far_away(), {})
    target = far_away(1.05)
    world.move_hand(target)
    world.step(250)
    assert_close(world.hand_pose()[:3, 3], target[:3, 3], WELD_TOL)


def test_hulls_collide_like_the_primitive_and_contacts_point_into_the_object() -> None:
    # the Panda's left pad pressed on a cube (as a box and as its hull): contacts on the pad, normal along -y
    hand = load_hand("panda")
    side = 0.04
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * side / 2
    for solid in (cube(), Solid("hulls", (), (corners,), 0.2, np.zeros(3), np.eye(3) * 0.2 * side ** 2 / 6)):
        world = build(hand, solid)
        pose = np.diag([-1.0, 1.0, -1.0, 1.0])
        pose[:3, 3] = -pose[:3, :3] @ hand.tcp  # tool centre point at the cube's centre, approaching along -z
        world.reset(pose, {"panda_finger_joint1": 0.0195, "panda_finger_joint2": 0.0195})
        points, normals, links = world.contact_points()
        assert set(links) == {"panda_leftfinger", "panda_rightfinger"}
        assert np.all(np.abs(np.abs(points[:, 1]) - side / 2) < 0.002)
        assert np.all(np.abs(normals[:, 1]) > 0.99) and np.all(np.sign(normals[:, 1]) == -np.sign(points[:, 1]))
        assert 0 < world.depth() < 0.002


def test_a_diverged_state_is_logged_not_written_beside_the_user(tmp_path, monkeypatch, caplog) -> None:  # type: ignore[no-untyped-def]
    """MuJoCo's own warning handler prints and appends to MUJOCO_LOG.TXT in the
    working directory; the adapter sends its warnings to the log instead."""
    import mujoco

    monkeypatch.chdir(tmp_path)
    model = mujoco.MjModel.from_xml_string('<mujoco><worldbody><body><freejoint/><geom size="0.1"/></body>'
                                           "</worldbody></mujoco>")
    data = mujoco.MjData(model)
    data.qvel[:] = np.nan
    with caplog.at_level("WARNING", logger="planner.sim.mujoco_world"):
        mujoco.mj_step(model, data)
    assert any("unstable" in r.getMessage() for r in caplog.records)
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_a_diverged_state_is_seen_until_the_next_reset() -> None:
    world = build(load_hand("panda"), cube())
    pose = np.eye(4)
    pose[:3, 3] = (0.0, 0.0, 0.3)  # the hand well above the cube
    world.reset(pose, {})
    world.step(5)
    assert not world.diverged()
    world.data.qvel[-1] = np.nan  # the object's spin
    assert world.diverged()  # not finite now
    world.step()  # MuJoCo resets the state, finite again, and counts a warning
    assert np.all(np.isfinite(world.data.qvel)) and world.diverged()
    world.reset(pose, {})
    assert not world.diverged()


def test_the_model_text_writes_mujocos_own_quaternions() -> None:
    # the MJCF builder (no mujoco) and the weld targets use one function with mju_mat2Quat's branches
    import mujoco
    from scipy.spatial.transform import Rotation

    from planner.sim.mujoco_mjcf import quat, quats

    turns = Rotation.random(500, random_state=np.random.default_rng(0)).as_matrix()
    flips = np.array([np.diag(d) for d in ([1.0, 1, 1], [1.0, -1, -1], [-1.0, 1, -1], [-1.0, -1, 1])])
    rotations = np.concatenate([turns, flips])
    theirs = np.zeros((len(rotations), 4))
    for row, r in zip(theirs, rotations):
        mujoco.mju_mat2Quat(row, r.ravel())
    assert_close(quats(rotations), theirs, QUAT_TOL)
    assert_close(quat(rotations[7]), theirs[7], QUAT_TOL)


#: Quaternions equal to a few units in the last place (the same formulas, normalised in another order).
QUAT_TOL = 1e-14


#: The Panda's fingers closing at 5 cm/s.
CLOSING = {"panda_finger_joint1": -0.05, "panda_finger_joint2": -0.05}


def _panda_above(solid: Solid, gap: float) -> World:
    """A world of the Panda from above ``solid`` (4 cm across), its pads ``gap`` [m] off the solid's sides."""
    hand = load_hand("panda")
    world = build(hand, solid)
    pose = np.diag([-1.0, 1.0, -1.0, 1.0])
    pose[:3, 3] = -pose[:3, :3] @ hand.tcp
    opening = 0.02 + gap
    world.reset(pose, {"panda_finger_joint1": opening, "panda_finger_joint2": opening})
    return world


def test_the_clearance_is_the_distance_to_the_object_and_the_speed_bounds_every_point() -> None:
    # the Panda from above a cube, its pads 5 mm off the cube's sides (fingers 2.5 cm apart + 5 mm each side)
    world = _panda_above(cube(), 0.005)
    gap, speed = world.clearance(CLOSING, 0.05)
    assert_close(gap, 0.005, 0.0005)  # the pads' faces, as the contact test above places them (<2 mm deep)
    assert_close(speed, 0.05, 1e-12)  # a slide: its own speed
    assert world.clearance({}, 0.05) == (0.05, 0.0)  # nothing moves: no gap to close
    world.reset(far_away(), {})
    assert world.clearance(CLOSING, 0.05)[0] == 0.05  # nothing within reach


def two_halves(mass: float = 0.2) -> Solid:
    """The cube of :func:`cube` as two convex parts (its -x and +x halves): an object MuJoCo keeps a
    bounding-volume tree of."""
    side = 0.04
    corners = np.array([[x, y, z] for x in (0, 1) for y in (-1, 1) for z in (-1, 1)], float) * side / 2
    halves = (corners * (-1.0, 1.0, 1.0), corners)
    return Solid("hulls", (), halves, mass, np.zeros(3), np.eye(3) * mass * side ** 2 / 6)


def test_the_clearance_sees_an_object_of_parts_within_reach() -> None:
    # the Panda's pads 2 cm off the sides of a cube of two parts: the moving pads' boxes do not meet the boxes of
    # the object's bounding-volume tree, which MuJoCo prunes at the bodies' margins (compiled 0; before 2026-12-07
    # the probe set only the geoms' and read nothing within 5 cm: gap 0.05)
    world = _panda_above(two_halves(), 0.02)
    gap, _ = world.clearance(CLOSING, 0.05)
    assert_close(gap, 0.02, 0.0005)  # as the one-part cube's 5 mm above
    margins = (world.model.geom_margin.copy(), world.model.body_margin.copy())
    world.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_MIDPHASE  # every pair of geoms, no tree
    assert world.clearance(CLOSING, 0.05)[0] == gap
    assert np.array_equal(world.model.geom_margin, margins[0]) and np.array_equal(world.model.body_margin, margins[1])


def test_the_speed_bound_of_a_revolute_finger_holds_its_fastest_point() -> None:
    # the Barrett's finger 1 turning at 1 rad/s on both joints: no vertex of its links moves faster
    hand = load_hand("barrett")
    world = build(hand, cube())
    world.reset(far_away(), hand.full_configuration({}))
    world.couple("bh_j13_joint", False)
    speeds = {"bh_j12_joint": 1.0, "bh_j13_joint": 1.0}
    _, bound = world.clearance(speeds, 0.05)
    links = {"bh_finger_12_link", "bh_finger_13_link"}
    geoms = [g for g, link in world.hand_geoms.items() if link in links]

    def points() -> np.ndarray:  # (n, 3) the geoms' bounding boxes' corners, world frame
        m, d = world.model, world.data
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        return np.concatenate([d.geom_xpos[g] + (corners * m.geom_size[g]) @ d.geom_xmat[g].reshape(3, 3).T
                               for g in geoms])

    before = points()
    dt = 1e-4
    world.set_fingers({name: world.joint_position(name) + v * dt for name, v in speeds.items()}, {})
    fastest = float(np.max(np.linalg.norm(points() - before, axis=1))) / dt
    assert 0.3 * bound < fastest <= bound


def test_following_a_path_in_one_call_steps_as_following_it_step_by_step() -> None:
    world = build(load_hand("panda"), cube())
    poses = np.repeat(far_away()[None], 40, axis=0)
    poses[:, 2, 3] += np.linspace(0.0, 0.02, 40)  # 2 cm up in 40 steps
    path = world.targets(poses)
    world.reset(far_away(), {})
    for row in path:
        world.follow(row)
        world.step()
    one_by_one = world.data.qpos.copy()
    world.reset(far_away(), {})
    world.follow_path(path)
    assert np.array_equal(world.data.qpos, one_by_one)
    assert_close(world.time, 40 * world.model.opt.timestep, 1e-12)
    assert world.hand_pose()[2, 3] > 0.015


def test_link_inertia_replaces_the_urdfs_moments_of_the_links_it_names() -> None:
    """hand.toml's [dynamics.link_inertia] (the PR2's URDF gives its finger links a placeholder 1 kg m^2): those
    links' principal moments in the model, mass and centre of mass the URDF's; every other link as before."""
    panda = load_hand("panda")
    before, after = (build(h, cube()).model for h in
                     (panda, replace(panda, link_inertia={"panda_leftfinger": (2e-5, 3e-5, 4e-5)})))
    left, right = (mujoco.mj_name2id(after, mujoco.mjtObj.mjOBJ_BODY, n) for n in ("panda_leftfinger",
                                                                                   "panda_rightfinger"))
    assert sorted(after.body_inertia[left]) == pytest.approx([2e-5, 3e-5, 4e-5], rel=1e-9)
    assert sorted(before.body_inertia[left]) == pytest.approx([0.1, 0.1, 0.1], rel=1e-9)  # the URDF's placeholder
    assert after.body_mass[left] == before.body_mass[left]
    assert_close(after.body_ipos[left], before.body_ipos[left], 0.0)
    assert_close(after.body_inertia[right], before.body_inertia[right], 0.0)


def test_multiccd_is_what_the_setting_says() -> None:
    # MuJoCo 4 makes several contact points per pair of convex shapes unless told not to: the setting's
    # False wrote no flag at all (only True wrote "enable"), so every trial ran with it while its record said
    # False. Now True (the default) is MuJoCo's default and False disables it.
    from planner.validation.mujoco_settings import Engine, MujocoSettings
    flag = mujoco.mjtDisableBit.mjDSBL_MULTICCD
    hand = load_hand("panda")
    assert MujocoSettings().multiccd and Engine().multiccd
    assert not build(hand, cube(), Engine()).model.opt.disableflags & flag
    assert build(hand, cube(), Engine(multiccd=False)).model.opt.disableflags & flag


def test_islands_are_what_the_engine_says() -> None:
    # MuJoCo 4 solves bodies that do not touch apart unless told not to; both switches off write one flag element
    from planner.validation.mujoco_settings import Engine
    islands, multiccd = mujoco.mjtDisableBit.mjDSBL_ISLAND, mujoco.mjtDisableBit.mjDSBL_MULTICCD
    hand = load_hand("panda")
    assert Engine().islands and not build(hand, cube(), Engine()).model.opt.disableflags & islands
    alone = build(hand, cube(), Engine(islands=False)).model.opt.disableflags
    both = build(hand, cube(), Engine(multiccd=False, islands=False)).model.opt.disableflags
    assert alone & islands and not alone & multiccd and both & islands and both & multiccd


def test_the_cone_is_what_the_engine_says() -> None:
    # every trial ran with elliptic cones; a pyramidal one (bench grids) reaches the compiled model
    from planner.validation.mujoco_settings import Engine
    hand = load_hand("panda")
    assert Engine().cone == "elliptic"
    assert build(hand, cube(), Engine()).model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert build(hand, cube(), Engine(cone="pyramidal")).model.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
