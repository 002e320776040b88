"""The rows the store takes and gives besides the grasp record: an
object's (:class:`ObjectRow`), a unit of work's (:class:`UnitRow`) and
one grasp's validation results (:class:`Validated`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from planner.record.grasp import RobustEpsilon, Trial


@dataclass(frozen=True)
class ObjectRow:
    """An ``objects`` row: the stored object's file and physical properties.

    ``scale`` turns ``source`` (the mesh or URDF file) into metres; ``com`` (3,) [m]
    and ``inertia`` (3, 3) [kg m^2] about the COM are in the scaled mesh frame;
    ``mesh_sha256``: :func:`~planner.geometry.mesh.mesh_hash` of the checked mesh;
    ``up``: the axis of that frame that is up as the object stands (:data:`planner.specs.up.AXES`);
    ``geometry``: the elements of a URDF the object is made of, ``collision`` or ``visual``.
    """

    name: str
    source: str
    scale: float
    mass: float
    friction: float
    density: float
    volume: float
    com: np.ndarray
    inertia: np.ndarray
    mesh_sha256: str = ""
    up: str = "+z"
    geometry: str = "collision"

    def properties(self) -> dict[str, float]:
        """Density [kg/m^3], friction and mass [kg]: what a p_hold model's domain is checked on
        (:func:`planner.calibration.logistic.properties`)."""
        from planner.calibration.logistic import properties

        return properties(self)


@dataclass(frozen=True)
class UnitRow:
    """One unit of work as the ``units`` table holds it."""

    object: str
    hand: str
    settings_hash: str
    settings: str  # JSON
    seed: int
    chunk: int
    error: str | None = None
    candidates: int = 0
    rejected: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0


@dataclass(frozen=True)
class Validated:
    """What physical validation found for one stored grasp, and how: the
    PyBullet ``trial``, the ``robust`` epsilon and the MuJoCo trial
    (``mujoco``), each None where not run (a row already stored stays)."""

    grasp_id: int
    trial: Trial | None
    robust: RobustEpsilon | None
    seed: int
    trial_settings: str  # JSON
    robust_settings: str  # JSON
    mujoco: Trial | None = None
    mujoco_settings: str = ""  # JSON
