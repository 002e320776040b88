"""The hand and the object an ACRONYM grasp file names, as ``grasp import``
and ``grasp calibrate`` both read them (the rules: :mod:`planner.datasets.importer`).

A relative ``object/file`` is looked up from the .h5 file's absolute path
(next to it, then one folder up), so a file given as ``r3.h5`` from inside
ACRONYM's ``grasps/`` finds ``../meshes/``. What an error suggests depends on
the command: ``import`` has ``--object``, ``calibrate`` has not (``HINTS``).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from planner.datasets.acronym import AcronymHeader
from planner.errors import InputError
from planner.geometry.solid import prepare
from planner.record.field import same_com, same_inertia
from planner.specs.hands import hand_names
from planner.specs.objects import (
    DEFAULT_FRICTION,
    DEFAULT_MASS,
    PROPERTY_RTOL,
    ObjectSpec,
    file_values,
    is_registered,
    resolve_spec,
)
from planner.specs.up import up_axis

HAND_ALIASES = {"panda": "panda", "franka_panda": "panda"}
#: What to do about a file whose object cannot be found, per command.
HINTS = {"import": "pass --object NAME or a mesh path",
         "calibrate": "put the mesh there, or set object/file to its path"}


def hand_name(path: Path, gripper: str) -> str:
    """The hand ``gripper/type`` names ("panda" and "franka_panda" mean ``panda``)."""
    name = HAND_ALIASES.get(gripper.lower(), gripper)
    if not gripper:
        raise InputError(f"{path}: no 'gripper/type' dataset says which hand made its grasps; pass --hand "
                         f"(available hands: {', '.join(hand_names())})")
    if name not in hand_names():
        raise InputError(f"{path}: gripper type '{gripper}' is not a known hand; pass --hand "
                         f"(available hands: {', '.join(hand_names())})")
    return name


def object_spec(h: AcronymHeader, object_name: str | None, command: str = "import", up: str | None = None,
                mass: float | None = None, friction: float | None = None) -> ObjectSpec:
    """The object an ACRONYM header names (see :mod:`planner.datasets.importer`); ``command``: whose hint an
    error gives (a key of :data:`HINTS`); ``up``, ``mass`` [kg], ``friction``: the object's where the file gives
    none (``grasp import --up``, ``--mass``, ``--friction``; a file's own ``object/up``, ``object/mass``,
    ``object/friction`` are what its grasps were measured with: another is refused).
    A built-in ``object/name`` is taken where its mesh is the file's:
    ``object/mesh_sha256``, or without one the file's own ``object/file`` where it is found (a user's file
    naming its own mesh 'box' was fitted on the built-in box)."""
    if up is not None and h.up is not None and up_axis(up, "", "--up") != h.up:
        raise InputError(f"{h.path}: its object/up is {h.up}, and --up gives {up_axis(up, '', '--up')}: its grasps "
                         "were measured about the file's; leave --up out for this file")
    for key, given, own in (("mass", mass, h.mass), ("friction", friction, h.friction)):
        if given is not None and own is not None and not math.isclose(given, own, rel_tol=PROPERTY_RTOL):
            raise InputError(f"{h.path}: its object/{key} is {own:g}, and --{key} gives {given:g}: its grasps were "
                             f"measured with the file's; leave --{key} out for this file (--{key} is one value "
                             f"for every file of the command: give it in a command of the files without object/{key})")
    props = {"mass": h.mass if h.mass is not None else mass,
             "friction": h.friction if h.friction is not None else friction, "up": h.up if h.up is not None else up}
    return _with_inertial(h, _object_spec(h, object_name, command, props))


def unstated(h: AcronymHeader, spec: ObjectSpec, command: str = "import",
             given: tuple[float | None, float | None] = (None, None)) -> str | None:
    """The line said where the file gives no ``object/mass`` or ``object/friction`` and the run (``given``: its
    mass and friction) none either: the values the object ``spec`` is taken at (its file's sidecar's, the
    registry's, else the defaults), which every measure and trial of its grasps reads; None where nothing is
    missing."""
    missing = [key for key, run in zip(("mass", "friction"), given) if getattr(h, key) is None and run is None]
    if not missing:
        return None
    obj = prepare(spec)
    used = {"mass": f"mass {obj.mass:g} kg", "friction": f"friction {obj.friction:g}"}
    defaults = {"mass": DEFAULT_MASS, "friction": DEFAULT_FRICTION}
    default = all(math.isclose(getattr(obj, key), defaults[key]) for key in missing)
    how = ("pass " + " and ".join(f"--{key}" for key in missing)) if command == "import" else \
        "set " + " and ".join(f"object/{key}" for key in missing) + " in the file"
    said = ", ".join(used[key] for key in missing) + (f" (the default{'s' * (len(missing) > 1)})" if default else "")
    return (f"{h.path}: no {' or '.join(f'object/{key}' for key in missing)}: object '{spec.name}' is taken at "
            f"{said}; if it is not the object's own, {how}")


def unstated_up(h: AcronymHeader, spec: ObjectSpec, up: str | None = None) -> str | None:
    """The line said where the file gives no ``object/up``, the run (``up``: its ``--up``) none either and the
    object is a user's file whose sidecar gives none: the up ``spec`` is taken standing on (its file's default,
    ``+z`` for an OBJ), which its grip measures, p_hold and the MuJoCo trial's weight read. ACRONYM's own meshes
    stand on ``+y``: untold, they were measured lying on their side. None where the up is known."""
    if h.up is not None or up is not None or not spec.user_file:
        return None  # a built-in's up is the registry's (every one Z-up)
    if any("up" in given for _, given in file_values(spec.source, spec)):
        return None
    kind = Path(spec.source).suffix.lower() or "mesh"
    return (f"{h.path}: no object/up: object '{spec.name}' is taken standing on {spec.up} (a {kind} file's "
            f"default); if it stands on another axis, pass --up AXIS (ACRONYM's own meshes stand on +y: --up +y)")


def replaced(h: AcronymHeader, spec: ObjectSpec) -> str | None:
    """The line said where the file's own ``object/mass``, ``object/friction`` or ``object/up`` replaces another
    value the sidecar beside its mesh gives (its grasps were measured with the file's; ``grasp generate`` on the
    mesh takes the sidecar's); None where none does."""
    own = {"mass": h.mass, "friction": h.friction, "up": h.up}
    said = []
    for where, given in file_values(spec.source, spec):
        for key, value in own.items():
            other = given.get(key)
            if value is None or other is None or _same(key, value, other):
                continue
            said.append(f"its object/{key} {value:g} replaces {where}'s {key} {other:g}" if key != "up" else
                        f"its object/up {value} replaces {where}'s up {other}")
    return f"{h.path}: {'; '.join(said)} (its grasps were measured with the file's)" if said else None


def _same(key: str, value: object, other: object) -> bool:
    return value == other if key == "up" else math.isclose(float(value), float(other),  # type: ignore[arg-type]
                                                           rel_tol=PROPERTY_RTOL)


def _with_inertial(h: AcronymHeader, spec: ObjectSpec) -> ObjectSpec:
    """``spec`` with the centre of mass and inertia this project's own file (one with ``object/mesh_sha256``)
    gives where they are not its mesh's at uniform density (a URDF's or a sidecar's when it was planned): its
    grasps' measures and trials were of those. Other ACRONYM files' (their mesh's) are not read."""
    if h.mesh_sha256 is None or h.com is None:
        return spec
    if spec.com is not None:
        return spec  # given here (a sidecar beside the mesh)
    mesh = prepare(spec)
    moved = not same_com(h.com, mesh.com)
    gyration = None
    if h.inertia is not None and h.mass is not None:  # its own (a URDF's) also where its centre is the mesh's
        if moved or not same_inertia(mesh.inertia, np.reshape(h.inertia, (3, 3)) * (mesh.mass / h.mass)):
            gyration = tuple(v / h.mass for v in h.inertia)
    if not moved and gyration is None:
        return spec  # the mesh's own (or the spec's, a URDF's)
    return replace(spec, gyration=gyration) if not moved else \
        replace(spec, com=h.com, com_from=f"{Path(h.path).name} object/com", gyration=gyration)


def _object_spec(h: AcronymHeader, object_name: str | None, command: str, props: dict) -> ObjectSpec:
    if object_name is not None:
        if is_registered(object_name):
            return resolve_spec(object_name, **props)
        return resolve_spec(object_name, scale=h.scale, **props)
    label = h.object_name
    if label is not None and is_registered(label):
        builtin = resolve_spec(label, **props)
        # without a hash, the file's own mesh (where found) says which mesh its grasps are of
        own = None if h.mesh_sha256 else _own_mesh(h, props, None)
        wanted = h.mesh_sha256 or (prepare(own).mesh_hash if own is not None else None)
        if wanted is None or prepare(builtin).mesh_hash == wanted:
            return builtin
        if own is not None:
            return own
    return _own_mesh(h, props, command)  # type: ignore[return-value]


def _own_mesh(h: AcronymHeader, props: dict, command: str | None) -> ObjectSpec | None:
    """``object/file`` at ``object/scale`` under the name ``object/name`` or the .h5 file's stem, looked up next to
    the .h5 file, then one folder up; not found: None if ``command`` is None, else refused with its hint."""
    if h.object_file is None:
        if command is None:
            return None
        raise InputError(f"{h.path}: no object/file; {HINTS[command]}")
    here = Path(h.path).absolute()  # Path('r3.h5').parent.parent is '.', not the folder above
    tried = [here.parent / h.object_file, here.parent.parent / h.object_file]
    found = next((p for p in tried if p.is_file()), None)
    if found is not None:
        return resolve_spec(str(found), scale=h.scale, label=h.object_name or h.path.stem, **props)
    if command is None:
        return None
    raise InputError(f"{h.path}: object/file '{h.object_file}' not found (looked at {', '.join(map(str, tried))}); "
                     f"{HINTS[command]}")
