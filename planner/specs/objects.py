"""Objects to grasp: the built-in registry (``objects/objects.toml``), the
procedurally generated ``random_NNN`` objects, user mesh files.

An :class:`ObjectSpec` says where an object's mesh comes from and its
physical parameters; :mod:`planner.geometry.solid` turns it into a checked
solid. The object frame is the frame of the (scaled) mesh file, as in
ACRONYM: every grasp pose in the database is expressed in it. Lengths in
metres, masses in kilograms.

An object's mass (or density) and friction come, the first that gives them:
a manifest line's columns, ``grasp generate --mass/--density/--friction``
(every object of the run), a TOML sidecar beside a mesh file
(``banana.obj`` + ``banana.toml`` with ``mass``, ``density``, ``friction``),
the registry entry, else :data:`DEFAULT_MASS` and :data:`DEFAULT_FRICTION`.
Mass and density are one property given two ways: a source gives one or
the other, never both, and the first source that gives either decides. Its
``up`` (:mod:`planner.specs.up`) comes from the same sources, else
:func:`~planner.specs.up.default_up` of its file (``+y`` for glTF, else ``+z``).
"""

from __future__ import annotations

import json
import math
import os
import stat
from collections.abc import Mapping
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path
from urllib.parse import unquote

from planner import assets
from planner.errors import ConfigError, InputError, UnknownNameError
from planner.specs.toml import Fields, read_toml
from planner.specs.up import DEFAULT_UP, default_up, up_axis
from planner.specs.urdf import object_mesh

REGISTRY_FILE = "objects.toml"
DEFAULT_MASS = 0.2  # kg, for user meshes given without a mass
DEFAULT_FRICTION = 0.5
#: Relative difference below which a stored mass, density or friction is the
#: one given: a density comes back from the store as mass / volume, a few ulp off.
PROPERTY_RTOL = 1e-9
RANDOM_PREFIX = "random_"
RANDOM_COUNT = 1000
RANDOM_MASS = 0.1  # kg: the generated objects are 5-10 cm across
#: Mesh files an object (or a folder of objects) may be given as.
MESH_SUFFIXES = (".obj", ".stl", ".ply", ".glb", ".gltf", ".off")
#: Said where a URDF is given as an object: its mesh is planned on, at the scale the URDF gives it.
URDF_HINT = " (a URDF: give the mesh file its link names, its <mesh scale> as --scale, its <inertial> mass as --mass)"
#: Largest Coulomb friction coefficient accepted: rubber on rough surfaces
#: reaches about 1-2, so a larger value is a typo (a percentage, a unit mix-up).
MAX_FRICTION = 3.0
#: The keys of a physical-properties sidecar (``banana.toml`` beside ``banana.obj``).
SIDECAR_SUFFIX = ".toml"
PHYSICAL_KEYS = ("mass", "density", "friction", "up")
_UNITS = {"mass": "kg", "density": "kg/m^3", "friction": "Coulomb coefficient"}


@dataclass(frozen=True)
class Physical:
    """Physical properties a user gives for an object; None: not given.

    ``mass`` [kg] or ``density`` [kg/m^3] (uniform over the closed mesh; the
    mass is then density x volume), never both; ``friction``: Coulomb
    coefficient, 0 < mu <= :data:`MAX_FRICTION`; ``up``: the axis of the
    object frame that is up as it stands (:data:`planner.specs.up.AXES`).
    Build with :meth:`checked` from user input for an error naming the source and field.
    """

    mass: float | None = None
    density: float | None = None
    friction: float | None = None
    up: str | None = None

    def __post_init__(self) -> None:
        check_physical(self.mass, self.density, self.friction, "", "")
        if self.up is not None:
            object.__setattr__(self, "up", up_axis(self.up))

    @classmethod
    def checked(cls, values: Mapping[str, object], where: str = "", prefix: str = "") -> Physical:
        """From raw values (numbers, or text of numbers); the error names
        ``where`` (a file and line) and the field as ``prefix + key``."""
        unknown = sorted(set(values) - set(PHYSICAL_KEYS))
        if unknown:
            raise InputError(f"{_at(where)}unknown field '{prefix}{unknown[0]}'; use "
                             f"{', '.join(prefix + k for k in PHYSICAL_KEYS)}")
        numbers = {k: _number(values[k], k, where, prefix) for k in PHYSICAL_KEYS[:3] if values.get(k) is not None}
        check_physical(numbers.get("mass"), numbers.get("density"), numbers.get("friction"), where, prefix)
        up = None if values.get("up") is None else up_axis(values["up"], where, f"{prefix}up")
        return cls(**numbers, up=up)

    def over(self, base: Physical) -> Physical:
        """These properties, with ``base``'s where these give none (mass or
        density together: whichever gives either decides)."""
        heavy = self.mass is not None or self.density is not None
        return Physical(self.mass if heavy else base.mass, self.density if heavy else base.density,
                        self.friction if self.friction is not None else base.friction,
                        self.up if self.up is not None else base.up)

    def given(self) -> dict[str, float | str]:
        return {k: v for k in PHYSICAL_KEYS if (v := getattr(self, k)) is not None}


def _at(where: str) -> str:
    return f"{where}: " if where else ""


def _number(value: object, key: str, where: str, prefix: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise InputError(f"{_at(where)}{prefix}{key} must be a number [{_UNITS[key]}], got {value!r}")
    try:
        return float(value)
    except ValueError:
        raise InputError(f"{_at(where)}{prefix}{key} must be a number [{_UNITS[key]}], got '{value}'") from None


def check_physical(mass: float | None, density: float | None, friction: float | None, where: str = "",
                   prefix: str = "") -> None:
    """Raise an InputError naming the field of the first bad value."""
    if mass is not None and density is not None:
        raise InputError(f"{_at(where)}{prefix}mass and {prefix}density exclude each other (the mass is density x "
                         "volume); give one")
    for key, value in (("mass", mass), ("density", density), ("friction", friction)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"{_at(where)}{prefix}{key} must be a positive number [{_UNITS[key]}], got {value}")
    if friction is not None and friction > MAX_FRICTION:
        raise InputError(f"{_at(where)}{prefix}friction must lie in (0, {MAX_FRICTION:g}] (a Coulomb coefficient), "
                         f"got {friction}")


#: No property given: each object keeps its own.
NO_PHYSICAL = Physical()


def sidecar(mesh: Path) -> Physical:
    """The properties in ``mesh``'s sidecar (:func:`sidecar_path`), if any."""
    path = sidecar_path(mesh)
    return Physical.checked(read_toml(path), str(path)) if path is not None else NO_PHYSICAL


def mesh_sidecar(named: Path) -> Path | None:
    """The sidecar of the mesh file a path names: beside that path (a
    symlink's own, ``link.toml`` beside ``link.obj``), else beside the file
    it leads to."""
    own = sidecar_path(named)
    if own is not None:
        return own
    target = named.resolve()
    return sidecar_path(target) if target != Path(os.path.abspath(named)) else None


def sidecar_path(mesh: Path) -> Path | None:
    """``mesh``'s sidecar (same stem, ``.toml`` in any case: ``B.STL`` + ``B.TOML`` or
    ``B.Toml``), if any; two sidecars of one mesh are refused. ``.toml`` and ``.TOML`` are probed (a case-blind
    file system, macOS's or Windows', answers them with ``b.toml`` beside ``B.STL``, once: files are told apart by
    identity), other spellings found in the folder's listing, made once per folder and change."""
    found: dict[tuple[int, int], Path] = {}
    for path in (mesh.with_suffix(SIDECAR_SUFFIX), mesh.with_suffix(SIDECAR_SUFFIX.upper()),
                 *_odd_sidecars(mesh.parent).get(mesh.stem, ())):
        try:
            st = path.stat()
        except OSError:
            continue
        if stat.S_ISREG(st.st_mode):
            found.setdefault((st.st_dev, st.st_ino), path)
    paths = sorted(found.values())
    if len(paths) > 1:
        raise InputError(f"{mesh}: two sidecars, {' and '.join(p.name for p in paths)}: keep one")
    meant = [p for key in (mesh.stem.lower(), mesh.name.lower()) for p in _folder_tomls(mesh.parent)[1].get(key, ())]
    if not paths and meant:  # read on a case-blind file system, the defaults here: refused, not silently differing
        raise InputError(f"{mesh}: {meant[0].name} beside it is not read as its sidecar (one takes the mesh's name, "
                         f"in the same case, with .toml in place of {mesh.suffix}): rename it {mesh.stem}.toml")
    return paths[0] if paths else None


def _odd_sidecars(folder: Path) -> dict[str, tuple[Path, ...]]:
    """stem -> the folder's sidecars spelt neither ``.toml`` nor ``.TOML`` (``.Toml``); {} if unreadable."""
    return _folder_tomls(folder)[0]


def _folder_tomls(folder: Path) -> tuple[dict[str, tuple[Path, ...]], dict[str, tuple[Path, ...]]]:
    """:func:`_listing` of ``folder`` as it is now; nothing if unreadable."""
    try:
        st = folder.stat()
        return _listing(folder, st.st_mtime_ns, st.st_ctime_ns)  # ctime: an mtime put back (cp -a, tar) moves it
    except OSError:  # an unreadable folder: the mesh's own read says what is wrong
        return {}, {}


@lru_cache(maxsize=64)
def _listing(folder: Path, mtime_ns: int, ctime_ns: int
             ) -> tuple[dict[str, tuple[Path, ...]], dict[str, tuple[Path, ...]]]:
    """The sidecars of ``folder`` as it was at ``mtime_ns`` and ``ctime_ns`` (a dataset folder of 20,000 meshes
    was listed once per mesh and per look: 27 ms each): stem -> those spelt neither ``.toml`` nor ``.TOML``
    (``.Toml``), and lower-case stem -> the TOML files whose stem no mesh file of the folder has (a sidecar
    meant for ``Banana.obj`` spelt ``banana.toml`` or ``Banana.obj.toml``)."""
    odd: dict[str, list[Path]] = {}
    lost: dict[str, list[Path]] = {}
    files = sorted(folder.iterdir())
    stems = {p.stem for p in files if p.suffix.lower() in MESH_SUFFIXES}
    for p in files:
        if p.suffix.lower() == SIDECAR_SUFFIX and p.suffix not in (SIDECAR_SUFFIX, SIDECAR_SUFFIX.upper()):
            odd.setdefault(p.stem, []).append(p)
        if p.suffix.lower() == SIDECAR_SUFFIX and p.stem not in stems:
            lost.setdefault(p.stem.lower(), []).append(p)
    return {k: tuple(v) for k, v in odd.items()}, {k: tuple(v) for k, v in lost.items()}


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
    mass: float = DEFAULT_MASS  # [kg]; replaced by density x volume when ``density`` is given
    friction: float = DEFAULT_FRICTION
    description: str = ""
    density: float | None = None  # [kg/m^3] when the user gave a density, else None (from the mass)
    up: str = DEFAULT_UP  # the axis of the object frame that is up as it stands (planner.specs.up)


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
                 friction: float | None = None, label: str | None = None, density: float | None = None,
                 up: str | None = None, scale_from: str = "--scale") -> ObjectSpec:
    """A built-in name, ``random_NNN``, or a path to a mesh file; ``label``
    renames it (two mesh files of one run with the same stem). ``mass`` (or
    ``density``), ``friction`` and ``up`` override the object's own, a mesh file's
    from its sidecar (see the module docstring). ``scale_from``: what gave
    ``scale``, for the error of a primitive, which takes none."""
    given = Physical.checked({"mass": mass, "density": density, "friction": friction, "up": up}, f"object '{name}'")
    if scale is not None and not (math.isfinite(scale) and scale > 0):
        raise InputError(f"object '{name}': scale must be a positive number, got {scale:g} (0.001 for a mesh in "
                         "millimetres)")
    builtin = builtin_specs()
    if name in builtin:
        spec = builtin[name]
        if scale is not None and spec.kind in ("mesh", "urdf"):
            spec = replace(spec, scale=spec.scale * scale)
        elif scale is not None and scale != 1:
            raise InputError(f"object '{name}': {scale_from} applies to meshes only; {name} is a primitive of "
                             f"fixed size ({spec.description}): for another size give a mesh file (trimesh.creation "
                             "makes one)")
    elif _random_index(name) is not None:
        spec = random_spec(_random_index(name))  # type: ignore[arg-type]
        if scale is not None:
            spec = replace(spec, scale=spec.scale * scale)
    elif Path(name).suffix.lower() in MESH_SUFFIXES or Path(name).exists():
        # named as given and its sidecar beside it (a symlink's own name and folder; the target's sidecar where
        # the link has none); the source is the file itself, whatever path names it
        named, path = Path(name).expanduser(), Path(name).expanduser().resolve()
        spec = ObjectSpec(name=named.stem, kind="mesh", source=str(path), scale=1.0 if scale is None else scale,
                          up=default_up(path))
        found = mesh_sidecar(named)
        given = given.over(Physical.checked(read_toml(found), str(found)) if found is not None else NO_PHYSICAL)
    else:
        raise UnknownNameError("object", name,
                               [*builtin, f"{RANDOM_PREFIX}000..{RANDOM_PREFIX}999", "or a mesh file path"])
    if label:
        spec = replace(spec, name=label)
    return with_physical(spec, given)


def with_physical(spec: ObjectSpec, physical: Physical) -> ObjectSpec:
    """``spec`` with the properties ``physical`` gives (a mass clears a density)."""
    overrides: dict[str, float | str | None] = dict(physical.given())
    if physical.mass is not None:
        overrides["density"] = None
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


def edited_since(source: Path, finished: float | None) -> bool:
    """Whether the mesh file ``source`` (or a buffer file of a ``.gltf``, :func:`gltf_buffers`) may have changed
    since ``finished`` (its object's last unit's end [s]; :meth:`~planner.db.store.Database.last_finished`):
    modified from that second on, no time known, or no file to read. A copy that keeps an older modification time
    is not seen."""
    try:
        return finished is None or any(f.stat().st_mtime >= finished
                                       for f in [source, *(b for b in gltf_buffers(source) if b.exists())])
    except OSError:
        return True


def gltf_buffers(path: Path) -> list[Path]:
    """The files the buffers of a ``.gltf`` name, where its geometry is
    (relative to it, each as written and URL-decoded: loaders differ; embedded
    ``data:`` buffers are in the file itself); [] for any other file, or one
    that is not glTF JSON (its loader says why)."""
    if path.suffix.lower() != ".gltf":
        return []
    try:
        data = json.loads(path.read_bytes())
    except (OSError, ValueError):
        return []
    buffers = data.get("buffers", []) if isinstance(data, dict) else []
    uris = [b.get("uri") for b in buffers if isinstance(b, dict)] if isinstance(buffers, list) else []
    names = [u for u in uris if isinstance(u, str) and u and not u.startswith("data:")]
    return [path.parent / n for n in dict.fromkeys(n for u in names for n in (u, unquote(u)))]
