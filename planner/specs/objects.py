"""Objects to grasp: the built-in registry (``objects/objects.toml``), the
procedurally generated ``random_NNN`` objects, user mesh files and URDF files.

An :class:`ObjectSpec` says where an object's mesh comes from and its
physical parameters; :mod:`planner.geometry.solid` turns it into a checked
solid. The object frame is the frame of the (scaled) mesh file, as in
ACRONYM (a URDF's: its root link's): every grasp pose in the database is
expressed in it. Lengths in metres, masses in kilograms.

An object's mass (or density) and friction come, the first that gives them:
a manifest line's columns, ``grasp generate --mass/--density/--friction``
(every object of the run), a TOML sidecar beside a mesh file
(``banana.obj`` + ``banana.toml`` with ``mass``, ``density``, ``friction``;
``obj.urdf`` + ``obj.toml``), a URDF file's own (its ``<inertial>`` mass,
its ``<lateral_friction>``: :meth:`~planner.specs.urdf_objects.UrdfObject.own`),
the registry entry, else :data:`DEFAULT_MASS` and :data:`DEFAULT_FRICTION`.
Mass and density are one property given two ways: a source gives one or
the other, never both, and the first source that gives either decides. Its
``up`` (:mod:`planner.specs.up`) comes from the same sources, else
:func:`~planner.specs.up.default_up` of its file (``+y`` for glTF, else ``+z``).
Its centre of mass ``com`` (object frame [m]) too: a manifest line's
``com=x,y,z``, a sidecar's ``com = [x, y, z]``, a URDF's ``<inertial>``
origins where they declare one (:mod:`planner.specs.urdf_inertial`: times
``--scale``, which scales the whole object about its frame's origin), else
the closed mesh's at uniform density; a URDF's inertia is its ``<inertial>``
tensors' (times the mass given over the file's, times ``--scale`` squared)
where :mod:`planner.geometry.inertial` finds it plausible. A URDF file is made
of its ``<collision>`` elements unless ``geometry = "visual"`` is given (a
manifest's ``geometry=visual``, ``--geometry visual``).
"""

from __future__ import annotations

import math
import os
import stat
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from planner import assets
from planner.errors import ConfigError, InputError, UnknownNameError
from planner.specs.physical import GEOMETRIES, NO_PHYSICAL, Physical, Value, Vector
from planner.specs.toml import Fields, read_toml
from planner.specs.up import DEFAULT_UP, default_up
from planner.specs.urdf_objects import URDF_SUFFIX, read_urdf_object

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
#: Files an object may be given as: a mesh file or a URDF.
OBJECT_SUFFIXES = (*MESH_SUFFIXES, URDF_SUFFIX)
#: The kind of a user's URDF file: its links' geometry merged (:mod:`planner.specs.urdf_objects`), stored as the
#: URDF itself. A registry entry of kind ``urdf`` is one mesh of a URDF, stored as that mesh file.
URDF_FILE = "urdf_file"
#: The suffix of a physical-properties sidecar (``banana.toml`` beside ``banana.obj``).
SIDECAR_SUFFIX = ".toml"


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
    stems = {p.stem for p in files if p.suffix.lower() in OBJECT_SUFFIXES}
    for p in files:
        if p.suffix.lower() == SIDECAR_SUFFIX and p.suffix not in (SIDECAR_SUFFIX, SIDECAR_SUFFIX.upper()):
            odd.setdefault(p.stem, []).append(p)
        if p.suffix.lower() == SIDECAR_SUFFIX and p.stem not in stems:
            lost.setdefault(p.stem.lower(), []).append(p)
    return {k: tuple(v) for k, v in odd.items()}, {k: tuple(v) for k, v in lost.items()}


@dataclass(frozen=True)
class ObjectSpec:
    """Where an object comes from and its physical parameters.

    ``kind`` is ``mesh`` (a mesh file), ``urdf`` (a registry entry: the mesh
    a URDF link declares, with the URDF's scale), :data:`URDF_FILE` (a user's
    URDF file, ``geometry`` the elements it is made of) or a primitive
    (``box``, ``cylinder``, ``sphere`` with ``dims`` in metres). ``com`` (3,)
    [m] a given centre of mass in the object frame (None: the mesh's),
    ``com_from`` who gave it; ``gyration`` (9,) [m^2] a URDF's inertia per kilogram
    about the centre of mass, object axes, row by row (None: the mesh's).
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
    com: Vector | None = None
    com_from: str = ""
    gyration: tuple[float, ...] | None = None

    @property
    def user_file(self) -> bool:
        """Whether the object is a user's file, a mesh or a URDF, named by its path."""
        return self.kind in ("mesh", URDF_FILE)


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
                 up: str | None = None, com: Vector | str | None = None, geometry: str | None = None,
                 scale_from: str = "--scale") -> ObjectSpec:
    """A built-in name, ``random_NNN``, or a path to a mesh or URDF file;
    ``label`` renames it (two files of one run with the same stem). ``mass``
    (or ``density``), ``friction``, ``up`` and ``com`` override the object's own, a file's
    from its sidecar, a URDF's own (see the module docstring); ``geometry`` makes a URDF file of its
    ``<visual>`` elements (another object's is refused). ``scale_from``: what gave
    ``scale``, for the error of a primitive, which takes none."""
    given = Physical.checked({"mass": mass, "density": density, "friction": friction, "up": up, "com": com,
                              "geometry": geometry}, f"object '{name}'")
    com_from = "as given" if given.com is not None else ""
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
    elif (path := file_named(name)) is not None and Path(name).suffix.lower() == URDF_SUFFIX:
        spec, given, com_from = _urdf_spec(Path(name).expanduser(), path, scale, given, com_from)
    elif path is not None:
        # named as given and its sidecar beside it (a symlink's own name and folder; the target's sidecar where
        # the link has none); the source is the file itself, whatever path names it
        named = Path(name).expanduser()
        spec = ObjectSpec(name=named.stem, kind="mesh", source=str(path), scale=1.0 if scale is None else scale,
                          up=default_up(path))
        found = mesh_sidecar(named)
        given, com_from = _over_sidecar(given, com_from, found)
    else:
        raise UnknownNameError("object", name,
                               [*builtin, f"{RANDOM_PREFIX}000..{RANDOM_PREFIX}999", "or a mesh or URDF file path"])
    if given.geometry is not None and spec.kind != URDF_FILE:
        raise InputError(f"object '{name}': geometry {given.geometry} chooses a URDF file's elements; "
                         f"{spec.name} is {'a mesh file' if spec.kind == 'mesh' else 'a registry object'}")
    if label:
        spec = replace(spec, name=label)
    spec = with_physical(spec, given)
    return replace(spec, com_from=com_from) if spec.com is not None else spec


def _over_sidecar(given: Physical, com_from: str, found: Path | None) -> tuple[Physical, str]:
    """``given`` over the sidecar ``found`` (None: none), and who gives the centre of mass."""
    if found is None:
        return given, com_from
    side = Physical.checked(read_toml(found), str(found))
    return given.over(side), com_from or (found.name if side.com is not None else "")


def file_named(name: str) -> Path | None:
    """The source of the object a user's mesh or URDF file ``name`` is, as :func:`resolve_spec` takes it (its stem
    names the object): a mesh file itself, whatever path names it (resolved); a URDF where it is named, its folder
    resolved but not the file (a link into a content store, whose files each sit alone in a folder): its meshes
    are found beside the path that names it, as PyBullet finds them. None for a built-in name or ``random_NNN``,
    which come first, or a name that is no such path. Reads no file: a stored object is found by its file where
    the file's own values are refused now (a URDF's mass 0, planned with ``--mass``)."""
    if is_registered(name):
        return None
    named = Path(name).expanduser()
    if named.suffix.lower() == URDF_SUFFIX:
        return Path(os.path.abspath(named)).parent.resolve() / named.name
    return named.resolve() if named.suffix.lower() in MESH_SUFFIXES or named.exists() else None


def _urdf_spec(named: Path, path: Path, scale: float | None, given: Physical, com_from: str
               ) -> tuple[ObjectSpec, Physical, str]:
    """The spec of the URDF file ``named`` (``path``: :func:`file_named`), the properties the run ``given``, over
    its sidecar's, over its own, and who gives its centre of mass; its mesh files checked to be of a type the
    planner reads."""
    if not named.is_file():
        raise InputError(f"{named}: file not found")
    given, com_from = _over_sidecar(given, com_from, mesh_sidecar(named))
    own = read_urdf_object(path, given.geometry or GEOMETRIES[0])
    if given.geometry is not None and own.geometry != given.geometry:
        raise InputError(f"{path}: geometry {given.geometry} is given and it has no <{given.geometry}> element")
    odd = next((p for p in own.parts if p.file is not None and p.file.suffix.lower() not in MESH_SUFFIXES), None)
    if odd is not None and odd.file is not None:
        raise InputError(f"{path}: link '{odd.link}': {odd.file.name}: unsupported mesh type '{odd.file.suffix}'; use "
                         f"one of {', '.join(MESH_SUFFIXES)} (convert it, e.g. in Blender or MeshLab)")
    factor = 1.0 if scale is None else scale
    spec = ObjectSpec(name=named.stem, kind=URDF_FILE, source=str(path), scale=factor, geometry=own.geometry)
    if own.inertial is not None:  # the whole object scaled about its frame's origin: its inertia per kg as length^2
        spec = replace(spec, gyration=tuple(float(v) for v in np.ravel(own.inertial.inertia) / own.inertial.mass
                                            * factor ** 2))
    if given.com is None and own.com is not None:
        x, y, z = (v * factor for v in own.com)
        if not all(math.isfinite(v) for v in (x, y, z)):
            raise InputError(f"{path}: its <inertial> origins give no finite centre of mass (a nan or inf value); give "
                             f"its own as com = [x, y, z] [m, object frame] in a sidecar ({path.stem}.toml)")
        given, com_from = replace(given, com=(x, y, z)), f"{path.name} <inertial><origin>"
    return spec, given.over(own.own(given)), com_from


def with_physical(spec: ObjectSpec, physical: Physical) -> ObjectSpec:
    """``spec`` with the properties ``physical`` gives (a mass clears a density)."""
    overrides: dict[str, object] = dict(physical.given())
    if physical.mass is not None:
        overrides["density"] = None
    return replace(spec, **overrides) if overrides else spec


def file_values(named: str, spec: ObjectSpec) -> list[tuple[str, dict[str, Value]]]:
    """The values the files of the user's file ``named`` (as the run names it; ``spec`` its object) give,
    first first, each with its file's name: its sidecar's, then a URDF's own
    (:meth:`~planner.specs.urdf_objects.UrdfObject.stated`, unchecked; its centre of mass scaled by the run's
    ``--scale``, as a sidecar's is given); [] for other objects."""
    if not spec.user_file or not spec.source:
        return []
    found = mesh_sidecar(Path(named))
    out = [] if found is None else [(found.name, Physical.checked(read_toml(found), str(found)).given())]
    if spec.kind == URDF_FILE:  # its centre as the scaled object has it, as the sidecar's is given (--scale)
        stated = read_urdf_object(Path(spec.source), spec.geometry).stated()
        if "com" in stated:
            stated["com"] = tuple(float(v) * spec.scale for v in stated["com"])  # type: ignore[union-attr]
        out.append((Path(spec.source).name, stated))
    return out


PRIMITIVES = ("box", "cylinder", "sphere")


def source_path(spec: ObjectSpec) -> Path:
    """The file whose bytes define the object (the URDF for ``urdf`` objects)."""
    if spec.source.startswith(assets.PYBULLET_DATA_PREFIX):
        return assets.resolve(spec.source, assets.project_dir("objects"), f"object '{spec.name}'")
    return Path(spec.source)


def urdf_mesh(spec: ObjectSpec) -> tuple[Path, float]:
    """A registry ``urdf`` object's mesh file and the URDF's own scale of it."""
    return read_urdf_object(source_path(spec), spec.geometry).single_mesh()


def file_scale(spec: ObjectSpec) -> float:
    """The factor turning the file the object is stored as into metres: the registry's ``scale`` times, for its
    URDF objects, the URDF's own ``<mesh scale>``; a URDF file's, the ``--scale`` of the whole."""
    if spec.kind in PRIMITIVES:
        return 1.0
    if spec.kind == "urdf":
        return urdf_mesh(spec)[1] * spec.scale
    return spec.scale
