import shutil
from pathlib import Path

import numpy as np
import pytest

from planner.errors import ConfigError, UnknownNameError
from planner.specs.hands import hands_dir, load_folder, load_hand
from planner.specs.preshapes import load_preshapes


def test_panda_hand_is_the_hand_only() -> None:
    h = load_hand("panda")
    assert set(h.links) == {"panda_hand", "panda_leftfinger", "panda_rightfinger", "panda_grasptarget"}
    assert [j.name for j in h.driven] == ["panda_finger_joint1"]
    mimic = h.joint("panda_finger_joint2")
    assert mimic.mimic == "panda_finger_joint1" and mimic.multiplier == 1.0
    assert h.full_configuration({"panda_finger_joint1": 0.03}) == {"panda_finger_joint1": 0.03,
                                                                   "panda_finger_joint2": 0.03}
    assert np.isclose(np.linalg.norm(h.approach), 1.0)
    assert h.urdf.is_file() and "panda_link1" not in h.urdf.read_text()


def test_panda_urdf_matches_yourdfpy_kinematics() -> None:
    import yourdfpy

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


def test_preshapes_fill_in_mimics() -> None:
    shapes = load_preshapes(load_hand("panda"))
    assert [s.name for s in shapes] == ["wide", "half"]
    assert shapes[0].joints["panda_finger_joint2"] == shapes[0].joints["panda_finger_joint1"] == 0.04
    with pytest.raises(UnknownNameError, match="Available preshapes: half, wide"):
        load_preshapes(load_hand("panda"), ["fist"])


def test_unknown_hand_lists_hands() -> None:
    with pytest.raises(UnknownNameError, match="Available hands: .*panda"):
        load_hand("shadow")
    with pytest.raises(ConfigError, match="folder name"):
        load_hand("../objects")


def broken_copy(tmp_path: Path, old: str, new: str) -> Path:
    folder = tmp_path / "panda"
    shutil.copytree(hands_dir() / "panda", folder)
    toml = folder / "hand.toml"
    text = toml.read_text()
    assert old in text
    toml.write_text(text.replace(old, new))
    return folder


@pytest.mark.parametrize("old, new, message", [
    ('name = "panda_finger_joint1"', 'name = "finger_joint9"', "finger_joint9.*not in"),
    ('root_link = "panda_hand"', 'root_link = "palm"', "root_link.*'palm'"),
    ('"panda_rightfinger", "panda_hand"]', '"panda_rightfinger", "thumb"]', "contact_links.*thumb"),
    ('approach = [0.0, 0.0, 1.0]', 'approach = [0.0, 0.0]', "approach.*3 numbers"),
    ('urdf = "pybullet_data:franka_panda/panda.urdf"\nroot', 'urdf = "missing.urdf"\nroot', "not found"),
    ('urdf = "pybullet_data:franka_panda/panda.urdf"\nroot', 'urdf = "pybullet_data:../../x.urdf"\nroot',
     "outside"),
    ('torsion = 0.005', 'torsion = 0.0', "torsion"),
    ("[[joints]]", "[[joints]", "malformed TOML"),
])
def test_broken_hand_folder_names_file_and_field(tmp_path: Path, old: str, new: str, message: str) -> None:
    folder = broken_copy(tmp_path, old, new)
    with pytest.raises(ConfigError, match=message) as err:
        load_folder(folder)
    assert "hand.toml" in str(err.value)
