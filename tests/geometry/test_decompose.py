import numpy as np
import trimesh

from planner.geometry import decompose
from planner.geometry.mesh import mesh_hash


def test_convex_bodies_skip_coacd() -> None:
    box = trimesh.creation.box(extents=[0.04, 0.04, 0.04])
    two = trimesh.util.concatenate([box, box.copy().apply_translation([0.1, 0, 0])])
    parts = decompose.convex_parts(two, mesh_hash(two))
    assert parts.method == "bodies" and len(parts) == 2


def test_concave_object_is_decomposed_once_and_cached(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    # an L made of two overlapping boxes, merged into one concave solid
    a = trimesh.creation.box(extents=[0.06, 0.02, 0.02])
    b = trimesh.creation.box(extents=[0.02, 0.06, 0.02]).apply_translation([-0.02, 0.02, 0])
    ell = a.union(b, engine="manifold") if "manifold" in trimesh.boolean.engines_available else None
    if ell is None:  # no boolean engine: build the L from its outline
        outline = np.array([[-0.03, -0.01], [0.03, -0.01], [0.03, 0.01], [-0.01, 0.01], [-0.01, 0.05], [-0.03, 0.05]])
        ell = trimesh.creation.extrude_polygon(trimesh.path.polygons.Polygon(outline), 0.02)
    assert ell.volume < 0.95 * ell.convex_hull.volume  # really concave
    settings = decompose.CoacdSettings(threshold=0.1, max_convex_hull=4, resolution=500)
    key = mesh_hash(ell)
    first = decompose.convex_parts(ell, key, settings)

    def no_coacd(*_: object) -> None:
        raise AssertionError("CoACD ran again instead of reading the cache")

    monkeypatch.setattr(decompose, "_run_coacd", no_coacd)
    again = decompose.convex_parts(ell, key, settings)
    assert first.method == again.method == "coacd" and 2 <= len(first) <= 4
    assert all(np.array_equal(x, y) for x, y in zip(first.vertices, again.vertices))
    hull_volume = sum(trimesh.Trimesh(v, f).convex_hull.volume for v, f in zip(first.vertices, first.faces))
    assert abs(hull_volume - ell.volume) < 0.3 * ell.volume


def test_every_setting_reaches_coacd_and_names_the_cache(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    import dataclasses

    import coacd

    seen: dict = {}

    def record(mesh: object, **kwargs: object) -> list:
        seen.update(kwargs)
        return [(np.eye(4, 3), np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]))]

    monkeypatch.setattr(coacd, "run_coacd", record)
    settings = decompose.CoacdSettings(threshold=0.07, mcts_iterations=11, mcts_nodes=7, mcts_max_depth=1,
                                       preprocess_resolution=33)
    box = trimesh.creation.box(extents=[0.04, 0.04, 0.04])
    parts = decompose._run_coacd(box, settings)
    assert seen == dataclasses.asdict(settings) and parts.method == "coacd" and len(parts) == 1
    # a decomposition made with other tree-search settings is not read back as this one's
    other = dataclasses.replace(settings, mcts_iterations=12)
    assert decompose._cache_path("abc", settings) != decompose._cache_path("abc", other)
    assert decompose._cache_path("abc", settings) == decompose._cache_path("abc", dataclasses.replace(settings))


def _ell() -> trimesh.Trimesh:
    outline = np.array([[-0.03, -0.01], [0.03, -0.01], [0.03, 0.01], [-0.01, 0.01], [-0.01, 0.05], [-0.03, 0.05]])
    return trimesh.creation.extrude_polygon(trimesh.path.polygons.Polygon(outline), 0.02)


def _torus() -> tuple[trimesh.Trimesh, "decompose.CoacdSettings"]:
    """A mesh and settings CoACD needs ~2 s of CPU for (12 parts), more than a 0.01 s limit leaves it."""
    return (trimesh.creation.torus(0.05, 0.015),
            decompose.CoacdSettings(threshold=0.03, max_convex_hull=12, resolution=500, seed=7))


def test_coacd_over_its_time_limit_fails_in_one_line_and_is_not_run_again(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """CoACD has no time limit: a mesh it cannot finish held a batch's worker for as long as it took, and every
    trial of the object ran it again. It runs in a child stopped at the limit of its CPU; the failure is
    recorded, so the next call is refused at once, and a larger limit tries again."""
    import subprocess

    import pytest

    from planner.errors import MeshError

    torus, settings = _torus()
    key = mesh_hash(torus)
    monkeypatch.setenv(decompose.TIME_LIMIT_ENV, "0.01")
    with pytest.raises(MeshError) as info:
        decompose.convex_parts(torus, key, settings)
    message = str(info.value)
    assert "did not finish" in message and "within 0.01 s of CPU" in message and decompose.TIME_LIMIT_ENV in message
    assert "\n" not in message
    real_run = subprocess.run

    def no_child(*_: object, **__: object) -> None:
        raise AssertionError("CoACD ran again after it had run out of the same limit")

    monkeypatch.setattr(subprocess, "run", no_child)
    with pytest.raises(MeshError, match="recorded earlier"):
        decompose.convex_parts(torus, key, settings)
    monkeypatch.setattr(subprocess, "run", real_run)
    monkeypatch.setenv(decompose.TIME_LIMIT_ENV, "120")
    parts = decompose.convex_parts(torus, key, settings)
    assert parts.method == "coacd" and 2 <= len(parts) <= 12
    assert decompose.ready_parts(torus, key, settings) is not None  # cached for every later call


def test_the_limit_counts_the_childs_cpu_not_the_wall_clock() -> None:
    """The limit was wall clock: on a loaded host a mesh that takes 153 s of CPU failed its 900 s, and the
    failure was recorded, so whether an object had trials depended on what else the machine ran. A process
    that waits (wall clock, no CPU) past its limit goes on; one that computes past it is stopped by SIGXCPU."""
    import signal
    import subprocess
    import sys

    code = ("from planner.geometry.decompose import _limit_cpu\n"
            "import time\n"
            "assert _limit_cpu(0.3) is not None\n"
            "time.sleep(1.5)\n"
            "print('waited past the limit', flush=True)\n"
            "while True:\n"
            "    pass\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert "waited past the limit" in done.stdout, done.stderr
    assert done.returncode == -signal.SIGXCPU


def test_a_limit_that_is_not_seconds_is_refused(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    import pytest

    from planner.errors import MeshError

    for text in ("soon", "-5", "nan", "inf"):
        monkeypatch.setenv(decompose.TIME_LIMIT_ENV, text)
        with pytest.raises(MeshError, match="give seconds"):
            decompose.time_limit()
    monkeypatch.setenv(decompose.TIME_LIMIT_ENV, "0")
    assert decompose.time_limit() == 0.0
    monkeypatch.delenv(decompose.TIME_LIMIT_ENV)
    assert decompose.time_limit() == decompose.TIME_LIMIT


def test_a_timeout_recorded_under_the_wall_clock_is_tried_again(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Records made while the limit counted wall clock (a loaded host's) do not refuse the mesh now that it
    counts CPU; a record made under today's clock does."""
    import json

    import pytest

    from planner.errors import MeshError

    monkeypatch.setenv("GRASP_CACHE", str(tmp_path))
    torus, settings = _torus()
    key = mesh_hash(torus)
    record = decompose._timeout_path(decompose._cache_path(key, settings))
    record.parent.mkdir(parents=True, exist_ok=True)
    record.write_text(json.dumps({"limit": 900.0, "reason": "CoACD did not finish ... within 900 s"}))
    decompose.refuse_known_timeout(key, settings, 900.0)  # the old, wall-clock record: not refused
    decompose._record(decompose._cache_path(key, settings), 900.0, "CoACD did not finish ... within 900 s of CPU")
    with pytest.raises(MeshError, match="recorded earlier"):
        decompose.refuse_known_timeout(key, settings, 900.0)
