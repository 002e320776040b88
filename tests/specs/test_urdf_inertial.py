"""A URDF's links' <inertial> elements made one body's: the centre of mass mass-weighted, the inertia by the
parallel-axis theorem in the object's axes, checked against trimesh's of the same solids; and when a file
declares a centre of mass."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import assert_close
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.specs.urdf_inertial import combined, link_inertial
from planner.specs.urdf_objects import read_urdf_object

#: [kg/m^3] one density for both boxes: their union's mass properties are trimesh's of the two meshes together.
DENSITY = 700.0
#: Relative agreement of two exact computations of one tensor (round-off of sums of ~1e-6 kg m^2 terms).
INERTIA_RTOL = 1e-9

lengths = st.floats(0.01, 0.06)
angles = st.floats(-np.pi, np.pi)
offsets = st.floats(-0.05, 0.05)


def box_link(extents: np.ndarray, pose: np.ndarray) -> tuple[trimesh.Trimesh, float, np.ndarray]:
    """A box of ``extents`` at ``pose`` in the object frame, its mass at :data:`DENSITY` and its inertia about
    its centre in its own axes (a textbook box's)."""
    mass = DENSITY * float(np.prod(extents))
    a, b, c = extents
    inertia = mass / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    return trimesh.creation.box(extents=extents, transform=pose), mass, inertia


@settings(max_examples=30, deadline=None)
@given(st.tuples(lengths, lengths, lengths), st.tuples(lengths, lengths, lengths),
       st.tuples(angles, angles, angles), st.tuples(offsets, offsets, offsets))
def test_two_links_combine_as_trimesh_finds_their_union(a: tuple, b: tuple, rpy: tuple, shift: tuple) -> None:
    """Two boxes, the second turned and moved well clear of the first: the combination of their inertials
    is the mass properties trimesh finds for both meshes together at one density."""
    first_pose = np.eye(4)
    second_pose = trimesh.transformations.euler_matrix(*rpy)
    second_pose[:3, 3] = np.array(shift) + [0.2, 0, 0]  # apart: no overlap to count twice
    parts = [box_link(np.array(a), first_pose), box_link(np.array(b), second_pose)]
    # the second link's frame is the joint's, its inertial origin half of the pose: the product is what counts
    half = trimesh.transformations.translation_matrix(second_pose[:3, 3] / 2)
    links = [link_inertial(parts[0][1], np.eye(4), None, parts[0][2]),
             link_inertial(parts[1][1], half, np.linalg.inv(half) @ second_pose, parts[1][2])]
    body = combined(links)
    union = trimesh.util.concatenate([p[0] for p in parts])
    union.density = DENSITY
    assert body is not None and body.declared
    assert body.mass == pytest.approx(union.mass, rel=INERTIA_RTOL)
    assert_close(body.com, union.center_mass)
    assert np.allclose(body.inertia, union.moment_inertia, rtol=INERTIA_RTOL, atol=INERTIA_RTOL * body.inertia.max())


def test_links_without_mass_count_for_nothing_and_none_is_none() -> None:
    pose = trimesh.transformations.translation_matrix([0.1, 0, 0])
    assert combined([link_inertial(0.0, pose, None, np.eye(3))]) is None
    body = combined([link_inertial(0.0, pose, None, np.eye(3)), link_inertial(2.0, np.eye(4), None, None)])
    assert body is not None and body.mass == 2.0 and not body.declared
    assert_close(body.com, np.zeros(3))
    assert_close(body.inertia, np.zeros((3, 3)))  # no <inertia>: zero, which the prepared object refuses


def urdf(folder: Path, inertial: str, name: str = "box") -> Path:
    path = folder / f"{name}.urdf"
    path.write_text(f"""<robot name="{name}"><link name="base">{inertial}
  <collision><geometry><box size="0.04 0.06 0.1"/></geometry></collision></link></robot>""")
    return path


@pytest.mark.parametrize("origin, declared", [
    ("", False),  # no <origin>: the link's, as a template's
    ('<origin xyz="0 0 0" rpy="0.3 0 0"/>', False),  # written zero (pybullet_data's 13 of 15): no declaration
    ('<origin xyz="0 0.01 0"/>', True),
])
def test_an_origin_off_the_link_origin_declares_the_centre_of_mass(tmp_path: Path, origin: str,
                                                                    declared: bool) -> None:
    path = urdf(tmp_path, f'<inertial>{origin}<mass value="0.3"/></inertial>')
    obj = read_urdf_object(path)
    assert obj.inertial is not None and obj.inertial.declared == declared
    assert obj.com == ((0.0, 0.01, 0.0) if declared else None)
    assert ("com" in obj.stated()) == declared


def test_a_child_links_inertial_is_placed_by_its_fixed_joint(tmp_path: Path) -> None:
    """Two links' masses, the child's 5 cm along x by its joint and 1 cm more by its own origin."""
    path = tmp_path / "two.urdf"
    path.write_text("""<robot name="two">
<link name="a"><inertial><mass value="1"/></inertial>
  <collision><geometry><box size="0.04 0.04 0.04"/></geometry></collision></link>
<link name="b"><inertial><origin xyz="0.01 0 0"/><mass value="3"/></inertial>
  <collision><origin xyz="0.01 0 0"/><geometry><box size="0.04 0.04 0.04"/></geometry></collision></link>
<joint name="j" type="fixed"><parent link="a"/><child link="b"/><origin xyz="0.05 0 0"/></joint>
</robot>""")
    obj = read_urdf_object(path)
    assert obj.mass == 4.0 and obj.com == pytest.approx((0.045, 0.0, 0.0))
