"""The PR2 gripper's dynamic model: its pads press ~30 N (an effort at the revolute hinge of 30 N x the
hinge-to-pad lever), its finger links are a finger's inertia, not pybullet_data's 1 kg m^2 placeholder, and
its verdicts made with the model before are tried again."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

from planner.record.grasp import Grasp
from planner.sim import Sim
from planner.specs.hands import load_hand
from planner.specs.preshapes import load_preshapes
from planner.validation import mujoco_trial, shake
from planner.validation.mujoco_settings import MujocoSettings
from planner.validation.settings import ShakeSettings
from tests.validation.support import as_row_of, box_of

#: [N] the force each PR2 pad presses with (hands/pr2/hand.toml [dynamics]).
PAD_FORCE = 30.0
#: [m] hinge to the centre of a fingertip pad (pr2_gripper.urdf: the tips' boxes 0.105 m out along the finger).
PAD_LEVER = 0.105
#: The relative error of a moment of inertia written to three significant digits.
DIGITS_TOL = 5e-3


def _pr2_pinch() -> tuple:  # type: ignore[type-arg]
    """The PR2 over a 4 cm box (its approach along the box's -z, closing along y), half open, its tool centre
    point on the box's centre: the planner's closed grasp of it."""
    from planner.plan.closing import Closed, CloseSettings, Grasper

    hand, obj = load_hand("pr2"), box_of((0.06, 0.04, 0.08), 0.2)
    pose = np.eye(4)
    pose[:3, :3] = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]  # hand x (approach) -> -z, y -> y
    pose[:3, 3] = obj.com - pose[:3, :3] @ hand.tcp
    half = {p.name: p for p in load_preshapes(hand)}["half"]
    with Sim() as sim:
        closed = Grasper(sim, hand, sim.add_static_mesh(obj.mesh.vertices, obj.mesh.faces),
                         CloseSettings()).close_at(pose, half)
    assert isinstance(closed, Closed)
    grasp: Grasp = as_row_of("pr2", closed.pose, closed.closed_joints, closed.contacts, "half",
                             open_joints=closed.open_joints)
    return hand, obj, grasp


def test_the_pr2s_effort_is_30_newtons_at_the_pad_over_the_hinge_lever() -> None:
    assert load_hand("pr2").actuators.effort == pytest.approx(PAD_FORCE * PAD_LEVER, rel=1e-12)


def test_the_pr2s_pads_press_about_30_newtons_in_the_mujoco_trial(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each finger's normal force on the box (mj_contactForce) while closing: ~30 N once squeezing, and no
    impact far above it (with 30 N m at the hinges and 1 kg m^2 fingers: ~250 N steady, 1-1.6 kN at impact)."""
    hand, obj, grasp = _pr2_pinch()
    forces: list[tuple[float, float]] = []
    step = mujoco.mj_step

    def recording(m, d) -> None:  # type: ignore[no-untyped-def]
        step(m, d)
        if not np.any(m.opt.gravity):  # closing and settling: the load not yet on
            per_link = world.contact_force()
            forces.append((per_link.get("left_tip", 0.0) + per_link.get("left_gripper", 0.0),
                           per_link.get("right_tip", 0.0) + per_link.get("right_gripper", 0.0)))

    from planner.validation.mujoco_worlds import world_for

    world = world_for(hand, obj, MujocoSettings(), obj.mass)
    monkeypatch.setattr(mujoco, "mj_step", recording)
    result = mujoco_trial.trial(hand, obj, grasp)
    monkeypatch.undo()
    assert result.reason == "held"
    f = np.array(forces)
    assert 0.3 * PAD_FORCE < f[-1].min() and f[-1].max() < 1.2 * PAD_FORCE  # squeezing at the end of closing
    assert f.max() < 2 * PAD_FORCE


def test_the_pr2s_finger_links_are_their_collision_shapes_about_the_hinge() -> None:
    """hand.toml's [dynamics.link_inertia] of the PR2: the moments bench/link_inertia.py derives from the
    URDF (each link's collision hulls as a uniform solid of its 0.1 kg, about the hinge), to three digits."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
    from link_inertia import about_urdf_com

    hand = load_hand("pr2")
    assert set(hand.link_inertia) == {"left_gripper", "left_tip", "right_gripper", "right_tip"}
    for link, moments in hand.link_inertia.items():
        tensor, _ = about_urdf_com("pr2", link)
        assert np.asarray(moments) == pytest.approx(np.diag(tensor), rel=DIGITS_TOL), link


@pytest.mark.parametrize("recorded, settings", [(mujoco_trial.recorded, MujocoSettings()),
                                                (shake.recorded, ShakeSettings())])
def test_a_pr2_verdict_made_with_the_model_before_is_not_kept(recorded, settings) -> None:  # type: ignore[no-untyped-def]
    """A stored verdict records the motors and the replaced inertias it was made with: those of the PR2 before
    2026-12-06 (30 N m, the URDF's inertias) are another trial's, so `grasp validate` tries those grasps again."""
    now = load_hand("pr2")
    before = replace(now, actuators=replace(now.actuators, effort=30.0), link_inertia={})
    assert recorded(settings, before) != recorded(settings, now)
