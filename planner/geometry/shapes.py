"""Objects made of shapes: the primitives (box, cylinder, sphere) as meshes,
and a URDF object's parts placed in its frame and merged into one solid.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

from planner import prepare
from planner.geometry.mesh import checked_solid, read_mesh_file
from planner.specs.urdf_objects import UrdfObject

#: Faces around a cylinder; subdivisions of a sphere (642 vertices: within 0.2% of its radius).
CYLINDER_SECTIONS = 48
SPHERE_SUBDIVISIONS = 3
#: [m] A URDF's undeclared centre of mass (its link origins) farther than this from its mesh's is said: 1 mm is
#: visible in a grip's lever, and pybullet_data's centred primitives and meshes lie within 1 mm of theirs.
TEMPLATE_NOTED = 1e-3


def primitive_mesh(kind: str, dims: Sequence[float]) -> trimesh.Trimesh:
    """A ``box`` (dims: (3,) extents), ``cylinder`` (radius, height along z) or ``sphere`` (radius) [m],
    centred on the origin."""
    if kind == "box":
        return trimesh.creation.box(extents=dims)
    if kind == "cylinder":
        radius, height = dims
        return trimesh.creation.cylinder(radius=radius, height=height, sections=CYLINDER_SECTIONS)
    if kind == "sphere":
        return trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=dims[0])
    raise ValueError(f"unknown primitive {kind!r}")


def urdf_solid(urdf: UrdfObject, scale: float = 1.0) -> trimesh.Trimesh:
    """The checked solid of a URDF object: each part (a mesh file at its per-axis scale, or a primitive) placed
    by its pose in the object frame, all of them one mesh, times ``scale`` about the frame's origin [m]. Parts
    that overlap stay as they are: the object's mass properties are their union's
    (:func:`~planner.geometry.mesh.union_of_bodies`)."""
    vertices, faces, count = [], [], 0
    for part in urdf.parts:
        piece = read_mesh_file(part.file, np.asarray(part.scale)) if part.file is not None else \
            primitive_mesh(part.shape, part.dims)
        points = np.asarray(piece.vertices, float)
        vertices.append((points @ part.pose[:3, :3].T + part.pose[:3, 3]) * scale)
        faces.append(np.asarray(piece.faces) + count)
        count += len(points)
    if urdf.geometry != "collision":
        prepare.noted(str(urdf.path), "it has no <collision> element: its <visual> geometry is planned on (once: "
                                      "cached afterwards)")
    solid = checked_solid(trimesh.Trimesh(np.concatenate(vertices), np.concatenate(faces), process=False),
                          str(urdf.path))
    _note_template_origin(urdf, solid, scale)
    return solid


def _note_template_origin(urdf: UrdfObject, solid: trimesh.Trimesh, scale: float) -> None:
    """Say where a URDF's <inertial> origins, all at their link origins (a template's: no declared centre of
    mass, :mod:`planner.specs.urdf_inertial`), put its centre farther than :data:`TEMPLATE_NOTED` from the mesh's,
    which is planned on, where PyBullet would take the origins."""
    if urdf.inertial is None or urdf.inertial.declared:
        return
    origins = urdf.inertial.com * scale
    apart = float(np.linalg.norm(np.asarray(solid.center_mass) - origins))
    if apart > TEMPLATE_NOTED:
        shown = ", ".join(f"{v:.4g}" for v in origins)
        prepare.noted(str(urdf.path), f"its <inertial> origins lie at their link origins ([{shown}] m), read as a "
                                      f"template's, not a centre of mass: its mesh's, {apart * 1e3:.3g} mm away, is "
                                      f"planned on (PyBullet takes the origins; com = [{shown}] in "
                                      f"{urdf.path.stem}.toml plans on them) (once: cached afterwards)")
