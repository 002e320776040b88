"""What closing (:mod:`planner.plan.closing`) takes and gives: its settings
(:class:`CloseSettings`), a hand closed on the object (:class:`Closed`) and
a candidate it turned down (:class:`Rejected`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from planner.plan.contacts import HandContacts
from planner.plan.measures import JointFrames
from planner.plan.patches import PatchSettings
from planner.plan.tolerances import MAX_PENETRATION


@dataclass(frozen=True)
class CloseSettings:
    """Tolerances of the closing stage (metres, radians)."""

    contact_tol: float = 0.0005  # a true gap below this is a contact
    gap: float = 0.0002  # conservative advancement stops this far short
    coarse_step: float = 0.01  # largest approach / prismatic step
    coarse_angle: float = 0.1  # largest revolute step
    max_penetration: float = MAX_PENETRATION  # deeper overlap rejects the grasp
    start_margin: float = 0.01  # start this far in front of the hand's tips
    max_iterations: int = 400
    # speed knobs of the fast path (touching is always decided on the exact mesh):
    near: float = 0.003  # below this gap to the surface hulls, ask the exact mesh
    exact_reach: float = 0.004  # ... within this range only (few triangles); steps are capped by it
    contacts: str = "patch"  # "patch": contact patches; "points": the legacy closest-point reading
    patches: PatchSettings = field(default_factory=PatchSettings)

    def __post_init__(self) -> None:
        if self.contacts not in CONTACT_READINGS:
            raise ValueError(f"CloseSettings.contacts must be one of {', '.join(CONTACT_READINGS)}")


#: How contacts are read: patches (default) or the legacy closest points.
CONTACT_READINGS = ("patch", "points")


@dataclass(frozen=True)
class Closed:
    """A hand closed on the object.

    Attributes:
        pose: (4, 4) hand frame in the object frame [m].
        open_joints / closed_joints: finger joint values by name [rad or m].
        contacts: the contacts, object frame.
        steps: simulator queries spent (for benchmarks).
        frames: every finger joint's origin and axis at the closed grasp, object frame.
        link_poses: (4, 4) pose of each contact link at the closed grasp, object frame
            (the grip measures, :mod:`planner.plan.grip`).
    """

    pose: np.ndarray
    open_joints: dict[str, float]
    closed_joints: dict[str, float]
    contacts: HandContacts
    steps: int = 0
    frames: JointFrames | None = None
    link_poses: dict[str, np.ndarray] | None = None


@dataclass(frozen=True)
class Rejected:
    reason: str  # start_collision | missed | no_contact | bad_link | penetration | table
    steps: int = 0
