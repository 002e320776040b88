"""Closing the fingers (:mod:`planner.plan.finger_closing`): a closing does not depend on which poses the grasper
closed before it, the speed bounds it steps by hold in every configuration, and a link's bracket of its gap to the
surface hulls holds it and spares queries without changing a closing."""

import itertools
from collections import Counter

import numpy as np
import pytest
from helpers import counting_queries

from planner.geometry.solid import load_object, prepare
from planner.plan import sampling
from planner.plan.closing import Closed, Grasper, Rejected
from planner.plan.obstacle_queries import HullBracket
from planner.plan.sweep import SweepSettings
from planner.plan.unit import UnitSpec, run_unit
from planner.sim import Sim
from planner.specs.hands import load_hand
from planner.specs.objects import ObjectSpec
from planner.specs.preshapes import load_preshapes

SEED = 0
RAYS = 6
#: [rad] the roll between two rays' candidates: each candidate turns the hand another way, and so its links' boxes
ROLL_STEP = 0.7
#: [m] round-off of a point moved by a joint, read back from the simulator
POINT_TOL = 1e-9
#: [rad] the joint step the bound is checked over (small: the bound is a speed)
DQ = 1e-3
CONFIGURATIONS = 20


def _closings(grasper: Grasper, candidates: list, order: list[int]) -> dict[int, Closed | Rejected]:
    return {i: grasper.close(*candidates[i]) for i in order}


@pytest.mark.parametrize("name", ["barrett", "allegro"])
def test_a_closing_does_not_depend_on_the_poses_closed_before(name: str) -> None:
    """The same candidates closed in two orders, each by a new grasper: every closing the same to the last bit.
    Before: the speed bound of a finger's links was read from the links' world boxes at the first pose closed, so
    closed joints moved by up to 3e-3 rad (Barrett) and 0.12 rad (Allegro) with the order."""
    hand = load_hand(name)
    obj = prepare(ObjectSpec(name="box", kind="box", dims=(0.06, 0.045, 0.09), mass=0.2))
    shape = next(s for s in load_preshapes(hand) if not s.table)
    rays = sampling.sample(obj.mesh, sampler="surface", count=RAYS, rng=np.random.default_rng(SEED))
    candidates = [(rays.points[i], rays.directions[i], ROLL_STEP * i, 0.0, shape, obj.torque_scale)
                  for i in range(len(rays))]
    runs = []
    for order in (list(range(len(candidates))), list(reversed(range(len(candidates))))):
        with Sim() as sim:
            runs.append(_closings(Grasper.for_mesh(sim, hand, obj.mesh), candidates, order))
    closed = [i for i, c in runs[0].items() if isinstance(c, Closed)]
    assert len(closed) >= 2, "the test needs closings to compare"
    for i in runs[0]:
        a, b = runs[0][i], runs[1][i]
        assert type(a) is type(b)
        if isinstance(a, Closed):
            assert isinstance(b, Closed)
            assert a.closed_joints == b.closed_joints, f"candidate {i}"
            assert np.array_equal(a.contacts.points, b.contacts.points)


def _corners(sim: Sim, grasper: Grasper, link: str, frame: np.ndarray) -> np.ndarray:
    """(8, 3) [m] world corners of ``link``'s box in its own frame, the link at ``frame`` (4, 4)."""
    body = grasper.body
    home = sim.link_pose(body, link)
    base = sim.link_pose(body, next(n for n, i in body.links.items() if i == -1))
    sim.set_pose(body, base @ np.linalg.inv(home))  # the link's frame at the world's: its box in its own frame
    lo, hi = sim.link_aabb(body, link)
    sim.set_pose(body, base)
    local = np.array(list(itertools.product(*zip(lo, hi))))
    return local @ frame[:3, :3].T + frame[:3, 3]


@pytest.mark.parametrize("name", ["barrett", "allegro"])
def test_the_speed_bounds_hold_in_every_configuration(name: str) -> None:
    """At seeded configurations within the joint limits, a small step of each finger DOF moves no corner of a
    moved link's own box (which holds the link's collision shape) farther than the DOF's bound times the step."""
    hand = load_hand(name)
    rng = np.random.default_rng(SEED)
    shape = next(s for s in load_preshapes(hand) if not s.table)
    with Sim() as sim:
        grasper = Grasper.for_mesh(sim, hand, prepare(ObjectSpec(name="s", kind="sphere", dims=(0.01,),
                                                                 mass=0.1)).mesh)
        body = grasper.body
        dofs = grasper._dofs(shape)
        for _ in range(CONFIGURATIONS):
            q = {j.name: float(rng.uniform(j.lower, j.upper)) for j in hand.joints}
            for dof in dofs:
                speeds = grasper._speeds(dof)
                grasper._place(np.eye(4), q)
                before = {link: _corners(sim, grasper, link, sim.link_pose(body, link)) for link in dof.links}
                grasper._place(np.eye(4), {j: q[j] + r * DQ for j, r in dof.rates.items()})
                for link in dof.links:
                    moved = np.linalg.norm(_corners(sim, grasper, link, sim.link_pose(body, link)) - before[link],
                                           axis=1)
                    assert moved.max() <= speeds[link] * DQ + POINT_TOL, (link, moved.max(), speeds[link] * DQ)
                grasper._place(np.eye(4), q)


#: Rays of the small default Barrett units below (40 candidates a ray).
UNIT_RAYS = 2


def _barrett_unit(name: str, bracketing: bool, monkeypatch: pytest.MonkeyPatch, guess: bool = True
                  ) -> tuple[list, Counter]:
    """A small default Barrett unit on ``name``: its grasps and how often each body was asked for a gap
    (``bracketing`` False: no link's bracket is ever set, every link asked at every step, as before; ``guess``
    False: no link is expected near, the hulls asked before the mesh)."""
    with monkeypatch.context() as m:
        asked = counting_queries(m, "min_distance")
        if not bracketing:
            m.setattr(HullBracket, "set", lambda self, low, high=np.inf: None)
        if not guess:
            m.setattr(HullBracket, "expected", lambda self: np.inf, raising=False)
        result = run_unit(UnitSpec(name, "barrett", SweepSettings(approaches=UNIT_RAYS, chunk=0, reach_placements=0),
                                   SEED))
    assert result.error is None and len(result.grasps) > 0
    return result.grasps, asked


def _assert_same_grasps(got: list, want: list) -> None:
    """The same grasps, bit for bit: poses, closed joints, epsilon, force closure and contact points."""
    assert len(got) == len(want)
    for x, y in zip(got, want):
        assert np.array_equal(x.pose, y.pose) and dict(x.closed_joints) == dict(y.closed_joints)
        assert x.epsilon == y.epsilon and x.force_closure == y.force_closure
        assert np.array_equal(x.contacts.points, y.contacts.points)


@pytest.mark.parametrize("name", ["box", "random_002"])
def test_a_link_far_from_the_hulls_is_asked_only_when_it_may_bound_its_finger(
        name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """A default Barrett unit stores the same grasps, bit for bit, whether closing asks every link at every step
    or skips the links whose bracket shows they can neither touch nor bound their finger's step (and asks a link
    it shows near the hulls the exact mesh alone); it asks the hulls far less often, the mesh no more."""
    want, before = _barrett_unit(name, False, monkeypatch)
    got, after = _barrett_unit(name, True, monkeypatch, guess=False)  # the brackets alone
    _assert_same_grasps(got, want)
    assert after["hulls"] < 0.85 * before["hulls"]
    assert after["mesh"] <= before["mesh"]


def test_a_links_bracket_holds_its_gap_to_the_hulls_at_every_step(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each time closing asks a link for its gap, the gap to the surface hulls PyBullet gives there lies within
    the bracket the link's earlier answers and steps left (a link with none yet: every bracket open)."""
    hand, obj = load_hand("barrett"), load_object("mug")
    shape = next(s for s in load_preshapes(hand) if not s.table)
    rays = sampling.sample(obj.mesh, sampler="surface", count=RAYS, rng=np.random.default_rng(SEED))
    checked: list[float] = []
    gap = Grasper._obstacle_gap

    def checking(self: Grasper, reach: float, link: str, bracket: HullBracket | None = None) -> float:
        if bracket is not None and self.far_body is not None:
            hulls = self.sim.min_distance(self.body.uid, self.far_body, 1.0, self.body.links[link])
            hulls += hand.distance_offset
            assert bracket.low <= hulls <= bracket.high, (link, bracket.low, hulls, bracket.high)
            checked.append(bracket.high - bracket.low)
        return gap(self, reach, link, bracket)

    monkeypatch.setattr(Grasper, "_obstacle_gap", checking)
    with Sim() as sim:
        grasper = Grasper.for_object(sim, hand, obj)
        for i in range(len(rays)):
            grasper.close(rays.points[i], rays.directions[i], ROLL_STEP * i, 0.0, shape, obj.torque_scale)
    assert sum(np.isfinite(checked)) > 50, "the test needs bracketed links to check"


def test_a_link_expected_near_the_hulls_asks_the_exact_mesh_first(monkeypatch: pytest.MonkeyPatch) -> None:
    """A link whose bracket expects it near the surface hulls (but cannot show it) asks the exact mesh first: where
    that finds it near, the hulls are not asked (one query instead of two) and the gap is the one the
    hulls-then-mesh path gives, bit for bit; where it does not (a guess gone wrong), the hulls decide as before,
    the same gap."""
    hand, obj = load_hand("barrett"), load_object("mug")
    shape = next(s for s in load_preshapes(hand) if not s.table)
    rays = sampling.sample(obj.mesh, sampler="surface", count=RAYS, rng=np.random.default_rng(SEED))
    reach = 0.05
    with Sim() as sim:
        grasper = Grasper.for_object(sim, hand, obj)
        closed = next(c for i in range(len(rays)) if isinstance(
            c := grasper.close(rays.points[i], rays.directions[i], ROLL_STEP * i, 0.0, shape, obj.torque_scale),
            Closed))
        link = closed.contacts.links[0]  # touching, the hand as it closed

        def hulls() -> float:  # the gap a bracket holds
            return sim.min_distance(grasper.body.uid, grasper.far_body, 1.0, grasper.body.links[link]) + \
                hand.distance_offset

        for back in (0.0, *np.arange(0.002, 0.03, 0.001)):  # touching; then backed off until the guess is wrong
            pose = closed.pose.copy()
            pose[:3, 3] -= back * (pose[:3, :3] @ hand.approach)
            grasper._place(pose, dict(closed.closed_joints))
            want = grasper._obstacle_gap(reach, link)  # no bracket: the hulls, then the mesh if they are near
            bracket = HullBracket()
            bracket.set(-0.001, 0.0075)  # holds the gap, does not show it near (> 3 mm), expects it within 2 mm
            if not bracket.low <= hulls() <= bracket.high:  # (it does not show the link near: high > 3 mm)
                continue
            with monkeypatch.context() as m:
                asked = counting_queries(m, "min_distance")
                got = grasper._obstacle_gap(reach, link, bracket)
            assert got == want
            if back == 0.0:
                assert want <= grasper.settings.near - 0.001 and asked == Counter(mesh=1)
            elif want > grasper.settings.near:
                assert asked == Counter(mesh=1, hulls=1)  # the guess gone wrong costs a query, not the answer
                break
        else:
            pytest.fail("no pose the guess was wrong at")


def test_the_exact_mesh_first_stores_the_same_grasps_with_fewer_queries_of_the_hulls(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A default Barrett unit stores the same grasps, bit for bit, whether a link its bracket expects near the hulls
    asks the exact mesh first or not; the hulls are asked less often, the mesh about as often."""
    want, before = _barrett_unit("mug", True, monkeypatch, guess=False)
    got, after = _barrett_unit("mug", True, monkeypatch)
    _assert_same_grasps(got, want)
    assert after["hulls"] < 0.95 * before["hulls"]
    assert after["mesh"] < 1.1 * before["mesh"]
