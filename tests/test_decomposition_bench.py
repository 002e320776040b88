"""bench/decomposition.py on a small concave mesh: a row with CoACD's CPU, its parts and how far they reach outside
the object, the settings as given, the parts cached as a trial would read them; a decomposition over its time limit
reported as timed out."""

import sys
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import decomposition  # noqa: E402

from planner.geometry import decompose  # noqa: E402
from planner.geometry.solid import load_object  # noqa: E402


def _ell(tmp_path: Path) -> Path:
    outline = np.array([[-0.03, -0.01], [0.03, -0.01], [0.03, 0.01], [-0.01, 0.01], [-0.01, 0.05], [-0.03, 0.05]])
    ell = trimesh.creation.extrude_polygon(trimesh.path.polygons.Polygon(outline), 0.02)
    path = tmp_path / "ell.obj"
    ell.export(path)
    return path


def test_a_row_per_object_and_the_parts_cached(tmp_path: Path) -> None:
    path = _ell(tmp_path)
    settings = decomposition.parse_settings(["threshold=0.1", "max_convex_hull=4", "resolution=500",
                                             "mcts_iterations=20"])
    assert settings["threshold"] == 0.1 and settings["mcts_iterations"] == 20 and settings["max_convex_hull"] == 4
    row = decomposition.measure(f"mesh:{path}", tmp_path, settings, timeout=120)
    assert row["object"] == "ell" and not row.get("timeout")
    assert 2 <= row["parts"] <= 4 and row["cpu"] > 0 and row["faces"] > 0
    assert 0.0 <= row["out_p95_mm"] <= row["out_max_mm"] < 20.0
    obj = load_object(str(path))  # the child's parts are the ones a trial of this object would read
    cached = decompose.ready_parts(obj.mesh, obj.mesh_hash, decompose.CoacdSettings(**settings))
    assert cached is not None and len(cached) == row["parts"]
    assert "1 objects (0 timed out)" in decomposition.summary([row])


def test_over_the_time_limit_is_reported_not_waited_for(tmp_path: Path) -> None:
    row = decomposition.measure(f"mesh:{_ell(tmp_path)}", tmp_path, decomposition.parse_settings([]), timeout=0.01)
    assert row == {"object": "ell", "timeout": True}
    assert decomposition.summary([row]) == "no decomposition finished"
