"""Object specs: the registry, ``random_NNN``, mesh paths, overrides."""

from __future__ import annotations

import pytest

from planner.errors import InputError, UnknownNameError
from planner.specs.objects import builtin_specs, file_scale, is_registered, random_spec, resolve_spec


def test_unknown_object_lists_builtins() -> None:
    with pytest.raises(UnknownNameError, match="mug.*sphere|Available objects"):
        resolve_spec("teapot")


def test_registered_names_and_mesh_paths() -> None:
    assert is_registered("mug") and is_registered("random_042") and not is_registered("random_x")
    assert resolve_spec("random_042").source.endswith("random_urdfs/042/042.urdf")
    spec = resolve_spec("/data/meshes/cup.obj", scale=0.001, mass=0.3, label="kitchen/cup")
    assert (spec.name, spec.kind, spec.scale, spec.mass) == ("kitchen/cup", "mesh", 0.001, 0.3)
    with pytest.raises(InputError, match="out of range"):
        random_spec(1000)
    with pytest.raises(InputError, match="friction must be a positive number"):
        resolve_spec("box", friction=-1.0)


def test_file_scale_includes_the_urdf_mesh_scale() -> None:
    assert file_scale(builtin_specs()["box"]) == 1.0
    assert file_scale(builtin_specs()["duck"]) == pytest.approx(0.05)
