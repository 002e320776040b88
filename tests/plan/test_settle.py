"""The settled epsilon (planner.plan.settle): the grasp a dynamic closing
settles into, scored like the planned one, and its place in the sweep."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planner.plan.settle import settled_epsilons
from planner.plan.sweep import SweepSettings
from planner.plan.unit import UnitSpec, run_unit
from planner.specs.hands import load_hand
from tests.validation.support import backed_off, box, pinch


@pytest.fixture(scope="module")
def pinched():  # type: ignore[no-untyped-def]
    hand = load_hand("panda")
    obj = box(0.04)
    return hand, obj, pinch(hand, obj)


def test_a_centred_pinch_settles_into_force_closure_and_a_backed_off_one_into_nothing(pinched) -> None:  # type: ignore[no-untyped-def]
    hand, obj, grasp = pinched
    centred, away = settled_epsilons(hand, obj, [grasp, backed_off(grasp, hand, 0.06)])
    assert centred > 0.0  # both pads pressed square on the faces: force closure
    assert away == 0.0  # the fingers close on air


def test_a_grasp_flagged_before_physics_settles_into_nothing(pinched) -> None:  # type: ignore[no-untyped-def]
    hand, obj, grasp = pinched
    at_limit = replace(grasp, closed_joints={j: hand.joint(j).upper for j in grasp.closed_joints})  # no clearance
    assert settled_epsilons(hand, obj, [at_limit])[0] == 0.0


SMALL = SweepSettings(approaches=3, rolls=1, preshapes=("wrap",), reach_placements=0, chunk=0)


@pytest.fixture(scope="module")
def barrett_units():  # type: ignore[no-untyped-def]
    settled = run_unit(UnitSpec("box", "barrett", SMALL, seed=3))
    planned = run_unit(UnitSpec("box", "barrett", replace(SMALL, settle=False), seed=3))
    assert settled.error is None and planned.error is None
    return settled, planned


def test_the_barrett_sweep_settles_its_force_closure_grasps_by_default_and_none_when_told(barrett_units) -> None:  # type: ignore[no-untyped-def]
    settled, planned = barrett_units
    assert load_hand("barrett").settle and not load_hand("panda").settle
    assert len(settled.grasps) == len(planned.grasps) > 0
    closure = [g for g in settled.grasps if g.force_closure]
    others = [g for g in settled.grasps if not g.force_closure]
    assert closure and others  # the unit has both kinds
    assert all(g.measures is not None and g.measures.settled_epsilon is not None for g in closure)
    assert all(g.measures is not None and g.measures.settled_epsilon is None for g in others)
    assert all(g.measures is not None and g.measures.settled_epsilon is None for g in planned.grasps)
    # the same grasps otherwise, and their settle does not depend on the others swept with them
    assert [g.pose.tolist() for g in settled.grasps] == [g.pose.tolist() for g in planned.grasps]
    alone = [settled_epsilons(load_hand("barrett"), settled.obj, [g])[0] for g in closure[:2]]
    assert alone == [g.measures.settled_epsilon for g in closure[:2]]  # type: ignore[union-attr]
    assert settled.timing["settle"] > 0.0 and planned.timing["settle"] == 0.0
    assert np.isfinite([g.measures.settled_epsilon for g in closure]).all()  # type: ignore[union-attr]


def test_the_allegro_sweep_settles_its_force_closure_grasps_by_default() -> None:
    """The Allegro's fingers reach a free object one after another (the first to touch pushes it off before
    the others arrive): its sweep settles, as the Barrett's; the parallel jaws' do not."""
    assert load_hand("allegro").settle and not load_hand("pr2").settle
    small = SweepSettings(approaches=2, rolls=1, preshapes=("power_wrap",), reach_placements=0, chunk=0)
    unit = run_unit(UnitSpec("box", "allegro", small, seed=3))
    assert unit.error is None
    closure = [g for g in unit.grasps if g.force_closure]
    assert closure and all(g.measures is not None and g.measures.settled_epsilon is not None for g in closure)
    assert unit.timing["settle"] > 0.0


def test_the_barrett_settles_with_its_own_dynamics(barrett_units) -> None:  # type: ignore[no-untyped-def]
    """hand.toml's [settle_dynamics] (coarser steps, shorter phases than the shake trial's) is what the
    settle runs unless it is given a trial."""
    from planner.validation.settings import ShakeSettings, settle_settings

    settled, planned = barrett_units
    hand = load_hand("barrett")
    closure = [g for g in planned.grasps if g.force_closure][:3]
    own = list(settled_epsilons(hand, settled.obj, closure))
    assert own == list(settled_epsilons(hand, settled.obj, closure, settings=settle_settings(hand.settle_dynamics)))
    assert own != list(settled_epsilons(hand, settled.obj, closure, settings=ShakeSettings()))


def test_settling_only_force_closure_grasps_keeps_their_ranks(barrett_units) -> None:  # type: ignore[no-untyped-def]
    """The force-closure grasps rank first whatever the others' settled
    epsilons, so settling only them gives them the same scores and ranks as
    settling every grasp."""
    from planner.db.ranking import RankingRule, rank_order, rule_measures
    from planner.plan.settle import with_settled

    settled, planned = barrett_units
    hand = load_hand("barrett")
    every = with_settled(hand, settled.obj, planned.grasps, only_force_closure=False)
    some = with_settled(hand, settled.obj, planned.grasps)
    assert any(g.measures.settled_epsilon for g in every if not g.force_closure)  # type: ignore[union-attr]
    fc = sum(g.force_closure for g in every)
    ranks = [rank_order(RankingRule().scores(m), m["force_closure"])[:fc] for m in map(rule_measures, (every, some))]
    assert list(ranks[0]) == list(ranks[1])


def test_the_settle_does_not_depend_on_the_last_bits_of_a_grasp(barrett_units) -> None:  # type: ignore[no-untyped-def]
    """Closing is a chaotic simulation: poses and joints that differ by
    round-off (numpy on another machine's BLAS kernel) grew into settled
    epsilons 0.007 and 0.2 apart for the same Barrett grasp on the cylinder.
    The dynamic world's inputs are rounded (planner.sim.dynamics.INPUT_DECIMALS),
    so such a grasp settles the same way."""
    settled, planned = barrett_units
    hand = load_hand("barrett")
    rng = np.random.default_rng(11)
    grasps = planned.grasps[:4]
    nudged = [replace(g, pose=g.pose * (1 + rng.normal(size=(4, 4)) * 1e-15),
                      closed_joints={k: v * (1 + 1e-15) for k, v in g.closed_joints.items()}) for g in grasps]
    assert any(not np.array_equal(a.pose, b.pose) for a, b in zip(grasps, nudged))
    assert list(settled_epsilons(hand, settled.obj, nudged)) == list(settled_epsilons(hand, settled.obj, grasps))


def test_a_stored_settled_epsilon_is_what_the_stored_grasp_settles_into(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The settle is chaotic (a nanometre of the pose gives another settled
    epsilon), so the sweep settles each grasp as the database will store it:
    a settle re-run from the database gives the stored value exactly."""
    from planner import api
    from planner.db.objects import stored_object
    from planner.db.store import open_db

    db_path = tmp_path / "b.db"
    api.generate(["box"], "barrett", db_path=db_path, settings=replace(SMALL, chunk=None), seed=3)
    with open_db(db_path, create=False, readonly=True) as db:
        closure = [g for g in db.best("box", "barrett", 100) if g.force_closure]
        obj = stored_object(db.object_row("box"))
    assert len(closure) >= 3
    stored = [g.measures.settled_epsilon for g in closure]  # type: ignore[union-attr]
    again = settled_epsilons(load_hand("barrett"), obj, closure)
    assert list(again) == stored
    assert any(e > 0.0 for e in stored)


def test_grasps_tried_one_after_another_in_one_world_end_as_each_in_a_fresh_world(barrett_units) -> None:  # type: ignore[no-untyped-def]
    """The settle and the PyBullet trial load the hand once and put the world
    back before each grasp (planner.validation.shake._in_turn): the settled
    contacts and the verdicts are those of a fresh world per grasp to the
    last bit, in either order. The Barrett's closing is chaotic and uses
    everything a grasp leaves behind (gears, worm-gear joint limits, motors),
    so any state carried over would show."""
    from planner.record.contacts import HandContacts
    from planner.validation import shake
    from planner.validation.parts import trial_shape
    from planner.validation.settings import ShakeSettings, settle_settings

    settled, planned = barrett_units
    hand, obj = load_hand("barrett"), settled.obj
    grasps = [g.as_stored() for g in planned.grasps[:6]]
    assert len(grasps) == 6

    def fresh(grasp, s, load, friction=obj.friction):  # type: ignore[no-untyped-def]
        seen: list[HandContacts] = []
        trial = shake._world(hand, obj, trial_shape(obj, s.part_tolerance), shake._Physical(friction, obj.mass),
                             [grasp], s, lambda _, c: seen.append(c), load)[0]
        return trial, seen

    def same(a: HandContacts, b: HandContacts) -> bool:
        return np.array_equal(a.points, b.points) and np.array_equal(a.normals, b.normals) and a.links == b.links

    s = settle_settings(hand.settle_dynamics)
    alone = [fresh(g, s, False)[1] for g in grasps]
    assert sum(len(c) for c in alone) == len(grasps)  # each settled (no flag)
    for order in (slice(None), slice(None, None, -1)):
        together = shake.settled_contacts(hand, obj, grasps[order], s)[order]
        assert all(same(a[0], b) for a, b in zip(alone, together))
    tried = [fresh(g, ShakeSettings(), True, friction=0.1)[0] for g in grasps]  # slippery: some drop
    assert {"held", "slipped", "squeezed_out"} <= {t.reason for t in tried}
    for order in (slice(None), slice(None, None, -1)):
        assert shake.trials(hand, obj, grasps[order], friction=0.1)[order] == tried


def test_grasps_tried_in_turn_share_one_object_body(barrett_units, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    """The settle and the PyBullet trial make the object once per world (~1 ms each time), not once per grasp:
    it waits parked between grasps (the results stay those of a fresh world: the test above)."""
    from planner.sim.dynamics import Dynamics
    from planner.validation import shake
    from planner.validation.settings import settle_settings

    settled, planned = barrett_units
    hand, obj = load_hand("barrett"), settled.obj
    grasps = [g.as_stored() for g in planned.grasps[:4]]
    made = []
    add_object = Dynamics.add_object
    monkeypatch.setattr(Dynamics, "add_object", lambda self, *a, **k: made.append(1) or add_object(self, *a, **k))
    contacts = shake.settled_contacts(hand, obj, grasps, settle_settings(hand.settle_dynamics))
    assert sum(len(c) > 0 for c in contacts) == 4 and len(made) == 1
    shake.trials(hand, obj, grasps)
    assert len(made) == 2


def test_a_settled_grasp_reads_its_preshapes_synergy_once(barrett_units, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    """The settle's set-up reads the grasp's closing synergy once (its rates, its clearance and the worm gears'
    hold after closing took it three times, each a look at the preshapes' file): the same contacts."""
    from planner.validation import fingers as fg
    from planner.validation import shake
    from planner.validation.settings import settle_settings

    settled, planned = barrett_units
    hand, obj = load_hand("barrett"), settled.obj
    grasps = [g.as_stored() for g in planned.grasps[:3]]
    s = settle_settings(hand.settle_dynamics)
    before = shake.settled_contacts(hand, obj, grasps, s)
    read = []
    synergy = fg.synergy
    monkeypatch.setattr(fg, "synergy", lambda h, preshape: read.append(preshape) or synergy(h, preshape))
    after = shake.settled_contacts(hand, obj, grasps, s)
    assert len(read) == 3
    assert [(c.points.tobytes(), c.normals.tobytes(), c.links) for c in after] == [
        (c.points.tobytes(), c.normals.tobytes(), c.links) for c in before]


def test_the_settle_does_not_measure_how_far_closing_moved_the_object(barrett_units, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The settle reads the contacts only: the closing's rotation angle (~0.2 ms a grasp) is left to the trial."""
    from planner.validation import shake
    from planner.validation.settings import settle_settings

    settled, planned = barrett_units
    hand, obj = load_hand("barrett"), settled.obj
    grasps = [g.as_stored() for g in planned.grasps[:2]]
    turned = []
    angle_between = shake.angle_between
    monkeypatch.setattr(shake, "angle_between", lambda a, b: turned.append(1) or angle_between(a, b))
    shake.settled_contacts(hand, obj, grasps, settle_settings(hand.settle_dynamics))
    assert turned == []
    shake.trials(hand, obj, grasps[:1])
    assert len(turned) >= 1
