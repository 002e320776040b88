"""Closing the hand on the object: known contacts on a box and a sphere,
rejections, and every hand closing to a force-closure grasp of objects of its size."""

import numpy as np
import pytest
import scanlike
import trimesh
from helpers import SIM_TOL, assert_close

from planner.geometry.proxy import ProxySettings, collision_proxy, distances
from planner.geometry.solid import PreparedObject, load_object, prepare
from planner.plan import sampling
from planner.plan.closing import Closed, Grasper, Rejected
from planner.plan.obstacle_queries import HullBracket
from planner.plan.unit import grasp_quality
from planner.sim import Sim
from planner.specs.hands import HandSpec, hand_names, load_hand
from planner.specs.objects import ObjectSpec
from planner.specs.preshapes import load_preshapes

DOWN = np.array([0.0, 0.0, -1.0])
HANDS = hand_names()
SEED = 0
#: Characteristic radius [m] of the test objects per hand (about a third of
#: the opening); a hand added later gets the default until it is listed.
OBJECT_RADIUS = {"panda": 0.025, "pr2": 0.02, "barrett": 0.04, "allegro": 0.03}
DEFAULT_RADIUS = 0.03
RAYS = 12
CONE_EDGES = 8


@pytest.fixture(scope="module")
def panda():  # type: ignore[no-untyped-def]
    h = load_hand("panda")
    return h, {s.name: s for s in load_preshapes(h)}


def close_on(obj_name: str, point, direction, roll, standoff, shape):  # type: ignore[no-untyped-def]
    obj = load_object(obj_name)
    h, shapes = shape
    with Sim() as sim:
        g = Grasper.for_mesh(sim, h, obj.mesh)
        return g.close(np.asarray(point, float), np.asarray(direction, float), roll, standoff, shapes["wide"],
                       obj.torque_scale)


def test_panda_pinches_box_symmetrically(panda) -> None:  # type: ignore[no-untyped-def]
    # box 5 x 4 x 8 cm; from the top with roll 0 the fingers (hand y) close on the 4 cm faces
    r = close_on("box", [0, 0, 0.04], DOWN, 0.0, 0.02, panda)
    assert isinstance(r, Closed)
    q = r.closed_joints
    assert q["panda_finger_joint1"] == pytest.approx(q["panda_finger_joint2"])
    finger_links = {"panda_leftfinger", "panda_rightfinger"}
    assert finger_links <= set(r.contacts.links)
    on_fingers = np.isin(r.contacts.links, list(finger_links))
    # contacts lie on the two y faces with normals pointing into the box
    assert_close(np.abs(r.contacts.points[on_fingers, 1]), np.full(on_fingers.sum(), 0.02), SIM_TOL)
    assert np.all(r.contacts.normals[on_fingers, 1] * r.contacts.points[on_fingers, 1] < 0)
    # the hand stays centred over the box and its z axis points down
    assert_close(r.pose[:2, 3], [0, 0], SIM_TOL)
    assert_close(r.pose[:3, 2], DOWN, 1e-9)


def test_standoff_zero_touches_with_the_palm(panda) -> None:  # type: ignore[no-untyped-def]
    r = close_on("box", [0, 0, 0.04], DOWN, 0.0, 0.0, panda)
    assert isinstance(r, Closed) and "panda_hand" in r.contacts.links


def test_too_wide_object_is_only_touched_on_the_near_face(panda) -> None:  # type: ignore[no-untyped-def]
    # from +x with the fingers closing along z: the box is 8 cm tall, wider than
    # the open hand's 7.8 cm between the pads, so the tips land on the +x face
    for roll in (0.0, np.pi / 2):
        r = close_on("box", [0.025, 0, 0], [-1, 0, 0], roll, 0.0, panda)
        assert isinstance(r, Closed)
        if abs(r.pose[2, 1]) > 0.99:  # hand y (the finger axis) along world z
            assert np.all(r.contacts.normals[:, 0] < -0.99)  # all on the +x face (tips, edges)
            assert set(r.contacts.links) == {"panda_leftfinger", "panda_rightfinger"}
            return
    raise AssertionError("no roll put the finger axis along z")


def test_ray_that_misses_is_rejected(panda) -> None:  # type: ignore[no-untyped-def]
    r = close_on("sphere", [0.5, 0.5, 0.5], DOWN, 0.0, 0.0, panda)
    assert isinstance(r, Rejected) and r.reason == "missed"


def test_sphere_contacts_have_radial_normals(panda) -> None:  # type: ignore[no-untyped-def]
    r = close_on("sphere", [0, 0, 0.03], DOWN, 0.3, 0.02, panda)
    assert isinstance(r, Closed)
    radial = r.contacts.points / np.linalg.norm(r.contacts.points, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", r.contacts.normals, -radial) > 0.95)
    assert_close(np.linalg.norm(r.contacts.points, axis=1), np.full(len(r.contacts), 0.03), SIM_TOL)


def fingers(hand: HandSpec) -> dict[str, str]:
    """Finger of each moving link: the outermost finger joint that moves it."""
    out: dict[str, str] = {}
    for joint in sorted(hand.joints, key=lambda j: -len(j.moves)):
        for link in joint.moves:
            out.setdefault(link, joint.name)
    return out


def sized_objects(radius: float) -> dict[str, PreparedObject]:
    """A sphere of ``radius`` [m], and a box and a cylinder of about its size."""
    r = radius
    specs = [ObjectSpec(name="sphere", kind="sphere", dims=(r,), mass=0.2),
             ObjectSpec(name="box", kind="box", dims=(1.6 * r, 1.2 * r, 2.4 * r), mass=0.2),
             ObjectSpec(name="cylinder", kind="cylinder", dims=(0.8 * r, 3.0 * r), mass=0.2)]
    return {s.name: prepare(s) for s in specs}


@pytest.mark.parametrize("name", HANDS)
def test_hand_closes_to_force_closure(name: str) -> None:
    hand = load_hand(name)
    shapes = load_preshapes(hand)
    finger_of = fingers(hand)
    multi = len(set(finger_of.values())) > 1
    for obj in sized_objects(OBJECT_RADIUS.get(name, DEFAULT_RADIUS)).values():
        rays = sampling.sample(obj.mesh, sampler="surface", count=RAYS, rng=np.random.default_rng(SEED))
        with Sim() as sim:
            grasper = Grasper.for_mesh(sim, hand, obj.mesh)
            found = _first_force_closure(grasper, shapes, rays, obj, finger_of, multi)
        assert found is not None, f"{name}: no force-closure grasp of the {obj.name}"


def _first_force_closure(grasper, shapes, rays, obj, finger_of, multi):  # type: ignore[no-untyped-def]
    for shape in shapes:
        for standoff in shape.standoffs:
            for i in range(len(rays)):
                closed = grasper.close(rays.points[i], rays.directions[i], 0.0, standoff, shape, obj.torque_scale)
                if not isinstance(closed, Closed):
                    continue
                touching = {finger_of[link] for link in closed.contacts.links if link in finger_of}
                if multi and len(touching) < 2:
                    continue
                if grasp_quality(closed.contacts, grasper.hand, obj, CONE_EDGES).force_closure:
                    return closed
    return None


# -- issue 26: closing at a given pose, thin walls, any tessellation ----------

#: Closing stops each finger within CloseSettings.contact_tol (0.5 mm) of the
#: surface, and a finer mesh of a curved surface lies up to its chord's
#: sagitta (0.11 mm for the 32-gon below) outside the coarse one: the closed
#: widths of two tessellations agree to twice their sum.
TESSELLATION_TOL = 2 * (0.0005 + 0.00011)
#: [m] a point placed on a surface is this close to it (round-off).
ON_SURFACE = 1e-9
#: The tube: 10 cm across (the open inner finger, 3.4 cm deep, fits inside),
#: 2 mm wall, 512 sections (4,096 triangles, more than one PyBullet body of
#: 127 surface hulls of 16 triangles covers).
WALL = 0.002
TUBE_RADIUS, TUBE_HEIGHT, TUBE_SECTIONS = 0.05, 0.06, 512
#: A flat pad 17.4 mm wide on the tube's inner face (radius r) touches at its
#: edges, r - sqrt(r^2 - 8.7 mm^2) = 0.79 mm off the face at its centre.
PAD_SAGITTA = 0.048 - np.sqrt(0.048**2 - 0.0087**2)


def _grasp_pose(hand: HandSpec, tcp: np.ndarray, approach: np.ndarray, fingers: np.ndarray) -> np.ndarray:
    """(4, 4) Panda pose with its tool centre point at ``tcp``, its approach
    along ``approach`` and its fingers opening along ``fingers`` (unit, orthogonal)."""
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([np.cross(fingers, approach), fingers, approach])
    pose[:3, 3] = tcp - pose[:3, :3] @ np.array([0.0, 0.0, 0.1034])
    return pose


def _finger_contacts(closed: Closed) -> set[str]:
    return {link for link in closed.contacts.links if link.endswith("finger")}


def test_panda_closes_on_a_thin_rim_without_penetration(panda) -> None:  # type: ignore[no-untyped-def]
    hand, shapes = panda
    tube = trimesh.creation.annulus(r_min=TUBE_RADIUS - WALL, r_max=TUBE_RADIUS, height=TUBE_HEIGHT,
                                    sections=TUBE_SECTIONS)
    with Sim() as sim:
        grasper = Grasper.for_mesh(sim, hand, tube)
        for angle in np.linspace(0.0, 2 * np.pi, 8, endpoint=False):
            radial = np.array([np.cos(angle), np.sin(angle), 0.0])
            rim = (TUBE_RADIUS - WALL / 2) * radial + [0.0, 0.0, TUBE_HEIGHT / 2 - 0.005]
            pose = _grasp_pose(hand, rim, DOWN, radial)
            assert not grasper.overlaps_at(pose, shapes["wide"].joints)
            closed = grasper.close_at(pose, shapes["wide"])
            assert isinstance(closed, Closed), f"angle {angle:.2f}: {closed}"
            assert _finger_contacts(closed) == {"panda_leftfinger", "panda_rightfinger"}
            width = closed.closed_joints["panda_finger_joint1"] + closed.closed_joints["panda_finger_joint2"]
            # first contact on each side of the wall: neither finger inside it, nor short of it
            tol = grasper.settings
            assert WALL - tol.max_penetration <= width <= WALL + PAD_SAGITTA + 2 * tol.contact_tol


def _capsule_widths(hand: HandSpec, shape, mesh: trimesh.Trimesh | PreparedObject) -> list[float]:  # type: ignore[no-untyped-def]
    """Closed widths [m] at poses across the capsule's side and its cap (an
    object: closed as the sweep closes it, through its collision proxy)."""
    return [w for w, _ in _capsule_closings(hand, shape, mesh)]


def _capsule_closings(hand: HandSpec, shape, mesh: trimesh.Trimesh | PreparedObject) -> list[tuple[float, Closed]]:  # type: ignore[no-untyped-def]
    poses = []
    for angle in np.linspace(0.0, np.pi, 5, endpoint=False):
        inward = -np.array([np.cos(angle), np.sin(angle), 0.0])
        across = np.array([-np.sin(angle), np.cos(angle), 0.0])
        poses.append(_grasp_pose(hand, np.array([0.0, 0.0, 0.02 * np.cos(3 * angle)]), inward, across))
    for height in (0.045, 0.05):  # over the end cap, fingers closing on the hemisphere
        poses.append(_grasp_pose(hand, np.array([0.0, 0.0, height]), DOWN, np.array([1.0, 0.0, 0.0])))
    out = []
    with Sim() as sim:
        grasper = Grasper.for_object(sim, hand, mesh) if isinstance(mesh, PreparedObject) else \
            Grasper.for_mesh(sim, hand, mesh)
        for pose in poses:
            closed = grasper.close_at(pose, shape)
            assert isinstance(closed, Closed), f"{mesh}: {closed}"
            assert _finger_contacts(closed) == {"panda_leftfinger", "panda_rightfinger"}
            out.append((closed.closed_joints["panda_finger_joint1"] + closed.closed_joints["panda_finger_joint2"],
                        closed))
    return out


def test_a_coarse_and_a_fine_capsule_close_alike(panda) -> None:  # type: ignore[no-untyped-def]
    hand, shapes = panda
    coarse = trimesh.creation.capsule(height=0.07, radius=0.022, count=[32, 32])  # 2,048 triangles
    fine = trimesh.creation.capsule(height=0.07, radius=0.022, count=[96, 96])  # 18,432 triangles
    assert_close(_capsule_widths(hand, shapes["wide"], fine), _capsule_widths(hand, shapes["wide"], coarse),
                 TESSELLATION_TOL)


#: A scan closes against its proxy, within ProxySettings.tolerance of it: the
#: closed widths of a scan and of a coarse mesh of the same shape agree to
#: twice the contact tolerance, the coarse mesh's sagitta (~0.11 mm for edges
#: of 4.4 mm on a 22 mm radius) and the proxy's tolerance.
PROXY_TESSELLATION_TOL = 2 * (0.0005 + 0.00011 + ProxySettings().tolerance)


def test_a_scan_closes_through_its_proxy_like_a_coarse_mesh_with_contacts_on_the_scan(panda, tmp_path) -> None:  # type: ignore[no-untyped-def]
    hand, shapes = panda
    path = tmp_path / "scan.obj"
    path.write_text(scanlike.uv_obj(20_000))  # UV-split vertices, as published
    scan = load_object(str(path))
    proxy = collision_proxy(scan.mesh, scan.mesh_hash)
    assert not proxy.exact and len(proxy.mesh.faces) < len(scan.mesh.faces) / 2
    closings = _capsule_closings(hand, shapes["wide"], scan)
    assert_close([w for w, _ in closings], _capsule_widths(hand, shapes["wide"], scanlike.capsule(2_000)),
                 PROXY_TESSELLATION_TOL)
    points = np.vstack([c.contacts.points for _, c in closings])
    assert distances(scan.mesh, points).max() < ON_SURFACE  # read on the proxy, placed on the scan
    assert distances(proxy.mesh, points).max() <= proxy.deviation + ON_SURFACE




@pytest.mark.parametrize("table", [False, True])
def test_a_links_gap_without_its_pairs_equals_the_gap_of_its_pairs(table: bool) -> None:
    """What closing a revolute finger reads of a link (:meth:`Grasper._obstacle_gap`, no pairs made) is the gap of
    the pairs the directional bound reads (far hulls, the exact mesh near them, a long reach cut, the table), to
    the last bit, and counts one query as they do: every read of the Barrett's closings on the mug, seeded rays."""
    hand, obj = load_hand("barrett"), load_object("mug")
    shapes = load_preshapes(hand)
    rays = sampling.sample(obj.mesh, sampler="surface", count=6, rng=np.random.default_rng(SEED))
    top = np.eye(4)
    top[2, 3] = obj.mesh.bounds.mean(axis=0)[2]  # a table through the mug: the fingers meet both
    seen = set()
    with Sim() as sim:
        grasper = Grasper.for_object(sim, hand, obj, table=top if table else None)
        s, read = grasper.settings, grasper._obstacle_gap

        def checked(reach: float, link: str, bracket: HullBracket | None = None) -> float:
            before = grasper.queries
            want = grasper._gap(grasper._obstacles(reach, link))
            middle = grasper.queries
            got = read(reach, link, bracket)
            assert got == want and grasper.queries - middle == middle - before
            seen.add("none" if np.isinf(got) else "far" if got > s.near else "cut" if reach > s.exact_reach else "near")
            return got

        grasper._obstacle_gap = checked  # type: ignore[method-assign]
        for i in range(len(rays)):
            for shape in shapes:
                grasper.close(rays.points[i], rays.directions[i], 0.0, 0.0, shape, obj.torque_scale)
    assert {"none", "far", "cut"} <= seen  # nothing near, a hull gap, the exact mesh within the cut reach


def test_the_broadphase_changes_no_read_and_skips_queries() -> None:
    """The box test before a query of the surface hulls (:meth:`Grasper._beyond`) gives every read of the
    Barrett's closings on the mug (seeded rays) as the query itself would, to the last bit: each gap of a
    finger link and each set of pairs of the whole hand; and it skips some of those queries, not all."""
    hand, obj = load_hand("barrett"), load_object("mug")
    shapes = load_preshapes(hand)
    rays = sampling.sample(obj.mesh, sampler="surface", count=4, rng=np.random.default_rng(SEED))
    skipped = asked = 0
    with Sim() as sim:
        grasper = Grasper.for_object(sim, hand, obj)
        gap, closest, beyond = grasper._obstacle_gap, grasper._closest, grasper._beyond

        def without(read, *args):  # type: ignore[no-untyped-def]
            kept, grasper._box_gap = grasper._box_gap, lambda index: -np.inf  # type: ignore[method-assign]
            try:
                return read(*args)
            finally:
                grasper._box_gap = kept  # type: ignore[method-assign]

        def counted(index: int, distance: float) -> bool:
            nonlocal skipped, asked
            out = beyond(index, distance)
            skipped, asked = skipped + int(out), asked + int(not out)
            return out

        hulls = [0]
        query = grasper.sim.min_distance

        def hull_counted(a: int, b: int, distance: float, link: int | None = None) -> float:
            hulls[0] += b == grasper.far_body
            return query(a, b, distance, link)

        def checked_gap(reach: float, link: str, bracket: HullBracket | None = None) -> float:
            nonlocal skipped, asked
            before = hulls[0]
            got = gap(reach, link, bracket)
            made = hulls[0] - before
            skipped, asked = skipped + int(not made), asked + made
            assert got == without(gap, reach, link)
            return got

        def checked_closest(reach: float, link: str | None = None):  # type: ignore[no-untyped-def]
            got, want = closest(reach, link), without(closest, reach, link)
            for key in ("links", "distance", "on_a", "on_b", "normal_b"):
                assert np.array_equal(getattr(got, key), getattr(want, key))
            assert type(got) is type(want)
            return got

        grasper._obstacle_gap, grasper._closest = checked_gap, checked_closest  # type: ignore[method-assign]
        grasper._beyond, grasper.sim.min_distance = counted, hull_counted  # type: ignore[method-assign]
        for i in range(len(rays)):
            for shape in shapes:
                grasper.close(rays.points[i], rays.directions[i], 0.0, 0.0, shape, obj.torque_scale)
    assert skipped > 0 and asked > 0


def test_a_link_far_from_the_object_is_not_queried() -> None:
    """A finger link a metre from the object reads no pairs, and PyBullet is not asked."""
    hand, obj = load_hand("barrett"), load_object("mug")
    with Sim() as sim:
        grasper = Grasper.for_object(sim, hand, obj)
        far = np.eye(4)
        far[0, 3] = 1.0
        grasper._place(far, {})
        calls = []
        for name in ("min_distance", "closest"):
            real = getattr(sim, name)
            setattr(sim, name, lambda *a, real=real, **k: calls.append(a) or real(*a, **k))
        link = hand.contact_links[-1]
        assert grasper._obstacle_gap(0.01, link) == np.inf
        assert len(grasper._closest(0.01, link)) == 0 and len(grasper._closest(0.01)) == 0
        assert calls == []

def _capsule_normal(points: np.ndarray) -> np.ndarray:
    """(n, 3) the true capsule's inward unit normals at ``points`` (n, 3) near it (scanlike's capsule)."""
    axis = np.zeros_like(points)
    axis[:, 2] = np.clip(points[:, 2], -0.5 * scanlike.HEIGHT, 0.5 * scanlike.HEIGHT)
    out = axis - points
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def test_a_rough_scans_contacts_take_the_surfaces_normal_not_a_noisy_facets(panda, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A rough scan (0.1 mm of noise on the capsule's 20k faces) is closed through its proxy; a contact's normal
    is the scan's averaged over a contact's scale, near the true shape's: it was the proxy facet's, tilted by
    the noise (up to tens of degrees), which decided force closure by which proxy a scan got."""
    hand, shapes = panda
    path = tmp_path / "rough.obj"
    path.write_text(scanlike.uv_obj(20_000, noise=1e-4))
    scan = load_object(str(path))
    assert not collision_proxy(scan.mesh, scan.mesh_hash).exact
    closings = _capsule_closings(hand, shapes["wide"], scan)
    contacts = [c.contacts for _, c in closings]
    points, normals = np.vstack([c.points for c in contacts]), np.vstack([c.normals for c in contacts])
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", normals, _capsule_normal(points)), -1.0, 1.0)))
    assert angle.max() < 5.0, np.round(np.sort(angle)[-5:], 1)


def test_a_fine_boxs_edge_contacts_keep_the_edges_normal_through_a_proxy(panda) -> None:  # type: ignore[no-untyped-def]
    """A finely meshed box (49k faces, closed on a proxy: here the 12-face box itself) gripped across two of its
    vertical edges: the contacts on an edge read on the proxy have a normal in the edge's cone (the diagonal,
    toward the pad), and moved onto the exact mesh they keep it, as the exact mesh's own reading has it. The
    exact mesh's closest face at an edge is a tie between its two faces: the contact took that face's normal,
    45 degrees off (90 degrees between the two fingers' contacts), or the top face's."""
    hand, shapes = panda
    coarse = trimesh.creation.box(extents=(0.04, 0.04, 0.04))
    fine = coarse.subdivide_to_size(0.0012)
    assert len(fine.faces) > 5000
    across = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    with Sim() as sim:
        exact = Grasper.for_mesh(sim, hand, fine)
        proxy = Grasper(sim, hand, sim.add_static_mesh(coarse.vertices, coarse.faces), mesh=coarse, exact=fine)
        for height in (0.0, 0.01):
            pose = _grasp_pose(hand, np.array([0.0, 0.0, height]), DOWN, across)
            want, got = exact.close_at(pose, shapes["wide"]), proxy.close_at(pose, shapes["wide"])
            assert isinstance(want, Closed) and isinstance(got, Closed)
            assert want.contacts.links == got.contacts.links
            assert np.abs(np.abs(want.contacts.normals[:, :2]).max(axis=1) - 0.71).min() < 0.05  # some on an edge
            cos = np.einsum("ij,ij->i", want.contacts.normals, got.contacts.normals)
            assert np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).max() < 10.0


def test_a_contact_on_a_thin_wall_keeps_its_side_through_a_proxy(panda) -> None:  # type: ignore[no-untyped-def]
    """A plate 0.8 mm thick, finely meshed; its proxy's top lies 0.5 mm below the plate's (within the spike
    bound of 1 mm): a finger pressing down on it touches the proxy 0.1 mm under the plate's mid-plane, whose
    nearest exact face is the underside. Moved onto the exact mesh the contact keeps pushing down (the faces on
    its proxy normal's side averaged): it took the underside's normal, pushing up, out of the object."""
    from planner.record.contacts import HandContacts

    hand, _ = panda
    plate = trimesh.creation.box(extents=(0.03, 0.03, 0.0008)).subdivide_to_size(0.001)
    proxy = trimesh.creation.box(extents=(0.03, 0.03, 0.0008))
    proxy.apply_translation([0.0, 0.0, -0.0005])
    touched = np.array([[0.001, 0.002, -0.0001], [-0.003, 0.0, -0.0001]])
    down = np.tile([0.0, 0.0, -1.0], (2, 1))
    with Sim() as sim:
        grasper = Grasper(sim, hand, sim.add_static_mesh(proxy.vertices, proxy.faces), mesh=proxy, exact=plate)
        got = grasper._onto_exact(HandContacts(touched, down, ("panda_leftfinger",) * 2))
    assert np.allclose(got.normals, down, atol=1e-9), got.normals
