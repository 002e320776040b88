"""The dynamic shake trial: a firm grasp holds, one finger or a slippery
heavy box does not, and a trial is deterministic."""

from __future__ import annotations

import numpy as np

from planner.geometry.solid import prepare
from planner.plan.closing import Closed, Grasper
from planner.sim import Sim
from planner.specs.objects import ObjectSpec
from planner.validation.shake import trial
from tests.validation.support import as_row


def test_box_enclosed_firmly_is_held(setup, firm) -> None:  # type: ignore[no-untyped-def]
    result = trial(setup[0], setup[2], firm)
    assert result.success and result.fingers_in_contact == 2
    assert result.shaking_linear < 0.02 and result.closing_linear < 0.01


def test_one_finger_touching_fails(setup) -> None:  # type: ignore[no-untyped-def]
    # a thin plate between one finger and the palm centre: the other finger
    # closes to its limit without meeting it
    hand, shapes, _ = setup
    plate = prepare(ObjectSpec(name="plate", kind="box", dims=(0.06, 0.004, 0.08), mass=0.1))
    for y in (0.03, -0.03):
        pose = np.array([[1.0, 0, 0, 0], [0, -1, 0, y], [0, 0, -1, 0.04 + 0.09], [0, 0, 0, 1]])
        with Sim() as sim:
            closed = Grasper(sim, hand, sim.add_static_mesh(plate.mesh.vertices, plate.mesh.faces)).close_at(
                pose, shapes["wide"])
        if isinstance(closed, Closed) and len({n for n in closed.contacts.links if n != "panda_hand"}) == 1:
            break
    else:
        raise AssertionError("no pose left exactly one finger on the plate")
    assert not trial(hand, plate, as_row(closed, "wide", "plate")).success


def test_heavy_slippery_box_slips(setup, firm) -> None:  # type: ignore[no-untyped-def]
    result = trial(setup[0], setup[2], firm, friction=0.05, mass=5.0)
    assert not result.success
    assert result.shaking_linear > 0.02 or result.fingers_in_contact < 2




def test_trials_are_deterministic(setup, firm) -> None:  # type: ignore[no-untyped-def]
    hand, _, obj = setup
    assert trial(hand, obj, firm) == trial(hand, obj, firm)
