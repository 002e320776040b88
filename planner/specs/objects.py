"""Objects to grasp: the built-in registry (``objects/objects.toml``), the
procedurally generated ``random_NNN`` objects, user mesh files.

An :class:`ObjectSpec` says where an object's mesh comes from and its
physical parameters; :mod:`planner.geometry.solid` turns it into a checked
solid. The object frame is the frame of the (scaled) mesh file, as in
ACRONYM: every grasp pose in the database is expressed in it. Lengths in
metres, masses in kilograms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

from planner import assets
from planner.errors import ConfigError, InputError, UnknownNameError
from planner.specs.toml import Fields, read_toml
from planner.specs.urdf import object_mesh

REGISTRY_FILE = "objects.toml"
DEFAULT_MASS = 0.2  # kg, for user meshes given without a mass
DEFAULT_FRICTION = 0.5
RANDOM_PREFIX = "random_"
RANDOM_COUNT = 1000
RANDOM_MASS = 0.1  # kg: the generated objects are 5-10 cm across
#: Mesh files an object (or a folder of objects) may be given as.
MESH_SUFFIXES = (".obj", ".stl", ".ply", ".glb", ".gltf", ".off")


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


def is_registered(name: str) -> bool:
    """A built-in or ``random_NNN`` name: an object with its own mesh and scale."""
    return name in builtin_specs() or _random_index(name) is not None


def _random_index(name: str) -> int | None:
    """NNN of a ``random_NNN`` name, else None."""
    digits = name[len(RANDOM_PREFIX):]
    return int(digits) if name.startswith(RANDOM_PREFIX) and digits.isdigit() else None


def random_spec(index: int) -> ObjectSpec:
    """One of the 1,000 procedurally generated objects in ``pybullet_data``."""
    if not 0 <= index < RANDOM_COUNT:
        raise InputError(f"random object index {index} out of range 0..{RANDOM_COUNT - 1}")
    tag = f"{index:03d}"
    return ObjectSpec(
        name=f"{RANDOM_PREFIX}{tag}",
        kind="urdf",
        source=f"{assets.PYBULLET_DATA_PREFIX}random_urdfs/{tag}/{tag}.urdf",
        mass=RANDOM_MASS,
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
            spec = replace(spec, scale=spec.scale * scale)
    elif _random_index(name) is not None:
        spec = random_spec(_random_index(name))  # type: ignore[arg-type]
    elif Path(name).suffix.lower() in MESH_SUFFIXES or Path(name).exists():
        path = Path(name).expanduser().resolve()
        spec = ObjectSpec(name=path.stem, kind="mesh", source=str(path), scale=scale or 1.0)
    else:
        raise UnknownNameError("object", name,
                               [*builtin, f"{RANDOM_PREFIX}000..{RANDOM_PREFIX}999", "or a mesh file path"])
    if label:
        spec = replace(spec, name=label)
    overrides = {k: v for k, v in (("mass", mass), ("friction", friction)) if v is not None}
    for key, value in overrides.items():
        if not math.isfinite(value) or value <= 0:
            raise InputError(f"object '{name}': {key} must be a positive number, got {value}")
    return replace(spec, **overrides) if overrides else spec


PRIMITIVES = ("box", "cylinder", "sphere")


def source_path(spec: ObjectSpec) -> Path:
    """The file whose bytes define the object (the URDF for ``urdf`` objects)."""
    if spec.source.startswith(assets.PYBULLET_DATA_PREFIX):
        return assets.resolve(spec.source, assets.project_dir("objects"), f"object '{spec.name}'")
    return Path(spec.source)


def urdf_mesh(spec: ObjectSpec) -> tuple[Path, float]:
    """A ``urdf`` object's mesh file and the URDF's own scale of it."""
    return object_mesh(source_path(spec), spec.geometry, f"object '{spec.name}'")


def file_scale(spec: ObjectSpec) -> float:
    """The factor turning the object's mesh file into metres: the registry's
    ``scale`` times, for URDF objects, the URDF's own ``<mesh scale>``."""
    if spec.kind in PRIMITIVES:
        return 1.0
    if spec.kind == "urdf":
        return urdf_mesh(spec)[1] * spec.scale
    return spec.scale
