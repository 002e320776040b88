"""Hand descriptions: every hand folder in ``hands/`` loads complete, errors
name file and field, and the hands authored here have their known answers.

Plus known answers of the hands authored here (Barrett, Allegro-style).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers import NUM_TOL, assert_close, hand_copy, refused_hand_toml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planner.errors import ConfigError, PlannerError, UnknownNameError
from planner.sim import Sim
from planner.specs.hands import hand_names, load_folder, load_hand
from planner.specs.preshapes import load_preshapes
from planner.specs.toml import read_toml

HANDS = hand_names()


def test_every_shipped_hand_is_found() -> None:
    assert {"panda", "barrett", "allegro", "pr2"} <= set(HANDS)


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


def test_parallel_jaws_default_to_the_antipodal_sampler_others_to_rays() -> None:
    assert load_hand("panda").sampler == "antipodal"
    assert {load_hand(name).sampler for name in ("barrett", "allegro", "pr2")} == {"surface"}


def test_unknown_hand_lists_hands() -> None:
    with pytest.raises(UnknownNameError, match="Available hands: .*panda"):
        load_hand("shadow")
    with pytest.raises(ConfigError, match="folder name"):
        load_hand("../objects")


def broken_copy(tmp_path: Path, old: str, new: str) -> Path:
    folder = hand_copy(tmp_path)
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
    ('torsion_radius = 0.0044', 'torsion_radius = 0.0', "torsion_radius"),
    ('torsion_radius = 0.0044', 'torsion = 0.005', "replaced by 'torsion_radius'"),
    ('effort = 70.0', 'effort = -70.0', "effort.*positive"),
    ('closing_speed = 0.05', 'closing_speed = -0.05', "closing_speed.*positive"),
    ("[[joints]]", "[[joints]", "malformed TOML"),
    ('sampler = "antipodal"', 'sampler = "grid"', "sampler.*unknown sampler 'grid'"),
    ("centering = true", "centering = false", "sampler.*antipodal sampler needs a self-centring parallel jaw"),
    ("effort = 70.0", "efort = 70.0", r"\[dynamics\] field 'efort': not a field read here \(did you mean 'effort'\? "
     r"known here: .*\beffort\b"),  # the right name listed, though the table does not give it
    ("centering = true", "centering = true\nsetle = false", "field 'setle': not a field read here"),
])
def test_broken_hand_folder_names_file_and_field(tmp_path: Path, old: str, new: str, message: str) -> None:
    folder = broken_copy(tmp_path, old, new)
    with pytest.raises(ConfigError, match=message) as err:
        load_folder(folder)
    assert "hand.toml" in str(err.value)


@pytest.mark.parametrize("table, message", [
    ("steps_per_second = 0\nclose_time = 0.1\nrest_time = 0.05",
     r"\[settle_dynamics\] field 'steps_per_second'.*positive"),
    ("steps_per_second = 240\nclose_time = 0.001\nrest_time = 0.05",
     r"\[settle_dynamics\] field 'close_time'.*shorter than one step"),
    ("steps_per_second = 240\nrest_time = 0.05", r"\[settle_dynamics\] field 'close_time'.*missing or not a number"),
    ("steps_per_second = 240\nclose_time = 0.1\nrest_time = -1", r"\[settle_dynamics\] field 'rest_time'.*positive"),
])
def test_broken_settle_dynamics_names_the_file_and_field(tmp_path: Path, table: str, message: str) -> None:
    refused_hand_toml(tmp_path, lambda text: text + "\n[settle_dynamics]\n" + table + "\n", message)


@pytest.mark.parametrize("table, message", [
    ("panda_thumb = [1e-5, 1e-5, 1e-5]", r"\[dynamics\]\[link_inertia\] field 'panda_thumb': unknown link; links: "
     r".*panda_leftfinger"),
    ("panda_leftfinger = [1e-5, 1e-5]", r"field 'panda_leftfinger': needs 3 numbers"),
    ("panda_leftfinger = [1e-5, 0.0, 1e-5]", r"field 'panda_leftfinger': principal moments must be positive"),
    ("panda_leftfinger = [1e-5, 1e-5, 3e-5]", r"field 'panda_leftfinger': .*each at most the sum of the other two"),
    # a massless link: PyBullet gave it the moments, MuJoCo's model its placeholder (the two trials differed)
    ("panda_grasptarget = [1e-5, 1e-5, 1e-5]", r"field 'panda_grasptarget': its URDF gives the link no <inertial>"),
])
def test_broken_link_inertia_names_the_file_table_and_link(tmp_path: Path, table: str, message: str) -> None:
    refused_hand_toml(tmp_path, lambda text: text.replace(
        "\n[dynamics]\n", "\n[dynamics.link_inertia]\n" + table + "\n\n[dynamics]\n", 1), message)


def test_link_inertia_replaces_the_moments_of_the_links_it_names_only(tmp_path: Path) -> None:
    folder = hand_copy(tmp_path)
    toml = folder / "hand.toml"
    toml.write_text(toml.read_text() + "\n[dynamics.link_inertia]\npanda_leftfinger = [2e-5, 3e-5, 4e-5]\n")
    assert load_folder(folder).link_inertia == {"panda_leftfinger": (2e-5, 3e-5, 4e-5)}
    assert load_hand("panda").link_inertia == {}


@pytest.mark.parametrize("value, message", [
    ('["panda_leftfinger"]',
     r"field 'width_links': needs two different links \(the pads\), got \['panda_leftfinger'\]"),
    ('["panda_leftfinger", "panda_leftfinger"]', "field 'width_links': needs two different links"),
    ('["panda_leftfinger", "thumb"]', "field 'width_links': 'thumb' is not a link of the hand with collision "
     "geometry; links with it: panda_hand, panda_leftfinger, panda_rightfinger"),
    ('["panda_leftfinger", "panda_grasptarget"]', "'panda_grasptarget' is not a link of the hand with collision"),
    ('"panda_leftfinger"', "field 'width_links': missing or not a list of strings"),
])
def test_broken_width_links_name_the_file_and_field(tmp_path: Path, value: str, message: str) -> None:
    folder = broken_copy(tmp_path, "centering = true", f"centering = true\nwidth_links = {value}")
    with pytest.raises(ConfigError, match=message) as err:
        load_folder(folder)
    assert "hand.toml" in str(err.value) and "\n" not in str(err.value)


def test_the_pr2_declares_its_pads_as_its_width_links(tmp_path: Path) -> None:
    assert load_hand("pr2").width_links == ("left_tip", "right_tip")
    assert all(load_hand(name).width_links is None for name in ("panda", "barrett", "allegro"))
    folder = broken_copy(tmp_path, "centering = true", 'centering = true\nwidth_link = ["a", "b"]')
    with pytest.raises(ConfigError, match=r"field 'width_link': not a field read here \(did you mean 'width_links'"):
        load_folder(folder)


def test_a_hand_settles_with_its_own_dynamics_unless_the_sweep_names_a_trial() -> None:
    from dataclasses import replace

    from planner.plan.sweep import SweepSettings
    from planner.specs.hand_spec import SettleDynamics
    from planner.validation.settings import ShakeSettings

    barrett = load_hand("barrett")
    assert barrett.settle_dynamics == SettleDynamics(240.0, 0.12, 0.05) and load_hand("panda").settle_dynamics is None
    trial = SweepSettings().resolved(barrett.sampler, barrett.settle, barrett.settle_dynamics).trial
    assert trial is not None and (trial.dt, trial.close_time, trial.settle_time, trial.batch) == (1 / 240, 0.12,
                                                                                                  0.05, 1)
    assert SweepSettings().resolved("surface", True).trial == ShakeSettings()  # no table: the shake trial's
    mine = ShakeSettings(close_time=0.3, batch=5)
    assert SweepSettings(trial=mine).resolved("surface", True, barrett.settle_dynamics).trial == replace(mine, batch=1)
    assert SweepSettings().resolved("surface", False, barrett.settle_dynamics).trial is None


def test_malformed_toml_names_the_file(tmp_path: Path) -> None:
    folder = hand_copy(tmp_path)
    (folder / "hand.toml").write_text("approach = [0, 0, 1\n")
    with pytest.raises(ConfigError, match=r"hand\.toml: malformed TOML"):
        load_folder(folder)


toml_values = st.one_of(st.integers(-5, 5), st.floats(allow_nan=True), st.text(max_size=8), st.booleans(),
                        st.lists(st.floats(-2, 2), max_size=4))


#: How each fuzzed field of hand.toml shows in the loaded spec.
LOADED = {"approach": lambda h: list(h.approach), "tcp": lambda h: list(h.tcp), "root_link": lambda h: h.root_link,
          "contact_links": lambda h: list(h.contact_links), "centering": lambda h: h.centering,
          "roll_symmetry": lambda h: h.roll_symmetry, "distance_offset": lambda h: h.distance_offset,
          "sampler": lambda h: h.sampler}


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(key=st.sampled_from(["approach", "tcp", "root_link", "contact_links", "centering", "roll_symmetry",
                            "urdf", "distance_offset", "sampler"]), value=toml_values, garbage=st.text(max_size=30))
def test_fuzz_hand_toml_loads_the_value_or_names_the_field(tmp_path_factory, key, value, garbage) -> None:  # type: ignore[no-untyped-def]
    """One field of the Panda's hand.toml set to an arbitrary value (and a
    comment of arbitrary text): the hand loads with exactly that value, or
    is refused with one line naming the file and the field."""
    folder = hand_copy(tmp_path_factory.mktemp("fuzz"))
    toml = folder / "hand.toml"
    data = read_toml(toml)
    data[key] = value
    lines = [f"{k} = {_toml(v)}" for k, v in data.items() if not isinstance(v, (dict, list)) or
             (isinstance(v, list) and not any(isinstance(x, dict) for x in v))]
    text = "\n".join(lines) + "\n" + "\n".join(toml.read_text().split("\n[[joints]]", 1)[1:2] and
                                               ["[[joints]]" + toml.read_text().split("\n[[joints]]", 1)[1]])
    # a line break ends the comment: "\r" too, since the file is read as text (universal newlines)
    comment = garbage.replace("\r", " ").replace("\n", " ")
    toml.write_text(text + ("\n# " + comment if garbage else ""))
    # TOML comments may hold any character but the control ones (tab aside)
    bad_comment = any((ord(c) < 32 and c != "\t") or ord(c) == 127 for c in comment)
    try:
        hand = load_folder(folder)
    except PlannerError as exc:
        message = str(exc)
        assert len(message.splitlines()) == 1 and "hand.toml" in message, message
        # the field named, or (contact_links) the [contact.links] entry it no longer lists
        assert ("malformed TOML" in message) if bad_comment else (key in message), message
        return
    assert not bad_comment
    if key == "approach":
        assert_close(LOADED[key](hand), np.asarray(value) / np.linalg.norm(value))
    elif key in LOADED:
        assert LOADED[key](hand) == value
    else:  # urdf: the value resolved to a URDF with the hand's links
        assert hand.root_link in hand.links


def _toml(value: object) -> str:
    """A TOML value (what json.dumps writes is TOML for these, but booleans and non-finite floats)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and not np.isfinite(value):
        return "nan" if np.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, str):  # TOML escapes only code points (JSON would write surrogate pairs)
        return '"' + "".join(c if c not in '"\\' and 32 <= ord(c) != 127 else f"\\U{ord(c):08x}" for c in value) + '"'
    return json.dumps(value)


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


def test_the_hands_know_their_finger_dofs() -> None:
    """Closing, the measures and the trial take the finger DOFs from here:
    a self-centring jaw's two fingers apart, a Barrett finger with its distal
    joint coupled (breakaway: the distal closes on alone), the spread holding;
    once broken away, the finger's DOF is its distal joint alone."""
    panda, barrett = load_hand("panda"), load_hand("barrett")
    wide = {p.name: p for p in load_preshapes(panda)}["wide"]
    assert [(d.driven, d.rates, d.after) for d in panda.closing_dofs(wide.close)] == [
        ("panda_finger_joint1", {"panda_finger_joint1": -1.0}, None),
        ("panda_finger_joint1", {"panda_finger_joint2": -1.0}, None)]
    pinch = {p.name: p for p in load_preshapes(barrett)}["pinch"]
    dofs = barrett.closing_dofs(pinch.close)
    assert [d.rates for d in dofs] == [{"bh_j12_joint": 1.0, "bh_j13_joint": 0.3333},
                                       {"bh_j22_joint": 1.0, "bh_j23_joint": 0.3333}]  # finger 3 and the spread hold
    assert [d.after for d in dofs] == [{"bh_j13_joint": 0.3333}, {"bh_j23_joint": 0.3333}]
    closed = barrett.full_configuration({"bh_j12_joint": 0.5, "bh_j22_joint": 0.5})
    closed["bh_j23_joint"] += 0.2  # finger 2 broke away
    assert barrett.broken_away(closed) == {"bh_j22_joint"}
    assert [d.rates for d in barrett.closing_dofs(pinch.close, closed)] == [
        {"bh_j12_joint": 1.0, "bh_j13_joint": 0.3333}, {"bh_j23_joint": 0.3333}]
    assert barrett.coupling("bh_j32_joint") == {"bh_j32_joint": 1.0, "bh_j33_joint": 0.3333}
    assert barrett.joint_rates({})["bh_j33_joint"] == 0.3333 and barrett.joint_rates({})["bh_j11_joint"] == 0.0


def test_a_parallel_jaw_knows_its_master_joint_opening_and_widest_preshape() -> None:
    panda, barrett = load_hand("panda"), load_hand("barrett")
    assert panda.jaw is not None and barrett.jaw is None
    master, slave = panda.jaw
    assert (master.name, slave.name) == ("panda_finger_joint1", "panda_finger_joint2")
    shapes = load_preshapes(panda)
    assert panda.widest(shapes).name == "wide"
    assert_close(panda.opening(panda.widest(shapes).joints), 0.08, NUM_TOL)  # the 8 cm stroke
    assert_close(panda.opening(panda.full_configuration({master.name: 0.01})), 0.02, NUM_TOL)
    # the Barrett's: every finger straight (wrap, circle, tee and hook tie at 0; the first wins), not the
    # pinch, whose fingers start half a radian closed
    assert barrett.widest(load_preshapes(barrett)).name == "wrap"


def test_open_travel_is_the_fastest_contacts_way_back_to_the_open_limit() -> None:
    panda = load_hand("panda")
    axes = {"panda_finger_joint1": (np.zeros(3), np.array([0.0, 1.0, 0.0])),
            "panda_finger_joint2": (np.zeros(3), np.array([0.0, -1.0, 0.0]))}
    closed = {"panda_finger_joint1": 0.03, "panda_finger_joint2": 0.025}
    points, links = np.array([[0.0, 0.03, 0.0], [0.0, -0.025, 0.0]]), ("panda_leftfinger", "panda_rightfinger")
    wide = {p.name: p for p in load_preshapes(panda)}["wide"]
    assert_close(panda.open_travel(wide.close, closed, points, links, axes), 0.04 - 0.03, NUM_TOL)
    assert panda.open_travel(wide.close, closed, points[:0], (), axes) == np.inf
    assert_close(panda.travel({"panda_finger_joint1": -1.0}, closed, 1.0, "closed"), 0.03, NUM_TOL)
    with pytest.raises(ValueError, match="towards"):
        panda.travel({"panda_finger_joint1": -1.0}, closed, 1.0, "shut")


def test_one_broken_hand_folder_leaves_the_others_listed(tmp_path: Path) -> None:
    """`grasp hands` lists every hand that loads, then one error line per folder that does not (exit 2)."""
    import os
    import shutil
    import subprocess
    import sys

    from planner.assets import PROJECT_ROOT

    for name in ("hands", "preshapes", "objects"):
        shutil.copytree(PROJECT_ROOT / name, tmp_path / name)
    shutil.copytree(tmp_path / "hands" / "panda", tmp_path / "hands" / "mypanda")
    toml = tmp_path / "hands" / "mypanda" / "hand.toml"
    toml.write_text(toml.read_text().replace("[[joints]]", "[[joints]", 1))
    run = subprocess.run([sys.executable, "-m", "planner.cli", "hands"], capture_output=True, text=True, timeout=120,
                         env={**os.environ, "GRASP_HOME": str(tmp_path)})
    assert run.returncode == 2
    assert {line.split()[0] for line in run.stdout.splitlines()} == {"allegro", "barrett", "panda", "pr2"}
    assert run.stderr.startswith("grasp: error: hand 'mypanda': ") and "malformed TOML" in run.stderr


@pytest.mark.parametrize("seed", range(5))
def test_contact_velocity_is_the_plain_sum_to_the_bit(seed: int) -> None:
    """Each contact's velocity under a DOF is the sum over its joints that move it of rate x (axis x (point -
    origin)) (revolute) or rate x axis (prismatic), with np.cross's products to the bit: the Barrett's three
    fingers and the Panda's jaw, seeded points and axes."""
    rng = np.random.default_rng(seed)
    for hand in (load_hand("barrett"), load_hand("panda")):
        links = tuple(rng.choice(hand.contact_links, size=7))
        points = rng.normal(size=(7, 3)) * 0.05
        axes = {}
        for j in hand.joints:
            axis = rng.normal(size=3)
            axes[j.name] = (rng.normal(size=3) * 0.05, axis / np.linalg.norm(axis))
        for dof in hand.closing_dofs(dict.fromkeys((j.name for j in hand.driven), 1.0)):
            want = np.zeros((7, 3))
            for name, rate in dof.rates.items():
                origin, axis = axes[name]
                moved = np.array([link in hand.joint(name).moves for link in links], bool)
                lin = np.cross(axis, points - origin) if hand.joint(name).kind == "revolute" else \
                    np.broadcast_to(axis, points.shape)
                want += rate * lin * moved[:, None]
            assert hand.contact_velocity(dof.rates, points, links, axes).tobytes() == want.tobytes()
