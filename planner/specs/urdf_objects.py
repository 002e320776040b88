"""A URDF file as an object to grasp: its links' geometry as one rigid body,
and the mass and friction it declares.

The object frame is the root link's frame. Every ``<collision>`` element of
every link is a part (the ``<visual>`` ones where the file has no collision
element, or where a registry entry asks for them), placed by its ``<origin>``
and its link's chain of fixed joints: a mesh at its ``<mesh scale>`` (per
axis), or a ``<box>``, ``<cylinder>``, ``<sphere>``.
:mod:`planner.geometry.shapes` makes them one mesh. A joint that moves (an
articulated object) is refused: the planner grasps rigid objects.

Mass and friction are read as PyBullet reads them: each link's
``<inertial><mass value>`` (summed: the links are one rigid body), and
PyBullet's extension ``<contact><lateral_friction value>``, the first
``<contact>`` of a link (PyBullet's 0.5 for a link with geometry that gives
none). The ``<inertial>`` origins and inertias make the object's centre of
mass and inertia (:mod:`planner.specs.urdf_inertial`, which says when a file
declares a centre of mass); :mod:`planner.geometry.solid` checks them against
the mesh.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from lxml import etree

if TYPE_CHECKING:
    import yourdfpy  # imports trimesh: loaded by load_model, where it is used

from planner.errors import ConfigError, InputError, MeshError
from planner.specs.physical import GEOMETRIES, Physical, Value
from planner.specs.urdf import descendants, link_chain, load_model, mesh_path, urdf_xml
from planner.specs.urdf_inertial import UrdfInertial, combined, link_inertial

URDF_SUFFIX = ".urdf"
#: The shapes of a ``<geometry>`` element, each made as a mesh.
SHAPES = ("mesh", "box", "cylinder", "sphere")
#: A link's lateral friction in PyBullet where its URDF gives none (its URDF importer's default).
PYBULLET_FRICTION = 0.5
#: Said where a value of the URDF that the run uses is bad, or its links' frictions differ.
_GIVE = "give the object's own with --{key}, a manifest's {key}= or a sidecar ({stem}.toml)"


@dataclass(frozen=True)
class UrdfPart:
    """One ``<collision>`` (or ``<visual>``) element of a URDF object.

    Attributes:
        link: the link it belongs to.
        shape: ``mesh``, ``box``, ``cylinder`` or ``sphere``.
        pose: (4, 4) its frame in the object frame (the root link's) [m], read-only.
        file: the mesh file (``mesh`` only).
        scale: (3,) the mesh's ``<mesh scale>`` per axis (1 for a primitive).
        dims: a box's (3,) size, a cylinder's radius and length, a sphere's radius [m].
    """

    link: str
    shape: str
    pose: np.ndarray
    file: Path | None = None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    dims: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        pose = np.array(self.pose, float)
        if pose.shape != (4, 4):
            raise ValueError(f"pose must be (4, 4), got {pose.shape}")
        pose.flags.writeable = False
        object.__setattr__(self, "pose", pose)


@dataclass(frozen=True)
class UrdfObject:
    """What a URDF file says of the object it describes (:func:`read_urdf_object`).

    Attributes:
        path: the URDF file.
        geometry: ``collision`` or ``visual``: the elements ``parts`` are.
        parts: every link's elements of that geometry, in the file's order.
        mass: [kg] the links' ``<inertial><mass>`` summed (a negative or NaN one instead, to be refused); None
            where no link gives one.
        frictions: (link, ``<lateral_friction>``) of each link with parts, PyBullet's 0.5 for one that gives
            none; () where no link gives one.
        inertial: the links' ``<inertial>`` elements as one body's, in the object frame unscaled; None where no
            link has a positive mass.
    """

    path: Path
    geometry: str
    parts: tuple[UrdfPart, ...]
    mass: float | None
    frictions: tuple[tuple[str, float], ...]
    inertial: UrdfInertial | None = None

    @property
    def files(self) -> tuple[Path, ...]:
        """The mesh files of the parts, each once, in order."""
        return tuple(dict.fromkeys(p.file for p in self.parts if p.file is not None))

    @property
    def com(self) -> tuple[float, float, float] | None:
        """[m] The centre of mass the file declares (:mod:`planner.specs.urdf_inertial`), object frame unscaled;
        None where it declares none."""
        if self.inertial is None or not self.inertial.declared:
            return None
        x, y, z = (float(v) for v in self.inertial.com)
        return (x, y, z)

    def stated(self) -> dict[str, Value]:
        """The mass, the one friction and the centre of mass the file gives (unchecked; no friction where its
        links' differ)."""
        frictions = {v for _, v in self.frictions}
        return {**({} if self.mass is None else {"mass": self.mass}),
                **({"friction": frictions.pop()} if len(frictions) == 1 else {}),
                **({} if self.com is None else {"com": self.com})}

    def own(self, given: Physical) -> Physical:
        """The file's mass and friction where ``given`` (the sources that come first) gives none, checked: a
        value another source replaces is not read (a tray's mass 0, PyBullet's mark of a fixed body)."""
        values: dict[str, float] = {}
        if given.mass is None and given.density is None and self.mass is not None:
            values["mass"] = self.mass
        if given.friction is None and self.frictions:
            if len({v for _, v in self.frictions}) > 1:
                listed = ", ".join(f"{link} {v:g}" for link, v in self.frictions)
                raise InputError(f"{self.path}: its links' <lateral_friction> differ ({listed}; PyBullet's "
                                 f"{PYBULLET_FRICTION:g} where a link gives none) and the planner takes one friction "
                                 f"per object: {_GIVE.format(key='friction', stem=self.path.stem)}")
            values["friction"] = self.frictions[0][1]
        for key, tag in (("mass", "<inertial><mass>"), ("friction", "<contact><lateral_friction>")):
            try:
                Physical.checked({k: v for k, v in values.items() if k == key}, f"{self.path} {tag}")
            except InputError as exc:
                fixed = " (PyBullet's mark of a fixed body)" if values.get(key) == 0 and key == "mass" else ""
                raise InputError(f"{exc}{fixed}; {_GIVE.format(key=key, stem=self.path.stem)}") from None
        return Physical(**values)

    def single_mesh(self) -> tuple[Path, float]:
        """The first mesh part's file and uniform scale, at the link frame: what a registry entry of kind ``urdf``
        is, stored as that file at that scale."""
        part = next((p for p in self.parts if p.shape == "mesh"), None)
        if part is None or part.file is None:
            raise ConfigError(f"{self.path}: needs a <{self.geometry}> mesh in its first link")
        if not np.array_equal(part.pose, np.eye(4)):
            raise MeshError(f"{self.path}: {self.geometry} origin offsets are not supported; export the mesh in the "
                            "link frame")
        if len(set(part.scale)) != 1:
            raise MeshError(f"{self.path}: non-uniform mesh scale {list(part.scale)} is not supported")
        return part.file, part.scale[0]


def read_urdf_object(path: Path, geometry: str = GEOMETRIES[0]) -> UrdfObject:
    """The object the URDF file ``path`` describes, made of its ``geometry`` elements (the other ones where it
    has none); a one-line ConfigError where it is not one rigid object the planner can make (see the module
    docstring). Read once per file and change."""
    try:
        st = Path(path).stat()
    except OSError as exc:
        raise InputError(f"{path}: cannot read it ({exc.strerror})") from None
    return _read(Path(os.path.abspath(path)), geometry, st.st_mtime_ns, st.st_ctime_ns, st.st_size)


@lru_cache(maxsize=256)
def _read(path: Path, geometry: str, mtime_ns: int, ctime_ns: int, size: int) -> UrdfObject:
    """:func:`read_urdf_object` of the file as it was at that modification and change time and size."""
    root = etree.fromstring(urdf_xml(path), etree.XMLParser(remove_comments=True))
    odd = next((s for s in root.iterfind("link/*/geometry/*") if s.tag not in SHAPES), None)
    if odd is not None:
        raise ConfigError(f"{path}: link '{odd.getparent().getparent().getparent().get('name')}': "
                          f"<{odd.tag}> geometry is not supported; use <mesh>, <box>, <cylinder> or <sphere>")
    with np.errstate(invalid="ignore", over="ignore"):  # a nan/inf <origin>: refused below, not numpy's warnings
        model = load_model(path)
    _check_rigid(path, model)
    links = model.robot.links
    if not any(getattr(link, f"{geometry}s") for link in links):
        geometry = next((g for g in GEOMETRIES if any(getattr(link, f"{g}s") for link in links)), "")
        if not geometry:
            raise ConfigError(f"{path}: no link has a <collision> or <visual> geometry: nothing to grasp")
    parts = tuple(_part(path, link.name, element, link_chain(model, link.name).frame({}))
                  for link in links for element in getattr(link, f"{geometry}s"))
    masses = [float(link.inertial.mass) for link in links if link.inertial is not None
              and link.inertial.mass is not None]
    mass = next((m for m in masses if not m >= 0), None)  # a negative or NaN one, for the check to refuse
    if mass is None and masses:
        mass = math.fsum(masses)
    inertial = combined([link_inertial(link.inertial.mass, link_chain(model, link.name).frame({}),
                                       link.inertial.origin, link.inertial.inertia)
                         for link in links if link.inertial is not None and link.inertial.mass is not None])
    return UrdfObject(path, geometry, parts, mass, _frictions(path, root, {p.link for p in parts}), inertial)


def _check_rigid(path: Path, model: yourdfpy.URDF) -> None:
    """Refuse links that are not one tree (PyBullet refuses them too), and joints that move."""
    robot = model.robot
    if not robot.links:
        return  # no tree, and nothing to grasp: said where the geometry is looked for
    children = [j.child for j in robot.joints]
    roots = [link.name for link in robot.links if link.name not in children]
    if len(roots) != 1 or len(set(children)) < len(children):
        raise ConfigError(f"{path}: " + (f"links {', '.join(roots)} are joined to none above them" if len(roots) > 1
                                         else "its joints make a loop") + ": one object is one tree of links")
    apart = [link.name for link in robot.links if link.name not in set(descendants(model, roots[0]))]
    if apart:
        raise ConfigError(f"{path}: links {', '.join(apart)} are not joined to {roots[0]} (their joints make a "
                          "loop): one object is one tree of links")
    moving = [f"'{j.name}' ({j.type})" for j in robot.joints if j.type != "fixed"]
    if moving:
        raise ConfigError(f"{path}: joint{'s' if len(moving) > 1 else ''} {', '.join(moving)} move"
                          f"{'' if len(moving) > 1 else 's'}: an articulated object, and the planner grasps rigid "
                          "ones; make the joint fixed at the pose to grasp (type=\"fixed\"), or give one link's mesh")


def _part(path: Path, link: str, element: yourdfpy.Collision | yourdfpy.Visual, frame: np.ndarray) -> UrdfPart:
    """One element of ``link`` (whose frame in the object's is ``frame``, (4, 4)), checked."""
    where = f"{path}: link '{link}'"
    pose = frame @ (np.eye(4) if element.origin is None else np.asarray(element.origin, float))
    g = element.geometry
    if g is None or all(getattr(g, s) is None for s in SHAPES):
        raise ConfigError(f"{where}: a <geometry> without <mesh>, <box>, <cylinder> or <sphere>")
    if g.mesh is not None:
        return UrdfPart(link, "mesh", pose, _mesh(path, where, g.mesh.filename or ""), _scale(where, g.mesh.scale))
    shape, dims = ("box", tuple(np.ravel(g.box.size))) if g.box is not None else \
        ("cylinder", (g.cylinder.radius, g.cylinder.length)) if g.cylinder is not None else \
        ("sphere", (g.sphere.radius,))
    try:
        dims = tuple(float(d) for d in dims)
    except (TypeError, ValueError):
        dims = ()
    if len(dims) != {"box": 3, "cylinder": 2, "sphere": 1}[shape] or not all(math.isfinite(d) and d > 0 for d in dims):
        raise ConfigError(f"{where}: <{shape}> needs positive lengths [m], got {list(dims) or 'none'}")
    return UrdfPart(link, shape, pose, dims=dims)


def _mesh(path: Path, where: str, filename: str) -> Path:
    """The mesh file ``filename`` names (:func:`~planner.specs.urdf.mesh_path`), which must exist."""
    if not filename:
        raise ConfigError(f"{where}: a <mesh> without a filename")
    found = mesh_path(path, filename)
    if not found.is_file():
        package = " (a package:// path is looked for from the URDF's folder and each folder above it)" \
            if filename.startswith("package://") else ""
        windows = " (a Windows path? write / between folders)" if "\\" in filename else ""
        raise ConfigError(f"{where}: mesh file not found: {filename} (looked at {found}){package}{windows}")
    return found


def _scale(where: str, scale: object) -> tuple[float, float, float]:
    """A ``<mesh scale>``: one factor or three, each positive."""
    values = np.atleast_1d(np.asarray(1.0 if scale is None else scale, float)).tolist()
    if len(values) == 1:
        values *= 3
    if len(values) != 3 or not all(math.isfinite(v) and v > 0 for v in values):
        raise ConfigError(f"{where}: <mesh scale> must be one or three positive numbers, got {values}")
    return (values[0], values[1], values[2])


def _frictions(path: Path, root: etree._Element, links: set[str]) -> tuple[tuple[str, float], ...]:
    """(link, lateral friction) of each of ``links`` as PyBullet reads it; () where none gives one."""
    found: dict[str, float | None] = {}
    for link in root.iterfind("link"):
        if link.get("name") not in links:
            continue
        contact = link.find("contact")  # PyBullet reads a link's first <contact>
        tag = contact.find("lateral_friction") if contact is not None else None
        if tag is not None:
            text = tag.get("value")
            try:
                found[link.get("name")] = float(text)  # type: ignore[arg-type]
            except (TypeError, ValueError):
                raise ConfigError(f"{path}: link '{link.get('name')}': <lateral_friction> needs a number value, "
                                  f"got {text!r}") from None
        else:
            found[link.get("name")] = None
    if all(v is None for v in found.values()):
        return ()
    return tuple((name, PYBULLET_FRICTION if v is None else v) for name, v in found.items())


def named_meshes(path: Path) -> set[Path]:
    """Every mesh file the URDF ``path`` names, visual and collision, resolved (:func:`mesh_path`); none where
    it does not read (its read as an object says why)."""
    try:
        root = etree.fromstring(urdf_xml(path))
    except InputError:
        return set()
    return {mesh_path(path, m.get("filename", "")) for m in root.iterfind("link/*/geometry/mesh") if m.get("filename")}
