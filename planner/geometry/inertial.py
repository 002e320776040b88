"""A given centre of mass and inertia (:attr:`~planner.specs.objects.ObjectSpec.com`, ``gyration``) checked
against the object's closed mesh.

A centre of mass outside the mesh's convex hull cannot be the object's (its mass lies within it): refused, one
line naming the file, the value and who gave it. An inertia that cannot be a body's of that mass within that
mesh is a placeholder (pybullet_data's objects all carry 1 kg m^2 moments on 0.05-10 kg bodies a few
centimetres across, some a zero one): the mesh's is kept and said so, since refusing would refuse every such
file for a value a user rarely meant. A body's inertia about its centre of mass is symmetric, positive definite
(a solid, not a rod or a point), its principal moments meet the triangle inequality (``I_a <= I_b + I_c``), and
``trace(I) = 2 sum m_i |r_i|^2 <= 2 m rho^2``, ``rho`` the largest distance from the centre to the mesh.
Where only the centre of mass is given, the inertia is the mesh's at uniform density about its own centroid,
moved unchanged to the given centre (not by the parallel-axis theorem, which would give the inertia of a body
whose centre is elsewhere).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from planner import prepare
from planner.errors import InputError
from planner.geometry.tolerances import HULL_TOL, INERTIA_TOL
from planner.specs.objects import ObjectSpec

#: The notes said in this process.
_SAID: set[tuple[str, str]] = set()


def given_inertial(spec: ObjectSpec, mesh: trimesh.Trimesh, com: np.ndarray, inertia: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The object's centre of mass (3,) [m] and inertia (3, 3) [kg m^2] about it, object frame: ``spec``'s given
    ones where it gives them (checked: the module docstring), else the mesh's ``com`` and ``inertia``."""
    if spec.com is not None:
        com = np.asarray(spec.com, float)
        outside = hull_distance(mesh, com)
        if outside > HULL_TOL:
            raise InputError(f"{spec.source or spec.name}: its centre of mass {_shown(com)} m ({spec.com_from}) lies "
                             f"{outside * 1e3:.3g} mm outside the object's convex hull, where none of its mass is; "
                             f"give its own as com = [x, y, z] [m, object frame] in a sidecar ({_stem(spec)}.toml) "
                             "or a manifest's com=x,y,z")
    if spec.gyration is not None:
        tensor = spec.mass * np.asarray(spec.gyration, float).reshape(3, 3)
        rho = float(np.linalg.norm(np.asarray(mesh.vertices) - com, axis=1).max())
        why = implausible(tensor, spec.mass, rho)
        if why is None:
            return com, tensor
        said = (f"object '{spec.name}'", f"{_file(spec)}'s <inertia> is not a body's of {spec.mass:g} kg within its "
                                         f"mesh ({why}): the mesh's at uniform density is used")
        if said not in _SAID:  # once per process: an object is prepared by the run's plan and again by its units
            _SAID.add(said)
            prepare.noted(*said)
    return com, inertia


def hull_distance(mesh: trimesh.Trimesh, point: np.ndarray) -> float:
    """How far [m] ``point`` (3,) lies outside ``mesh``'s convex hull along the normal of its farthest face
    plane (a lower bound of its distance; <= 0 inside)."""
    hull = mesh.convex_hull
    return float(np.max(np.einsum("ij,ij->i", hull.face_normals, point - hull.triangles[:, 0])))


def implausible(inertia: np.ndarray, mass: float, rho: float) -> str | None:
    """Why ``inertia`` (3, 3) [kg m^2] cannot be a solid's of ``mass`` [kg] whose points lie within ``rho`` [m]
    of its centre of mass (the module docstring); None where it can."""
    size = max(float(np.abs(inertia).max()), np.finfo(float).tiny)
    if not np.isfinite(inertia).all() or np.abs(inertia - inertia.T).max() > INERTIA_TOL * size:
        return "not symmetric"
    moments = np.linalg.eigvalsh(inertia)
    if moments.min() <= INERTIA_TOL * size:
        return f"principal moments {_shown(moments)} kg m^2, not positive"
    if moments[2] > (moments[0] + moments[1]) * (1 + INERTIA_TOL):
        return f"principal moments {_shown(moments)} kg m^2 break the triangle inequality"
    bound = 2 * mass * rho ** 2
    if np.trace(inertia) > bound * (1 + INERTIA_TOL):
        return (f"trace {np.trace(inertia):.3g} kg m^2, more than {bound:.3g} with all its mass at the mesh's "
                "farthest point")
    return None


def _shown(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.4g}" for v in np.ravel(values)) + "]"


def _file(spec: ObjectSpec) -> str:
    return Path(spec.source).name if spec.source else spec.name


def _stem(spec: ObjectSpec) -> str:
    return Path(spec.source).stem if spec.source else spec.name
