"""A parallel jaw's squeeze (planner.plan.squeeze), stored beside the grasp as planned.

A thin slab tilted by TILT about the pads' width direction, pinched by the Panda at its middle: held still, each
flat pad touches it at one edge, the two edges on opposite sides of the wall (not force closure as planned);
squeezed, the hand turns by about the tilt and the pads lie flat on both faces (force closure). The grasp keeps
its planned pose and measures; the squeeze's outcome is three measures beside them."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from planner.datasets.importer import RescoreUnit, rescore_poses
from planner.geometry.solid import load_object
from planner.plan import keeping, unit
from planner.plan.squeeze import SHARES, bracketed, cosine, midway, squeezes, turn, turned, turning
from planner.plan.sweep import SweepSettings
from planner.record.contacts import HandContacts
from planner.specs.hands import load_hand

#: [rad] the slab's tilt: more than the friction angle (atan 0.5 = 26.6 deg) lies between the edges' line and the
#: faces' normal, less than a turn the open jaw could not make.
TILT = np.radians(20.0)
#: [m] the slab's thickness, width (across the pads) and height (along the approach).
THICK, WIDE, TALL = 0.004, 0.06, 0.1
#: [rad] how closely the squeeze's turn matches the tilt: held still, one finger touches the slab's top edge too
#: (a contact with the pad's own normal there), so the one turn is ~2 degrees short.
TURN_TOL = np.radians(3.0)
#: [m] the Panda's tool centre point in its hand frame.
TCP = np.array([0.0, 0.0, 0.1034])
#: The squeeze's measures (planner.record.measures.Measures).
SQUEEZE = ("squeezed_force_closure", "squeezed_epsilon", "squeeze_turn")


def slab(tmp_path: Path, tilt: float):  # type: ignore[no-untyped-def]
    """The slab as an object spec (its faces' normals along +-y turned by ``tilt`` about x), its top 3 cm above
    the origin."""
    box = trimesh.creation.box([WIDE, THICK, TALL])
    box.apply_translation([0.0, 0.0, 0.03 - TALL / 2])
    box.apply_transform(trimesh.transformations.rotation_matrix(tilt, [1.0, 0.0, 0.0]))
    path = tmp_path / f"slab{tilt:.3f}.obj"
    box.export(path)
    return load_object(str(path)).spec


def pinch() -> np.ndarray:
    """(4, 4) the Panda from above, its fingers opening along y, its tool centre point at the origin."""
    pose = np.eye(4)
    pose[:3, :3] = np.diag([-1.0, 1.0, -1.0])  # approach (hand z) down
    pose[:3, 3] = -pose[:3, :3] @ TCP
    return pose


@pytest.mark.parametrize("tilt", [TILT, -TILT])
def test_a_slanted_wall_is_kept_as_planned_and_squeezes_to_force_closure(tmp_path: Path, tilt: float) -> None:
    (grasp,) = rescore_poses(RescoreUnit(0, 0, pinch()[None], load_hand("panda"), slab(tmp_path, tilt))).grasps
    assert not grasp.force_closure and grasp.epsilon == 0.0  # as planned: the pads' edges make a couple
    np.testing.assert_allclose(np.asarray(grasp.pose)[:3, :3], pinch()[:3, :3], atol=1e-12)  # not turned
    m = grasp.measures
    assert m is not None and m.squeezed_force_closure is True and m.squeezed_epsilon > 0.0
    assert abs(m.squeeze_turn - abs(tilt)) < TURN_TOL


def test_an_upright_wall_is_force_closure_as_planned_and_not_turned(tmp_path: Path) -> None:
    (grasp,) = rescore_poses(RescoreUnit(0, 0, pinch()[None], load_hand("panda"), slab(tmp_path, 0.0))).grasps
    m = grasp.measures
    assert grasp.force_closure and m is not None
    assert (m.squeezed_force_closure, m.squeezed_epsilon, m.squeeze_turn) == (True, grasp.epsilon, 0.0)


def test_only_a_self_centring_parallel_jaw_squeezes() -> None:
    assert [squeezes(load_hand(h)) for h in ("panda", "pr2", "barrett", "allegro")] == [True, False, False, False]


def test_hands_that_do_not_squeeze_store_none(tmp_path: Path) -> None:
    hand = load_hand("panda")
    pr2 = replace(hand, centering=False)  # the Panda's jaw, declared not self-centring (as the PR2's)
    (grasp,) = rescore_poses(RescoreUnit(0, 0, pinch()[None], pr2, slab(tmp_path, TILT))).grasps
    assert grasp.measures is not None
    assert [getattr(grasp.measures, name) for name in SQUEEZE] == [None, None, None]


def test_the_squeeze_leaves_the_sweep_as_it_was(monkeypatch: pytest.MonkeyPatch) -> None:
    """A unit's grasps as planned are those it plans without the squeeze, field for field, but for the squeeze's
    measures: the squeeze's closings leave the grasper's world as they found it (later grasps unchanged)."""
    obj = load_object("mug")
    settings = SweepSettings(approaches=60, rolls=2, reach_placements=0)
    result = unit.plan_object(obj, "panda", settings, 3)
    squeezed = [g for g in result.grasps if g.squeezed_from_turn is None]
    monkeypatch.setattr(keeping, "squeezed", lambda *args: None)
    plain = unit.plan_object(obj, "panda", settings, 3).grasps
    assert len(squeezed) == len(plain) > 10 and all(g.squeezed_from_turn is None for g in plain)
    turned = [g for g in squeezed if g.measures.squeeze_turn > 0.0]  # type: ignore[union-attr]
    assert turned and any(not g.force_closure for g in squeezed)
    assert all(t >= 0.0 for t in result.timing.values()), result.timing  # the squeeze's contacts not in closing's
    for a, b in zip(squeezed, plain):
        assert a.measures is not None and b.measures is not None
        assert a.measures.squeezed_force_closure >= a.force_closure  # type: ignore[operator]
        assert b.measures.squeezed_force_closure is None
        bare = replace(a, measures=replace(a.measures, **dict.fromkeys(SQUEEZE)), end_kept=None)  # the squeeze's too
        assert bare.to_json() == b.to_json()


#: The candidate fields a squeeze's end shares with its parent.
CANDIDATE = ("object", "hand", "preshape", "candidate", "seed", "roll", "standoff", "table_plane")


def test_a_squeeze_that_ends_force_closure_is_kept_as_a_grasp_of_its_own() -> None:
    """Where the planned contacts are not force closure and the squeeze ends force closure, the sweep keeps the end
    right after its parent: the turned pose, force closure as planned there (its own squeeze not turned), the
    parent's candidate fields, ``squeezed_from_turn`` the parent's turn; a parent of each kind has one, no other."""
    result = unit.plan_object(load_object("mug"), "panda", SweepSettings(approaches=60, rolls=2, reach_placements=0),
                              3)
    grasps = result.grasps
    ends = [i for i, g in enumerate(grasps) if g.squeezed_from_turn is not None]
    parents = [i for i, g in enumerate(grasps) if not g.force_closure and g.measures.squeezed_force_closure]  # type: ignore[union-attr]
    assert ends and [i + 1 for i in parents] == ends
    assert result.force_closure == sum(g.force_closure for g in grasps if g.squeezed_from_turn is None) + len(ends)
    for i in ends:
        parent, end = grasps[i - 1], grasps[i]
        assert parent.squeezed_from_turn is None and not parent.force_closure and parent.epsilon == 0.0
        assert end.force_closure and end.epsilon > 0.0
        assert end.squeezed_from_turn == parent.measures.squeeze_turn > 0.0  # type: ignore[union-attr]
        assert end.measures is not None and end.measures.squeezed_force_closure is True
        assert (end.measures.squeezed_epsilon, end.measures.squeeze_turn) == (end.epsilon, 0.0)
        assert [getattr(end, k) for k in CANDIDATE] == [getattr(parent, k) for k in CANDIDATE]
        np.testing.assert_array_equal(end.approach_point, parent.approach_point)
        turned = Rotation.from_matrix(end.pose[:3, :3] @ parent.pose[:3, :3].T).magnitude()
        assert turned == pytest.approx(end.squeezed_from_turn, abs=1e-9)


def test_turn_brings_the_closing_axis_onto_the_walls_normal_about_the_contacts_centre() -> None:
    """Known answer: contacts whose normals say the wall's normal is y turned by TILT about x; the pose turns by
    TILT about the contacts' centre (which stays where it is in the hand's frame)."""
    wall = np.array([0.0, np.cos(TILT), np.sin(TILT)])
    points = np.array([[0.0, 0.005, 0.01], [0.0, -0.005, -0.01]])
    contacts = HandContacts(points, np.array([-wall, wall]), ("a", "b"))
    pose = np.eye(4)
    turned = turn(contacts, (frozenset({"a"}), frozenset({"b"})), pose, np.array([0.0, 1.0, 0.0]))
    assert turned is not None
    np.testing.assert_allclose(turned[:3, :3] @ [0.0, 1.0, 0.0], wall, atol=1e-12)
    np.testing.assert_allclose(turned[:3, :3] @ [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], atol=1e-12)
    centre = points.mean(axis=0)
    np.testing.assert_allclose(turned[:3, :3].T @ (centre - turned[:3, 3]), centre - pose[:3, 3], atol=1e-12)
    assert turn(contacts, (frozenset({"a"}), frozenset({"c"})), pose, np.array([0.0, 1.0, 0.0])) is None


def squeeze_on(obj_spec, table_below: float | None, pose: np.ndarray | None = None):  # type: ignore[no-untyped-def]
    """The squeeze of the pinch (or the hand at ``pose`` (4, 4)) of the slab ``obj_spec`` on a table whose top lies
    ``table_below`` [m] under the slab's lowest point (None: no table), and the planned grasp's force closure."""
    from collections import Counter

    from planner.datasets.importer import CONE_EDGES, MAX_BACK_OFF
    from planner.geometry.solid import prepare
    from planner.geometry.support import Support
    from planner.plan.closing import Closed, Grasper
    from planner.plan.squeeze import squeezed
    from planner.plan.tolerances import TABLE_CLEARANCE
    from planner.sim import Sim
    from planner.specs.preshapes import sweep_preshapes

    hand, obj = load_hand("panda"), prepare(obj_spec)
    table = None if table_below is None else Support(np.array([0.0, 0.0, 1.0]), float(
        obj.mesh.vertices[:, 2].min()) - table_below).raised(TABLE_CLEARANCE).frame()
    shape = hand.widest(sweep_preshapes(hand))
    with Sim() as sim:
        grasper = Grasper.for_object(sim, hand, obj, table=table)
        closed = grasper.close_at(pinch() if pose is None else pose, shape, MAX_BACK_OFF)
        assert isinstance(closed, Closed)
        q = unit.scored(closed.contacts, hand, obj, CONE_EDGES, Counter())
        assert q is not None
        score = lambda c: unit.scored(c, hand, obj, CONE_EDGES, Counter(), False)  # noqa: E731
        return squeezed(grasper, closed, shape, q, score), q.force_closure


def test_on_a_table_the_squeeze_does_not_take_the_object_through_it(tmp_path: Path) -> None:
    """On a table it is the object that turns between the pads (the hand and the table stay): turned upright about
    the pinch near its top, the slanted slab's lower end swings down by ~4 mm, through the table it rests on. The
    table stops that turn (and each part of it); 5 cm under the slab, it does not."""
    spec = slab(tmp_path, TILT)
    resting, planned_fc = squeeze_on(spec, 0.0)
    assert not planned_fc and resting is not None
    assert (resting.force_closure, resting.turn) == (False, 0.0)
    free, _ = squeeze_on(spec, 0.05)
    assert free is not None and free.force_closure and abs(free.turn - TILT) < TURN_TOL


def test_no_turn_where_the_normals_give_no_walls_normal() -> None:
    """A contact normal that is not finite, or two fingers' normals that cancel: no turn (was a NaN pose, closed
    again)."""
    points = np.array([[0.0, 0.005, 0.01], [0.0, -0.005, -0.01]])
    sides, axis = (frozenset({"a"}), frozenset({"b"})), np.array([0.0, 1.0, 0.0])
    for normals in ([[np.nan, 0.0, 0.0], [0.0, 1.0, 0.0]], [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]):
        assert turn(HandContacts(points, np.array(normals), ("a", "b")), sides, np.eye(4), axis) is None


def test_an_import_rescored_keeps_each_pose_once_and_no_squeezes_end(tmp_path: Path) -> None:
    """`grasp import --rescore` stores exactly the poses it is given, one record each: the tilted slab's pinch
    (squeezed to force closure, the sweep would keep its end) and the upright one's, no squeeze's end."""
    import h5py

    from planner.datasets.importer import import_files
    from planner.db.store import open_db

    hand = load_hand("panda")
    folder = tmp_path / "foreign"
    (folder / "meshes").mkdir(parents=True)
    slab(tmp_path, TILT)
    trimesh.load(tmp_path / f"slab{TILT:.3f}.obj").export(folder / "meshes" / "slab.obj")
    upright = pinch()
    upright[:3, :3] = trimesh.transformations.rotation_matrix(-TILT, [1.0, 0.0, 0.0])[:3, :3] @ upright[:3, :3]
    file = folder / "slab.h5"
    with h5py.File(file, "w") as f:
        f["gripper/type"], f["gripper/configuration"] = "franka_panda", [0.08]
        f["object/file"], f["object/scale"] = "meshes/slab.obj", 1.0
        f["grasps/transforms"] = np.stack([pinch(), upright]) @ hand.export_frame
        f["grasps/qualities/flex/object_in_gripper"] = np.ones(2, np.int64)
    (result,) = import_files([file], tmp_path / "imported.db", rescore=True)
    assert result.error is None
    with open_db(tmp_path / "imported.db", create=False, readonly=True) as db:
        (stored,) = [[g for batch in db.grasp_batches(o, h) for g in batch] for o, h in db.pairs()]
    assert sorted(g.candidate for g in stored) == [0, 1] and [g.squeezed_from_turn for g in stored] == [None, None]
    tilted = next(g for g in stored if g.candidate == 0)
    assert not tilted.force_closure and tilted.measures.squeezed_force_closure is True  # type: ignore[union-attr]


def test_a_resumed_unit_stores_the_same_records_squeezes_ends_included(tmp_path: Path) -> None:
    """The mug in units of 100 points, one unit's row deleted (its grasps with it: a run killed before it was
    written) and the same command run again: every record as the uninterrupted run stored it, the squeezes' ends
    beside their parents (the same unit and candidate) included."""
    import shutil
    import sqlite3

    from helpers import grasp

    from planner.db.store import open_db

    args = ("generate", "mug", "--hand", "panda", "--approaches", "300", "--rolls", "2", "--chunk", "100",
            "--reach-placements", "1", "--workers", "1", "--quiet")
    whole, resumed = tmp_path / "whole.db", tmp_path / "resumed.db"
    code, _, err = grasp(*args, "--db", str(whole))
    assert code == 0, err

    def records(path: Path) -> list[dict]:
        with open_db(path, create=False, readonly=True) as db:
            out = [g.to_json() for batch in db.grasp_batches("mug", "panda") for g in batch]
        return sorted(({k: v for k, v in g.items() if k not in ("id", "unit_id")} for g in out),
                      key=lambda g: (g["candidate"], g["squeezed_from_turn"] is not None))

    shutil.copy(whole, resumed)
    with sqlite3.connect(resumed) as conn:
        conn.execute("PRAGMA foreign_keys = ON")
        unit = conn.execute("SELECT unit_id FROM grasps WHERE squeezed_from_turn IS NOT NULL LIMIT 1").fetchone()[0]
        conn.execute("DELETE FROM units WHERE id = ?", (unit,))
        assert conn.execute("SELECT COUNT(*) FROM grasps WHERE unit_id = ?", (unit,)).fetchone()[0] == 0
    code, _, err = grasp(*args, "--db", str(resumed))
    assert code == 0, err
    expected = records(whole)
    assert any(g["squeezed_from_turn"] is not None for g in expected)
    assert records(resumed) == expected


#: [rad] the slope of the grooved slab's two facets under the pad: more than the friction angle's half, so a pad
#: touching one edge of the groove turns past the flush pose to its other edge.
GROOVE = np.radians(20.0)


def grooved(tmp_path: Path):  # type: ignore[no-untyped-def]
    """A slab extruded along z: its -y face flat, its +y face a shallow V groove along z (facets sloped GROOVE either
    way, 6 cm wide), centred so a pad 2 cm wide pressed flush touches the groove at both its edges, 6 mm either side
    of the origin."""
    from shapely.geometry import Polygon

    half, a, t = 0.01, 0.006, np.tan(GROOVE)
    section = [(-0.03, -a), (0.03, -a), (0.03, a - half * t + 0.03 * t), (0.0, a - half * t),
               (-0.03, a - half * t + 0.03 * t)]
    mesh = trimesh.creation.extrude_polygon(Polygon(section), TALL)
    mesh.apply_translation([0.0, 0.0, 0.03 - TALL])
    mesh.export(tmp_path / "groove.obj")
    return load_object(str(tmp_path / "groove.obj")).spec


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_pad_on_a_concave_face_turns_back_half_way_to_force_closure(tmp_path: Path, sign: float) -> None:
    """The jaw turned by half the groove's slope about its approach: one pad flat on the slab's flat face touches it
    at one edge, the other pad the groove at its opposite edge (a couple: not force closure). The whole turn takes
    the closing axis onto that facet's normal and the flat face's, past the flush pose to its mirror image, where the
    pad touches the groove at its other edge and the turn points back (until ALGORITHM_VERSION 28 the squeeze flipped
    so three times and ended not force closure); bisected, the hand ends flush, turned by half the slope."""
    rolled = np.eye(4)
    rolled[:3, :3] = Rotation.from_rotvec([0.0, 0.0, sign * GROOVE / 2.0]).as_matrix()
    squeeze, planned_fc = squeeze_on(grooved(tmp_path), None, rolled @ pinch())
    assert not planned_fc and squeeze is not None
    assert squeeze.force_closure and squeeze.epsilon > 0.0
    assert squeeze.turn == pytest.approx(GROOVE / 2.0, abs=TURN_TOL)


def test_bracketed_halves_a_bracket_towards_the_turn_and_opens_one_where_the_turn_turns_back() -> None:
    """Known answers about z: from 0 to 0.2 rad, a turn back to -0.1 opens the bracket (0, 0.2) (a turn about x
    does not); at its middle a turn towards 0.2 keeps the upper half, towards 0 the lower; midway between 0 and 0.2
    lies 0.1."""
    def about(axis: str, angle: float) -> np.ndarray:
        out = np.eye(4)
        out[:3, :3] = Rotation.from_euler(axis, angle).as_matrix()
        return out

    low, high = about("z", 0.0), about("z", 0.2)
    assert bracketed(None, low, high, about("z", -0.1)) == (low, high)
    assert bracketed(None, low, high, about("x", 0.3) @ high) is None
    assert bracketed(None, None, high, about("z", -0.1)) is None
    middle = midway(low, high)
    np.testing.assert_allclose(middle, about("z", 0.1), atol=1e-12)
    assert bracketed((low, high), None, middle, about("z", 0.15)) == (middle, high)
    assert bracketed((low, high), None, middle, about("z", 0.05)) == (low, middle)


@pytest.mark.parametrize("lean", [0.1, -0.1, 0.5, -0.5])
def test_at_a_brackets_middle_a_turn_about_another_axis_is_a_turn_not_a_half(lean: float) -> None:
    """At the middle of the bracket (0, 0.2) about z, a turn mostly about x (leaning ``lean`` rad about z: its
    cosine with either end at most 0.7) is the wall curving the other way: no half of the bracket, as at its first
    closing (until ALGORITHM_VERSION 29 the sign of that cosine picked a half)."""
    low, high = np.eye(4), np.eye(4)
    high[:3, :3] = Rotation.from_euler("z", 0.2).as_matrix()
    middle = midway(low, high)
    whole = np.eye(4)
    whole[:3, :3] = Rotation.from_rotvec([0.3, 0.0, 0.3 * lean]).as_matrix() @ middle[:3, :3]
    assert bracketed((low, high), high, middle, whole) is None


def test_every_share_of_a_turn_is_made_from_one_reading_of_the_contacts() -> None:
    """The squeeze reads a closing's turn once (:func:`turning`) and makes each share from it (:func:`turned`): the
    same poses, bit for bit, as :func:`turn` reading the contacts again for each share; None where it gives None."""
    rng = np.random.default_rng(7)
    sides, axis = (frozenset({"a"}), frozenset({"b"})), np.array([0.0, 1.0, 0.0])
    for _ in range(50):
        normals = rng.normal(size=(6, 3))
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        contacts = HandContacts(rng.normal(scale=0.01, size=(6, 3)), normals, ("a", "a", "b", "b", "a", "b"))
        pose = np.eye(4)
        pose[:3, :3] = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
        pose[:3, 3] = rng.normal(scale=0.1, size=3)
        by = turning(contacts, sides, pose, axis)
        assert by is not None
        for share in SHARES:
            assert np.array_equal(turned(pose, *by, share), turn(contacts, sides, pose, axis, share))
    assert turning(HandContacts(np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]]), ("a",)), sides, np.eye(4), axis) is None


def test_bracketed_reads_each_cosine_as_the_plain_rule_does() -> None:
    """:func:`bracketed` reads the turn from ``pose`` once (and, after a closing at a bracket's middle, the cosine with
    the bracket's end once for both ends of its rule): the same brackets as the rule written plainly, on random
    poses."""
    def plain(bracket, before, pose, whole):  # type: ignore[no-untyped-def]
        if bracket is not None:
            toward = cosine(pose, whole, bracket[1])
            if abs(toward) > 0.7:
                return (pose, bracket[1]) if toward > 0.0 else (bracket[0], pose)
        if before is not None and cosine(pose, whole, before) > 0.7:
            return before, pose
        return None

    rng = np.random.default_rng(3)

    def near(pose: np.ndarray) -> np.ndarray:
        out = np.eye(4)
        out[:3, :3] = Rotation.from_rotvec(rng.normal(scale=0.2, size=3)).as_matrix() @ pose[:3, :3]
        return out

    answers = set()
    for _ in range(200):
        low = near(np.eye(4))
        high = near(low)
        pose = midway(low, high)
        whole = near(pose)
        for bracket, before in (((low, high), high), ((low, high), low), (None, high), ((low, high), None),
                                (None, None)):
            got, want = bracketed(bracket, before, pose, whole), plain(bracket, before, pose, whole)
            assert (got is None) == (want is None)
            assert got is None or all(a is b for a, b in zip(got, want))
            answers.add(None if got is None else tuple(id(a) for a in got) == (id(before), id(pose)))
    assert answers == {None, True, False}  # each answer drawn: none, a new bracket, a half
