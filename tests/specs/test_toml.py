"""Reading TOML at the edge: errors name the file, the table and the field."""

from __future__ import annotations

import codecs
from pathlib import Path

import pytest
from helpers import hand_copy
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planner.errors import ConfigError, PlannerError
from planner.specs import preshapes
from planner.specs.hands import load_folder, load_hand
from planner.specs.toml import Fields, read_toml


def test_fields_say_file_table_and_field(tmp_path: Path) -> None:
    path = tmp_path / "x.toml"
    path.write_text('name = ""\nsize = -1.0\nflags = [1, "a"]\n[inner]\nk = 2\n')
    f = Fields(read_toml(path), str(path))
    with pytest.raises(ConfigError, match=r"x.toml field 'name': missing or not a non-empty string"):
        f.str("name")
    with pytest.raises(ConfigError, match=r"field 'size': must be positive and finite, got -1.0"):
        f.float("size", positive=True)
    with pytest.raises(ConfigError, match=r"field 'flags': missing or not a list of finite numbers"):
        f.floats("flags")
    assert f.table("inner").float("k") == 2.0
    with pytest.raises(ConfigError, match=r"x.toml\[inner\] field 'missing': missing or not a number"):
        f.table("inner").float("missing")


@pytest.mark.parametrize("text, message", [(None, "file not found"), ("", "file is empty"),
                                           ("a = [1,", "malformed TOML")])
def test_missing_empty_and_malformed_files(tmp_path: Path, text: str | None, message: str) -> None:
    path = tmp_path / "f.toml"
    if text is not None:
        path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        read_toml(path)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(max_size=200))
def test_fuzz_arbitrary_toml_text_is_refused_cleanly(tmp_path_factory, text: str) -> None:  # type: ignore[no-untyped-def]
    """Arbitrary text as a hand's hand.toml, then as its preshapes file (where
    the planner reads it): refused with one line naming the file."""
    root = tmp_path_factory.mktemp("fuzztext")
    folder = hand_copy(root)
    (folder / "hand.toml").write_text(text)
    with pytest.raises(PlannerError) as refused:
        load_folder(folder)
    assert len(str(refused.value).splitlines()) == 1 and "hand.toml" in str(refused.value)
    presets = root / "preshapes" / "panda.toml"
    presets.parent.mkdir()
    presets.write_text(text)
    hand = load_hand("panda")
    with pytest.MonkeyPatch.context() as patch, pytest.raises(PlannerError) as refused:
        patch.setattr(preshapes.assets, "project_dir", lambda name: root / name)
        preshapes.load_preshapes(hand)
    assert len(str(refused.value).splitlines()) == 1 and str(presets) in str(refused.value)


@pytest.mark.parametrize("data, line, byte", [
    # a UTF-8 byte-order mark and a Latin-1 'ä' on line 2: utf-8-sig counted the offset past the mark, so the
    # message named line 1 and the byte 0x62 ('b') three bytes before the one at fault
    (codecs.BOM_UTF8 + b"a = 1\nb = 'c\xe4'\n", 2, 0xE4),
    # UTF-16 whose 'Ċ' (U+010A) holds a 0x0a byte, then an unpaired surrogate on line 2 (not line 3)
    (codecs.BOM_UTF16_LE + "a = 'Ċ'\nb = '".encode("utf-16-le") + b"\x00\xd8" + "'\n".encode("utf-16-le"), 2, 0x00),
])
def test_undecodable_bytes_are_named_with_their_line_and_byte(data: bytes, line: int, byte: int) -> None:
    from planner.specs.toml import decode_text

    with pytest.raises(ConfigError, match=rf"x.toml:{line}: not UTF-(8|16) text \(byte 0x{byte:02x}\)"):
        decode_text(data, Path("x.toml"), "the file")
