"""Approach sampling: the surface and box ray samplers, the fan, and the
antipodal sampler (pairs antipodal within the opening, seeded, poses that put
the fingers on the closing axis)."""

import numpy as np
import pytest
import trimesh
from helpers import NUM_TOL, assert_close
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.geometry.frames import hand_rotation
from planner.geometry.solid import load_object
from planner.plan import sampling
from planner.plan.sweep import SweepSettings, antipodal_candidates, candidates
from planner.plan.tolerances import ABOVE_PHASES, ABOVE_POINTS, ABOVE_RAYS, ABOVE_TURN, MIN_CHORD
from planner.specs.hands import load_hand
from planner.specs.preshapes import load_preshapes

#: Points on a faceted sphere lie within this of the true sphere [m]
#: (icosphere, 3 subdivisions, 3 cm radius: the facet sagitta is ~0.1 mm).
FACET_TOL = 3e-4
#: Friction coefficient of the cone test in these tests.
MU = 0.5
BOX = (0.05, 0.04, 0.08)


def test_surface_rays_on_sphere_point_to_the_centre() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.03)
    rays = sampling.sample(mesh, sampler="surface", count=50, rng=np.random.default_rng(1))
    assert len(rays) == 50
    radial = rays.points / np.linalg.norm(rays.points, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", rays.directions, -radial) > 0.98)


def test_surface_rays_are_reproducible() -> None:
    mesh = trimesh.creation.box(extents=[0.05, 0.04, 0.08])
    a = sampling.sample(mesh, sampler="surface", count=20, rng=np.random.default_rng(7))
    b = sampling.sample(mesh, sampler="surface", count=20, rng=np.random.default_rng(7))
    assert_close(a.points, b.points)


def test_box_rays_hit_faces_with_axis_normals() -> None:
    mesh = trimesh.creation.box(extents=[0.05, 0.04, 0.08])
    rays = sampling.sample(mesh, sampler="box", count=0, rng=np.random.default_rng(0), delta=0.02)
    assert len(rays) > 20
    assert np.allclose(np.abs(rays.normals).max(axis=1), 1.0)
    assert np.allclose(np.abs(rays.points).max(axis=0), [0.025, 0.02, 0.04])


def test_fan_tilts_by_the_angle() -> None:
    mesh = trimesh.creation.box(extents=[0.05, 0.04, 0.08])
    base = sampling.sample(mesh, sampler="surface", count=5, rng=np.random.default_rng(0))
    fanned = sampling.fan(base, 4, 0.3)
    assert len(fanned) == 25
    cos = np.einsum("ij,ij->i", fanned.directions[5:], np.tile(base.directions, (4, 1)))
    assert_close(cos, np.full(20, np.cos(0.3)), 1e-9)


# -- straight down onto an object on a table -------------------------------------
@settings(max_examples=25, deadline=None)
@given(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1), st.floats(0, 2 * np.pi),
       st.sampled_from(["panda", "barrett", "allegro", "pr2"]))
def test_rays_from_above_come_down_over_the_footprint_rolled_along_its_long_side(
        x: float, y: float, z: float, spin: float, hand: str) -> None:
    """A 12 x 6 x 3 cm box lying on its large face, turned any way: the
    rays come straight down through the centre of mass and through the
    points a quarter of its length either side of the centre along its long
    side, and each ray's phase turns the hand's reference axis onto that side
    (three sets, each a further ABOVE_TURN)."""
    up = np.array([x, y, z])
    if np.linalg.norm(up) < 0.1:
        up = np.array([0.0, 0.0, 1.0])
    up /= np.linalg.norm(up)
    turn = trimesh.geometry.align_vectors([0, 0, 1], up) @ trimesh.transformations.rotation_matrix(spin, [0, 0, 1])
    mesh = trimesh.creation.box(extents=[0.12, 0.06, 0.03], transform=turn)
    long = turn[:3, 0]
    approach = load_hand(hand).approach
    rays = sampling.from_above(mesh, up, mesh.center_mass, approach)
    assert len(rays) == ABOVE_RAYS == ABOVE_POINTS * ABOVE_PHASES
    assert_close(rays.directions, np.tile(-up, (ABOVE_RAYS, 1)), NUM_TOL)
    # on the top face (to 10 nm: a box turned 1.8e-8 rad from level put its ray's hit 1.05e-9 m off)
    assert_close(rays.points[:ABOVE_POINTS] @ up, np.full(ABOVE_POINTS, 0.015), 1e-8)
    flat = rays.points[:ABOVE_POINTS] - np.outer(rays.points[:ABOVE_POINTS] @ up, up)
    long = long if flat[1] @ long > 0 else -long  # the rectangle's long side has no sign of its own
    assert_close(flat, np.array([[0, 0, 0], 0.03 * long, -0.03 * long]), 1e-8)
    ref = np.eye(3)[int(np.argmin(np.abs(approach)))]
    ref = (ref - (ref @ approach) * approach) / np.linalg.norm(ref - (ref @ approach) * approach)
    for k in range(ABOVE_PHASES):
        for i in range(ABOVE_POINTS):
            along = hand_rotation(approach, -up, rays.phase(k * ABOVE_POINTS + i)) @ ref
            # to 1e-8 rad: a box turned 1e-9 rad from the axes was found along them (1e-9 + 2e-16 off)
            assert_close(along, np.cos(k * ABOVE_TURN) * long + np.sin(k * ABOVE_TURN) * np.cross(-up, long), 1e-8)


def test_a_rays_phase_starts_its_rolls() -> None:
    mesh = trimesh.creation.box(extents=[0.12, 0.06, 0.03])
    rays = sampling.from_above(mesh, np.array([0.0, 0.0, 1.0]), mesh.center_mass, np.array([0.0, 0.0, 1.0]))
    shapes = load_preshapes(load_hand("barrett"))[:1]
    found = candidates(rays, shapes, SweepSettings(rolls=3).resolved("surface"), symmetry=1)
    assert len(found) == ABOVE_RAYS * 3 * len(shapes[0].standoffs)
    for c in found:
        assert np.isclose(np.mod(c.roll - rays.phase(c.ray), 2 * np.pi / 3), 0, atol=1e-12) \
            or np.isclose(np.mod(c.roll - rays.phase(c.ray), 2 * np.pi / 3), 2 * np.pi / 3, atol=1e-12)


# -- antipodal ------------------------------------------------------------------
def test_sphere_pairs_along_the_normal_run_through_the_centre() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.03)
    pairs = sampling.antipodal(mesh, 40, np.random.default_rng(2), max_width=0.08, mu=MU, tries=0)
    assert pairs.reasons == ("",) * 40
    assert_close(pairs.axes, -pairs.normals, NUM_TOL)  # along the inward normal of the sampled facet
    assert_close(np.linalg.norm(pairs.opposite, axis=1), np.full(40, 0.03), FACET_TOL)  # on the sphere
    assert_close(pairs.widths, np.full(40, 0.06), 3 * FACET_TOL)  # nearly a diameter


def test_box_pairs_are_antipodal_within_the_opening() -> None:
    """A box's chords run straight across along the face normal; those wider
    than the opening are refused, the others are antipodal: both normals on
    the axis, inside any friction cone."""
    mesh = trimesh.creation.box(extents=BOX)
    max_width = 0.045
    pairs = sampling.antipodal(mesh, 200, np.random.default_rng(3), max_width=max_width, mu=MU, tries=0)
    across = np.abs(pairs.normals) @ np.array(BOX)  # the box's size along each point's normal
    assert_close(pairs.widths, across, NUM_TOL * 1e3)
    assert_close(pairs.axes, -pairs.normals, NUM_TOL)
    usable = np.array([r == "" for r in pairs.reasons])
    assert usable.any() and (~usable).any()
    assert np.all(pairs.widths[usable] <= max_width)
    assert {pairs.reasons[i] for i in np.flatnonzero(~usable)} == {"too_wide"}
    assert np.all(pairs.widths[~usable] > max_width)


def test_exit_normal_outside_the_friction_cone_is_refused() -> None:
    """A prism on a 30-60-90 triangle: every chord across the triangle meets
    one face at 30 or 60 degrees from its normal, outside the friction cone
    of mu = 0.5 (26.6 degrees); chords between the two end caps are square."""
    tri = np.array([[0.0, 0.0], [0.04, 0.0], [0.0, 0.04 * np.tan(np.pi / 3)]])
    prism = trimesh.convex.convex_hull(np.vstack([np.c_[tri, np.zeros(3)], np.c_[tri, np.full(3, 0.03)]]))
    pairs = sampling.antipodal(prism, 200, np.random.default_rng(0), max_width=0.1, mu=MU, tries=0)
    caps = np.abs(pairs.normals[:, 2]) > 0.99
    assert caps.any() and (~caps).any()
    assert {pairs.reasons[i] for i in np.flatnonzero(caps)} == {""}
    wide_enough = pairs.widths >= MIN_CHORD
    assert {pairs.reasons[i] for i in np.flatnonzero(~caps & wide_enough)} == {"cone"}


def test_rays_in_the_cone_only_where_the_normal_gives_no_pair() -> None:
    """The ray along the normal first: a point whose normal pair is usable
    keeps it; a refused one may find a pair tilted inside the friction cone
    (the mug: its handle and its curved wall)."""
    mesh = load_object("mug").mesh
    along = sampling.antipodal(mesh, 300, np.random.default_rng(8), max_width=0.076, mu=MU, tries=0)
    cone = sampling.antipodal(mesh, 300, np.random.default_rng(8), max_width=0.076, mu=MU)
    first = np.array([r == "" for r in along.reasons])
    assert_close(cone.points, along.points, 0.0)
    assert_close(cone.opposite[first], along.opposite[first], 0.0)
    later = np.array([r == "" for r in cone.reasons]) & ~first
    assert later.any()
    tilt = np.arccos(np.clip(np.einsum("ij,ij->i", cone.axes[later], -cone.normals[later]), -1, 1))
    assert np.all((tilt > 1e-6) & (tilt <= np.arctan(MU) + NUM_TOL))


def test_cone_directions_stay_in_the_cone_and_are_seeded() -> None:
    axes = np.tile([0.0, 0.0, -1.0], (500, 1))
    d = sampling.cone_directions(axes, MU, np.random.default_rng(4))
    assert_close(np.linalg.norm(d, axis=1), np.ones(500), NUM_TOL)
    angle = np.arccos(np.clip(d @ [0.0, 0.0, -1.0], -1, 1))
    assert angle.max() <= np.arctan(MU) + NUM_TOL
    assert np.ptp(np.arctan2(d[:, 1], d[:, 0])) > 6.0  # every azimuth
    assert_close(d, sampling.cone_directions(axes, MU, np.random.default_rng(4)), 0.0)
    assert_close(sampling.cone_directions(axes, 0.0, np.random.default_rng(4)), axes, 0.0)


def a_cone(diameter: float = 0.07, height: float = 0.08) -> trimesh.Trimesh:
    """A right circular cone, its base at z = 0 (issue 26's tapered object)."""
    return trimesh.creation.cone(radius=diameter / 2, height=height, sections=64)


def test_a_cone_gets_pairs_only_from_rays_in_the_cone() -> None:
    """7 cm across, 8 cm tall: the side is 23.6 degrees off vertical. Along the
    normal, a side ray meets the far side 47 degrees off its normal (refused);
    in the cone, level chords meet both sides 23.6 degrees off (< 26.6)."""
    cone = a_cone()
    along = sampling.antipodal(cone, 400, np.random.default_rng(0), max_width=0.076, mu=MU, tries=0)
    inside = sampling.antipodal(cone, 400, np.random.default_rng(0), max_width=0.076, mu=MU)
    side = cone.face_normals[cone.nearest.on_surface(along.points)[2]][:, 2] < 0.99  # not the base
    assert not any(r == "" for r, s in zip(along.reasons, side) if s)
    usable = np.array([r == "" for r in inside.reasons])
    assert (usable & side).sum() >= 5
    assert np.all(np.abs(inside.axes[usable & side, 2]) < np.sin(np.arctan(MU) - np.arctan(0.035 / 0.08)) + 1e-6)


def test_antipodal_pairs_are_seeded() -> None:
    mesh = trimesh.creation.box(extents=BOX)
    a = sampling.antipodal(mesh, 30, np.random.default_rng(5), max_width=0.07, mu=MU)
    b = sampling.antipodal(mesh, 30, np.random.default_rng(5), max_width=0.07, mu=MU)
    c = sampling.antipodal(mesh, 30, np.random.default_rng(6), max_width=0.07, mu=MU)
    assert_close(a.points, b.points, 0.0) and a.reasons == b.reasons
    assert_close(a.phases, b.phases, 0.0)
    assert not np.allclose(a.points, c.points)


unit = st.lists(st.floats(-1, 1), min_size=3, max_size=3).map(np.array).filter(lambda v: np.linalg.norm(v) > 0.1)


@settings(max_examples=50, deadline=None)
@given(axis=unit, centre=st.lists(st.floats(-0.1, 0.1), min_size=3, max_size=3), angle=st.floats(-7, 7),
       depth=st.floats(0, 0.02))
def test_antipodal_pose_puts_the_fingers_on_the_axis(axis, centre, angle, depth) -> None:  # type: ignore[no-untyped-def]
    hand = load_hand("panda")
    finger = np.array([0.0, 1.0, 0.0])  # the Panda's fingers close along its y axis
    axis = axis / np.linalg.norm(axis)
    pose = sampling.antipodal_poses(hand.approach, finger, hand.tcp, axis[None], np.array(centre)[None],
                                    np.array([angle]), np.array([depth]))[0]
    rot = pose[:3, :3]
    assert_close(rot.T @ rot, np.eye(3), 1e-12)
    assert np.linalg.det(rot) == pytest.approx(1.0)
    assert_close(rot @ finger, axis, 1e-12)
    approach = rot @ hand.approach
    assert abs(approach @ axis) < 1e-12
    assert_close(rot @ hand.tcp + pose[:3, 3], np.array(centre) + depth * approach, 1e-12)


def test_antipodal_candidates_are_numbered_per_point_and_fit_the_preshape() -> None:
    hand = load_hand("panda")
    shapes = load_preshapes(hand)
    openings = {"wide": 0.08, "half": 0.04}
    mesh = trimesh.creation.box(extents=BOX)
    pairs = sampling.antipodal(mesh, 12, np.random.default_rng(1), max_width=0.076, mu=MU)
    settings_ = SweepSettings(sampler="antipodal", rolls=3, depths=(0.0, 0.01)).resolved("antipodal")
    every = antipodal_candidates(pairs, shapes, openings, settings_, 0.002)
    assert [c.index for c in every] == list(range(12 * 3 * 2))
    assert [c.ray for c in every[:6]] == [0] * 6
    for c in every:
        width = pairs.widths[c.ray]
        assert c.preshape.name == ("half" if width + 0.004 <= 0.04 else "wide")
    angles = [c.roll - pairs.phases[0] for c in every[:6:2]]
    assert_close(angles, [0.0, 2 * np.pi / 3, 4 * np.pi / 3], 1e-12)
    part = antipodal_candidates(pairs, shapes, openings, settings_, 0.002, rays=range(4, 8))
    assert [(c.index, c.roll, c.standoff) for c in part] == [(c.index, c.roll, c.standoff) for c in every[24:48]]


def test_a_box_grid_too_fine_to_cast_is_refused_before_it_is_made() -> None:
    """--box-delta 1e-9 made a grid that grew one worker to 24 GB: refused, counting the rays first."""
    from planner.errors import InputError

    box = trimesh.creation.box(extents=[0.05, 0.04, 0.08])
    with pytest.raises(InputError, match=r"--box-delta 1e-09 m casts 3\.\d+e\+16 rays .*at most 1,000,000"):
        sampling.sample(box, sampler="box", count=0, rng=np.random.default_rng(0), delta=1e-9)
    assert len(sampling.sample(box, sampler="box", count=0, rng=np.random.default_rng(0), delta=0.01).points) > 0
