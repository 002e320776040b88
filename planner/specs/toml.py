"""Reading TOML descriptions at the edge, with errors naming file and field."""

from __future__ import annotations

import codecs
import math
import sys
from pathlib import Path
from typing import Any

from planner.errors import ConfigError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def decode_text(data: bytes, path: Path, what: str, error: type[Exception] = ConfigError) -> str:
    """A text file's ``data``: UTF-8, or UTF-16 with its byte-order mark (Windows PowerShell's ``>`` and Notepad's
    'Unicode' write it); a UTF-8 byte-order mark (other Windows editors') is dropped. Other bytes (a Latin-1 name)
    raise ``error`` naming the line and saying to save ``what`` as UTF-8."""
    utf16 = data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE))
    if data.startswith(codecs.BOM_UTF8):  # dropped here: utf-8-sig counts an error's offset after it
        data = data[len(codecs.BOM_UTF8):]
    codec = "utf-16" if utf16 else "utf-8"
    try:
        return data.decode(codec)
    except UnicodeDecodeError as exc:  # lines counted as text: a UTF-16 character may hold a 0x0a byte
        line = data[:exc.start].decode(codec, errors="replace").count("\n") + 1
        raise error(f"{path}:{line}: not {'UTF-16' if utf16 else 'UTF-8'} text (byte 0x{data[exc.start]:02x}): save "
                    f"{what} as UTF-8") from None


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file (:func:`decode_text`); a missing, empty or malformed file is a ConfigError."""
    if not path.is_file():
        raise ConfigError(f"{path}: file not found")
    try:
        text = decode_text(path.read_bytes(), path, "the file")
    except OSError as exc:
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

    def __init__(self, data: Any, where: str, read: dict[int, tuple[str, dict, set]] | None = None) -> None:
        if not isinstance(data, dict):
            raise ConfigError(f"{where}: expected a table, got {type(data).__name__}")
        self.data = data
        self.where = where
        # every table reached from the file's root (by identity) and the keys read in it, for check_unknown
        self._read = {} if read is None else read
        self._keys = self._read.setdefault(id(data), (where, data, set()))[2]

    def _fail(self, key: str, problem: str) -> ConfigError:
        return ConfigError(f"{self.where} field '{key}': {problem}")

    def has(self, key: str) -> bool:
        self._keys.add(key)
        return key in self.data

    def get(self, key: str, default: Any = None) -> Any:
        """The raw value (``default`` if absent)."""
        self._keys.add(key)
        return self.data.get(key, default)

    def names(self) -> list[str]:
        """The table's keys, where they are names (joints, links) rather than fields: all of them read."""
        self._keys.update(self.data)
        return list(self.data)

    def child(self, data: Any, where: str) -> Fields:
        """A table found inside this one's values (checked by :meth:`check_unknown` with it)."""
        return Fields(data, where, self._read)

    def check_unknown(self) -> None:
        """Refuse a field that nothing read in this file's tables reached so far: a misspelt name (``efort``,
        ``setle``), whose default would be used silently, or one this hand's other settings never read."""
        from difflib import get_close_matches

        for where, data, keys in self._read.values():
            unknown = sorted(set(data) - keys)
            if unknown:
                # every field this table is read for, given or not: the misspelt one's right name among them
                close = get_close_matches(unknown[0], sorted(keys), n=1)
                hint = f"did you mean '{close[0]}'?" if close else "misspelt?"
                raise ConfigError(f"{where} field '{unknown[0]}': not a field read here ({hint} known here: "
                                  f"{', '.join(sorted(keys)) or 'none'})")

    def str(self, key: str, default: str | None = None) -> str:
        value = self.get(key, default)
        if not isinstance(value, str) or not value:
            raise self._fail(key, "missing or not a non-empty string")
        return value

    def float(self, key: str, default: float | None = None, *, positive: bool = False) -> float:
        value = self.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self._fail(key, "missing or not a number")
        if not math.isfinite(value) or (positive and value <= 0):
            raise self._fail(key, f"must be {'positive and ' if positive else ''}finite, got {value}")
        return float(value)

    def bool(self, key: str, default: bool) -> bool:
        value = self.get(key, default)
        if not isinstance(value, bool):
            raise self._fail(key, "must be true or false")
        return value

    def floats(self, key: str, length: int | None = None, default: list[float] | None = None) -> list[float]:
        value = self.get(key, default)
        if not isinstance(value, list) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value
        ):
            raise self._fail(key, "missing or not a list of finite numbers")
        if length is not None and len(value) != length:
            raise self._fail(key, f"needs {length} numbers, got {len(value)}")
        return [float(v) for v in value]

    def strs(self, key: str, default: list[str] | None = None) -> list[str]:
        value = self.get(key, default)
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self._fail(key, "missing or not a list of strings")
        return list(value)

    def table(self, key: str, default: dict[str, Any] | None = None) -> Fields:
        value = self.get(key, default)
        if value is None:
            raise self._fail(key, "missing table")
        return self.child(value, f"{self.where}[{key}]")

    def tables(self, key: str) -> list[Fields]:
        value = self.get(key)
        if not isinstance(value, list) or not value or not all(isinstance(v, dict) for v in value):
            raise self._fail(key, "missing or not an array of tables ([[...]])")
        return [self.child(v, f"{self.where}[[{key}]] #{i + 1}") for i, v in enumerate(value)]
