"""One-time preparation is announced: the first ``grasp validate`` on a
concave mesh says on stderr when its convex decomposition starts and ends,
a second run (cached) says nothing, ``--json`` keeps stderr clean."""

from __future__ import annotations

from pathlib import Path

import pytest
import trimesh
from helpers import FAST, grasp
from shapely.geometry import Polygon


def ell(path: Path, arm: float) -> Path:
    """An L-shaped prism [m]: concave, so CoACD decomposes it; ``arm`` makes
    its content, and so its cache entry, its own."""
    outline = Polygon([(0, 0), (arm, 0), (arm, 0.02), (0.02, 0.02), (0.02, arm), (0, arm)])
    trimesh.creation.extrude_polygon(outline, 0.03).export(path)
    return path


def decomposition_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if "convex decomposition" in line]


@pytest.mark.parametrize(("workers", "arm"), [("1", 0.06), ("2", 0.061)])
def test_validate_announces_a_decomposition_once(tmp_path: Path, workers: str, arm: float) -> None:
    mesh, db = ell(tmp_path / "ell.obj", arm), tmp_path / "ell.db"
    code, _, err = grasp("generate", str(mesh), "--hand", "panda", "--db", str(db), "--quiet", *FAST)
    assert code == 0, err
    validate = ("validate", "--db", str(db), "--top", "1", "--robust", "0", "--workers", workers)
    code, _, err = grasp(*validate)
    assert code == 0, err
    started, ended = decomposition_lines(err)
    assert "of ell: started (once: cached afterwards)" in started, err
    assert "of ell: done in " in ended and ended.endswith(" s"), err
    code, _, err = grasp(*validate)
    assert code == 0 and decomposition_lines(err) == [], err


def test_json_keeps_stderr_clean(tmp_path: Path) -> None:
    mesh, db = ell(tmp_path / "ell.obj", 0.059), tmp_path / "ell.db"
    code, _, err = grasp("generate", str(mesh), "--hand", "panda", "--db", str(db), "--quiet", *FAST)
    assert code == 0, err
    code, out, err = grasp("validate", "--db", str(db), "--top", "1", "--robust", "0", "--workers", "1", "--json")
    assert code == 0 and out.startswith("{") and decomposition_lines(err) == [], err


def test_generate_says_once_that_it_closed_an_open_mesh(tmp_path: Path) -> None:
    """A repair changes the object the user gave (an open cup becomes a solid): `generate` says so on stderr
    the first time (the repaired mesh is cached: not again), and not under --quiet or --json."""
    def open_cup(height: float) -> Path:
        cup = trimesh.creation.cylinder(radius=0.03, height=height)
        top = cup.triangles_center[:, 2] > height / 2 - 1e-9
        path = tmp_path / f"cup{height}.obj"
        trimesh.Trimesh(cup.vertices, cup.faces[~top]).export(path)
        return path

    for path, flags, expected in ((open_cup(0.08), (), 1), (open_cup(0.08), (), 0), (open_cup(0.07), ("--json",), 0)):
        code, _, err = grasp("generate", str(path), "--hand", "panda", "--db", str(tmp_path / "cup.db"), *flags,
                             *FAST)
        assert code == 0, err
        lines = [line for line in err.splitlines() if "closing it into a solid" in line]
        assert len(lines) == expected and all(line.startswith(f"{path}: capped") for line in lines), err


def test_a_batch_on_worker_processes_says_what_preparing_its_objects_did(tmp_path: Path) -> None:
    """A batch's objects are prepared in the worker processes, where nothing showed the lines: with --workers 2
    (the default on two cores) an open mesh was closed without a word, and, cached, never said later."""
    paths = []
    for height in (0.0801, 0.0701):
        cup = trimesh.creation.cylinder(radius=0.03, height=height)
        top = cup.triangles_center[:, 2] > height / 2 - 1e-9
        paths.append(tmp_path / f"cup{height}.obj")
        trimesh.Trimesh(cup.vertices, cup.faces[~top]).export(paths[-1])
    fast = [*FAST[:FAST.index("--workers")], *FAST[FAST.index("--workers") + 2:]]
    code, _, err = grasp("generate", *map(str, paths), "--hand", "panda", "--db", str(tmp_path / "cups.db"),
                         "--workers", "2", *fast)
    assert code == 0, err
    lines = [line for line in err.splitlines() if "closing it into a solid" in line]
    assert sorted(lines) == [f"{p}: capped the mesh's open boundary loops, closing it into a solid (once: cached "
                             "afterwards)" for p in sorted(paths)], err


@pytest.mark.parametrize(("workers", "height"), [("1", 0.0802), ("2", 0.0702)])
def test_import_says_what_preparing_a_files_mesh_did(tmp_path: Path, workers: str, height: float) -> None:
    """`grasp import --rescore` closed an open mesh (ACRONYM's often are) without a word: no command showed the
    lines, and in worker processes nothing would have."""
    import h5py
    import numpy as np

    cup = trimesh.creation.cylinder(radius=0.03, height=height)
    top = cup.triangles_center[:, 2] > height / 2 - 1e-9
    (tmp_path / "meshes").mkdir()
    trimesh.Trimesh(cup.vertices, cup.faces[~top]).export(tmp_path / "meshes" / "cup.obj")
    poses = np.tile(np.eye(4), (40, 1, 1))
    poses[:, 0, 3] = np.linspace(-0.2, 0.2, 40)
    with h5py.File(tmp_path / "cup.h5", "w") as f:
        f["grasps/transforms"], f["gripper/type"] = poses, "panda"
        f["object/file"], f["object/scale"] = "meshes/cup.obj", 1.0
    code, _, err = grasp("import", "--format", "acronym", str(tmp_path / "cup.h5"), "--db", str(tmp_path / "i.db"),
                         "--rescore", "--workers", workers)
    assert code == 0, err
    lines = [line for line in err.splitlines() if "closing it into a solid" in line]
    assert lines == [f"{tmp_path / 'meshes' / 'cup.obj'}: capped the mesh's open boundary loops, closing it into a "
                     "solid (once: cached afterwards)"], err
