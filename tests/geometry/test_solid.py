"""The prepared object: known mass properties, built-ins load as closed solids."""

import math
from pathlib import Path

import numpy as np
import pytest
from helpers import assert_close

from planner.geometry.solid import load_object


def test_sphere_known_answers() -> None:
    o = load_object("sphere")
    r = o.spec.dims[0]
    assert_close(o.com, [0, 0, 0], 1e-9)
    assert o.torque_scale == pytest.approx(r, rel=1e-6)
    # icosphere volume is slightly under the sphere's
    assert o.volume == pytest.approx(4 / 3 * math.pi * r**3, rel=0.02)
    assert o.density == pytest.approx(o.mass / o.volume)
    # radius of gyration from the mean principal moment, k^2 = trace(I) / (3 m):
    # for a solid sphere (I = 2/5 m r^2 per axis) k = sqrt(2/5) r
    assert o.gyration_radius == pytest.approx(math.sqrt(0.4) * r, rel=0.02)


def test_box_torque_scale_is_half_diagonal() -> None:
    o = load_object("box")
    assert o.torque_scale == pytest.approx(0.5 * np.linalg.norm(o.spec.dims), rel=1e-9)


@pytest.mark.parametrize("name", ["mug", "duck", "teddy", "bunny", "box", "cylinder", "sphere", "random_007"])
def test_builtins_load_as_closed_solids_of_hand_size(name: str) -> None:
    o = load_object(name)
    assert o.mesh.is_watertight and o.volume > 0
    assert 0.02 < max(o.mesh.extents) < 0.2
    assert np.all(np.isfinite(o.inertia))


def test_mug_keeps_its_handle_and_cavity() -> None:
    o = load_object("mug")
    # the cavity: a point on the axis inside the cup is outside the solid
    assert not o.mesh.contains([[0.0, 0.0, 0.06]])[0]
    # the handle: a solid piece beyond the cup's radius
    assert o.mesh.bounds[1][1] > 0.07




def test_scale_multiplies_builtin_mesh_scale() -> None:
    plain, half = load_object("duck"), load_object("duck", scale=0.5)
    assert_close(half.mesh.extents, plain.mesh.extents * 0.5, 1e-9)


def test_a_cached_mesh_keeps_the_path_it_was_asked_for(tmp_path: Path) -> None:
    """The cache is keyed by content: the same bytes at two paths are one
    entry, but each object names its own file (the other may be gone)."""
    import trimesh

    first, second = tmp_path / "a" / "cube.obj", tmp_path / "b" / "cube.obj"
    for path in (first, second):
        path.parent.mkdir()
        trimesh.creation.box(extents=[0.04, 0.05, 0.06]).export(path)
    assert load_object(str(first)).source_file == str(first)
    assert load_object(str(second)).source_file == str(second)
