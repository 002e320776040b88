"""Mass properties for grasp analysis: the torque scale rho [m] of an object
(eq 2.3 and the two choices after it). Pure numpy; ``planner.quality``
re-exports both functions.

* largest distance from the centre of mass to the object (GraspIt's
  maxRadius): then a unit force anywhere yields at most unit scaled torque.
* radius of gyration k: the mass-weighted spread of the body.  Define k by
  m k^2 = I_avg, the mean principal moment of inertia about the centre of
  mass.  Since trace(I) = sum_i m_i (3|r_i|^2 - |r_i|^2) = 2 sum_i m_i |r_i|^2,
      k = sqrt(trace(I) / (3 m)).
  (The polar radius sqrt(trace(I) / (2 m)), the RMS distance of mass from the
  COM, is larger by sqrt(3/2); we use the mean-principal-moment one.)  For a
  solid sphere of radius R, k = sqrt(2/5) R.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from planner.errors import InputError, MeshError
from planner.geometry.tolerances import INERTIA_TOL


def torque_scale_max_distance(vertices: ArrayLike, com: ArrayLike) -> float:
    """max_v |v - com| [m] over mesh vertices (v, 3) [m]; com : (3,) [m]."""
    verts = np.asarray(vertices, dtype=float)
    centre = np.asarray(com, dtype=float)
    if verts.ndim != 2 or verts.shape[1] != 3 or len(verts) == 0:
        raise MeshError(f"vertices must have shape (v, 3) with v >= 1, got {verts.shape}")
    if centre.shape != (3,):
        raise MeshError(f"com must have shape (3,), got {centre.shape}")
    if not (np.isfinite(verts).all() and np.isfinite(centre).all()):
        raise MeshError("vertices or com contain NaN or infinite values")
    rho = float(np.linalg.norm(verts - centre, axis=1).max())
    if rho <= 0:
        raise MeshError("all vertices coincide with the centre of mass; rho would be 0")
    return rho


def radius_of_gyration(mass: float, inertia: ArrayLike) -> float:
    """k = sqrt(trace(I) / (3 m)) [m]; mass [kg] > 0, inertia (3, 3) [kg m^2]
    about the centre of mass, symmetric positive semi-definite."""
    m = float(mass)
    tensor = np.asarray(inertia, dtype=float)
    if not np.isfinite(m) or m <= 0:
        raise InputError(f"mass must be a positive number of kg, got {mass!r}")
    if tensor.shape != (3, 3) or not np.isfinite(tensor).all():
        raise InputError(f"inertia must be a finite (3, 3) array, got shape {tensor.shape}")
    size = max(float(np.abs(tensor).max()), np.finfo(float).tiny)
    if np.abs(tensor - tensor.T).max() > INERTIA_TOL * size:
        raise InputError("inertia must be symmetric")
    if np.linalg.eigvalsh(tensor).min() < -INERTIA_TOL * size or np.trace(tensor) <= 0:
        raise InputError("inertia must be positive semi-definite with a positive trace")
    return float(np.sqrt(np.trace(tensor) / (3.0 * m)))
