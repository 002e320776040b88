"""``grasp view``: the scene it draws, its filters, and the page in a real
headless browser (Debian's Chromium driven by Playwright; `.ci/run` installs it)."""

from __future__ import annotations

import os
import shutil
import socket
from pathlib import Path

import numpy as np
import pytest
from helpers import grasp, one_line_error

from planner import api
from planner.present import scene as scenes
from planner.present.viewer import Filters, filtered
from tests.helpers import assert_close

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
#: Flags for Chromium on a machine without a screen or a GPU and with a closed network.
CHROMIUM_FLAGS = ("--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync")


def _stored(box_db: Path):
    grasps = api.best("box", "panda", db_path=box_db, top=5)
    spec, _ = api.hand("panda")
    from planner.db.objects import stored_object
    from planner.db.store import open_db

    with open_db(box_db, create=False, readonly=True) as db:
        obj = stored_object(db.object_row("box"))
    return grasps, spec, obj


def test_scene_places_the_hand_at_the_grasp_and_opens_it(box_db: Path) -> None:
    grasps, spec, obj = _stored(box_db)
    g = grasps[0]
    s = scenes.grasp_scene(spec, obj.mesh, g, obj.friction)
    assert_close(s.object.world_vertices(), obj.mesh.vertices)
    closed = {p.name.split("/")[-1]: p.world_vertices() for p in s.closed}
    opened = {p.name.split("/")[-1]: p.world_vertices() for p in s.open}
    assert any("panda_hand" in k for k in closed) and not any("panda_hand" in k for k in opened), \
        "the palm is drawn once: it is at the grasp pose in both"
    assert opened and all("finger" in k for k in opened)
    assert all(not np.allclose(closed[k], opened[k], atol=1e-4) for k in opened), "open fingers are elsewhere"
    # every contact is on the object's surface and near a closed finger
    assert len(s.contacts) == len(g.contacts) == len(s.cones)
    fingers = np.vstack([v for k, v in closed.items() if "finger" in k])
    gaps = np.min(np.linalg.norm(s.contacts[:, None] - fingers[None], axis=2), axis=1)
    assert gaps.max() < 0.02


def test_object_pose_moves_everything_together(box_db: Path) -> None:
    grasps, spec, obj = _stored(box_db)
    g = grasps[0]
    pose = np.eye(4)
    pose[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    pose[:3, 3] = [0.5, 0.1, 0.02]
    here, there = scenes.grasp_scene(spec, obj.mesh, g, obj.friction), scenes.grasp_scene(
        spec, obj.mesh, g, obj.friction, pose)
    move = lambda x: x @ pose[:3, :3].T + pose[:3, 3]  # noqa: E731
    assert_close(there.object.world_vertices(), move(here.object.world_vertices()))
    assert_close(there.contacts, move(here.contacts))
    assert_close(there.approach, move(here.approach))
    for a, b in zip(here.closed, there.closed):
        assert_close(b.world_vertices(), move(a.world_vertices()))


def test_friction_cones_open_outwards(box_db: Path) -> None:
    grasps, spec, obj = _stored(box_db)
    s = scenes.grasp_scene(spec, obj.mesh, grasps[0], obj.friction)
    for cone, point, normal in zip(s.cones, s.contacts, s.normals):
        base = cone.world_vertices().mean(axis=0) - point
        assert base @ normal < 0, "the cone's body lies outside the object (against the inward normal)"


def test_arm_is_drawn_without_its_own_hand() -> None:
    spec, _ = api.hand("panda")
    assert spec.arm is not None
    parts = scenes.robot_parts(spec.arm.urdf, {}, np.eye(4), "arm", scenes.ARM_RGB, skip_below=spec.arm.ee_link)
    names = [p.name for p in parts]
    assert any("link1" in n for n in names)
    assert not any("finger" in n or "panda_hand" in n for n in names)


def test_filters_select_by_field(box_db: Path) -> None:
    from planner.present.viewer import Entry

    grasps, _, _ = _stored(box_db)
    entries = [Entry(g, lambda: None) for g in grasps]  # type: ignore[arg-type,return-value]
    assert filtered(entries, Filters()) == entries
    shape = grasps[0].preshape
    assert all(e.grasp.preshape == shape for e in filtered(entries, Filters(preshape=shape)))
    assert filtered(entries, Filters(hand="barrett")) == []
    assert len(filtered(entries, Filters(label="not validated"))) == len(entries)
    assert filtered(entries, Filters(label="held")) == []
    fc = filtered(entries, Filters(force_closure="yes")) + filtered(entries, Filters(force_closure="no"))
    assert sorted(id(e) for e in fc) == sorted(id(e) for e in entries)


def test_the_force_closure_filter_keeps_what_ranks_first() -> None:
    """The force-closure filter keeps the grasps force closure as planned or once squeezed
    (planner.db.ranking.FIRST), and the measures say which of the two; one whose squeeze's end is stored beside it
    ranks with the others (the end stands for it)."""
    from dataclasses import replace

    from planner.present.viewer import Entry, measures_text
    from planner.record.measures import Measures
    from tests.helpers import made_up

    squeeze = Measures(3.0, 4.0, 0.01, 0.01, 1.0, ())
    grasps = [made_up(0, 0.1), *(replace(made_up(i, 0.0, fc=False), measures=replace(squeeze, squeezed_force_closure=s))
                                 for i, s in ((1, True), (2, False))), made_up(3, 0.0, fc=False)]
    entries = [Entry(g, lambda: None) for g in grasps]  # type: ignore[arg-type,return-value]
    assert filtered(entries, Filters(force_closure="yes")) == entries[:2]
    assert filtered(entries, Filters(force_closure="no")) == entries[2:]
    assert "| force closure | once squeezed (not as planned) |" in measures_text(entries[1])
    assert "| force closure | no |" in measures_text(entries[2])
    parent = [Entry(replace(grasps[1], end_kept=True), lambda: None)]  # type: ignore[arg-type,return-value]
    assert filtered(parent, Filters(force_closure="yes")) == []  # its squeeze's end is stored: it stands for it
    assert filtered(parent, Filters(force_closure="no")) == parent
    assert "| force closure | once squeezed (not as planned, its stored end ranks for it) |" in measures_text(parent[0])


def test_a_squeezes_end_says_whose_end_it_is() -> None:
    """An end (`squeezed_from_turn` set, its parent's candidate number) read "force closure | yes" alone in the
    viewer, beside its parent of the same number; `grasp best` and `grasp show` say whose end it is."""
    import math
    from dataclasses import replace

    from planner.present.viewer import Entry, measures_text
    from tests.helpers import made_up

    end = replace(made_up(7, 0.05), squeezed_from_turn=math.radians(5.7))
    text = measures_text(Entry(end, lambda: None))  # type: ignore[arg-type,return-value]
    assert f"| force closure | yes, a squeeze's end: turned 5.7 deg from candidate {end.candidate}'s planned grasp |" \
        in text


def test_an_imported_files_label_is_listed_with_the_measures() -> None:
    """A grasp imported with its file's label (ACRONYM's flex/object_in_gripper) listed none of it."""
    from dataclasses import replace

    from planner.present.viewer import Entry, measures_text
    from planner.record.grasp import FileLabel
    from tests.helpers import made_up

    label = FileLabel(False, "crate.h5 grasps/qualities/flex/object_in_gripper")
    text = measures_text(Entry(replace(made_up(3, 0.05), file_label=label), lambda: None))  # type: ignore[arg-type,return-value]
    assert "| label of the file it was imported from | dropped (crate.h5 grasps/qualities/flex/object_in_gripper) |" \
        in text
    assert "imported from" not in measures_text(Entry(made_up(3, 0.05), lambda: None))  # type: ignore[arg-type,return-value]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.skipif(CHROMIUM is None and not os.environ.get("CI"),
                    reason="Chromium not installed (.ci/run installs it)")
def test_page_loads_in_a_real_browser(box_db: Path, tmp_path: Path) -> None:
    assert CHROMIUM is not None, "CI must have Chromium (apt-get install chromium)"
    from playwright.sync_api import sync_playwright

    viewer = api.view("box", ["panda"], db_path=box_db, top=5, port=_free_port())
    connects: list[int] = []
    viewer.server.on_client_connect(lambda client: connects.append(client.client_id))
    shot = tmp_path / "view.png"
    try:
        names = set(viewer.nodes)
        assert "object" in names and "approach" in names
        assert any(n.startswith("hand/closed/") for n in names) and any(n.startswith("hand/open/") for n in names)
        assert any(n.startswith("contacts/cone_") for n in names)
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=list(CHROMIUM_FLAGS))
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.goto(viewer.url)
            # the panel the page built from the server's messages: filters and the selected grasp's measures
            page.get_by_text("epsilon (Ferrari-Canny L1)").wait_for(timeout=60_000)
            for text in ("force closure", "open hand", "hand base, object frame", viewer.entries[0].title()):
                assert page.get_by_text(text).count() >= 1, text
            assert page.locator("canvas").count() >= 1, "the 3D canvas"
            page.wait_for_timeout(6000)  # new meshes fade in
            page.screenshot(path=str(shot))
            # picking the second grasp in the page replaces the hand on screen
            first = {n: h for n, h in viewer.nodes.items() if n.startswith("hand/closed/")}
            viewer.rank.value = 2
            page.get_by_text(viewer.entries[1].title()).first.wait_for(timeout=30_000)
            browser.close()
        assert connects, "the page opened the viewer's websocket"
        assert viewer.selected is viewer.entries[1]
        assert all(viewer.nodes.get(n) is not h for n, h in first.items())
        assert shot.stat().st_size > 10_000
    finally:
        viewer.stop()
    keep = os.environ.get("GRASP_VIEW_SCREENSHOT")
    if keep:  # for looking at it: GRASP_VIEW_SCREENSHOT=/tmp/view.png pytest -k real_browser
        shutil.copy(shot, keep)


@pytest.mark.parametrize("option, message", [(["--port", "99999"], "--port must be within 0-65535"),
                                             (["--host", "10.255.255.1"], "cannot serve on --host 10.255.255.1")])
def test_an_address_the_server_cannot_take_is_a_one_line_error(box_db: Path, option: list[str], message: str) -> None:
    """viser's server thread failed on these while the command waited for it forever."""
    code, _, err = grasp("view", "box", "--hand", "panda", "--db", str(box_db), *option)
    one_line_error(code, err, 2, message)


def test_a_broken_away_distal_is_drawn_at_its_stored_angle() -> None:
    """yourdfpy moved a Barrett mimic joint with its master, so a broken-away distal (stored behind its coupling)
    was drawn at the coupling: 74 of 640 grasps' contacts lay 4-36 mm off their links in the pictures."""
    from planner.specs.hands import load_hand

    hand = load_hand("barrett")
    coupled = hand.posture({"bh_j11_joint": 0.0, "bh_j12_joint": 1.0, "bh_j22_joint": 1.0, "bh_j32_joint": 1.0})
    broken = {**coupled, "bh_j13_joint": coupled["bh_j13_joint"] - 0.5}
    poses = [{p.name: p.pose for p in scenes.robot_parts(hand.urdf, joints, np.eye(4), "h", (0, 0, 0))}
             for joints in (coupled, broken)]
    assert [name for name in poses[0] if not np.allclose(poses[0][name], poses[1][name])] == ["h/bh_finger_13_link_4"]


def test_the_viewer_stands_an_object_on_its_own_up(tmp_path: Path) -> None:
    """A Y-up file's object (up +y) is shown with +y up, the camera above it; with --object-pose the world's z."""
    import trimesh

    mesh = trimesh.creation.box(extents=(0.05, 0.04, 0.08))
    mesh.apply_transform(np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]]))
    mesh.export(tmp_path / "crate.glb")
    db = tmp_path / "g.db"
    code, _, err = grasp("generate", str(tmp_path / "crate.glb"), "--hand", "panda", "--db", str(db), "--quiet",
                         "--approaches", "6", "--rolls", "2", "--workers", "1", "--reach-placements", "0")
    assert code == 0, err
    shown = api.view("crate", db_path=db, top=2, port=_free_port())
    try:
        camera = shown.server.initial_camera
        assert shown.up == "+y" and np.allclose(camera.up, [0.0, 1.0, 0.0])
        assert np.subtract(camera.position, camera.look_at)[1] > 0  # seen from above its up
    finally:
        shown.stop()


def test_the_measures_panel_prints_a_coordinate_that_rounds_to_zero_as_best_does() -> None:
    """The panel said "(-0.035, -0.000, 0.107) m" for the hand base `grasp best` gives as "(-0.035, 0.000, 0.107)"."""
    from dataclasses import replace

    from helpers import made_up

    from planner.present.viewer import Entry, measures_text

    pose = np.eye(4)
    pose[:3, 3] = [-0.035, -1e-17, 0.107]
    pose[:3, :3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 1e-12], [0.0, -1e-12, 1.0]]  # a hair's turn: x of xyzw -5e-13
    text = measures_text(Entry(replace(made_up(0, 0.05), pose=pose), lambda: None))  # type: ignore[arg-type,return-value]
    assert "| hand base, object frame | (-0.035, 0.000, 0.107) m |" in text, text
    assert "-0.000" not in text, text
