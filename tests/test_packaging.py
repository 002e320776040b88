"""The README's first install (``pip install -e .``) makes every subcommand work."""

from __future__ import annotations

import re
import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

PYPROJECT = Path(__file__).parents[1] / "pyproject.toml"
#: What subcommands import on demand: show and report (matplotlib), export and import (h5py, pyarrow),
#: validate (mujoco: its default trial).
SUBCOMMAND_IMPORTS = {"matplotlib", "h5py", "pyarrow", "mujoco"}


def names(requirements: list[str]) -> set[str]:
    return {re.split(r"[<>=!~; \[]", r, maxsplit=1)[0].lower() for r in requirements}


def test_every_subcommand_needs_only_the_core_dependencies() -> None:
    project = tomllib.loads(PYPROJECT.read_text())["project"]
    assert SUBCOMMAND_IMPORTS <= names(project["dependencies"])
    extras = project["optional-dependencies"]
    assert set(extras) == {"dev", "ray"}  # Ray is the one optional backend
    assert "pandas" in names(extras["dev"]) and names(extras["ray"]) == {"ray"}
