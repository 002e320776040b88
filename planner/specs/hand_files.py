"""The files a hand is made of, each with a digest of its content: what a
database records of the hand its grasps were made with (``meta.hand_files``,
checked by :mod:`planner.db.hand_files`), so that grasps of an edited hand
are not stored, validated or imported beside those of the hand as it was.

The files: ``hands/<name>/hand.toml`` and ``preshapes/<name>.toml`` (their
parsed content: comments, layout and hand.toml's ``description`` do not
count), the URDF that
``hand.toml`` names and the collision meshes of its links, and the arm's
URDF and collision meshes when the hand has an arm (reachability); each
URDF and mesh by its bytes. Visual meshes are left out: they draw pictures,
no stored value depends on them.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from planner import assets
from planner.specs.hands import check_hand_name
from planner.specs.toml import read_toml
from planner.specs.urdf import load_model

#: Hex digits of each file's sha256 kept (64 bits: a collision by chance is not a concern).
DIGEST_CHARS = 16


def hand_files(name: str) -> dict[str, str]:
    """{file label: digest} of hand ``name``'s files, labels sorted; a label is
    the file's path under the project (``hands/panda/hand.toml``) or under
    ``pybullet_data`` (``pybullet_data:franka_panda/panda.urdf``), else its
    absolute path."""
    folder = check_hand_name(name)
    toml_path = folder / "hand.toml"
    data = read_toml(toml_path)
    out = {_label(toml_path): _parsed_digest({k: v for k, v in data.items() if k != "description"})}
    preshapes = assets.project_dir("preshapes") / f"{name}.toml"
    if preshapes.is_file():
        out[_label(preshapes)] = _parsed_digest(read_toml(preshapes))
    urdfs = [assets.resolve(str(data["urdf"]), folder, f"{toml_path} field 'urdf'")]
    arm = data.get("arm")
    if isinstance(arm, dict) and "urdf" in arm:
        urdfs.append(assets.resolve(str(arm["urdf"]), folder, f"{toml_path} field 'arm.urdf'"))
    for urdf in urdfs:
        out[_label(urdf)] = _bytes_digest(urdf)
        for mesh in _collision_meshes(urdf):
            out[_label(mesh)] = _bytes_digest(mesh)
    return dict(sorted(out.items()))


def changed(stored: dict[str, str], now: dict[str, str]) -> list[str]:
    """Labels of the files that differ between two :func:`hand_files`
    (added, removed or edited), sorted."""
    return sorted(k for k in stored.keys() | now.keys() if stored.get(k) != now.get(k))


def _collision_meshes(urdf: Path) -> list[Path]:
    model = load_model(urdf)
    names = {c.geometry.mesh.filename for link in model.robot.links for c in link.collisions
             if c.geometry is not None and c.geometry.mesh is not None and c.geometry.mesh.filename}
    paths = {(urdf.parent / n.replace("package://", "")).resolve() for n in names}
    return sorted(p for p in paths if p.is_file())  # a missing mesh is the hand loader's error to give


def _parsed_digest(data: dict) -> str:
    text = json.dumps(data, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:DIGEST_CHARS]


def _bytes_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:DIGEST_CHARS]


def _label(path: Path) -> str:
    path = path.resolve()
    for root, prefix in ((assets.pybullet_data_root().resolve(), assets.PYBULLET_DATA_PREFIX),
                         (assets.PROJECT_ROOT, "")):
        if path.is_relative_to(root):
            return prefix + path.relative_to(root).as_posix()
    return str(path)
