"""Batch generation: inputs, worker counts, Ray, crashes, resumption."""

import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
import trimesh

from planner import api
from planner.plan.sweep import SweepSettings
from planner.specs import inputs

SMALL = SweepSettings(approaches=8, rolls=2, preshapes=("wide",), chunk=4, reach_placements=1)
OBJECTS = ["box", "sphere"]


def content(db: Path) -> list[tuple]:
    """Everything that must not depend on workers, backend or interruptions."""
    with sqlite3.connect(db) as conn:
        return conn.execute(
            "SELECT object, hand, preshape, candidate, pose, closed_joints, contacts, epsilon, volume, force_closure,"
            " reachability, score, rank FROM grasps ORDER BY object, hand, candidate").fetchall()


def test_inputs_expand_folders_globs_manifests_and_builtins(tmp_path: Path) -> None:
    for sub in ("a", "b"):
        (tmp_path / sub).mkdir()
        trimesh.creation.box(extents=[0.03, 0.03, 0.03]).export(tmp_path / sub / "model.obj")
    (tmp_path / "manifest.txt").write_text("# objects\nbox\na/model.obj 0.5\n\nrandom_004\n")
    by_folder = inputs.expand([str(tmp_path)])
    assert sorted(r.name for r in by_folder) == ["a/model", "b/model"]
    assert len(inputs.expand([str(tmp_path / "*" / "*.obj")])) == 2
    manifest = inputs.expand([f"@{tmp_path / 'manifest.txt'}"])
    assert [r.source.endswith("model.obj") for r in manifest] == [False, True, False]
    assert manifest[1].scale == 0.5
    assert [r.name for r in inputs.expand(["builtin:random:3"])] == ["random_000", "random_001", "random_002"]
    assert [r.name for r in inputs.expand(["builtin:random:5-7"])] == ["random_005", "random_006", "random_007"]
    assert {"mug", "box", "sphere"} <= {r.name for r in inputs.expand(["builtin:all"])}
    assert len(inputs.expand(["builtin:random"])) == 1000
    assert len(inputs.expand(["box", "box"])) == 1


@pytest.fixture(scope="module")
def serial(tmp_path_factory: pytest.TempPathFactory) -> Path:
    db = tmp_path_factory.mktemp("serial") / "one.db"
    api.generate(OBJECTS, "panda", db_path=db, settings=SMALL, seed=11, workers=1)
    assert content(db)
    return db


def test_two_workers_give_the_same_database(serial: Path, tmp_path: Path) -> None:
    db = tmp_path / "two.db"
    summary = api.generate(OBJECTS, "panda", db_path=db, settings=SMALL, seed=11, workers=2)
    assert summary.units == 2 * SMALL.chunks() and not summary.failed
    assert content(db) == content(serial)


def test_failing_object_is_recorded_and_the_batch_goes_on(tmp_path: Path) -> None:
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n")
    db = tmp_path / "b.db"
    summary = api.generate([str(bad), "box"], "panda", db_path=db, settings=SMALL, seed=11, workers=2)
    assert "bad" in summary.failed and "NaN" in summary.failed["bad"]
    with sqlite3.connect(db) as conn:
        status = dict(conn.execute("SELECT object, status FROM units WHERE chunk = 0").fetchall())
        errors = conn.execute("SELECT error FROM units WHERE object = 'bad'").fetchall()
    assert status == {"bad": "failed", "box": "done"}
    assert all("NaN" in e[0] for e in errors)
    # a rerun retries only the failed units
    again = api.generate([str(bad), "box"], "panda", db_path=db, settings=SMALL, seed=11, workers=1)
    assert again.skipped == SMALL.chunks() and again.units == SMALL.chunks()


def _cli(db: Path) -> list[str]:
    return [sys.executable, "-m", "planner.cli", "generate", *OBJECTS, "--hand", "panda", "--db", str(db),
            "--seed", "11", "--approaches", "8", "--rolls", "2", "--preshapes", "wide", "--chunk", "4",
            "--reach-placements", "1", "--workers", "1", "--quiet"]


@pytest.mark.parametrize("kill_after_units", [1, 3])
def test_sigkill_mid_run_then_resume_ends_identical(serial: Path, tmp_path: Path, kill_after_units: int) -> None:
    db = tmp_path / "killed.db"
    proc = subprocess.Popen(_cli(db), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None:
        try:
            with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=1) as conn:
                if conn.execute("SELECT COUNT(*) FROM units").fetchone()[0] >= kill_after_units:
                    break
        except sqlite3.Error:
            pass
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert api.check_db(db) == []
    subprocess.run(_cli(db), check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    assert content(db) == content(serial)


def test_ray_backend_on_a_local_instance(serial: Path, tmp_path: Path) -> None:
    pytest.importorskip("ray")
    db = tmp_path / "ray.db"
    summary = api.generate(OBJECTS, "panda", db_path=db, settings=SMALL, seed=11, workers=2, use_ray=True)
    assert not summary.failed
    assert content(db) == content(serial)
