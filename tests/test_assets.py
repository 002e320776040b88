"""Locating files: built-in locators stay inside their roots; the cache; atomic writes."""

from __future__ import annotations

from pathlib import Path

import pytest

from planner import assets
from planner.errors import ConfigError


def test_builtin_locators_cannot_escape(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="outside"):
        assets.resolve("../../../etc/passwd", tmp_path, "objects.toml [evil] field 'source'")
    with pytest.raises(ConfigError, match="outside"):
        assets.resolve("pybullet_data:../../../../etc/passwd", tmp_path, "x")
    with pytest.raises(ConfigError, match="absolute"):
        assets.resolve("/etc/passwd", tmp_path, "x")


def test_locators_resolve_inside_pybullet_data_and_the_toml_folder(tmp_path: Path) -> None:
    assert assets.resolve("pybullet_data:duck_vhacd.urdf", tmp_path, "x").name == "duck_vhacd.urdf"
    (tmp_path / "m.obj").write_text("v 0 0 0\n")
    assert assets.resolve("m.obj", tmp_path, "x") == (tmp_path / "m.obj").resolve()
    with pytest.raises(ConfigError, match="x: file not found"):
        assets.resolve("missing.obj", tmp_path, "x")


def test_cache_folders_and_atomic_writes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("GRASP_CACHE", str(tmp_path / "cache"))
    folder = assets.cache_dir("parts")
    assert folder == tmp_path / "cache" / "parts" and folder.is_dir()
    assets.atomic_write(folder / "a.bin", b"abc")
    assert (folder / "a.bin").read_bytes() == b"abc" and [p.name for p in folder.iterdir()] == ["a.bin"]
