"""The analytic measures of closed grasps: the centred box pinch holds
2 mu F / (m g) along the pads, feasibility reasons name what is wrong, the
Barrett's fingers break away past the first touch."""

import numpy as np
import pytest

from planner.geometry.solid import load_object
from planner.plan.closing import Closed, Grasper
from planner.plan.measures import measure
from planner.quality.resistance import AXES
from planner.quality.tolerances import GRAVITY
from planner.record.tolerances import MIN_OPEN_MARGIN
from planner.sim import Sim
from planner.specs.hands import load_hand
from planner.specs.preshapes import load_preshapes

DOWN = np.array([0.0, 0.0, -1.0])


def close(hand_name: str, obj_name: str, shape: str, point, direction, roll: float = 0.0,  # type: ignore[no-untyped-def]
          standoff: float = 0.02) -> tuple[Closed, object, object, object]:
    hand, obj = load_hand(hand_name), load_object(obj_name)
    pre = {s.name: s for s in load_preshapes(hand)}[shape]
    with Sim() as sim:
        closed = Grasper.for_mesh(sim, hand, obj.mesh).close(np.asarray(point, float), np.asarray(direction, float),
                                                              roll, standoff, pre, obj.torque_scale)
    assert isinstance(closed, Closed)
    return closed, hand, pre, obj


def test_a_centred_box_pinch_holds_two_mu_f_along_its_pads_and_is_feasible() -> None:
    closed, hand, pre, obj = close("panda", "box", "wide", [0, 0, 0.04], DOWN)
    m = measure(closed.contacts, closed.frames, hand, pre, closed.closed_joints, obj, directions=AXES)  # type: ignore[arg-type]
    friction_only = 2 * obj.friction * (hand.actuators.effort / 2) / (obj.mass * GRAVITY)  # 35 N per pad
    # gravity towards the palm, along the pads: held by friction alone (pulling the other way the pad
    # corners on the box's top edge, where the pad's own tilted normal applies, add a little)
    r = measure(closed.contacts, closed.frames, hand, pre, closed.closed_joints, obj,  # type: ignore[arg-type]
                directions=np.array([[0.0, 0.0, 1.0]]))
    assert r.resist_worst == pytest.approx(friction_only, rel=0.02)
    assert m.feasible and m.push == pytest.approx(1.0, abs=1e-3)
    assert m.open_margin > MIN_OPEN_MARGIN and m.close_margin > MIN_OPEN_MARGIN


def test_fingers_at_their_open_limit_have_no_clearance_and_the_object_fills_the_jaw() -> None:
    closed, hand, pre, obj = close("panda", "box", "wide", [0, 0, 0.04], DOWN)
    at_limit = {name: 0.0395 for name in closed.closed_joints}  # 0.5 mm from the 4 cm open limit per finger
    m = measure(closed.contacts, closed.frames, hand, pre, at_limit, obj)  # type: ignore[arg-type]
    assert m.open_margin == pytest.approx(0.0005, abs=1e-9)
    assert "open_limit" in m.reasons and "too_wide" in m.reasons and not m.feasible
    at_stop = {name: 0.0 for name in closed.closed_joints}
    assert "at_close_stop" in measure(closed.contacts, closed.frames, hand, pre, at_stop, obj).reasons  # type: ignore[arg-type]


def test_barrett_fingers_break_away_and_curl_their_distal_links_on() -> None:
    # the box off-centre over the palm, towards finger 3: its proximal link touches first
    hand, obj = load_hand("barrett"), load_object("box")
    wrap = {s.name: s for s in load_preshapes(hand)}["wrap"]
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = np.diag([1.0, -1.0, -1.0]), [0.0, 0.04, 0.13]
    with Sim() as sim:
        closed = Grasper.for_mesh(sim, hand, obj.mesh).close_at(pose, wrap)
    assert isinstance(closed, Closed)
    q = closed.closed_joints
    assert hand.broken_away(q) == {"bh_j32_joint"}
    assert q["bh_j33_joint"] > q["bh_j32_joint"] / 3 + 0.1  # the distal link closed on alone
    assert q["bh_j13_joint"] == pytest.approx(q["bh_j12_joint"] * 0.3333)  # fingers 1 and 2 stayed coupled
    m = measure(closed.contacts, closed.frames, hand, wrap, q, obj)  # type: ignore[arg-type]
    assert m.resist_worst >= 0 and np.isfinite(m.resist_mean)


def test_the_weight_torque_per_friction_scales_with_mass_and_inverse_friction(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """torque_per_mu = m g gravity_arm / mu for every stored grasp; twice the mass at half the friction: 4x."""
    from planner import api
    from planner.db.store import open_db
    from planner.plan.sweep import SweepSettings

    settings = SweepSettings(approaches=4, rolls=2, preshapes=("wide",), reach_placements=0)
    found = {}
    for tag, mass, friction in (("plain", 0.2, 0.5), ("heavy", 0.4, 0.25)):
        db = tmp_path / f"{tag}.db"
        api.generate(["box"], "panda", db_path=db, settings=settings, workers=1, mass=mass, friction=friction)
        with open_db(db, create=False, readonly=True) as d:
            grasps = d.best("box", "panda", 1000)
        assert grasps and all(g.measures is not None and g.measures.torque_per_mu is not None for g in grasps)
        for g in grasps:
            assert g.measures.torque_per_mu == pytest.approx(mass * GRAVITY * g.measures.gravity_arm / friction,
                                                             rel=1e-9, abs=1e-12)
        found[tag] = {g.candidate: g.measures.torque_per_mu for g in grasps}
    common = sorted(set(found["plain"]) & set(found["heavy"]))
    assert common and any(found["plain"][c] > 1e-4 for c in common)
    for c in common:  # the same poses: the same arms
        assert found["heavy"][c] == pytest.approx(4 * found["plain"][c], rel=1e-6, abs=1e-9)


def test_measures_waiting_for_the_batched_resistance_are_the_measures_of_one_grasp() -> None:
    """The sweep's grasps wait in ``measured_later`` for their weight resistances, solved together: the same
    Measures as ``measure`` of each alone (HiGHS), filled in even when the sweep stops on an error."""
    from dataclasses import dataclass
    from functools import partial

    from planner.plan.measures import measured_later, resistance_program

    @dataclass(frozen=True)
    class Record:
        measures: object = None

    found = [close("panda", "box", "wide", [0, 0, 0.04], DOWN), close("panda", "box", "wide", [0.02, 0, 0.04], DOWN),
             close("barrett", "box", "wrap", [0, 0, 0.04], DOWN)]
    records, timing = [Record() for _ in found], {"quality": 0.0}
    with pytest.raises(RuntimeError), measured_later(records, timing) as later:  # type: ignore[arg-type]
        for i, (closed, hand, pre, obj) in enumerate(found):
            at = (closed.contacts, closed.frames, hand, pre, closed.closed_joints, obj)
            later.append((i, resistance_program(*at), partial(measure, *at, 0.05)))  # type: ignore[arg-type]
        raise RuntimeError("the sweep stopped")
    assert timing["quality"] > 0
    for record, (closed, hand, pre, obj) in zip(records, found):
        alone = measure(closed.contacts, closed.frames, hand, pre, closed.closed_joints, obj, 0.05)  # type: ignore[arg-type]
        got = record.measures
        assert got.resist_worst == pytest.approx(alone.resist_worst, rel=1e-7, abs=1e-7)
        assert got.resist_mean == pytest.approx(alone.resist_mean, rel=1e-7, abs=1e-7)
        assert got.reasons == alone.reasons and got.push == alone.push and got.open_margin == alone.open_margin
    assert records[0].measures.resist_worst > 1.0  # a real pinch, not two zeros compared


def test_a_grasp_whose_measures_fail_ends_the_sweep_there_as_when_measured_one_at_a_time() -> None:
    """A grasp measure() cannot measure (an error while ``measured_later`` fills them in) is not kept, nor are
    those after it (before the batch the sweep stopped at it, and no grasp is ever stored without measures); the
    grasps before it keep theirs, and the error is raised."""
    from dataclasses import dataclass
    from functools import partial

    from planner.plan.measures import measured_later, resistance_program

    @dataclass(frozen=True)
    class Record:
        measures: object = None

    def fails(**_: object) -> None:
        raise ValueError("not measurable")

    found = [close("panda", "box", "wide", [0, 0, 0.04], DOWN), close("panda", "box", "wide", [0.02, 0, 0.04], DOWN)]
    records, timing = [Record() for _ in range(3)], {"quality": 0.0}
    with pytest.raises(ValueError, match="not measurable"), measured_later(records, timing) as later:  # type: ignore[arg-type]
        for i, (closed, hand, pre, obj) in enumerate([found[0], found[1], found[0]]):
            at = (closed.contacts, closed.frames, hand, pre, closed.closed_joints, obj)
            later.append((i, resistance_program(*at), fails if i == 1 else partial(measure, *at, 0.05)))  # type: ignore[arg-type]
    assert len(records) == 1 and records[0].measures is not None


def test_grasps_are_measured_whenever_enough_wait_not_all_at_the_end(monkeypatch: pytest.MonkeyPatch) -> None:
    """A unit of 1,000,000 candidates would queue every grasp's program (~28 KB a Barrett grasp): once WAITING
    wait they are solved and filled in, the queue emptied."""
    from dataclasses import dataclass
    from functools import partial

    from planner.plan import measures as measures_module
    from planner.plan.measures import measured_later, resistance_program

    @dataclass(frozen=True)
    class Record:
        measures: object = None

    monkeypatch.setattr(measures_module, "WAITING", 2)
    closed, hand, pre, obj = close("panda", "box", "wide", [0, 0, 0.04], DOWN)
    at = (closed.contacts, closed.frames, hand, pre, closed.closed_joints, obj)
    records, timing = [Record() for _ in range(3)], {"quality": 0.0}
    with measured_later(records, timing) as later:  # type: ignore[arg-type]
        for i in range(3):
            later.append((i, resistance_program(*at), partial(measure, *at, 0.05)))  # type: ignore[arg-type]
            if i == 1:
                assert records[0].measures is not None and records[1].measures is not None and not later
        assert records[2].measures is None and len(later) == 1
    assert all(r.measures is not None for r in records)
    assert records[2].measures == records[0].measures


def test_a_waiting_grasp_gets_its_local_sdf_as_read_alone() -> None:
    """A grasp that waits with where its ``local_sdf`` is to be read (the unit's LocalSurface and its pose) is
    measured with the cells ``LocalSurface.of`` reads at that pose, to the bit; one that waits without it keeps
    the measure it was given."""
    from dataclasses import dataclass
    from functools import partial

    from planner.plan.local_sdf import LocalSurface
    from planner.plan.measures import measured_later, resistance_program

    @dataclass(frozen=True)
    class Record:
        measures: object = None

    found = [close("panda", "box", "wide", [0, 0, 0.04], DOWN), close("panda", "box", "wide", [0.02, 0, 0.04], DOWN)]
    local = LocalSurface(found[0][1], found[0][3].mesh)
    records = [Record() for _ in found]
    with measured_later(records, {"quality": 0.0}) as later:  # type: ignore[arg-type]
        for i, (closed, hand, pre, obj) in enumerate(found):
            at = (closed.contacts, closed.frames, hand, pre, closed.closed_joints, obj)
            if i == 0:
                later.append((i, resistance_program(*at), partial(measure, *at, 0.05), (local, closed.pose)))
            else:
                later.append((i, resistance_program(*at), partial(measure, *at, 0.05)))  # type: ignore[arg-type]
    first, second = (r.measures for r in records)
    assert first.local_sdf.tobytes() == local.of(found[0][0].pose).tobytes()  # type: ignore[union-attr]
    assert second.local_sdf is None  # type: ignore[union-attr]
