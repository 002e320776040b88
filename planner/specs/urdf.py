"""URDF files: the hand subtree cut out for PyBullet, the kinematic tree of a
hand, and the mesh of a URDF object."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from planner import assets
from planner.errors import ConfigError, MeshError


class UrdfTree:
    """Just enough URDF structure: links, joints, parent/child relations."""

    def __init__(self, path: Path, root: ET.Element) -> None:
        self.path = path
        self.links = [el.get("name", "") for el in root.findall("link")]
        self.joints = {el.get("name", ""): el for el in root.findall("joint")}
        self.movable = [n for n, el in self.joints.items() if el.get("type") in ("revolute", "prismatic", "continuous")]
        self.children: dict[str, list[str]] = {}
        for el in self.joints.values():
            self.children.setdefault(el.find("parent").get("link"), []).append(el.find("child").get("link"))  # type: ignore[union-attr]

    @classmethod
    def parse(cls, path: Path) -> UrdfTree:
        try:
            return cls(path, ET.parse(path).getroot())
        except (ET.ParseError, AttributeError) as exc:
            raise ConfigError(f"{path}: malformed URDF: {exc}") from exc

    def descendants(self, link: str) -> list[str]:
        out, stack = [], [link]
        while stack:
            current = stack.pop()
            out.append(current)
            stack.extend(self.children.get(current, []))
        return out


def cut_subtree(source: Path, root_link: str, where: str) -> Path:
    """Write the subtree of ``source`` below ``root_link`` with absolute mesh paths."""
    try:
        tree = ET.parse(source)
    except ET.ParseError as exc:
        raise ConfigError(f"{source}: malformed URDF: {exc}") from exc
    robot = tree.getroot()
    full = UrdfTree(source, robot)
    if root_link not in full.links:
        raise ConfigError(f"{where}: link '{root_link}' is not in {source.name}")
    keep = set(full.descendants(root_link))
    for el in list(robot):
        ends = {el.find("parent").get("link"), el.find("child").get("link")} if el.tag == "joint" else set()  # type: ignore[union-attr]
        if (el.tag == "link" and el.get("name") not in keep) or (el.tag == "joint" and not ends <= keep):
            robot.remove(el)
    for mesh in robot.iter("mesh"):
        name = mesh.get("filename", "")
        path = (source.parent / name.replace("package://", "")).resolve()
        if not path.is_file():
            raise ConfigError(f"{source}: mesh file not found: {name} (looked at {path})")
        mesh.set("filename", str(path))
    data = ET.tostring(robot, encoding="utf-8")
    out = assets.cache_dir("hands") / f"{source.stem}-{root_link}-{assets.sha256_bytes(data)[:12]}.urdf"
    if not out.exists():
        assets.atomic_write(out, data)
    return out


def object_mesh(urdf: Path, geometry: str, where: str) -> tuple[Path, float]:
    """The first ``<geometry><mesh>`` of the first link, with its URDF scale."""
    try:
        root = ET.parse(urdf).getroot()
    except ET.ParseError as exc:
        raise ConfigError(f"{urdf}: malformed URDF: {exc}") from exc
    node = root.find(f"link/{geometry}/geometry/mesh")
    if node is None or not node.get("filename"):
        raise ConfigError(f"{urdf}: {where} needs a <{geometry}> mesh in its first link")
    origin = root.find(f"link/{geometry}/origin")
    offsets = "" if origin is None else origin.get("xyz", "0 0 0") + " " + origin.get("rpy", "0 0 0")
    if any(float(v) != 0 for v in offsets.split()):
        raise MeshError(f"{urdf}: {geometry} origin offsets are not supported; export the mesh in the link frame")
    scales = [float(v) for v in node.get("scale", "1 1 1").split()]
    if len(set(scales)) != 1:
        raise MeshError(f"{urdf}: non-uniform mesh scale {scales} is not supported")
    path = (urdf.parent / node.get("filename", "").replace("package://", "")).resolve()
    return path, scales[0]
