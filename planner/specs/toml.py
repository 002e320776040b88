"""Reading TOML descriptions at the edge, with errors naming file and field."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

from planner.errors import ConfigError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; a missing, empty or malformed file is a ConfigError."""
    if not path.is_file():
        raise ConfigError(f"{path}: file not found")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read: {exc}") from exc
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: malformed TOML: {exc}") from exc
    if not data:
        raise ConfigError(f"{path}: file is empty")
    return data


class Fields:
    """Typed access to one TOML table; errors say ``file: [table] field: problem``."""

    def __init__(self, data: Any, where: str) -> None:
        if not isinstance(data, dict):
            raise ConfigError(f"{where}: expected a table, got {type(data).__name__}")
        self.data = data
        self.where = where

    def _fail(self, key: str, problem: str) -> ConfigError:
        return ConfigError(f"{self.where} field '{key}': {problem}")

    def has(self, key: str) -> bool:
        return key in self.data

    def str(self, key: str, default: str | None = None) -> str:
        value = self.data.get(key, default)
        if not isinstance(value, str) or not value:
            raise self._fail(key, "missing or not a non-empty string")
        return value

    def float(self, key: str, default: float | None = None, *, positive: bool = False) -> float:
        value = self.data.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self._fail(key, "missing or not a number")
        if not math.isfinite(value) or (positive and value <= 0):
            raise self._fail(key, f"must be {'positive and ' if positive else ''}finite, got {value}")
        return float(value)

    def bool(self, key: str, default: bool) -> bool:
        value = self.data.get(key, default)
        if not isinstance(value, bool):
            raise self._fail(key, "must be true or false")
        return value

    def floats(self, key: str, length: int | None = None, default: list[float] | None = None) -> list[float]:
        value = self.data.get(key, default)
        if not isinstance(value, list) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value
        ):
            raise self._fail(key, "missing or not a list of finite numbers")
        if length is not None and len(value) != length:
            raise self._fail(key, f"needs {length} numbers, got {len(value)}")
        return [float(v) for v in value]

    def strs(self, key: str, default: list[str] | None = None) -> list[str]:
        value = self.data.get(key, default)
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self._fail(key, "missing or not a list of strings")
        return list(value)

    def table(self, key: str, default: dict[str, Any] | None = None) -> Fields:
        value = self.data.get(key, default)
        if value is None:
            raise self._fail(key, "missing table")
        return Fields(value, f"{self.where}[{key}]")

    def tables(self, key: str) -> list[Fields]:
        value = self.data.get(key)
        if not isinstance(value, list) or not value or not all(isinstance(v, dict) for v in value):
            raise self._fail(key, "missing or not an array of tables ([[...]])")
        return [Fields(v, f"{self.where}[[{key}]] #{i + 1}") for i, v in enumerate(value)]
