"""The measures record: the analytic measures of one closed grasp, and the
hand's joint frames at it. How they are computed, and what each
feasibility reason means, is :mod:`planner.plan.measures`'.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.geometry.gravity import DIRECTIONS
from planner.record.field import stored

#: Points of every hand's ``[local_sdf]`` grid (:class:`planner.specs.hand_spec.LocalGrid`): the stored measure's
#: length, the same for all hands.
LOCAL_CELLS = 75

#: The feasibility reasons a grasp can carry (:attr:`Measures.reasons`).
REASONS = ("open_limit", "too_wide", "at_close_stop", "back_or_side_contact", "cannot_hold_weight")


@dataclass(frozen=True)
class Measures:
    """The analytic measures of one grasp (:mod:`planner.plan.measures`).

    resist_worst, resist_mean: weight resistance [g] over 14 gravity
    directions of the object frame (axes and diagonals); open_margin,
    close_margin [m] (inf when no finger touches); push (cosine, 0 when no
    finger touches); reasons: the feasibility flags that apply;
    settled_epsilon: Ferrari-Canny epsilon of the contacts the grasp settles
    into when the fingers close dynamically on the free object
    (:mod:`planner.plan.settle`; 0 if the object is pushed out or the trial
    is flagged; None: not measured, the hand's ``settle`` off).

    The grip measures (:mod:`planner.plan.grip`; None: not measured, a grasp
    stored before schema version 6): pad_area [m^2], pad_alignment (cosine),
    opposition (cosine), jaw_fill [m^2], palm_gap [m], com_lever [m];
    com_height [m], gravity_arm [m] (None also for grasps stored before
    schema version 9); torque_per_mu [N m]: the object's weight's torque
    about the grip axis over its friction coefficient (mass x g x
    gravity_arm / mu; None also for grasps stored before schema version 10);
    local_sdf (LOCAL_CELLS,) [m]: the object's clipped signed distance at
    the hand's grid (:mod:`planner.plan.local_sdf`; None: the hand declares
    no grid, or a grasp stored before schema version 11).

    The squeeze (:mod:`planner.plan.squeeze`; None: the hand does not squeeze, or a grasp stored before schema
    version 14), beside the grasp as planned: squeezed_force_closure, squeezed_epsilon: the force closure and
    epsilon of the contacts a self-centring parallel jaw ends in when its squeeze turns the free object flush
    (the planned ones where those are force closure); squeeze_turn [rad]: how far the hand turned.
    """

    resist_worst: float = stored("real", "g", 3,
                                 f"weight resistance, worst of {DIRECTIONS} gravity directions (object frame)",
                                 required=False, ranked="resist_worst")
    resist_mean: float = stored("real", "g", 3, f"weight resistance, mean over the {DIRECTIONS} directions",
                                required=False)
    open_margin: float = stored("margin", "m", 3, "smallest travel a touching finger has left towards its open limit",
                                required=False, ranked="open_margin")
    close_margin: float = stored("margin", "m", 3, "smallest travel a touching finger has left towards its closing "
                                 "stop", required=False, ranked="close_margin")
    push: float = stored("real", "", 3, "smallest cosine between a finger region's contact normal and its closing "
                         "motion", required=False, ranked="push")
    reasons: tuple[str, ...] = stored("reasons", "", 3, "feasibility reasons, comma-separated ('' = feasible)",
                                      required=False, column="feasibility")
    settled_epsilon: float | None = stored("real", "", 4, "Ferrari-Canny epsilon of the contacts after a dynamic "
                                           "closing (hands with `settle`)", required=False, ranked="settled_epsilon",
                                           default=None)
    pad_area: float | None = stored("real", "m^2", 6, "object surface under the pads (within 1.5 mm of a touching "
                                    "finger's hull, facing it), smallest over the touching fingers", required=False,
                                    default=None)
    pad_alignment: float | None = stored("real", "", 6, "mean cosine between the surface under a pad and the pad "
                                         "(1 = flat on it), smallest over the touching fingers", required=False,
                                         default=None)
    opposition: float | None = stored("real", "", 6, "how straight two touching fingers' pad surfaces face each "
                                      "other (-n_i . n_j, best pair; 1 = opposite)", required=False, default=None)
    jaw_fill: float | None = stored("real", "m^2", 6, "object surface inside the convex hull of the touching "
                                    "fingers (the faces under the pads and all else between them)", required=False,
                                    default=None)
    palm_gap: float | None = stored("real", "m", 6, "smallest distance from the object to the palm (root link), "
                                    "at most 5 cm", required=False, default=None)
    com_lever: float | None = stored("real", "m", 6, "distance from the centre of mass to the line through the pad "
                                     "centres of the best-opposed touching fingers", required=False, default=None)
    com_height: float | None = stored("real", "m", 9, "height of the centre of mass above the midpoint of those pad "
                                      "centres, along the object's up as it rests (`object_up`, its frame's +z "
                                      "unless told; planned on a table: the table's up) (< 0: the object hangs "
                                      "below the grip)",
                                      required=False, default=None)
    gravity_arm: float | None = stored("real", "m", 9, "lever of the object's weight (along its down, -up, or the "
                                       "table's down) about the line through those pad centres", required=False,
                                       default=None)
    torque_per_mu: float | None = stored("real", "N m", 10, "the object's weight's torque about that line over its "
                                         "friction coefficient (mass x g x gravity_arm / mu)", required=False,
                                         default=None)
    local_sdf: np.ndarray | None = stored("vector", "m", 11, "the object around the grasp: its signed distance "
                                          "(< 0 inside; clipped to +-2 cm, 0.1 mm) at the hand's [local_sdf] grid "
                                          f"of {LOCAL_CELLS} points, hand frame, x slowest", required=False,
                                          default=None, shape=(LOCAL_CELLS,))
    squeezed_force_closure: bool | None = stored("bool", "", 14, "1 if the contacts a self-centring parallel jaw's "
                                                 "squeeze ends in (planner.plan.squeeze: the hand turned about "
                                                 "the contacts until the jaw lies along the wall's normal, closed "
                                                 "again, at most 3 times) are force closure, else 0; the planned "
                                                 "force closure where that is 1; NULL: the hand does not squeeze",
                                                 required=False, default=None)
    squeezed_epsilon: float | None = stored("real", "", 14, "Ferrari-Canny epsilon of those squeezed contacts (the "
                                            "planned epsilon where the planned contacts are force closure or the "
                                            "squeeze could not turn)", required=False, default=None)
    squeeze_turn: float | None = stored("real", "rad", 14, "angle the squeeze turned the hand by, planned pose to "
                                        "squeezed pose (0: not turned)", required=False, default=None)

    @property
    def feasible(self) -> bool:
        return not self.reasons

    def to_json(self) -> dict:
        """The measures as ``grasp best --json`` prints them (:func:`planner.record.fields.json_value`)."""
        from planner.record.fields import group, json_value

        return {f.name: json_value(f, getattr(self, f.attr.partition(".")[2])) for f in group("measures")}


@dataclass(frozen=True)
class JointFrames:
    """Every finger joint of the hand at the closed grasp, object frame.

    names : q joint names (hand spec order); origins : (q, 3) [m]; axes : (q, 3) unit.
    """

    names: tuple[str, ...]
    origins: np.ndarray
    axes: np.ndarray
