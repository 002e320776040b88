"""The approach kept between standoffs (:meth:`planner.plan.closing.Grasper.close`): the standoffs of one
(ray, roll, preshape) approach once, and each closing is the one a grasper that approaches every time makes,
to the last bit."""

import numpy as np
import pytest

from planner.geometry.solid import load_object
from planner.plan import sampling
from planner.plan.closing import Closed, Grasper, Rejected
from planner.sim import Sim
from planner.specs.hands import load_hand
from planner.specs.preshapes import load_preshapes

SEED = 0


def _same(a: Closed | Rejected, b: Closed | Rejected) -> None:
    """``a`` and ``b`` the same closing, bit for bit (the queries spent aside)."""
    assert type(a) is type(b)
    if isinstance(a, Rejected):
        assert a.reason == b.reason  # type: ignore[union-attr]
        return
    assert isinstance(b, Closed)
    assert np.array_equal(a.pose, b.pose)
    assert a.open_joints == b.open_joints and a.closed_joints == b.closed_joints
    for key in ("points", "normals", "radius", "region"):
        assert np.array_equal(getattr(a.contacts, key), getattr(b.contacts, key), equal_nan=True)
    assert a.contacts.links == b.contacts.links


@pytest.mark.parametrize("name", ["mug", "box"])
def test_a_second_standoff_closes_as_before_without_approaching_again(name: str) -> None:
    """The Barrett on seeded rays, candidates in the sweep's order (standoffs innermost, then rolls, preshapes
    and rays): each closing equals the one of a grasper made to approach every time (its kept approach
    forgotten before each candidate), bit for bit; a standoff after the first of its (ray, roll, preshape)
    spends fewer queries (no approach)."""
    hand, obj = load_hand("barrett"), load_object(name)
    shapes = [s for s in load_preshapes(hand) if not s.table]
    rays = sampling.sample(obj.mesh, sampler="surface", count=2, rng=np.random.default_rng(SEED))
    todo = [(i, shape, roll, standoff) for i in range(len(rays)) for shape in shapes for roll in (0.0, 1.0)
            for standoff in shape.standoffs]
    fewer = 0
    with Sim() as sim, Sim() as other:
        grasper, every_time = Grasper.for_object(sim, hand, obj), Grasper.for_object(other, hand, obj)
        for i, shape, roll, standoff in todo:
            args = (rays.points[i], rays.directions[i], roll, standoff, shape, obj.torque_scale)
            kept = grasper.close(*args)
            every_time._approached = None  # forgotten: it approaches again
            alone = every_time.close(*args)
            _same(kept, alone)
            if standoff != shape.standoffs[0] and isinstance(alone, Closed):
                assert kept.steps < alone.steps
                fewer += 1
    assert fewer > 0
