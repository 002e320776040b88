"""Stored objects rebuilt from their ``objects`` row (planner.db.objects), and the mesh files of exports."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import assert_close

from planner.datasets.meshes import obj_text
from planner.db.objects import stored_object
from planner.db.store import ObjectRow, open_db
from planner.errors import InputError
from planner.geometry.solid import load_object


def row(db: Path, name: str) -> ObjectRow:
    with open_db(db, create=False, readonly=True) as handle:
        found = handle.object_row(name)
    assert found is not None
    return found


def test_the_stored_scale_and_mass_are_used(stored_db: Path) -> None:
    duck = stored_object(row(stored_db, "duck"))  # generated with --scale 1.5
    assert_close(duck.mesh.vertices, load_object("duck", scale=1.5).mesh.vertices)
    assert duck.name == "duck" and duck.mass == row(stored_db, "duck").mass


def test_a_renamed_primitive_is_found_by_its_mesh(stored_db: Path) -> None:
    crate = stored_object(replace(row(stored_db, "box"), name="crate", mass=0.7))
    assert crate.name == "crate" and crate.mass == 0.7
    assert crate.mesh_hash == load_object("box").mesh_hash


def test_a_pybullet_data_file_moves_with_the_package(stored_db: Path) -> None:
    duck = row(stored_db, "duck")
    inside = Path(duck.source).parts[Path(duck.source).parts.index("pybullet_data"):]
    elsewhere = replace(duck, source=str(Path("/another/machine/site-packages", *inside)))
    assert stored_object(elsewhere).mesh_hash == duck.mesh_sha256


def test_a_mesh_that_changed_since_is_refused(stored_db: Path, tmp_path: Path) -> None:
    capsule = row(stored_db, "capsule")
    with pytest.raises(InputError, match="cannot rebuild the mesh its grasps were planned on.*another mesh"):
        stored_object(replace(capsule, scale=capsule.scale * 1.01))
    with pytest.raises(InputError, match="file not found"):
        stored_object(replace(capsule, source=str(tmp_path / "gone.obj")))


def test_obj_text_loads_back_as_the_same_single_mesh(tmp_path: Path) -> None:
    mesh = load_object("cylinder").mesh
    path = tmp_path / "c.obj"
    path.write_text(obj_text(mesh))
    loaded = trimesh.load(path)
    assert isinstance(loaded, trimesh.Trimesh)
    assert np.array_equal(loaded.vertices, mesh.vertices) and np.array_equal(loaded.faces, mesh.faces)
    assert "vn " not in path.read_text() and "usemtl" not in path.read_text()


def test_the_stored_up_is_the_rebuilt_objects_and_another_up_differs(stored_db: Path) -> None:
    from planner.db.objects import differs

    box = row(stored_db, "box")
    assert box.up == "+z"  # every object nobody gave another up
    turned = stored_object(replace(box, up="+y"))
    assert turned.spec.up == "+y" and turned.up.tolist() == [0.0, 1.0, 0.0]
    assert differs(box, stored_object(box)) is None
    assert differs(box, turned) == "with up +z (now +y)"
