from pathlib import Path

import numpy as np
import pytest

from planner import api
from planner.plan.sweep import SweepSettings
from planner.present.render import HAND_RGBA, OBJECT_RGBA


@pytest.fixture(scope="module")
def db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("show") / "g.db"
    api.generate(["box"], "panda", db_path=path, settings=SweepSettings(approaches=8, rolls=2, reach_placements=0),
                 workers=1)
    return path


def colour_share(image: np.ndarray, rgba: tuple[float, ...]) -> float:
    """Share of pixels whose hue is close to ``rgba`` (lighting scales brightness)."""
    rgb = image[..., :3].astype(float)
    ref = np.array(rgba[:3]) / np.linalg.norm(rgba[:3])
    norm = np.linalg.norm(rgb, axis=-1, keepdims=True)
    cos = (rgb / np.maximum(norm, 1e-9)) @ ref
    return float(np.mean((cos > 0.995) & (norm[..., 0] > 40)))


def test_show_draws_hand_and_object(db: Path, tmp_path: Path) -> None:
    import matplotlib.image as mpimg

    out = tmp_path / "g.png"
    rows = api.show("box", "panda", out, db_path=db, rank=1)
    assert rows[0].rank == 1
    image = (mpimg.imread(out) * 255).astype(np.uint8)
    assert colour_share(image, OBJECT_RGBA) > 0.01
    assert colour_share(image, HAND_RGBA) > 0.01


def test_a_picture_that_cannot_be_written_is_a_one_line_error(db: Path, tmp_path: Path) -> None:
    """--out under a file was an internal error (FileExistsError, exit 1) after the rendering; now refused
    before, exit 2; a folder in its path that does not exist yet is still made."""
    from click.testing import CliRunner

    from planner.cli import main

    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    result = CliRunner().invoke(main, ["show", "box", "--hand", "panda", "--db", str(db), "--out",
                                       str(blocker / "g.png")])
    assert result.exit_code == 2 and "a_file is a file, not a folder" in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    api.show("box", "panda", tmp_path / "new" / "folder" / "g.png", db_path=db, rank=1)
    assert (tmp_path / "new" / "folder" / "g.png").stat().st_size > 1000


def test_contact_sheet_has_one_row_per_grasp(db: Path, tmp_path: Path) -> None:
    import matplotlib.image as mpimg

    one, three = tmp_path / "1.png", tmp_path / "3.png"
    api.show("box", "panda", one, db_path=db, top=1)
    api.show("box", "panda", three, db_path=db, top=3)
    assert mpimg.imread(three).shape[0] == pytest.approx(3 * mpimg.imread(one).shape[0], rel=0.05)


def test_patch_meshes_span_each_region_just_outside_the_object() -> None:
    from planner.present.render import PATCH_LIFT, patch_meshes
    from planner.record.contacts import HandContacts

    square = np.array([[0, 0, 0], [0.01, 0, 0], [0.01, 0.01, 0], [0, 0.01, 0]], float)
    points = np.vstack([square, [[0.05, 0.0, 0.0]]])
    normals = np.tile([0.0, 0.0, 1.0], (5, 1))  # into the object: the object lies at z > 0
    contacts = HandContacts(points, normals, ("a",) * 4 + ("b",), radius=np.array([0, 0, 0, 0, 0.003]),
                            region=np.array([0, 0, 0, 0, 1]))
    (quad, quad_faces), (disc, disc_faces) = patch_meshes(contacts)
    assert quad.shape == (5, 3) and len(quad_faces) == 8  # centre + 4 corners, a fan of 4 drawn both sides
    np.testing.assert_allclose(quad[:, 2], -PATCH_LIFT)  # lifted off the surface, towards the hand
    np.testing.assert_allclose(quad[0, :2], [0.005, 0.005])
    assert {tuple(np.round(v[:2], 6)) for v in quad[1:]} == {tuple(p[:2]) for p in square}
    np.testing.assert_allclose(np.linalg.norm(disc[1:, :2] - [0.05, 0.0], axis=1), 0.003)
    assert patch_meshes(HandContacts(points[:1], normals[:1], ("a",))) == []  # legacy points: no patches


def test_contact_marks_project_as_the_renderer_does() -> None:
    """``project`` is PyBullet's camera: its view and projection matrices map
    the same points to the same pixels."""
    import pybullet as pb

    from planner.present.render import FOV, project

    rng = np.random.default_rng(3)
    eye, target, up, size = np.array([0.4, -0.5, 0.3]), np.array([0.0, 0.01, 0.05]), np.array([0.0, 0.0, 1.0]), \
        (640, 520)
    points = target + rng.uniform(-0.05, 0.05, (20, 3))
    view = np.array(pb.computeViewMatrix(list(eye), list(target), list(up))).reshape(4, 4).T
    proj = np.array(pb.computeProjectionMatrixFOV(FOV, size[0] / size[1], 0.01, 5.0)).reshape(4, 4).T
    clip = (proj @ view @ np.c_[points, np.ones(len(points))].T).T
    ndc = clip[:, :2] / clip[:, 3:]
    expected = np.column_stack([(ndc[:, 0] + 1) / 2 * size[0], (1 - ndc[:, 1]) / 2 * size[1]])
    assert np.allclose(project(points, eye, target, up, size, FOV), expected, atol=1e-6)


def test_show_writes_large_views(db: Path, tmp_path: Path) -> None:
    import matplotlib.image as mpimg

    out = tmp_path / "big.png"
    api.show("box", "panda", out, db_path=db, rank=1)
    height, width = mpimg.imread(out).shape[:2]
    assert width >= 1800 and height >= 500


def test_a_grasp_planned_on_a_table_is_drawn_with_the_table_seen_from_above(db: Path) -> None:
    from dataclasses import replace

    from planner.db.store import open_db
    from planner.geometry.solid import load_object
    from planner.present.render import TABLE_RGBA, grasp_views
    from planner.specs.hands import load_hand

    hand, obj = load_hand("panda"), load_object("box")
    with open_db(db, create=False, readonly=True) as store:
        grasp = store.best("box", "panda", 1)[0]
    bottom = float(obj.mesh.bounds[0][2])
    alone = grasp_views(hand, obj, grasp, size=(160, 130))
    on_table = grasp_views(hand, obj, replace(grasp, table_plane=np.array([0.0, 0.0, 1.0, bottom])), size=(160, 130))
    assert all(colour_share(v.image, TABLE_RGBA) < 0.01 for v in alone)
    # every view shows the table and, seen from its side, the object above it
    assert all(colour_share(v.image, TABLE_RGBA) > 0.05 for v in on_table)
    assert all(colour_share(v.image, OBJECT_RGBA) > 0.005 for v in on_table)


def test_framing_distance_puts_every_point_just_inside_the_picture() -> None:
    from planner.present.render import FOV, framing_distance, project

    rng = np.random.default_rng(5)
    size, up = (640, 520), np.array([0.0, 0.0, 1.0])
    for _ in range(20):
        points = rng.uniform(-0.1, 0.1, (8, 3)) * rng.uniform(0.2, 2.0, 3)
        view = rng.normal(size=3)
        view[2] = abs(view[2]) * 0.5
        view /= np.linalg.norm(view)
        d = framing_distance(points, view, up, size, FOV)
        px = project(points, view * d, np.zeros(3), up, size, FOV)
        assert np.all(px >= -1e-6) and np.all(px <= np.array(size) + 1e-6)
        closer = project(points, view * 0.95 * d, np.zeros(3), up, size, FOV)
        assert np.any((closer < 0) | (closer > np.array(size)))  # the least such distance


def test_the_views_hold_the_whole_object_and_hand(tmp_path: Path) -> None:
    """No object or hand pixel on a view's border: nothing cut off (a tall
    box, which the views cut before they were framed on both)."""
    import trimesh

    from planner.db.objects import stored_object
    from planner.db.store import open_db
    from planner.present.render import grasp_views
    from planner.specs.hands import load_hand

    mesh, db = tmp_path / "tall.obj", tmp_path / "g.db"
    trimesh.creation.box(extents=[0.06, 0.04, 0.12]).export(mesh)
    api.generate([str(mesh)], "panda", db_path=db, settings=SweepSettings(approaches=32, reach_placements=0),
                 workers=1)
    with open_db(db, create=False, readonly=True) as store:
        grasps, obj = store.best("tall", "panda", 6), stored_object(store.object_row("tall"))
    assert grasps
    for grasp in grasps:
        for view in grasp_views(load_hand("panda"), obj, grasp):
            border = np.concatenate([view.image[0], view.image[-1], view.image[:, 0], view.image[:, -1]])[None]
            assert colour_share(border, OBJECT_RGBA) == 0.0 and colour_share(border, HAND_RGBA) == 0.0
            assert colour_share(view.image, OBJECT_RGBA) > 0.005 and colour_share(view.image, HAND_RGBA) > 0.005


def test_an_object_given_another_up_is_drawn_standing(db: Path, tmp_path: Path) -> None:
    """A Y-up copy of the box told its up, its grasp turned with it: the views are the upright box's (the cameras
    turn with the object's up); untold, they show it on its side."""
    from dataclasses import replace

    from planner.db.store import open_db
    from planner.geometry.solid import load_object
    from planner.present.render import grasp_views
    from planner.record.contacts import HandContacts
    from planner.specs.hands import load_hand

    turn = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])  # the box's +z to +y, exactly
    hand, box = load_hand("panda"), load_object("box")
    box.mesh.copy().apply_transform(np.block([[turn, np.zeros((3, 1))], [np.zeros(3), 1.0]])).export(
        tmp_path / "box.obj")
    with open_db(db, create=False, readonly=True) as store:
        grasp = store.best("box", "panda", 1)[0]
    c = grasp.contacts
    pose = np.eye(4)
    pose[:3, :3] = turn
    turned = replace(grasp, pose=pose @ grasp.pose, contacts=HandContacts(c.points @ turn.T, c.normals @ turn.T,
                                                                          c.links))
    size = (160, 130)
    upright = grasp_views(hand, box, grasp, size=size)
    told = grasp_views(hand, load_object(str(tmp_path / "box.obj"), up="+y"), turned, size=size)
    untold = grasp_views(hand, load_object(str(tmp_path / "box.obj")), turned, size=size)

    def apart(a: list, b: list) -> float:
        return max(float(np.mean(np.abs(x.image.astype(float) - y.image.astype(float)))) for x, y in zip(a, b))

    assert apart(told, upright) < 0.2 * apart(untold, upright)  # the light stays the world's: shading differs
    assert all(np.allclose(x.contacts, y.contacts, atol=1.0) for x, y in zip(told, upright))



def test_the_centre_of_mass_is_marked_where_it_projects(db: Path, tmp_path: Path) -> None:
    """A grasp's views carry where the object's own centre of mass (a given one too) projects, and the sheet draws
    a black and white disc there: nothing black where a view has none."""
    from dataclasses import replace

    import matplotlib.image as mpimg

    from planner.geometry.solid import load_object
    from planner.present.render import View, grasp_views, save_sheet
    from planner.specs.hands import load_hand

    (grasp,) = api.best("box", "panda", db_path=db, top=1)
    box = load_object("box")
    views = grasp_views(load_hand("panda"), box, grasp)
    moved = grasp_views(load_hand("panda"), replace(box, com=np.asarray(box.com) + [0.0, 0.0, 0.02]), grasp)
    for view, other in zip(views, moved):
        assert view.com.shape == (1, 2) and 0 < view.com[0, 0] < view.image.shape[1]
        assert np.linalg.norm(view.com - other.com) > 5  # 2 cm up moves the mark by pixels
    blank, dark = np.full((100, 120, 3), 255, np.uint8), []
    for name, com in (("marked", np.array([[60.0, 50.0]])), ("none", np.zeros((0, 2)))):
        save_sheet([([View(blank, np.zeros((0, 2)), com)], "")], tmp_path / f"{name}.png")
        dark.append(int((mpimg.imread(tmp_path / f"{name}.png")[..., :3].max(axis=-1) < 0.2).sum()))
    assert dark[0] > 50 and dark[1] == 0


def test_the_title_of_a_squeezes_end_says_so(db: Path) -> None:
    """A squeeze's end (planner.plan.keeping) was captioned "epsilon ... (force closure)" as any grasp, beside its
    parent's picture of nearly the same pose, which said it turned: the end's title names the turn and its parent."""
    from dataclasses import replace

    from planner.db.store import open_db
    from planner.present.render import title

    with open_db(db, readonly=True) as d:
        planned = d.best("box", "panda", 1)[0]
    end = replace(planned, squeezed_from_turn=np.radians(12.5))
    assert "squeeze" not in title(planned)
    assert f"a squeeze's end: turned 12.5 deg from candidate {planned.candidate}'s planned grasp" in title(end)


def test_a_long_title_does_not_shrink_the_views(tmp_path: Path) -> None:
    """`grasp show mug --rank 3 --diverse` of a squeeze's end, whose title runs ~250 characters (its squeeze, the
    feasibility reasons), gave a 1918 x 279 px picture: the three 640 x 520 px views shrunk to a third to fit the
    title's one line. The title wraps; the views keep their size."""
    from matplotlib import image

    from planner.present.render import VIEW_SIZE, View, save_sheet

    width, height = VIEW_SIZE
    blank = View(np.full((height, width, 3), 255, np.uint8), np.zeros((0, 2)))
    title = "#4 mug/panda half: " + ", ".join(f"a measure of the grasp number {i} = 0.{i:04d}" for i in range(7))
    assert len(title) > 250
    out = tmp_path / "long.png"
    save_sheet([([blank] * 3, title)], out)
    h, w = image.imread(out).shape[:2]
    assert w >= 3 * width * 0.95 and h >= height * 0.95, (w, h)


def test_no_view_looks_at_the_back_of_the_hand(db: Path, tmp_path: Path) -> None:
    """`grasp show` of a Barrett grasp drew its third view from behind the palm: the palm alone, no object, no
    finger on it. The box and its best grasp turned together so that the hand approaches straight towards the third
    view's camera: every view still shows the object (before, the third showed 0.1% of its pixels as box)."""
    from dataclasses import replace

    from planner.db.store import open_db
    from planner.geometry.frames import rotation_onto
    from planner.geometry.solid import load_object
    from planner.present.render import BEHIND_THE_PALM, VIEWS, clear_of_the_palm, grasp_views
    from planner.record.contacts import HandContacts
    from planner.specs.hands import load_hand

    hand, box = load_hand("panda"), load_object("box")
    with open_db(db, create=False, readonly=True) as store:
        grasp = store.best("box", "panda", 1)[0]
    third = VIEWS[2] / np.linalg.norm(VIEWS[2])
    pose = np.eye(4)
    pose[:3, :3] = rotation_onto(np.asarray(grasp.pose)[:3, :3] @ hand.approach, -third)
    box.mesh.copy().apply_transform(pose).export(tmp_path / "turned.obj")
    c = grasp.contacts
    turned = replace(grasp, pose=pose @ grasp.pose, contacts=HandContacts(c.points @ pose[:3, :3].T,
                                                                          c.normals @ pose[:3, :3].T, c.links))
    views = grasp_views(hand, load_object(str(tmp_path / "turned.obj")), turned, size=(160, 130))
    assert all(colour_share(v.image, OBJECT_RGBA) > 0.01 for v in views), [colour_share(v.image, OBJECT_RGBA)
                                                                          for v in views]
    up = np.array([0.0, 0.0, 1.0])
    for approach in (-third, -up, np.array([1.0, 0.0, 0.0])):  # a table's views, all from above it, stay above
        for view in (-approach, third * [1, 1, -1], up, np.array([-1.0, 0.0, 0.1]) / np.hypot(1.0, 0.1)):
            if view @ up > 0:
                seen = clear_of_the_palm(view, approach, up)
                assert np.isclose(np.linalg.norm(seen), 1.0) and seen @ approach > -BEHIND_THE_PALM and seen @ up > 0
