"""Builders of the validation tests."""

from __future__ import annotations

import numpy as np

from planner.grasp import Grasp
from planner.plan.closing import Closed, Grasper
from planner.sim import Sim


def as_row(closed: Closed, preshape: str, obj: str = "box") -> Grasp:
    return Grasp(object=obj, hand="panda", preshape=preshape, candidate=0, seed=0, approach_point=np.zeros(3),
                 approach_dir=np.array([0, 0, -1.0]), roll=0.0, standoff=0.0, pose=closed.pose,
                 open_joints=closed.open_joints, closed_joints=closed.closed_joints, width=None,
                 contacts=closed.contacts, epsilon=0.0, volume=0.0, force_closure=True, id=0, score=0.0, rank=1)


def close(setup, *, point=(0, 0, 0.04), direction=(0, 0, -1.0), roll=0.0, standoff=0.02, pose=None):  # type: ignore[no-untyped-def]
    hand, shapes, obj = setup
    with Sim() as sim:
        g = Grasper.for_mesh(sim, hand, obj.mesh)
        if pose is not None:
            return g.close_at(pose, shapes["wide"])
        return g.close(np.array(point), np.array(direction), roll, standoff, shapes["wide"], obj.torque_scale)
