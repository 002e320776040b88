import numpy as np
import pytest

from planner.geometry.solid import load_object, prepare
from planner.grasp import Grasp
from planner.plan.closing import Closed, Grasper
from planner.sim import Sim
from planner.specs.hands import load_hand
from planner.specs.objects import ObjectSpec
from planner.specs.preshapes import load_preshapes
from planner.validation.robust import NoiseSettings, epsilon_samples, robust_epsilon, summarise
from planner.validation.shake import trial


@pytest.fixture(scope="module")
def setup():  # type: ignore[no-untyped-def]
    hand = load_hand("panda")
    return hand, {p.name: p for p in load_preshapes(hand)}, load_object("box")


def as_row(closed: Closed, preshape: str, obj: str = "box") -> Grasp:
    return Grasp(object=obj, hand="panda", preshape=preshape, candidate=0, seed=0, approach_point=np.zeros(3),
                 approach_dir=np.array([0, 0, -1.0]), roll=0.0, standoff=0.0, pose=closed.pose,
                 open_joints=closed.open_joints, closed_joints=closed.closed_joints, width=None,
                 contacts=closed.contacts, epsilon=0.0, volume=0.0, force_closure=True, id=0, score=0.0, rank=1)


def close(setup, *, point=(0, 0, 0.04), direction=(0, 0, -1.0), roll=0.0, standoff=0.02, pose=None):  # type: ignore[no-untyped-def]
    hand, shapes, obj = setup
    with Sim() as sim:
        g = Grasper(sim, hand, sim.add_static_mesh(obj.mesh.vertices, obj.mesh.faces))
        if pose is not None:
            return g.close_at(pose, shapes["wide"])
        return g.close(np.array(point), np.array(direction), roll, standoff, shapes["wide"], obj.torque_scale)


def test_box_enclosed_firmly_is_held(setup) -> None:  # type: ignore[no-untyped-def]
    closed = close(setup)
    assert isinstance(closed, Closed)
    result = trial(setup[0], setup[2], as_row(closed, "wide"))
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


def test_heavy_slippery_box_slips(setup) -> None:  # type: ignore[no-untyped-def]
    closed = close(setup)
    result = trial(setup[0], setup[2], as_row(closed, "wide"), friction=0.05, mass=5.0)
    assert not result.success
    assert result.shaking_linear > 0.02 or result.fingers_in_contact < 2


def test_trials_and_robust_epsilon_are_deterministic(setup) -> None:  # type: ignore[no-untyped-def]
    hand, _, obj = setup
    row = as_row(close(setup), "wide")
    assert trial(hand, obj, row) == trial(hand, obj, row)
    noise = NoiseSettings(samples=4)
    values_a = epsilon_samples(hand, obj, row, np.random.default_rng(3), noise)
    values_b = epsilon_samples(hand, obj, row, np.random.default_rng(3), noise)
    a, b = summarise(values_a, noise.quantile), summarise(values_b, noise.quantile)
    assert a.mean == b.mean and np.array_equal(values_a, values_b) and a.samples == len(values_a) == 4
    assert robust_epsilon(hand, obj, row, np.random.default_rng(3), noise) == a
    assert 0.0 <= a.quantile <= a.mean
