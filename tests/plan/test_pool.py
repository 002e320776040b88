"""Running units: a local process pool, Ray; the same results whatever the
backend, and a worker that dies is replaced."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
from helpers import REFERENCE_OBJECTS, content

from planner import api
from planner.plan import pool
from planner.plan.sweep import SweepSettings
from planner.plan.unit import UnitResult, UnitSpec

#: The reference batch's settings (tests/helpers.py REFERENCE_ARGS).
SMALL = SweepSettings(approaches=8, rolls=2, preshapes=("wide",), chunk=4, reach_placements=1).resolved("antipodal")
#: [s] how long a unit waits for the others before giving up (only reached if the pool misbehaves).
WAIT_LIMIT = 60.0


def test_two_workers_give_the_same_database(reference_db: Path, tmp_path: Path) -> None:
    db = tmp_path / "two.db"
    summary = api.generate(REFERENCE_OBJECTS, "panda", db_path=db, settings=SMALL, seed=11, workers=2)
    assert summary.units == 2 * SMALL.chunks() and not summary.failed
    assert content(db) == content(reference_db)


def test_ray_backend_on_a_local_instance(reference_db: Path, tmp_path: Path) -> None:
    pytest.importorskip("ray")
    db = tmp_path / "ray.db"
    summary = api.generate(REFERENCE_OBJECTS, "panda", db_path=db, settings=SMALL, seed=11, workers=2, use_ray=True)
    assert not summary.failed
    assert content(db) == content(reference_db)


def crash_after_the_others(unit: UnitSpec) -> UnitResult:
    """A stand-in for run_unit, run in the workers: each call leaves a mark;
    the unit named "crash" kills its worker once the caller has received the
    other units' results (so none of them is in flight when the pool breaks)."""
    marks = Path(os.environ["POOL_TEST_MARKS"])
    (marks / f"{unit.object_name}.{os.getpid()}.{time.monotonic_ns()}").touch()
    if unit.object_name != "crash":
        return UnitResult(unit)
    deadline = time.monotonic() + WAIT_LIMIT
    while len(list(marks.glob("received.*"))) < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    os._exit(1)  # what a simulator segfault looks like to the pool


def test_a_worker_that_dies_is_replaced_its_unit_retried_then_recorded_failed(tmp_path: Path,
                                                                              monkeypatch: pytest.MonkeyPatch
                                                                              ) -> None:
    monkeypatch.setenv("POOL_TEST_MARKS", str(tmp_path))
    monkeypatch.setattr(pool, "run_unit", crash_after_the_others)
    units = [UnitSpec(name, "panda", SMALL, 0) for name in ("crash", "ok_a", "ok_b")]
    results = {}
    for result, _ in pool.execute(units, workers=2):
        results[result.spec.object_name] = result
        (tmp_path / f"received.{result.spec.object_name}").touch()
    assert results["ok_a"].error is None and results["ok_b"].error is None
    assert "worker process crashed" in (results["crash"].error or "")
    attempts = sorted(p.name.split(".") for p in tmp_path.iterdir() if p.name.startswith("crash."))
    assert len(attempts) == pool.MAX_CRASHES  # retried once, then recorded as failed
    assert len({pid for _, pid, _ in attempts}) == pool.MAX_CRASHES  # each time in a fresh worker
    assert len(list(tmp_path.glob("ok_*"))) == 2  # the others ran once


def test_one_worker_runs_units_in_this_process_in_order() -> None:
    units = [UnitSpec(name, "panda", SMALL, 0) for name in ("teapot", "kettle")]
    results = [r for r, _ in pool.execute(units, workers=1)]
    assert [r.spec.object_name for r in results] == ["teapot", "kettle"]
    assert all("unknown object" in (r.error or "") for r in results)  # failures are recorded, not raised
