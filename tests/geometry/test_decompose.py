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


def test_coacd_over_its_time_limit_fails_in_one_line_and_is_not_run_again(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """CoACD has no time limit: a mesh it cannot finish held a batch's worker for as long as it took, and every
    trial of the object ran it again. It runs in a child killed at the limit; the failure is recorded, so the
    next call is refused at once, and a larger limit tries again."""
    import subprocess

    import pytest

    from planner.errors import MeshError

    ell, settings = _ell(), decompose.CoacdSettings(threshold=0.1, max_convex_hull=4, resolution=500, seed=7)
    key = mesh_hash(ell)
    monkeypatch.setenv(decompose.TIME_LIMIT_ENV, "0.01")  # less than the child needs to start
    with pytest.raises(MeshError) as info:
        decompose.convex_parts(ell, key, settings)
    message = str(info.value)
    assert "did not finish" in message and "within 0.01 s" in message and decompose.TIME_LIMIT_ENV in message
    assert "\n" not in message
    real_run = subprocess.run

    def no_child(*_: object, **__: object) -> None:
        raise AssertionError("CoACD ran again after it had run out of the same limit")

    monkeypatch.setattr(subprocess, "run", no_child)
    with pytest.raises(MeshError, match="recorded earlier"):
        decompose.convex_parts(ell, key, settings)
    monkeypatch.setattr(subprocess, "run", real_run)
    monkeypatch.setenv(decompose.TIME_LIMIT_ENV, "120")
    parts = decompose.convex_parts(ell, key, settings)
    assert parts.method == "coacd" and 2 <= len(parts) <= 4
    assert decompose.ready_parts(ell, key, settings) is not None  # cached for every later call


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
