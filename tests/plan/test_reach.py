import json
import sqlite3
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from planner import api
from planner.cli import main
from planner.geometry.frames import angle_between, pose_from_xyzquat
from planner.geometry.solid import load_object
from planner.plan.reach import MISSES, ReachScene, ReachSettings
from planner.plan.sweep import SweepSettings
from planner.plan.tolerances import ANGLE_TOL, POSITION_TOL
from planner.plan.unit import UnitSpec, add_reachability, run_unit
from planner.sim import Sim
from planner.specs.hands import load_hand

TOP_DOWN = np.array([[1.0, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 0.04 + 0.1034], [0, 0, 0, 1]])  # above the box top


@pytest.fixture(scope="module")
def scene():  # type: ignore[no-untyped-def]
    with Sim() as sim:
        yield ReachScene(sim, load_hand("panda"), load_object("box"), ReachSettings())


def fingers(q: float) -> dict[str, float]:
    return {"panda_finger_joint1": q, "panda_finger_joint2": q}


def test_top_down_grasp_in_front_is_reachable_and_verified_by_fk(scene) -> None:  # type: ignore[no-untyped-def]
    scene.place_object(scene.resting_pose(0.5, 0.0, 0.0))
    r = scene.check(TOP_DOWN, fingers(0.02), fingers(0.04), np.random.default_rng(0))
    assert r.reachable
    target = scene.object_pose @ TOP_DOWN
    for solution, pose in ((r.grasp, target), (r.pregrasp, None)):
        scene.sim.set_joints(scene.arm, solution.joints)
        ee = scene.sim.link_pose(scene.arm, scene.ee_link)
        if pose is None:  # pre-grasp: backed off 10 cm along the approach (+z of the hand = world -z)
            pose = target.copy()
            pose[2, 3] += 0.10
        assert np.linalg.norm(ee[:3, 3] - pose[:3, 3]) <= POSITION_TOL
        assert angle_between(ee[:3, :3], pose[:3, :3]) <= ANGLE_TOL
        for name, value in solution.joints.items():
            lo, hi = scene.sim.joint_limits(scene.arm, name)
            assert lo <= value <= hi
    assert r.grasp.manipulability > 0


def test_far_outside_the_workspace_is_unreachable(scene) -> None:  # type: ignore[no-untyped-def]
    scene.place_object(scene.resting_pose(2.0, 0.0, 0.0))
    assert not scene.check(TOP_DOWN, fingers(0.02), fingers(0.04), np.random.default_rng(0)).reachable


def test_hand_through_the_table_is_rejected(scene) -> None:  # type: ignore[no-untyped-def]
    scene.place_object(scene.resting_pose(0.5, 0.0, 0.0))
    from_below = TOP_DOWN.copy()
    from_below[:3, :3] = np.diag([1.0, 1.0, 1.0])  # hand z up: approaching the box bottom from under the table
    from_below[2, 3] = -0.04 - 0.1034
    assert scene.hand_hits_table(scene.object_pose @ from_below, fingers(0.02))
    assert not scene.check(from_below, fingers(0.02), fingers(0.04), np.random.default_rng(0)).reachable


def test_stored_reachability_agrees_with_a_recheck() -> None:
    settings = SweepSettings(approaches=16, rolls=2, preshapes=("wide",), reach_placements=3, reach_top=0)
    spec = UnitSpec("box", "panda", settings, seed=5)
    result = run_unit(spec)
    fc = [g for g in result.grasps if g.force_closure]
    assert fc and all(g.reachability is not None for g in fc)
    resolved = settings.resolved("antipodal")
    again = add_reachability([g for g in fc[:4]], result.obj, load_hand("panda"), spec, resolved)  # type: ignore[arg-type]
    assert [g.reachability for g in again] == [g.reachability for g in fc[:4]]
    assert any(g.reachability > 0 for g in fc)


def test_reachability_goes_to_the_best_force_closure_grasps_of_a_unit() -> None:
    top = 3
    settings = SweepSettings(approaches=16, rolls=2, preshapes=("wide",), reach_placements=1, reach_top=top)
    result = run_unit(UnitSpec("box", "panda", settings, seed=5))
    fc = sorted((g for g in result.grasps if g.force_closure), key=lambda g: -g.epsilon)
    assert len(fc) > top
    assert all(g.reachability is not None for g in fc[:top])
    assert all(g.reachability is None for g in result.grasps if g not in fc[:top])


def test_cli_best_at_pose_returns_fk_consistent_joint_solutions(tmp_path: Path) -> None:
    db = tmp_path / "g.db"
    settings = SweepSettings(approaches=8, rolls=2, reach_placements=2, sampler="surface")
    api.generate(["box"], "panda", db_path=db, settings=settings, workers=1)
    result = CliRunner().invoke(main, ["best", "box", "--hand", "panda", "--db", str(db), "--object-pose",
                                       "0.5,0,0.04,0,0,0,1", "--top", "2", "--json"])
    assert result.exit_code == 0, result.stderr
    found = json.loads(result.stdout)
    assert found
    obj_pose = pose_from_xyzquat((0.5, 0, 0.04, 0, 0, 0, 1))
    with Sim() as sim:
        scene = ReachScene(sim, load_hand("panda"), load_object("box"))
        scene.place_object(obj_pose)
        for g in found:
            sim.set_joints(scene.arm, g["arm"]["grasp"])
            sim.set_joints(scene.arm, g["joints"])
            ee = sim.link_pose(scene.arm, "panda_hand")
            target = obj_pose @ np.array(g["pose"])
            assert np.linalg.norm(ee[:3, 3] - target[:3, 3]) <= POSITION_TOL
            assert angle_between(ee[:3, :3], target[:3, :3]) <= ANGLE_TOL
            for link in scene.arm_links:  # the base link is bolted to the table top: it touches it
                assert scene._gap(scene.arm, link, scene.table) > 0 or scene.arm.links[link] < 0
    rows = sqlite3.connect(db).execute("SELECT COUNT(*) FROM grasps WHERE reachability IS NOT NULL").fetchone()[0]
    assert rows > 0


def test_hand_on_the_kuka_arm_through_its_mount() -> None:
    """Hands other than the Panda ride on the KUKA iiwa; the hand body follows the flange."""
    hand = load_hand("barrett")
    assert hand.arm is not None and hand.arm.ee_link == "lbr_iiwa_link_7"
    with Sim() as sim:
        scene = ReachScene(sim, hand, load_object("box"))
        assert scene.hand_body is not scene.arm
        scene.place_object(scene.resting_pose(0.5, 0.0, 0.0))
        top_down = np.diag([1.0, -1.0, -1.0, 1.0])
        top_down[2, 3] = 0.04 + 0.12
        r = scene.check(top_down, {}, {}, np.random.default_rng(0))
        assert r.reachable
        sim.set_joints(scene.arm, r.grasp.joints)
        flange = sim.link_pose(scene.arm, "lbr_iiwa_link_7")
        hand_pose = flange @ hand.arm.mount
        target = scene.object_pose @ top_down
        assert np.linalg.norm(hand_pose[:3, 3] - target[:3, 3]) <= POSITION_TOL


@pytest.mark.parametrize("up", ["+y", "-x", "-z"])
def test_an_object_stands_on_its_own_up_on_the_table(scene, up: str) -> None:  # type: ignore[no-untyped-def]
    """The placements stand an object given another up (a Y-up file) on that up: it points along the world's +z
    and the object's lowest point along it touches the table top."""
    from dataclasses import replace

    box = load_object("box")
    turned = replace(box, spec=replace(box.spec, up=up))
    scene.use_object(turned)
    try:
        pose = scene.resting_pose(0.5, 0.1, 0.7)
        assert np.allclose(pose[:3, :3] @ turned.up, [0.0, 0.0, 1.0], atol=1e-12)
        world = turned.mesh.vertices @ pose[:3, :3].T + pose[:3, 3]
        assert world[:, 2].min() == pytest.approx(scene.settings.table_height, abs=1e-12)
    finally:
        scene.use_object(box)



def test_a_pregrasp_on_another_ik_branch_is_not_a_way_to_the_grasp(scene, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The PR2's arm reached a mug grasp, but backing off 10 cm on that branch took a joint just past its limit
    and the pre-grasp's IK answered with the elbow flipped: 5.74 rad between pre-grasp and grasp, reported as
    reachable. Here the pre-grasp's IK is made to answer on another branch (the base joint half a turn on): not
    a way to the grasp, and said so."""
    scene.place_object(scene.resting_pose(0.5, 0.0, 0.0))
    solve = scene.solve

    def other_branch(hand_pose, fingers, rng, *, grasp, seed=None, accept=None):  # type: ignore[no-untyped-def]
        found = solve(hand_pose, fingers, rng, grasp=grasp, seed=seed)
        if grasp or found is None:
            return found
        turned = replace(found, joints={**found.joints, "panda_joint1": found.joints["panda_joint1"] + np.pi})
        return turned if accept is None or accept(turned) else None

    monkeypatch.setattr(scene, "solve", other_branch)
    r = scene.check(TOP_DOWN, fingers(0.02), fingers(0.04), np.random.default_rng(0))
    assert r.grasp is not None and not r.reachable and r.why == MISSES[4]

def test_a_joint_path_that_leaves_the_approach_line_is_not_straight(scene) -> None:  # type: ignore[no-untyped-def]
    """The back-off's joint path is checked by forward kinematics: the real pre-grasp's is straight; the same
    with one joint turned half a turn is not."""
    scene.place_object(scene.resting_pose(0.5, 0.0, 0.0))
    r = scene.check(TOP_DOWN, fingers(0.02), fingers(0.04), np.random.default_rng(0))
    world = scene.object_pose @ TOP_DOWN
    pre = world.copy()
    pre[2, 3] += 0.10
    assert r.reachable and scene._straight(r.grasp, r.pregrasp, world, pre)
    turned = dict(r.pregrasp.joints)
    turned["panda_joint1"] += np.pi
    assert not scene._straight(r.grasp, replace(r.pregrasp, joints=turned), world, pre)


def test_a_pregrasp_distance_of_0_still_reaches_the_grasp() -> None:
    """A back-off of 0 (a distance the settings accept) is no line at all: the pre-grasp is the grasp with the
    fingers open. The path check allowed 0 mm off it, and the solutions' own FK error (up to POSITION_TOL) made
    every grasp "cannot back off along the approach"; it now allows POSITION_TOL, and still refuses another
    branch."""
    with Sim() as sim:
        scene = ReachScene(sim, load_hand("panda"), load_object("box"), ReachSettings(pregrasp_distance=0.0))
        for x in (0.4, 0.5, 0.6):
            scene.place_object(scene.resting_pose(x, 0.0, 0.0))
            r = scene.check(TOP_DOWN, fingers(0.02), fingers(0.04), np.random.default_rng(0))
            assert r.reachable, r.why
        turned = dict(r.pregrasp.joints)
        turned["panda_joint1"] += np.pi
        world = scene.object_pose @ TOP_DOWN
        assert not scene._straight(r.grasp, replace(r.pregrasp, joints=turned), world, world)


def test_a_grasp_force_closure_only_once_squeezed_is_reached_by_its_squeezes_epsilon() -> None:
    # it ranks first (planner.db.ranking.FIRST): with its planned epsilon 0 it used to stay unreached (neutral, 1)
    # while its reached end could score 0 (teddy's #2 of 2026-12-07)
    settings = SweepSettings(approaches=16, rolls=2, preshapes=("wide",), reach_placements=1, reach_top=0)
    spec = UnitSpec("box", "panda", settings, seed=5)
    result = run_unit(spec)
    fc = sorted((g for g in result.grasps if g.force_closure), key=lambda g: -g.epsilon)
    assert len(fc) >= 3
    squeezed = replace(fc[-1], force_closure=False, epsilon=0.0, reachability=None, manipulability=None,
                       measures=replace(fc[-1].measures, squeezed_force_closure=True,  # type: ignore[arg-type]
                                        squeezed_epsilon=2 * fc[0].epsilon, resist_worst=0.0))
    others = [replace(g, reachability=None, manipulability=None) for g in fc[:2]]
    again = add_reachability([*others, squeezed], result.obj, load_hand("panda"), spec,
                             replace(settings.resolved("antipodal"), reach_top=1))
    assert [g.reachability is None for g in again] == [True, True, False]
