"""bench/mujoco_protocols.py --split: the check objects come from the calibration split, and the third held-out
list (the independent-protocol check of issue 26) shares no object with what the Barrett's rule was tuned on."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from mujoco_protocols import split_objects  # noqa: E402


def test_the_third_held_out_list_is_fifty_objects_none_tuned_on() -> None:
    check = split_objects("held_out_3")
    assert len(check) == len(set(check)) == 50
    barrett_rule = {f"random_{i}" for i in range(300, 324)}  # bench/barrett_rule.py's default objects
    assert not set(check) & (barrett_rule | set(split_objects("tuning")))


def test_the_fourth_held_out_list_shares_no_object_with_earlier_lists_or_tuned_objects() -> None:
    check = split_objects("held_out_4")
    assert len(check) == len(set(check)) == 50
    used = {f"random_{i}" for i in (*range(300, 324), *range(100, 108))}  # the Barrett rule's, the first check's
    for name in ("tuning", "held_out", "held_out_2", "held_out_3"):
        used |= set(split_objects(name))
    assert not set(check) & used


def test_an_unknown_list_is_a_one_line_exit(tmp_path: Path) -> None:
    toml = tmp_path / "split.toml"
    toml.write_text('salt = "x"\ntuning = ["a"]\nheld_out = ["b"]\n')
    with pytest.raises(SystemExit, match="no list 'nope' in split.toml; it has held_out, tuning"):
        split_objects("nope", toml)
    assert split_objects("held_out", toml) == ["b"]
