"""Preshape taxonomies: every hand's preshapes load within the joint limits."""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers import NUM_TOL

from planner.errors import ConfigError, UnknownNameError
from planner.specs import preshapes
from planner.specs.hands import hand_names, load_hand
from planner.specs.preshapes import load_preshapes, sweep_preshapes

HANDS = hand_names()


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


def test_preshapes_fill_in_mimics() -> None:
    shapes = load_preshapes(load_hand("panda"))
    assert [s.name for s in shapes] == ["wide", "half"]
    assert shapes[0].joints["panda_finger_joint2"] == shapes[0].joints["panda_finger_joint1"] == 0.04
    with pytest.raises(UnknownNameError, match="Available preshapes: half, wide"):
        load_preshapes(load_hand("panda"), ["fist"])


@pytest.mark.parametrize("name", ["barrett", "allegro"])
def test_table_preshapes_are_swept_only_on_a_table(name: str) -> None:
    hand = load_hand(name)
    table = {s.name for s in load_preshapes(hand) if s.table}
    assert table  # the multi-finger hands have pre-curled preshapes for objects on a table
    alone = {s.name for s in sweep_preshapes(hand)}
    assert not alone & table and alone | table == {s.name for s in sweep_preshapes(hand, on_table=True)}
    assert [s.name for s in sweep_preshapes(hand, [min(table)])] == [min(table)]  # named: used anywhere
    # the exports' open hand is the widest of the preshapes of the object alone, whatever a table preshape opens
    assert hand.widest(sweep_preshapes(hand)).name == {"barrett": "wrap", "allegro": "power_wrap"}[name]


def test_a_table_flag_that_is_not_a_boolean_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = tmp_path / "preshapes"
    folder.mkdir()
    (folder / "panda.toml").write_text('hand = "panda"\n[[preshape]]\nname = "w"\ntags = ["power"]\n'
                                       'joints = { panda_finger_joint1 = 0.04 }\ntable = "yes"\n')
    monkeypatch.setattr(preshapes.assets, "project_dir", lambda name: tmp_path / name)
    with pytest.raises(ConfigError, match="'table'"):
        load_preshapes(load_hand("panda"))


@pytest.mark.parametrize("value", ["0", "1.5", '"2"', "true"])
def test_a_roll_symmetry_that_is_not_a_whole_number_from_1_is_refused(
        value: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = tmp_path / "preshapes"
    folder.mkdir()
    (folder / "panda.toml").write_text('hand = "panda"\n[[preshape]]\nname = "w"\ntags = ["power"]\n'
                                       f'joints = {{ panda_finger_joint1 = 0.04 }}\nroll_symmetry = {value}\n')
    monkeypatch.setattr(preshapes.assets, "project_dir", lambda name: tmp_path / name)
    with pytest.raises(ConfigError, match="'roll_symmetry'"):
        load_preshapes(load_hand("panda"))


def test_the_allegros_table_preshapes_pinch_across_each_other() -> None:
    """table_pinch closes thumb against fingers (along the palm's z); table_spread
    index against ring through their abduction joints only (along y), its
    pinch repeating after a half turn."""
    shapes = {s.name: s for s in load_preshapes(load_hand("allegro")) if s.table}
    spread = shapes["table_spread"]
    assert spread.roll_symmetry == 2 and shapes["table_pinch"].roll_symmetry == 2
    assert {j for j, r in spread.close.items() if r} == {"index_abd", "ring_abd"}
    assert spread.close["index_abd"] < 0 < spread.close["ring_abd"]  # each towards the other
    assert spread.joints["index_abd"] > 0 > spread.joints["ring_abd"]  # opened outwards


@pytest.mark.parametrize("typo", ["standofs = [0.05]", "tabel = true"])
def test_a_misspelt_preshape_field_is_refused(typo: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """It was ignored: the default (standoff 0, not a table preshape) used without a word."""
    folder = tmp_path / "preshapes"
    folder.mkdir()
    (folder / "panda.toml").write_text('hand = "panda"\n[[preshape]]\nname = "w"\ntags = ["power"]\n'
                                       f'joints = {{ panda_finger_joint1 = 0.04 }}\n{typo}\n')
    monkeypatch.setattr(preshapes.assets, "project_dir", lambda name: tmp_path / name)
    with pytest.raises(ConfigError, match=f"field '{typo.split()[0]}': not a field read here"):
        load_preshapes(load_hand("panda"))
