"""The per-grasp content of an ACRONYM-style export, shared by the HDF5
(``acronym``) and JSON (``graspgen``) writers so both carry the same data.

Keys are paths below ``grasps/`` in the HDF5 layout; the JSON writer uses
the last path component. ``transforms`` = pose @ export_frame: the dataset
gripper frame (ACRONYM's convention: +z approach, fingers along x, finger
pads at z = tcp) in the scaled mesh frame, metres.
"""

from __future__ import annotations

import numpy as np

from planner.datasets.batch import Batch
from planner.specs.hands import HandSpec

#: ``object_in_gripper`` label source, per file: every row validated in
#: simulation, none (the force-closure flag), or some of each (then a row's
#: ``simulated_success`` >= 0 says it was simulated).
SIMULATION, FORCE_CLOSURE, MIXED = "simulation", "force_closure", "mixed"

FLEX = "qualities/flex/"
MOTIONS = {f"{FLEX}object_motion_during_{stage}_{kind}": f"{stage}_{kind}"
           for stage in ("closing", "shaking") for kind in ("linear", "angular")}


def max_opening(hand: HandSpec) -> float:
    """``gripper/configuration``: a parallel jaw's largest opening [m] (the sum
    of its prismatic finger upper limits); 0 for other hands."""
    if not hand.centering:
        return 0.0
    return float(sum(j.upper for j in hand.joints if j.kind == "prismatic"))


def joint_names(hand: HandSpec) -> list[str]:
    return [j.name for j in hand.joints]


def per_grasp(batch: Batch, hand: HandSpec) -> dict[str, np.ndarray | list[str]]:
    """Every per-grasp field of one batch; (n, ...) arrays or n strings."""
    labels = np.where(batch.sim_success >= 0, batch.sim_success, batch.force_closure).astype(np.int64)
    names = joint_names(hand)
    out: dict[str, np.ndarray | list[str]] = {
        "transforms": batch.pose @ hand.export_frame,
        f"{FLEX}object_in_gripper": labels,
        **{key: getattr(batch, column) for key, column in MOTIONS.items()},
        "qualities/epsilon": batch.epsilon,
        "qualities/volume": batch.volume,
        "qualities/force_closure": batch.force_closure,
        "qualities/reachability": batch.reachability,
        "qualities/manipulability": batch.manipulability,
        "qualities/score": batch.score,
        "qualities/rank": batch.rank,
        "qualities/simulated_success": batch.sim_success,
        "qualities/robust_epsilon_mean": batch.robust_mean,
        "qualities/robust_epsilon_quantile": batch.robust_quantile,
        "joints_closed": batch.joints(names, closed=True),
        "joints_open": batch.joints(names, closed=False),
        "width": batch.width,
        "preshape": batch.preshape,
        "candidate": batch.candidate,
        "seed": batch.seed,
        "contacts": batch.contacts,
        "poses_hand_frame": batch.pose,
        "approach_point": batch.approach_point,
        "approach_dir": batch.approach_dir,
        "roll": batch.roll,
        "standoff": batch.standoff,
    }
    return out


def label_source(validated: int, total: int) -> str:
    if validated == 0:
        return FORCE_CLOSURE
    return SIMULATION if validated == total else MIXED
