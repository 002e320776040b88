"""The Ray backend: the pool's contract on a private local instance. That
the instance goes with its driver, and that ``generate --ray`` gives the same
database, even when killed and resumed: tests/test_reliability.py. Needs Ray
(the dev extra has it)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

pytest.importorskip("ray")

from processes import ROOT  # noqa: E402

from planner.run.pool import Failure  # noqa: E402
from planner.run.ray_local import local_ray, run_ray  # noqa: E402
from tests.run import pool_units as units  # noqa: E402

pytestmark = pytest.mark.ray


@pytest.fixture(scope="module")
def cluster():  # type: ignore[no-untyped-def]
    """One private instance for this module; its workers import tests.plan.pool_units."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
        with local_ray(2) as info:
            yield info


def test_results_errors_and_crashes(cluster, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    once, always = tmp_path / "once", tmp_path / "always"
    once.mkdir()
    always.mkdir()
    jobs = [1, 2, (str(once), "exit", 5), (str(always), "segv")]
    out = {u: r for u, r, _ in run_ray(units.square_crash_or_retry, jobs, 2)}
    assert out[1] == 1 and out[2] == 4
    assert out[(str(once), "exit", 5)][0] == 5 and len(list(once.iterdir())) == 2
    failure = out[(str(always), "segv")]
    assert isinstance(failure, Failure) and failure.kind == "crash" and len(list(always.iterdir())) == 2
    [(_, error, _)] = run_ray(units.fail, ["bad"], 2)
    assert error == Failure("error", "ValueError: bad", 1)


def test_time_out(cluster, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    # 10 s, not less: on a loaded 2-core machine a Ray worker may take seconds
    # to pick up even the quick unit (a 2 s limit failed in CI that way).
    out = {u: r for u, r, _ in run_ray(units.block_or_square, [str(tmp_path), 3], 2, timeout=10.0)}
    assert out[3] == 9 and out[str(tmp_path)].kind == "timeout"

