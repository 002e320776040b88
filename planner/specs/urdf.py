"""URDF files, parsed with yourdfpy: a hand's kinematic tree, the hand subtree
cut out of a whole robot for PyBullet, and where a mesh a URDF names is (a
URDF object, its links' geometry merged: :mod:`planner.specs.urdf_objects`).

The cut keeps, of the source file, the links below ``root_link`` and the
joints between them (yourdfpy's model decides which), with absolute mesh
paths. It copies those elements as the author wrote them rather than letting
yourdfpy write its model back: yourdfpy stores origins as matrices and writes
them as re-derived Euler angles (near a quarter turn of pitch that moves an
angle by ~1e-9, and it turns the angles into an equivalent triple), and it
does not model PyBullet's ``<contact>`` extension (the Panda's finger pads:
contact stiffness, damping, spinning friction), which the dynamic trials
need. PyBullet and yourdfpy then load the very same cut file.
"""

from __future__ import annotations

import io
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from lxml import etree

if TYPE_CHECKING:
    import yourdfpy  # imports trimesh: loaded by load_model, where it is used

from planner import assets
from planner.errors import ConfigError

#: Joint types that move (the others are fixed or floating).
MOVABLE = ("revolute", "prismatic", "continuous")


#: An XML declaration; some shipped URDFs (pybullet_data's duck and teddy)
#: declare version "0.0", which lxml refuses and PyBullet ignores.
_DECLARATION = re.compile(rb"^\s*<\?xml[^>]*\?>")


def urdf_xml(path: Path) -> bytes:
    """The URDF's text without its XML declaration, checked to be well formed
    (yourdfpy alone would recover from broken XML silently)."""
    try:
        text = _DECLARATION.sub(b"", path.read_bytes(), count=1)
        etree.fromstring(text)
    except (etree.XMLSyntaxError, OSError) as exc:
        raise ConfigError(f"{path}: malformed URDF: {exc}") from exc
    return text


def load_model(path: Path) -> yourdfpy.URDF:
    """The URDF's kinematic model (no meshes loaded); a malformed file is a ConfigError."""
    import yourdfpy

    text = urdf_xml(path)
    try:
        return yourdfpy.URDF.load(io.BytesIO(text), build_scene_graph=False, build_collision_scene_graph=False,
                                  load_meshes=False, load_collision_meshes=False)
    except (AttributeError, KeyError, ValueError, IndexError, TypeError) as exc:
        raise ConfigError(f"{path}: malformed URDF: {exc}") from exc


def link_names(model: yourdfpy.URDF) -> list[str]:
    return [link.name for link in model.robot.links]


def movable_joints(model: yourdfpy.URDF) -> list[str]:
    return [j.name for j in model.robot.joints if j.type in MOVABLE]


def descendants(model: yourdfpy.URDF, link: str) -> list[str]:
    """``link`` and every link below it, depth first."""
    children: dict[str, list[str]] = {}
    for joint in model.robot.joints:
        children.setdefault(joint.parent, []).append(joint.child)
    out, stack = [], [link]
    while stack:
        current = stack.pop()
        out.append(current)
        stack.extend(children.get(current, []))
    return out


@dataclass(frozen=True)
class LinkChain:
    """The joints from a URDF's root link down to one link: that link's frame
    at any joint values (forward kinematics, pure numpy; PyBullet's and
    yourdfpy's to float32 round-off, tests/specs/test_urdf.py).

    Attributes:
        joints: (k,) joint names, root first; kinds: (k,) their URDF types.
        origins: (k, 4, 4) each joint's frame in its parent link's frame.
        axes: (k, 3) each joint's unit axis in its own frame.
    """

    joints: tuple[str, ...]
    kinds: tuple[str, ...]
    origins: np.ndarray
    axes: np.ndarray

    def frame(self, values: Mapping[str, float]) -> np.ndarray:
        """(4, 4) the link's frame in the root link's frame with the joints at
        ``values`` [rad or m] (a joint left out at 0)."""
        out = np.eye(4)
        for name, kind, origin, axis in zip(self.joints, self.kinds, self.origins, self.axes):
            motion = np.eye(4)
            q = float(values.get(name, 0.0))
            if kind in ("revolute", "continuous"):
                from scipy.spatial.transform import Rotation  # loaded by the hands that measure a pad gap only

                motion[:3, :3] = Rotation.from_rotvec(q * axis).as_matrix()
            elif kind == "prismatic":
                motion[:3, 3] = q * axis
            out = out @ origin @ motion
        return out


def link_chain(model: yourdfpy.URDF, link: str) -> LinkChain:
    """The :class:`LinkChain` of ``link`` (a link of ``model``) from the model's root."""
    parent = {j.child: j for j in model.robot.joints}
    chain = []
    while link in parent:
        chain.append(parent[link])
        link = parent[link].parent
    chain.reverse()
    axes = [np.zeros(3) if j.axis is None else np.asarray(j.axis, float) / np.linalg.norm(j.axis) for j in chain]
    return LinkChain(tuple(j.name for j in chain), tuple(j.type or "fixed" for j in chain),
                     np.array([np.eye(4) if j.origin is None else np.asarray(j.origin, float) for j in chain]
                              ).reshape(-1, 4, 4), np.array(axes).reshape(-1, 3))


def cut_subtree(source: Path, root_link: str, where: str) -> Path:
    """Write the subtree of ``source`` below ``root_link``, with absolute mesh
    paths and its collision boxes and spheres as meshes
    (:func:`_primitives_as_meshes`), into the cache (named by its content);
    returns the file."""
    model = load_model(source)
    if root_link not in model.link_map:
        raise ConfigError(f"{where}: link '{root_link}' is not in {source.name}")
    keep = set(descendants(model, root_link))
    joints = {j.name for j in model.robot.joints if j.parent in keep and j.child in keep}
    meshes = {}
    for link in model.robot.links:
        for element in (*link.visuals, *link.collisions) if link.name in keep else ():
            mesh = element.geometry.mesh if element.geometry is not None else None
            if mesh is not None:
                meshes[mesh.filename] = _mesh_file(source, mesh.filename)
    robot = etree.fromstring(urdf_xml(source), etree.XMLParser(remove_comments=True))
    for element in list(robot):
        name = element.get("name")
        if (element.tag == "link" and name not in keep) or (element.tag == "joint" and name not in joints):
            robot.remove(element)
    for mesh in robot.iter("mesh"):
        name = mesh.get("filename", "")
        mesh.set("filename", str(meshes.get(name) or _mesh_file(source, name)))
    _primitives_as_meshes(robot, f"{where} ({source.name})")
    data = etree.tostring(robot, encoding="utf-8")
    out = assets.cache_dir("hands") / f"{source.stem}-{root_link}-{assets.sha256_bytes(data)[:12]}.urdf"
    if not out.exists():
        assets.atomic_write(out, data)
    return out


#: Subdivisions of the icosphere a collision sphere becomes (642 vertices: within 0.2% of its radius).
SPHERE_SUBDIVISIONS = 3


def _primitives_as_meshes(robot: etree._Element, where: str) -> None:
    """Turn every ``<collision>`` box and sphere into a mesh of the same
    shape (an OBJ in the cache, in metres). PyBullet pads a mesh and a
    cylinder by 1 mm, which the hand's ``distance_offset`` takes off every
    reported gap, but a box or sphere by less, and unevenly: the PR2's box
    fingertips read 0.15-0.73 mm smaller than they are, so closing pressed
    them ~1.5 mm into the object and the table clearance let them 1 mm
    nearer the table than it says. As meshes every link is padded alike."""
    import trimesh

    for shape in list(robot.iterfind("link/collision/geometry/*")):
        try:
            if shape.tag == "box":
                mesh = trimesh.creation.box(extents=[float(v) for v in shape.get("size", "").split()])
            elif shape.tag == "sphere":
                mesh = trimesh.creation.icosphere(SPHERE_SUBDIVISIONS, float(shape.get("radius", "")))
            else:
                continue
        except ValueError as exc:
            raise ConfigError(f"{where}: collision <{shape.tag}> with bad dimensions: {exc}") from exc
        text = trimesh.exchange.obj.export_obj(mesh, include_normals=False, include_texture=False,
                                               digits=17).encode()
        out = assets.cache_dir("hands") / f"{shape.tag}-{assets.sha256_bytes(text)[:16]}.obj"
        if not out.exists():
            assets.atomic_write(out, text)
        replacement = etree.Element("mesh", filename=str(out))
        replacement.tail = shape.tail
        shape.getparent().replace(shape, replacement)


#: What PyBullet drops from the head of a mesh's filename before it looks for the file (its UrdfFindMeshFile).
MESH_URL_PREFIXES = ("file://", "package://", "model://")


def mesh_path(urdf: Path, filename: str) -> Path:
    """Where a mesh a URDF names is, looked for as PyBullet does (less its last resort, the working folder): a
    ``file://``, ``package://`` or ``model://`` dropped, the rest taken from the URDF's folder, else from the nearest
    folder above it that holds it (``package://pkg/meshes/m.obj`` of ``pkg/urdf/o.urdf`` is ``pkg/meshes/m.obj``);
    where none does, the path beside the URDF, which does not exist."""
    name = next((filename[len(p):] for p in MESH_URL_PREFIXES if filename.startswith(p)), filename)
    folder = Path(urdf).absolute().parent  # the folder it is named in (a link's, not its target's), as before
    beside = (folder / name).resolve()
    if beside.exists() or Path(name).is_absolute():
        return beside
    return next((found for above in folder.parents if (found := (above / name).resolve()).exists()), beside)


def _mesh_file(urdf: Path, filename: str) -> Path:
    """A mesh a URDF names (:func:`mesh_path`), which must exist."""
    path = mesh_path(urdf, filename)
    if not path.is_file():
        raise ConfigError(f"{urdf}: mesh file not found: {filename} (looked at {path})")
    return path
