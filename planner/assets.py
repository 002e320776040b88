"""Locating files: project folders, the installed ``pybullet_data`` package,
and the on-disk cache.

Built-in descriptions refer to files with two kinds of locator:

- ``pybullet_data:RELATIVE/PATH`` -- a file inside the installed
  ``pybullet_data`` package, found at run time (never copied here);
- a path relative to the TOML file that names it.

A built-in locator may not escape its root (``..`` or an absolute path), so a
registry entry can never point outside the project or the package.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from planner.errors import ConfigError, InputError

PYBULLET_DATA_PREFIX = "pybullet_data:"

def _project_root() -> Path:
    """The folder holding ``hands/``, ``preshapes/`` and ``objects/``: the
    checkout this package lives in (``pip install -e .``), or ``$GRASP_HOME``."""
    env = os.environ.get("GRASP_HOME")
    if env:
        return Path(env).resolve()
    here = Path(__file__).resolve().parent.parent
    return here if (here / "hands").is_dir() else Path.cwd()


#: The repository root (the folder holding ``hands/``, ``objects/``...).
PROJECT_ROOT = _project_root()


#: The asset folders a ``$GRASP_HOME`` must hold.
ASSET_FOLDERS = ("hands", "preshapes", "objects")


def project_dir(name: str) -> Path:
    """One of the project's asset folders: ``hands``, ``preshapes``, ``objects``."""
    path = PROJECT_ROOT / name
    if name in ASSET_FOLDERS and not path.is_dir():
        missing = ", ".join(f + "/" for f in ASSET_FOLDERS if not (PROJECT_ROOT / f).is_dir())
        if os.environ.get("GRASP_HOME"):
            raise ConfigError(f"GRASP_HOME={os.environ['GRASP_HOME']}: no {missing} folder there (GRASP_HOME names "
                              f"the folder holding {', '.join(f + '/' for f in ASSET_FOLDERS)}: a checkout of this "
                              "project)")
        # a `pip install .` copies the package only: run from elsewhere, it read the current folder's (a traceback)
        raise ConfigError(f"no {missing} folder beside the installed package or in the current folder {PROJECT_ROOT}: "
                          "install from a checkout with `pip install -e .`, run grasp in the checkout, or set "
                          "GRASP_HOME to it")
    return path


def pybullet_data_root() -> Path:
    """The folder of the installed ``pybullet_data`` package."""
    try:
        import pybullet_data
    except ImportError as exc:  # pragma: no cover - pybullet is a core dependency
        raise InputError("pybullet_data is not installed: pip install pybullet") from exc
    return Path(pybullet_data.getDataPath()).resolve()


def _inside(root: Path, relative: str, where: str) -> Path:
    rel = Path(relative)
    if rel.is_absolute():
        raise ConfigError(f"{where}: '{relative}' must be relative, not absolute")
    path = (root / rel).resolve()
    if root != path and root not in path.parents:
        raise ConfigError(f"{where}: '{relative}' points outside {root}")
    return path


def resolve(locator: str, base: Path, where: str) -> Path:
    """Turn a built-in locator into an existing file path.

    ``base`` is the folder of the TOML file that holds the locator; ``where``
    names that file and field for error messages.
    """
    if locator.startswith(PYBULLET_DATA_PREFIX):
        path = _inside(pybullet_data_root(), locator[len(PYBULLET_DATA_PREFIX):], where)
    else:
        path = _inside(base.resolve(), locator, where)
    if not path.is_file():
        raise ConfigError(f"{where}: file not found: {path}")
    return path


def cache_dir(kind: str) -> Path:
    """A writable cache folder (``$GRASP_CACHE`` or ``~/.cache/grasp-planner``)."""
    root = Path(os.environ.get("GRASP_CACHE", Path.home() / ".cache" / "grasp-planner"))
    path = root / kind
    path.mkdir(parents=True, exist_ok=True)
    return path


def sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` so readers never see a half-written file."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except BaseException:  # a full disk, Ctrl-C: no half-written file left under any name
        tmp.unlink(missing_ok=True)
        raise
