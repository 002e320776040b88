"""A grasp's links read together (:func:`planner.plan.patches.regions`): the regions of one link at a time
(:func:`planner.plan.patches.link_regions`), bit for bit, at the poses sweeps close at and at poses moved a
little from them, with one object query of each kind per grasp instead of one per link; and a closed hand's
link poses asked of the simulator once per reading."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planner.geometry.solid import load_object
from planner.plan import contact_reading
from planner.plan.closing import Closed, CloseSettings, Grasper
from planner.plan.patches import ObjectSurface, Region, hand_surfaces, link_regions, regions
from planner.plan.sweep import SweepSettings
from planner.plan.unit import UnitSpec, run_unit
from planner.sim import Sim
from planner.specs.hands import load_hand
from planner.specs.preshapes import load_preshapes

#: [m], [rad] how far the poses of a sweep's grasps are moved (a band's samples change, its shape stays).
SHIFT, TURN = 0.0005, 0.02
#: The grasps of a unit compared (a Barrett unit closes many).
CALLS = 60


@pytest.fixture(scope="module", params=[("panda", "box", 12), ("panda", "duck", 16), ("barrett", "mug", 6)])
def read(request: pytest.FixtureRequest) -> tuple[str, list[tuple[ObjectSurface, dict, tuple]]]:
    """(hand, the arguments of every ``regions`` call of a small sweep's unit)."""
    hand, name, approaches = request.param
    calls = []

    def spy(hand_spec, obj, poses, links):  # type: ignore[no-untyped-def]
        calls.append((obj, {k: v.copy() for k, v in poses.items()}, links))
        return regions(hand_spec, obj, poses, links)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(contact_reading, "regions", spy)
        settings = SweepSettings(approaches=approaches, rolls=2, reach_placements=0, settle=False)
        run_unit(UnitSpec(name, hand, settings, 0))
    assert len(calls) > 5
    return hand, calls


def _one_at_a_time(hand: str, obj: ObjectSurface, poses: dict, links: tuple) -> list[Region]:
    surfaces = hand_surfaces(load_hand(hand), obj.settings)
    return [r for link in links if link in surfaces for r in link_regions(link, surfaces[link], poses[link], obj)]


def _same(got: list[Region], want: list[Region]) -> bool:
    return len(got) == len(want) and all(
        a.link == b.link and a.area == b.area and a.diameter == b.diameter
        and all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("points", "normals", "normal"))
        and (a.plane is None) == (b.plane is None) and (a.plane is None or np.array_equal(a.plane, b.plane))
        for a, b in zip(got, want))


def test_links_read_together_are_each_links_regions_bit_for_bit(read) -> None:  # type: ignore[no-untyped-def]
    hand, calls = read
    rng = np.random.default_rng(0)
    found = 0
    for obj, poses, links in calls[:CALLS]:
        moved = {}
        for link, pose in poses.items():
            turn = np.eye(4)
            turn[:3, :3] = Rotation.from_rotvec(rng.normal(scale=TURN, size=3)).as_matrix()
            turn[:3, 3] = rng.normal(scale=SHIFT, size=3)
            moved[link] = turn @ pose
        for at in (poses, moved):
            want = _one_at_a_time(hand, obj, at, links)
            assert _same(regions(load_hand(hand), obj, at, links), want)
            found += len(want)
    assert found > min(len(calls), CALLS)  # regions found, not empty lists compared


def test_a_grasps_links_ask_the_object_once(read, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """One exact closest-point query and two bound queries (the cells' centroids, then the samples of the cells
    kept) per grasp however many links touch, and features read for the patch's samples, not the whole band's
    (one link at a time: a query of each per link)."""
    hand, calls = read
    asked: dict[str, list[int]] = {"nearest": [], "bounds": [], "_feature": []}
    for name in asked:
        method = getattr(ObjectSurface, name)

        def counted(self, points, *args, _name=name, _method=method):  # type: ignore[no-untyped-def]
            asked[_name].append(len(points))
            return _method(self, points, *args)

        monkeypatch.setattr(ObjectSurface, name, counted)
    several = [c for c in calls if len(c[2]) >= 2]
    assert several
    for obj, poses, links in several:
        for counts in asked.values():
            counts.clear()
        found = regions(load_hand(hand), obj, poses, links)
        assert len(asked["nearest"]) <= 1 and len(asked["bounds"]) <= 2 and len(asked["_feature"]) <= 1
        assert sum(asked["_feature"]) >= sum(len(r.points) for r in found)


def test_a_reading_asks_each_links_pose_once(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The Panda closed on the box, read again: each contact link's pose asked once (the patches, the joint frames
    and the record read them; they were asked for the touching links, each joint's child and every contact link
    apart), and the same reading."""
    hand, obj = load_hand("panda"), load_object("box")
    wide = {s.name: s for s in load_preshapes(hand)}["wide"]
    with Sim() as sim:
        g = Grasper.for_mesh(sim, hand, obj.mesh, CloseSettings())
        closed = g.close(np.array([0, 0, 0.04]), np.array([0.0, 0.0, -1.0]), 0.0, 0.02, wide, obj.torque_scale)
        assert isinstance(closed, Closed) and len(set(closed.contacts.links)) == 2
        asked: list[str] = []
        link_pose = type(sim).link_pose
        monkeypatch.setattr(type(sim), "link_pose", lambda self, body, link: asked.append(link) or link_pose(
            self, body, link))
        again = g.read(closed.pose, closed.open_joints, closed.closed_joints)
    assert isinstance(again, Closed)
    assert sorted(asked) == sorted(hand.contact_links)
    assert np.array_equal(again.contacts.points, closed.contacts.points)
    assert all(np.array_equal(again.link_poses[k], v) for k, v in closed.link_poses.items())
    assert np.array_equal(again.frames.origins, closed.frames.origins)  # type: ignore[union-attr]
    assert np.array_equal(again.frames.axes, closed.frames.axes)  # type: ignore[union-attr]
