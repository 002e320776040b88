"""URDFs with yourdfpy: the cut hand subtree loads in PyBullet with the same
kinematics, keeps PyBullet's contact extension; mesh paths found as PyBullet finds them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yourdfpy
from helpers import assert_close, hand_copy

from planner import assets
from planner.errors import ConfigError
from planner.sim import Sim, pb
from planner.specs.hands import hand_names, load_folder, load_hand
from planner.specs.urdf import cut_subtree, descendants, link_chain, load_model, mesh_path

HANDS = hand_names()
SEED = 0
#: PyBullet's and yourdfpy's forward kinematics of one URDF [m, rotation entries]:
#: both are exact up to float32 storage inside PyBullet.
FK_TOL = 1e-5


@pytest.mark.parametrize("name", HANDS)
def test_pybullet_and_yourdfpy_kinematics_agree(name: str) -> None:

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
def test_a_links_chain_gives_its_frame_as_pybullet_does(name: str) -> None:
    """LinkChain's forward kinematics (the width's pads) against PyBullet's, every link of every hand."""
    hand = load_hand(name)
    model = load_model(hand.urdf)
    chains = {link: link_chain(model, link) for link in hand.links}
    assert chains[hand.root_link].joints == ()
    rng = np.random.default_rng(SEED)
    with Sim() as sim:
        body = sim.load_urdf(hand.urdf)
        for _ in range(3):
            q = hand.full_configuration({j.name: float(rng.uniform(j.lower, j.upper)) for j in hand.driven})
            sim.set_joints(body, q)
            root = np.linalg.inv(sim.link_pose(body, hand.root_link))
            for link, chain in chains.items():
                assert_close(chain.frame(q), root @ sim.link_pose(body, link), FK_TOL)


def test_panda_urdf_matches_yourdfpy_kinematics() -> None:

    from planner.sim import Sim

    h = load_hand("panda")
    robot = yourdfpy.URDF.load(str(h.urdf), load_meshes=False, build_collision_scene_graph=False)
    q = {"panda_finger_joint1": 0.031, "panda_finger_joint2": 0.031}
    robot.update_cfg(q)
    with Sim() as sim:
        body = sim.load_urdf(h.urdf)
        sim.set_joints(body, q)
        for link in ("panda_leftfinger", "panda_rightfinger"):
            assert np.allclose(robot.get_transform(link, "panda_hand"), sim.link_pose(body, link), atol=1e-6)


def test_urdf_with_missing_mesh_and_unknown_joint(tmp_path: Path) -> None:
    folder = hand_copy(tmp_path)
    source = assets.pybullet_data_root() / "franka_panda" / "panda.urdf"
    text = source.read_text().replace("meshes/collision/finger.obj", "meshes/collision/nope.obj")
    (folder / "hand.urdf").write_text(text.replace("package://", str(source.parent) + "/"))
    toml = folder / "hand.toml"
    toml.write_text(toml.read_text().replace('urdf = "pybullet_data:franka_panda/panda.urdf"\nroot',
                                             'urdf = "hand.urdf"\nroot'))
    with pytest.raises(ConfigError, match="mesh file not found: .*nope.obj"):
        load_folder(folder)
    (folder / "hand.urdf").write_text(source.read_text().replace("package://", str(source.parent) + "/"))
    toml.write_text(toml.read_text().replace('name = "panda_finger_joint1"', 'name = "thumb_joint"'))
    with pytest.raises(ConfigError, match="thumb_joint.*hand.urdf"):
        load_folder(folder)


def test_the_cut_keeps_the_subtree_and_the_pybullet_contact_extension() -> None:
    source = assets.pybullet_data_root() / "franka_panda" / "panda.urdf"
    cut = cut_subtree(source, "panda_hand", "test")
    model = load_model(cut)
    assert {link.name for link in model.robot.links} == set(descendants(load_model(source), "panda_hand"))
    assert "<contact>" in cut.read_text() and "stiffness" in cut.read_text()
    with Sim() as sim:
        body = sim.load_urdf(cut)
        stiffness = [pb.getDynamicsInfo(body.uid, body.links[f"panda_{side}finger"], physicsClientId=sim.client)[9]
                     for side in ("left", "right")]
    assert stiffness == [30000.0, 30000.0]  # the finger pads' contact stiffness reached PyBullet
    assert cut_subtree(source, "panda_hand", "test") == cut  # content-named: written once
    with pytest.raises(ConfigError, match="link 'palm' is not in panda.urdf"):
        cut_subtree(source, "palm", "test")


def test_malformed_urdf_is_a_config_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot>")
    with pytest.raises(ConfigError, match="bad.urdf: malformed URDF"):
        load_model(bad)


def test_mesh_paths_are_found_as_pybullet_finds_them(tmp_path: Path) -> None:
    """``package://pkg/...`` of ``pkg/urdf/o.urdf`` is ``pkg/...`` (PyBullet tries the URDF's folder and each one
    above it); ``file://`` and absolute paths are themselves; one found nowhere is the path beside the URDF."""
    urdf = tmp_path / "pkg" / "urdf" / "o.urdf"
    mesh = tmp_path / "pkg" / "meshes" / "m.obj"
    mesh.parent.mkdir(parents=True)
    urdf.parent.mkdir()
    mesh.write_text("v 0 0 0\n")
    assert mesh_path(urdf, "package://pkg/meshes/m.obj") == mesh
    assert mesh_path(urdf, "../meshes/m.obj") == mesh
    assert mesh_path(urdf, f"file://{mesh}") == mesh == mesh_path(urdf, str(mesh))
    assert mesh_path(urdf, "package://other/m.obj") == urdf.parent / "other" / "m.obj"
