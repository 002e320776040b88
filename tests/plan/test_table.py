"""Grasps planned on a table: closing with the table as an obstacle, ``grasp
generate --on-table``, and queries at table poses that never return a hand
through the table (issue 25, item 5)."""

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import grasp, made_up, one_line_error

from planner import api
from planner.api import reaching as api_reaching
from planner.geometry.solid import load_object
from planner.geometry.support import Support
from planner.plan.patch_surfaces import collision_mesh
from planner.plan.sweep import SweepSettings
from planner.plan.tolerances import TABLE_CLEARANCE
from planner.plan.unit import FROM_BELOW, UnitSpec, pregrasp, run_unit
from planner.record.grasp import Grasp
from planner.sim import Sim
from planner.specs.hands import load_hand
from planner.specs.preshapes import load_preshapes
from planner.specs.urdf import load_model

#: A small Barrett sweep: two preshapes, no settle (its dynamic closing is not what is tested here).
BARRETT = ["--approaches", "8", "--rolls", "2", "--preshapes", "pinch,wrap", "--no-settle", "--workers", "1",
           "--reach-placements", "1"]
#: [m] how far a true clearance may fall short of TABLE_CLEARANCE: a link's 64-sided cylinder
#: (its hull's vertices, measured here) lies within 0.02 mm of the cylinder PyBullet collides.
HULL_TOL = 1e-4
#: The box standing on its 5 x 4 cm end, 8 cm tall: not one of its two most probable resting poses.
STANDING = [0.5, 0.0, 0.04, 0.0, 0.0, 0.0, 1.0]


def gap_to_table(hand: str, pose: np.ndarray, joints: dict, support: Support) -> float:
    """Smallest true height [m] of the hand at ``pose`` with ``joints`` above
    ``support``'s plane (all in one frame): the lowest vertex of its links'
    collision hulls, placed by PyBullet's forward kinematics. Not PyBullet's
    closest points, whose margins the planner corrects: a table measured by
    them passed a finger 0.2 mm into it."""
    spec = load_hand(hand)
    model = load_model(spec.urdf)
    lowest = np.inf
    with Sim() as sim:
        body = sim.load_urdf(spec.urdf)
        sim.set_pose(body, pose)
        sim.set_joints(body, dict(joints))
        for link in body.links:
            mesh = collision_mesh(model, link)
            if mesh is not None:
                placed = trimesh.transform_points(mesh.vertices, sim.link_pose(body, link))
                lowest = min(lowest, float((placed @ support.normal).min() - support.height))
    return lowest


def world_gap(g: api.ReachableGrasp) -> float:
    """The returned grasp's hand, where the arm puts it, against the table top z = 0."""
    return gap_to_table(g.grasp.hand, np.array(g.hand_pose_world), g.grasp.closed_joints,
                        Support(np.array([0.0, 0.0, 1.0]), 0.0))


@pytest.fixture(scope="module")
def barrett_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The box for the Barrett: a small sweep on the object alone, then on the table in its two most probable
    resting poses."""
    db = tmp_path_factory.mktemp("table") / "g.db"
    for extra in ([], ["--on-table", "--stable-poses", "2"]):
        code, _, err = grasp("generate", "box", "--hand", "barrett", "--db", str(db), "--quiet", *BARRETT, *extra)
        assert code == 0, err
    return db


def test_a_sweep_on_the_table_keeps_every_hand_off_it() -> None:
    support = api.table_supports(load_object("box"), 1)[0]
    settings = SweepSettings(approaches=12, rolls=2, preshapes=("pinch", "wrap"), settle=False,
                             reach_placements=0).on(support)
    result = run_unit(UnitSpec("box", "barrett", settings, seed=0))
    assert result.error is None and result.force_closure > 0
    assert result.rejected[FROM_BELOW] > 0  # the rays from under the table were not tried
    hand = load_hand("barrett")
    for g in result.grasps:
        assert g.table_plane is not None and np.allclose(g.table_plane, support.vector(), atol=1e-7)
        assert gap_to_table("barrett", g.pose, g.closed_joints, support) >= TABLE_CLEARANCE - HULL_TOL
        assert gap_to_table("barrett", pregrasp(g.pose, hand, settings.pregrasp_distance), g.open_joints,
                            support) > 0


@pytest.mark.parametrize("obj", ["box", "mug"])
def test_the_pr2s_box_fingertips_keep_the_clearance(obj: str) -> None:
    """PyBullet padded the PR2's box fingertips by less than its meshes: they
    came 1 mm nearer the table than planned (0.95 mm true clearance)."""
    support = api.table_supports(load_object(obj), 1)[0]
    settings = SweepSettings(approaches=24, rolls=2, reach_placements=0).on(support)
    result = run_unit(UnitSpec(obj, "pr2", settings, seed=0))
    assert result.error is None and result.grasps
    assert min(gap_to_table("pr2", g.pose, g.closed_joints, support) for g in result.grasps) >= \
        TABLE_CLEARANCE - HULL_TOL


@pytest.mark.parametrize("hand", ["allegro", "barrett"])
def test_a_low_box_on_the_table_gets_a_force_closure_table_pinch_that_stays_above_it(hand: str) -> None:
    """The box lying down (4 cm tall) is lower than the open fingers reach past
    the palm: the pre-curled table preshape closes on its sides above the table."""
    support = api.table_supports(load_object("box"), 1)[0]
    settings = SweepSettings(approaches=24, rolls=2, preshapes=("table_pinch",), settle=False,
                             reach_placements=0).on(support)
    result = run_unit(UnitSpec("box", hand, settings, seed=0))
    assert result.error is None and result.force_closure > 0
    for g in result.grasps:
        assert gap_to_table(hand, g.pose, g.closed_joints, support) >= TABLE_CLEARANCE - HULL_TOL
        heights = g.contacts.points @ support.normal - support.height
        assert np.all(heights > 0)  # on the object, none under the table


def test_a_flat_object_wider_than_the_thumbs_pinch_gets_a_force_closure_spread_pinch() -> None:
    """random_000 lying flat (12 x 9 cm, 3 cm tall) is wider than the Allegro's
    thumb-against-fingers table_pinch opens (9.6 cm clear): no force-closure
    grasp of it on the table before table_spread. The index and ring, spread
    13.7 cm apart, close on its sides above the table."""
    support = api.table_supports(load_object("random_000"), 1)[0]
    settings = SweepSettings(approaches=16, rolls=2, preshapes=("table_spread",), settle=False,
                             reach_placements=0).on(support)
    result = run_unit(UnitSpec("random_000", "allegro", settings, seed=0))
    assert result.error is None and result.force_closure > 0
    for g in result.grasps:
        assert gap_to_table("allegro", g.pose, g.closed_joints, support) >= TABLE_CLEARANCE - HULL_TOL
        assert np.all(g.contacts.points @ support.normal - support.height > 0)
    fc = [g for g in result.grasps if g.force_closure]
    assert {link.split("_")[0] for g in fc for link in g.contacts.links} <= {"index", "ring"}


def test_the_sweep_of_the_object_alone_does_not_try_table_preshapes() -> None:
    result = run_unit(UnitSpec("box", "barrett", SweepSettings(approaches=2, rolls=1, settle=False,
                                                                reach_placements=0), seed=0))
    table = {s.name for s in load_preshapes(load_hand("barrett")) if s.table}
    assert result.grasps and not {g.preshape for g in result.grasps} & table


def test_the_barrett_on_a_small_box_on_a_table_reaches_a_grasp_off_the_table(barrett_db: Path) -> None:
    code, out, err = grasp("best", "box", "--hand", "barrett", "--db", str(barrett_db), "--on-table",
                           "--stable-poses", "2", "--no-plan", "--json")
    assert code == 0, err
    for pose in json.loads(out):
        assert pose["grasps"], "no reachable grasp in a resting pose"
        g = pose["grasps"][0]
        assert g["arm"]["grasp"] and not g["planned_now"]
        closed = {k: float(v) for k, v in g["closed_joints"].items()}
        assert gap_to_table("barrett", np.array(g["hand_pose_world"]), closed,
                            Support(np.array([0.0, 0.0, 1.0]), 0.0)) > 0


def test_a_grasp_through_the_table_is_never_returned(barrett_db: Path, box_db: Path) -> None:
    """Stored grasps tried in query order and grasps planned on the spot: the
    ones returned keep the hand off the table, the ones through it were
    tried and refused."""
    lying = [0.5, 0.0, 0.02, 0.7071068, 0.0, 0.0, 0.7071068]  # on its 5 x 8 cm face, 4 cm tall
    for db, hand, pose, top, tried in ((box_db, "panda", lying, 3, 40), (barrett_db, "barrett", lying, 60, 60),
                                       (box_db, "panda", STANDING, 3, 0)):
        misses: list[tuple[int, str]] = []
        found = api.best_at("box", hand, pose, db_path=db, top=top, max_candidates=tried, misses=misses, seed=1,
                            plan=not tried)
        assert found, hand
        for r in found:
            assert world_gap(r) > 0, (hand, r.grasp.rank)
        if tried:  # stored grasps through the table were tried, and refused
            assert any("hit the table" in why for _, why in misses), hand
        else:
            assert all(r.planned_now for r in found)


def test_a_stored_grasp_a_millimetre_into_the_table_is_not_returned(tmp_path: Path, shipped_models: None) -> None:
    """The reach check read the table's gaps 1 mm too large (PyBullet pads a
    box less than a mesh): the Panda's rank-58 box grasp (as the shipped
    p_hold model ranks them) came back first at the lying pose with a finger
    0.18 mm into the table."""
    db = tmp_path / "g.db"
    api.generate(["box"], "panda", db_path=db, settings=SweepSettings(approaches=64))
    lying = [0.5, 0.0, 0.02, 0.7071068, 0.0, 0.0, 0.7071068]
    found = api.best_at("box", "panda", lying, db_path=db, top=2, max_candidates=100, seed=1, plan=False)
    assert len(found) == 2 and min(world_gap(r) for r in found) > 0


def test_grasps_planned_on_the_spot_are_reproducible_from_the_seed(box_db: Path) -> None:
    first, again = (api.best_at("box", "panda", STANDING, db_path=box_db, top=1, max_candidates=0, seed=4)
                    for _ in range(2))
    assert first[0].planned_now and first[0].grasp.rank is None
    assert np.array_equal(first[0].grasp.pose, again[0].grasp.pose)
    assert first[0].arm_grasp == again[0].arm_grasp


def test_generate_on_the_table_resumes_and_keys_units_by_the_plane(tmp_path: Path) -> None:
    db = tmp_path / "g.db"
    settings = SweepSettings(approaches=24, rolls=2, preshapes=("wide",), reach_placements=0)
    first = api.generate(["box"], "panda", db_path=db, settings=settings, on_table=2)
    again = api.generate(["box"], "panda", db_path=db, settings=settings, on_table=2)
    assert first.units == 2 and again.units == 0 and again.skipped == 2
    alone = api.generate(["box"], "panda", db_path=db, settings=settings)  # the object alone: units of its own
    assert alone.units == 1
    planes = {tuple(g.table_plane) if g.table_plane is not None else None
              for g in api.best("box", "panda", db_path=db, top=1000)}
    assert None in planes and len(planes) == 3


def test_a_miss_without_planning_names_the_on_table_sweep(box_db: Path) -> None:
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--object-pose", "3,0,0.04,0,0,0,1",
                           "--max-candidates", "2", "--no-plan")
    one_line_error(code, err, 1, "none of the 2 best grasps", "--on-table`", "grasp generate box --hand panda")
    assert out == ""


def test_planned_grasps_are_printed_as_not_stored(box_db: Path) -> None:
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--object-pose",
                           ",".join(map(str, STANDING)), "--max-candidates", "0")
    assert code == 0, err
    assert out.startswith("#- (planned now with the table, not stored)") and "planned on a table" in out


def test_a_grasp_record_refuses_a_bad_table_plane() -> None:
    with pytest.raises(ValueError, match="table_plane"):
        Grasp(object="o", hand="h", preshape="p", candidate=0, seed=0, approach_point=np.zeros(3),
              approach_dir=np.array([0.0, 0.0, 1.0]), roll=0.0, standoff=0.0, pose=np.eye(4), open_joints={},
              closed_joints={}, width=None, contacts=None, epsilon=0.0, volume=0.0,  # type: ignore[arg-type]
              force_closure=False, table_plane=np.zeros(3))


def test_the_table_plane_is_part_of_the_settings_digest_only_when_there_is_one() -> None:
    settings = SweepSettings(approaches=6).resolved("surface")
    support = Support(np.array([0.0, 0.0, 1.0]), -0.04)
    assert "table_plane" not in settings.to_json()  # sweeps on the object alone keep their stored digests
    assert "table_version" not in settings.to_json() and "table_version" in settings.on(support).to_json()
    assert settings.on(support).digest != settings.digest != settings.on(support.raised(0.01)).digest
    assert settings.on(support).on(None).digest == settings.digest


def test_force_closure_grasps_come_first_stored_before_planned() -> None:
    def reached(candidate: int, fc: bool, planned: bool = False) -> api.ReachableGrasp:
        return api.ReachableGrasp(made_up(candidate, 0.1, fc), {}, {}, 0.0, [], planned)

    stored_fc, stored_not, planned_fc = reached(1, True), reached(2, False), reached(3, True, planned=True)
    assert api._preferred([stored_not], [planned_fc], 1) == [planned_fc]
    assert api._preferred([stored_fc, stored_not], [planned_fc], 3) == [stored_fc, planned_fc, stored_not]


def test_grasps_force_closure_once_squeezed_come_first_as_the_database_ranks_them() -> None:
    """A stored Panda grasp force closure only after the squeeze ranks first in the database
    (planner.db.ranking.FIRST): reaching keeps it before a planned grasp that is neither, and counts it."""
    from dataclasses import replace

    from planner.record.measures import Measures

    def reached(candidate: int, squeezed: bool | None, planned: bool = False) -> api.ReachableGrasp:
        g = made_up(candidate, 0.1, False)
        measures = replace(g.measures or Measures(5.0, 5.0, 0.01, 0.01, 1.0, ()), squeezed_force_closure=squeezed)
        return api.ReachableGrasp(replace(g, measures=measures), {}, {}, 0.0, [], planned)

    stored_squeezed, planned_not = reached(1, True), reached(2, False, planned=True)
    assert api._preferred([planned_not], [stored_squeezed], 1) == [stored_squeezed]
    assert api._preferred([stored_squeezed], [planned_not], 2) == [stored_squeezed, planned_not]
    assert api_reaching._closures([stored_squeezed, planned_not, reached(3, None)]) == 1
