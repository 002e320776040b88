"""Scanned meshes as published (issue 24): UV-split vertices, small holes and
several bodies load into closed solids; a mesh that cannot be repaired is
refused with one line saying why."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import grasp, one_line_error
from scanlike import RADIUS, bodies, capsule, uv_grid, uv_obj, with_holes

from planner.errors import MeshError
from planner.geometry.mesh import load_mesh_file

#: [m^3] a capsule meshed with ~2k faces holds this much less than the true one at most (inscribed polygon).
VOLUME_TOL = 3e-6
TRUE_VOLUME = np.pi * RADIUS**2 * 0.07 + 4 / 3 * np.pi * RADIUS**3


def test_uv_split_vertices_are_merged_into_one_closed_solid(tmp_path: Path) -> None:
    vertices, _, faces = uv_grid(2_000)
    path = tmp_path / "scan.obj"
    path.write_text(uv_obj(2_000))
    raw = trimesh.load(str(path), force="mesh", process=False)
    used = vertices[np.unique(faces)]
    assert len(raw.vertices) == len(used) > len(np.unique(used.round(9), axis=0))  # split at the seam and poles
    assert not raw.is_watertight  # as published: the seam is open until merged
    mesh = load_mesh_file(path)
    assert mesh.is_watertight and len(mesh.faces) == len(capsule(2_000).faces)
    assert TRUE_VOLUME - VOLUME_TOL <= mesh.volume <= TRUE_VOLUME


def test_small_holes_are_closed(tmp_path: Path) -> None:
    holed = with_holes(capsule(4_000), 4, np.random.default_rng(3))
    assert not holed.is_watertight
    path = tmp_path / "holed.obj"
    holed.export(path)
    mesh = load_mesh_file(path)
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx(capsule(4_000).volume, rel=1e-3)


def test_several_bodies_load_as_one_object(tmp_path: Path) -> None:
    two = bodies(capsule(2_000), trimesh.creation.icosphere(2, 0.02))
    path = tmp_path / "two.obj"
    two.export(path)
    mesh = load_mesh_file(path)
    assert mesh.is_watertight and len(mesh.split(only_watertight=False)) == 2
    assert mesh.volume == pytest.approx(capsule(2_000).volume + trimesh.creation.icosphere(2, 0.02).volume)


def test_a_mesh_that_cannot_be_closed_is_refused_in_one_line(tmp_path: Path) -> None:
    # a fin: a fourth face on one edge of a tetrahedron, the edge no longer manifold
    vertices = np.array([[0, 0, 0], [0.05, 0, 0], [0, 0.05, 0], [0, 0, 0.05], [0.05, 0.05, 0.05]], float)
    faces = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2], [1, 4, 3]])
    path = tmp_path / "fin.obj"
    trimesh.Trimesh(vertices, faces, process=False).export(path)
    with pytest.raises(MeshError, match="not watertight and could not be repaired") as err:
        load_mesh_file(path)
    assert "\n" not in str(err.value)
    code, _, stderr = grasp("generate", str(path), "--hand", "panda", "--db", str(tmp_path / "g.db"), "--quiet")
    one_line_error(code, stderr, 2, "could not be repaired")
