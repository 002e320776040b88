"""What closing asks the simulator (issue 24): a finger that closing expects near the surface hulls asks the exact
mesh first (:meth:`planner.plan.closing.Grasper._closest_near`), and every closing is the one made by asking the
hulls first, to the last bit, with fewer queries of the hulls."""

from collections import Counter
from dataclasses import fields

import numpy as np
import pytest
from helpers import counting_queries

from planner.geometry.solid import load_object
from planner.plan.closing import Grasper
from planner.plan.sweep import SweepSettings
from planner.plan.unit import UnitSpec, run_unit
from planner.sim import Sim
from planner.specs.hands import load_hand

SEED = 0
#: Antipodal points of the small Panda unit below: ~100-200 closings, squeezes included.
POINTS = 24


def _unit(name: str, hulls_first: bool, monkeypatch: pytest.MonkeyPatch) -> tuple[list, Counter]:
    """A small default Panda unit on ``name``, its grasps and how often each body was asked (``hulls_first``: the
    way every query of a finger asked before, the hulls first)."""
    with monkeypatch.context() as m:
        asked = counting_queries(m, "closest")
        if hulls_first:
            m.setattr(Grasper, "_closest_near", lambda self, reach, link: self._closest(reach, link))
        result = run_unit(UnitSpec(name, "panda", SweepSettings(approaches=POINTS, chunk=0, reach_placements=0), SEED))
    assert result.error is None
    return result.grasps, asked


def _equal(a: object, b: object) -> bool:
    """``a`` and ``b`` the same value, NaN equal to NaN."""
    a, b = np.asarray(a), np.asarray(b)
    return np.array_equal(a, b, equal_nan=a.dtype.kind == "f" and b.dtype.kind == "f")


def _same_grasps(a: list, b: list) -> None:
    assert len(a) == len(b) > 0
    for x, y in zip(a, b):
        assert np.array_equal(x.pose, y.pose) and dict(x.closed_joints) == dict(y.closed_joints)
        assert x.epsilon == y.epsilon and x.force_closure == y.force_closure
        for key in ("points", "normals", "radius", "region"):
            assert np.array_equal(getattr(x.contacts, key), getattr(y.contacts, key), equal_nan=True)
        for field in fields(x.measures):
            assert _equal(getattr(x.measures, field.name), getattr(y.measures, field.name)), field.name


@pytest.mark.parametrize("name", ["mug", "duck"])
def test_a_finger_near_the_hulls_asks_the_exact_mesh_first_and_closes_as_before(
        name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """A Panda unit (the sweep's closings and the squeeze's) stores the same grasps, bit for bit, whether a finger
    expected near the surface hulls asks them first or not; asking the exact mesh first saves hull queries (one
    of each finger's closing on most grasps) and asks the exact mesh hardly more often."""
    want, before = _unit(name, True, monkeypatch)
    got, after = _unit(name, False, monkeypatch)
    _same_grasps(got, want)
    assert after["hulls"] < 0.8 * before["hulls"]
    assert after["mesh"] <= 1.02 * before["mesh"]  # a guess that was wrong (a squeeze's finger far) asks it again


def test_a_finger_guessed_near_but_far_reads_the_hulls_pairs() -> None:
    """Where closing's guess is wrong (a finger far from the hulls, asked as near), the answer is still the hulls'
    pairs, as :meth:`Grasper._closest` gives them."""
    hand, obj = load_hand("panda"), load_object("mug")
    with Sim() as sim:
        grasper = Grasper.for_object(sim, hand, obj)
        far = np.eye(4)
        far[0, 3] = obj.mesh.bounds[1][0] + 0.03  # the fingers ~3 cm beside the mug
        grasper._place(far, {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04})
        for link in ("panda_leftfinger", "panda_rightfinger"):
            got, want = grasper._closest_near(0.05, link), grasper._closest(0.05, link)
            assert type(got) is type(want) and len(want) > 0 and want.min_distance + hand.distance_offset > 0.003
            for key in ("links", "distance", "on_a", "on_b", "normal_b"):
                assert np.array_equal(getattr(got, key), getattr(want, key))
