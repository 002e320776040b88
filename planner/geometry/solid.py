"""The prepared object: a checked closed mesh with its mass properties, and
the on-disk cache of checked meshes.

The object frame is the frame of the (scaled) mesh file. Volume, and the
centre of mass and inertia where the spec gives none (:mod:`planner.geometry.inertial`),
come from the closed mesh (the union of its bodies where they overlap) and the spec's mass
(uniform density); the torque scale rho and the radius of gyration come from
:mod:`planner.geometry.mass`.
"""

from __future__ import annotations

import hashlib
import io
import json
from dataclasses import dataclass, field, replace

import numpy as np
import trimesh

from planner import assets
from planner.errors import MeshError
from planner.geometry.inertial import given_inertial
from planner.geometry.mass import radius_of_gyration, torque_scale_max_distance
from planner.geometry.mesh import load_mesh_file, mesh_hash, union_of_bodies
from planner.geometry.shapes import primitive_mesh, urdf_solid
from planner.specs.object_files import object_files
from planner.specs.objects import (
    PRIMITIVES,
    URDF_FILE,
    ObjectSpec,
    file_scale,
    resolve_spec,
    source_path,
    urdf_mesh,
)
from planner.specs.up import up_vector
from planner.specs.urdf_objects import read_urdf_object

#: Bumped when the checked mesh of the same source would come out differently.
CACHE_VERSION = 3  # 2: the union of overlapping bodies cached beside the mesh; 3: flat bodies refused


@dataclass(frozen=True)
class PreparedObject:
    """A checked object ready for simulation and analysis.

    Attributes:
        mesh: closed triangle mesh in the object frame [m].
        source_file: the mesh file (``primitive:box`` etc. for primitives).
        file_scale: what turns ``source_file`` into this mesh (a URDF's mesh scale included).
        mesh_hash: sha256 of the geometry, the key of every cache.
        volume: [m^3]; density: [kg/m^3] (uniform).
        com: (3,) centre of mass in the object frame [m].
        inertia: (3, 3) inertia about the centre of mass, object axes [kg m^2].
        torque_scale: rho [m], largest distance from ``com`` to the surface
            (seed section 2.2.1).
        gyration_radius: radius of gyration [m], the other choice of rho
            (sqrt(trace(I) / (3 m)), from the mean principal moment).
        up: (3,) unit, object frame: the object's up as it stands (its spec's ``up``,
            :mod:`planner.specs.up`; the mesh stays in the file's frame).
    """

    spec: ObjectSpec
    mesh: trimesh.Trimesh = field(repr=False)
    source_file: str
    file_scale: float
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

    @property
    def up(self) -> np.ndarray:
        return up_vector(self.spec.up)


def load_object(name: str, *, label: str | None = None, **overrides: float | str | None) -> PreparedObject:
    """Resolve and prepare an object by name or mesh path."""
    return prepare(resolve_spec(name, label=label, **overrides))


def prepare(spec: ObjectSpec) -> PreparedObject:
    """The checked object; a spec with a ``density`` gets the mass density x volume."""
    mesh, source_file, union = _cached_mesh(spec)
    solid = mesh if union is None else union  # what the mass fills: overlapping bodies count once
    volume = float(solid.volume)
    if spec.density is not None:
        spec = replace(spec, mass=spec.density * volume)
    density = spec.mass / volume if spec.density is None else spec.density
    solid.density = density
    com, inertia = given_inertial(spec, mesh, np.asarray(solid.center_mass, float),
                                  np.asarray(solid.moment_inertia, float))
    return PreparedObject(
        spec=spec, mesh=mesh, source_file=source_file, file_scale=file_scale(spec), mesh_hash=mesh_hash(mesh),
        volume=volume, density=density, com=com, inertia=inertia,
        torque_scale=torque_scale_max_distance(mesh.vertices, com),
        gyration_radius=radius_of_gyration(spec.mass, inertia),
    )


def _cached_mesh(spec: ObjectSpec) -> tuple[trimesh.Trimesh, str, trimesh.Trimesh | None]:
    """The checked, repaired mesh, its source file and the union of its
    bodies where they overlap (:func:`~planner.geometry.mesh.union_of_bodies`),
    cached on disk by source content and scale (``.npz`` of plain arrays, no
    pickle) and shared by runs and workers."""
    if spec.kind in PRIMITIVES:
        return (*_build_mesh(spec), None)
    source = source_path(spec)
    if not source.is_file():
        raise MeshError(f"{source}: file not found")
    h = hashlib.sha256(json.dumps([CACHE_VERSION, spec.kind, spec.geometry, spec.scale]).encode())
    h.update(source.read_bytes())
    # the meshes a URDF points at matter as much as the URDF, and a .gltf's geometry is in the files it names
    for file in object_files(source, spec.geometry)[1:]:
        h.update(file.read_bytes() if file.is_file() else f"missing {file}".encode())
    path = assets.cache_dir("objects") / f"{h.hexdigest()[:24]}.npz"
    if path.is_file():
        try:
            with np.load(path, allow_pickle=False) as data:
                mesh = trimesh.Trimesh(data["vertices"], data["faces"], process=False)
                union = (trimesh.Trimesh(data["union_vertices"], data["union_faces"], process=False)
                         if "union_vertices" in data else None)
            # the file this spec names, not the cached one: the same bytes may have been cached from
            # another path (an earlier export folder, another environment's pybullet_data)
            return mesh, str(urdf_mesh(spec)[0] if spec.kind == "urdf" else source), union
        except (OSError, ValueError, KeyError):
            path.unlink(missing_ok=True)  # a damaged cache entry is rebuilt
    mesh, source_file = _build_mesh(spec)
    union = union_of_bodies(mesh, source_file)
    extra = {} if union is None else {"union_vertices": np.asarray(union.vertices),
                                      "union_faces": np.asarray(union.faces)}
    buffer = io.BytesIO()
    np.savez(buffer, vertices=np.asarray(mesh.vertices), faces=np.asarray(mesh.faces), source=np.array(source_file),
             **extra)
    assets.atomic_write(path, buffer.getvalue())
    return mesh, source_file, union


def _build_mesh(spec: ObjectSpec) -> tuple[trimesh.Trimesh, str]:
    """The checked mesh and the file it is stored as (``primitive:box`` ...; a URDF file itself, a registry URDF
    entry its mesh file)."""
    if spec.kind in PRIMITIVES:
        return primitive_mesh(spec.kind, spec.dims), f"primitive:{spec.kind}"
    path = source_path(spec)
    if spec.kind == "mesh":
        return load_mesh_file(path, spec.scale), str(path)
    if spec.kind == URDF_FILE:
        return urdf_solid(read_urdf_object(path, spec.geometry), spec.scale), str(path)
    mesh_file, scale = urdf_mesh(spec)
    return load_mesh_file(mesh_file, scale * spec.scale), str(mesh_file)
