"""A URDF object's centre of mass and inertia, its links' ``<inertial>`` elements made one rigid body's.

Each link's ``<inertial>`` places its centre of mass at its ``<origin xyz>`` in the link frame (metres: a
``<mesh scale>`` does not act on it) with its ``<inertia>`` about that point in the axes its ``<origin rpy>``
turns; the link sits in the object frame (the root link's) by its chain of fixed joints, as its geometry does.
The links make one body: the centre of mass is their mass-weighted mean, the inertia their tensors turned into
the object's axes and moved to that centre by the parallel-axis theorem,
``I = sum_i R_i I_i R_i^T + m_i (|d_i|^2 E - d_i d_i^T)``, ``d_i`` from the body's centre to the link's.

Whether the file *declares* a centre of mass: of the 14 pybullet_data object URDFs bench/urdf_objects.py reads,
11 write ``<origin xyz="0 0 0">`` as a template does (the mug's lies on its base, 50 mm below its mesh's centre);
the three that write another (the duck, the teddy, xarm's link6) lie 5-17 mm from their meshes' centres, inside
them. So an origin off its link origin on some link with mass is a declaration, and every link's is then read as
written (as PyBullet reads them); origins all at their link origins, written or not, declare nothing: the mesh's
centre of mass is planned on (:mod:`planner.geometry.shapes` says where they lie far apart).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: [m] An ``<inertial><origin xyz>`` no farther than this from its link origin is that origin: a template's zero
#: written as 1e-12 by an exporter is no declaration.
DECLARED_TOL = 1e-9


@dataclass(frozen=True)
class LinkInertial:
    """One link's ``<inertial>``: ``mass`` [kg]; ``pose`` (4, 4) its frame in the object frame [m] (the link's
    frame times its ``<origin>``); ``inertia`` (3, 3) [kg m^2] about its origin in its axes; ``offset``: whether
    its ``<origin xyz>`` is off the link origin (more than :data:`DECLARED_TOL`)."""

    mass: float
    pose: np.ndarray
    inertia: np.ndarray
    offset: bool


@dataclass(frozen=True)
class UrdfInertial:
    """The links' ``<inertial>`` elements as one rigid body's.

    Attributes:
        mass: [kg] the links' masses summed (> 0).
        com: (3,) [m] the centre of mass in the object frame (the root link's), unscaled.
        inertia: (3, 3) [kg m^2] about ``com``, object axes, for ``mass`` (unchecked: a file's placeholder).
        declared: whether some link with mass places its centre off its link origin (the module docstring).
    """

    mass: float
    com: np.ndarray
    inertia: np.ndarray
    declared: bool

    def __post_init__(self) -> None:
        com, inertia = np.array(self.com, float), np.array(self.inertia, float)
        if com.shape != (3,) or inertia.shape != (3, 3):
            raise ValueError(f"com must be (3,) and inertia (3, 3), got {com.shape} and {inertia.shape}")
        com.flags.writeable = inertia.flags.writeable = False
        object.__setattr__(self, "com", com)
        object.__setattr__(self, "inertia", inertia)


def link_inertial(mass: float, frame: np.ndarray, origin: np.ndarray | None, inertia: np.ndarray | None
                  ) -> LinkInertial:
    """A link's ``<inertial>``: ``frame`` (4, 4) the link in the object frame, ``origin`` (4, 4) its
    ``<origin>`` (None: the link's own), ``inertia`` (3, 3) its tensor (None where the file gives none: zero)."""
    local = np.eye(4) if origin is None else np.asarray(origin, float)
    tensor = np.zeros((3, 3)) if inertia is None else np.asarray(inertia, float)
    return LinkInertial(float(mass), np.asarray(frame, float) @ local, tensor,
                        not bool(np.linalg.norm(local[:3, 3]) <= DECLARED_TOL))  # nan: declared, refused


def combined(links: Sequence[LinkInertial]) -> UrdfInertial | None:
    """The links with a positive, finite mass as one body (the module docstring); None where none has one."""
    massive = [link for link in links if math.isfinite(link.mass) and link.mass > 0]
    if not massive:
        return None
    masses = np.array([link.mass for link in massive])
    centres = np.array([link.pose[:3, 3] for link in massive])
    total = math.fsum(masses)
    com = masses @ centres / total
    inertia = np.zeros((3, 3))
    for m, c, link in zip(masses, centres, massive):
        turn = link.pose[:3, :3]
        d = c - com
        inertia += turn @ link.inertia @ turn.T + m * (float(d @ d) * np.eye(3) - np.outer(d, d))
    return UrdfInertial(total, com, inertia, any(link.offset for link in massive))
