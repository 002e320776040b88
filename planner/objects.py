"""Objects to grasp: the built-in registry, user meshes, and their physics.

The object frame is the frame of the (scaled) mesh file, as in ACRONYM: every
grasp pose in the database is expressed in it. Lengths in metres, masses in
kilograms.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np
import trimesh

from planner import assets
from planner import mesh as meshes
from planner.config import Fields, read_toml
from planner.errors import ConfigError, InputError, MeshError, UnknownNameError

REGISTRY_FILE = "objects.toml"
DEFAULT_MASS = 0.2  # kg, for user meshes given without a mass
DEFAULT_FRICTION = 0.5
RANDOM_PREFIX = "random_"
RANDOM_COUNT = 1000


@dataclass(frozen=True)
class ObjectSpec:
    """Where an object comes from and its physical parameters.

    ``kind`` is ``mesh`` (a mesh file), ``urdf`` (the mesh a URDF link
    declares, with the URDF's scale) or a primitive (``box``, ``cylinder``,
    ``sphere`` with ``dims`` in metres).
    """

    name: str
    kind: str
    source: str = ""
    scale: float = 1.0
    geometry: str = "collision"  # which URDF mesh: "collision" or "visual"
    dims: tuple[float, ...] = ()
    mass: float = DEFAULT_MASS
    friction: float = DEFAULT_FRICTION
    description: str = ""


@dataclass(frozen=True)
class PreparedObject:
    """A checked object ready for simulation and analysis.

    Attributes:
        mesh: closed triangle mesh in the object frame [m].
        com: (3,) centre of mass in the object frame [m].
        inertia: (3, 3) inertia about the centre of mass, object axes [kg m^2].
        torque_scale: rho [m], largest distance from ``com`` to the surface
            (seed section 2.2.1).
        gyration_radius: radius of gyration [m], the other choice of rho
            (``planner.quality.radius_of_gyration``: sqrt(trace(I) / (3 m)),
            from the mean principal moment).
        mesh_hash: sha256 of the geometry, the key of every cache.
    """

    spec: ObjectSpec
    mesh: trimesh.Trimesh = field(repr=False)
    source_file: str
    file_scale: float  # what turns ``source_file`` into this mesh [m] (a URDF's mesh scale included)
    mesh_hash: str
    volume: float
    density: float
    com: np.ndarray
    inertia: np.ndarray
    torque_scale: float
    gyration_radius: float

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def mass(self) -> float:
        return self.spec.mass

    @property
    def friction(self) -> float:
        return self.spec.friction


def registry_path() -> Path:
    return assets.project_dir("objects") / REGISTRY_FILE


@lru_cache(maxsize=1)
def builtin_specs() -> dict[str, ObjectSpec]:
    """The built-in registry, ``objects/objects.toml``."""
    path = registry_path()
    data = read_toml(path)
    return {name: _spec_from_toml(name, Fields(table, f"{path} [{name}]")) for name, table in data.items()}


def _spec_from_toml(name: str, f: Fields) -> ObjectSpec:
    kind = f.str("kind")
    common = dict(
        name=name,
        kind=kind,
        mass=f.float("mass", positive=True),
        friction=f.float("friction", DEFAULT_FRICTION, positive=True),
        description=f.data.get("description", ""),
    )
    if kind in ("box", "cylinder", "sphere"):
        lengths = {"box": 3, "cylinder": 2, "sphere": 1}[kind]
        dims = f.floats("dims", lengths)
        if min(dims) <= 0:
            raise ConfigError(f"{f.where} field 'dims': lengths must be positive")
        return ObjectSpec(dims=tuple(dims), **common)
    if kind in ("mesh", "urdf"):
        geometry = f.str("geometry", "collision")
        if geometry not in ("collision", "visual"):
            raise ConfigError(f"{f.where} field 'geometry': must be 'collision' or 'visual'")
        return ObjectSpec(source=f.str("source"), scale=f.float("scale", 1.0, positive=True), geometry=geometry,
                          **common)
    raise ConfigError(f"{f.where} field 'kind': unknown kind '{kind}'; use mesh, urdf, box, cylinder or sphere")


def random_spec(index: int) -> ObjectSpec:
    """One of the 1,000 procedurally generated objects in ``pybullet_data``."""
    if not 0 <= index < RANDOM_COUNT:
        raise InputError(f"random object index {index} out of range 0..{RANDOM_COUNT - 1}")
    tag = f"{index:03d}"
    return ObjectSpec(
        name=f"{RANDOM_PREFIX}{tag}",
        kind="urdf",
        source=f"{assets.PYBULLET_DATA_PREFIX}random_urdfs/{tag}/{tag}.urdf",
        mass=0.1,
        friction=DEFAULT_FRICTION,
        description="procedurally generated object from pybullet_data/random_urdfs",
    )


def resolve_spec(name: str, *, scale: float | None = None, mass: float | None = None,
                 friction: float | None = None, label: str | None = None) -> ObjectSpec:
    """A built-in name, ``random_NNN``, or a path to a mesh file; ``label``
    renames it (two mesh files of one run with the same stem)."""
    builtin = builtin_specs()
    if name in builtin:
        spec = builtin[name]
        if scale is not None and spec.kind in ("mesh", "urdf"):
            spec = _replace(spec, scale=spec.scale * scale)
    elif name.startswith(RANDOM_PREFIX) and name[len(RANDOM_PREFIX):].isdigit():
        spec = random_spec(int(name[len(RANDOM_PREFIX):]))
    elif Path(name).suffix.lower() in meshes.MESH_SUFFIXES or Path(name).exists():
        path = Path(name).expanduser().resolve()
        spec = ObjectSpec(name=path.stem, kind="mesh", source=str(path), scale=scale or 1.0)
    else:
        raise UnknownNameError("object", name,
                               [*builtin, f"{RANDOM_PREFIX}000..{RANDOM_PREFIX}999", "or a mesh file path"])
    if label:
        spec = _replace(spec, name=label)
    overrides = {k: v for k, v in (("mass", mass), ("friction", friction)) if v is not None}
    for key, value in overrides.items():
        if not math.isfinite(value) or value <= 0:
            raise InputError(f"object '{name}': {key} must be a positive number, got {value}")
    return _replace(spec, **overrides) if overrides else spec


def _replace(spec: ObjectSpec, **changes: object) -> ObjectSpec:
    from dataclasses import replace

    return replace(spec, **changes)  # type: ignore[arg-type]


def load(name: str, *, label: str | None = None, **overrides: float | None) -> PreparedObject:
    """Resolve and prepare an object by name or mesh path."""
    return prepare(resolve_spec(name, label=label, **overrides))


def prepare(spec: ObjectSpec) -> PreparedObject:
    mesh, source_file = _cached_mesh(spec)
    volume = float(mesh.volume)
    density = spec.mass / volume
    mesh.density = density
    com = np.asarray(mesh.center_mass, float)
    inertia = np.asarray(mesh.moment_inertia, float)
    from planner import quality

    rho = quality.torque_scale_max_distance(mesh.vertices, com)
    gyration = quality.radius_of_gyration(spec.mass, inertia)
    return PreparedObject(
        spec=spec, mesh=mesh, source_file=source_file, file_scale=file_scale(spec), mesh_hash=meshes.mesh_hash(mesh),
        volume=volume, density=density, com=com, inertia=inertia, torque_scale=rho, gyration_radius=gyration,
    )


CACHE_VERSION = 1


def file_scale(spec: ObjectSpec) -> float:
    """The factor turning the object's mesh file into metres: the registry's
    ``scale`` times, for URDF objects, the URDF's own ``<mesh scale>``."""
    if spec.kind in ("box", "cylinder", "sphere"):
        return 1.0
    if spec.kind == "urdf":
        return _urdf_mesh(_source_file(spec), spec.geometry, f"object '{spec.name}'")[1] * spec.scale
    return spec.scale


def _cached_mesh(spec: ObjectSpec) -> tuple[trimesh.Trimesh, str]:
    """The checked, repaired mesh, cached on disk by source content and scale
    (``.npz`` of plain arrays, no pickle) and shared by runs and workers."""
    if spec.kind in ("box", "cylinder", "sphere"):
        return _build_mesh(spec)
    import hashlib
    import json

    source = _source_file(spec)
    if not source.is_file():
        raise MeshError(f"{source}: file not found")
    h = hashlib.sha256(json.dumps([CACHE_VERSION, spec.kind, spec.geometry, spec.scale]).encode())
    h.update(source.read_bytes())
    if spec.kind == "urdf":  # the mesh the URDF points at matters as much as the URDF
        mesh_file, _ = _urdf_mesh(source, spec.geometry, f"object '{spec.name}'")
        if mesh_file.is_file():
            h.update(mesh_file.read_bytes())
    path = assets.cache_dir("objects") / f"{h.hexdigest()[:24]}.npz"
    if path.is_file():
        try:
            with np.load(path, allow_pickle=False) as data:
                mesh = trimesh.Trimesh(data["vertices"], data["faces"], process=False)
                return mesh, str(data["source"])
        except (OSError, ValueError, KeyError):
            path.unlink(missing_ok=True)  # a damaged cache entry is rebuilt
    mesh, source_file = _build_mesh(spec)
    import io

    buffer = io.BytesIO()
    np.savez(buffer, vertices=np.asarray(mesh.vertices), faces=np.asarray(mesh.faces), source=np.array(source_file))
    assets.atomic_write(path, buffer.getvalue())
    return mesh, source_file


def _source_file(spec: ObjectSpec) -> Path:
    """The file whose bytes define the object (the URDF for ``urdf`` objects)."""
    if spec.source.startswith(assets.PYBULLET_DATA_PREFIX):
        return assets.resolve(spec.source, assets.project_dir("objects"), f"object '{spec.name}'")
    return Path(spec.source)


def _build_mesh(spec: ObjectSpec) -> tuple[trimesh.Trimesh, str]:
    where = f"object '{spec.name}'"
    if spec.kind == "box":
        return trimesh.creation.box(extents=spec.dims), "primitive:box"
    if spec.kind == "cylinder":
        radius, height = spec.dims
        return trimesh.creation.cylinder(radius=radius, height=height, sections=48), "primitive:cylinder"
    if spec.kind == "sphere":
        return trimesh.creation.icosphere(subdivisions=3, radius=spec.dims[0]), "primitive:sphere"
    base = assets.project_dir("objects")
    if spec.kind == "mesh":
        path = assets.resolve(spec.source, base, where) if spec.source.startswith(assets.PYBULLET_DATA_PREFIX) \
            else Path(spec.source)
        return meshes.load_mesh_file(path, spec.scale), str(path)
    urdf = assets.resolve(spec.source, base, where)
    path, scale = _urdf_mesh(urdf, spec.geometry, where)
    return meshes.load_mesh_file(path, scale * spec.scale), str(path)


def _urdf_mesh(urdf: Path, geometry: str, where: str) -> tuple[Path, float]:
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
