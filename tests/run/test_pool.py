"""The crash-safe pool: results, failures, crashes, time-outs, workers that
die with their driver; and ``generate`` on it (same database whatever the
worker count, a unit that kills its workers recorded as failed)."""

from __future__ import annotations

import logging
import os
import signal
import sqlite3
import sys
import threading
from pathlib import Path

import pytest
from helpers import REFERENCE_OBJECTS, content
from processes import STARTUP, Driver, python, running, tree, wait_until

from planner import api
from planner.plan.sweep import SweepSettings
from planner.run import pool, procs, worker
from planner.run.pool import START_METHODS, Failure, PoolError, run
from tests import crash_units
from tests.run import pool_units as units

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
#: The reference batch's settings (tests/helpers.py REFERENCE_ARGS).
SMALL = SweepSettings(approaches=8, rolls=2, preshapes=("wide",), chunk=4, reach_placements=1).resolved("antipodal")


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_every_unit_once_with_its_result(workers: int) -> None:
    out = list(run(units.square, range(7), workers))
    assert sorted((u, r) for u, r, _ in out) == [(i, i * i) for i in range(7)]
    assert all(s >= 0 for _, _, s in out)


@pytest.mark.parametrize("start_method", START_METHODS)
def test_both_start_methods_give_the_results(start_method: str) -> None:
    out = list(run(units.square, range(5), 2, start_method=start_method))
    assert sorted(r for _, r, _ in out) == [i * i for i in range(5)]


def test_results_come_as_units_finish(tmp_path: Path) -> None:
    """Unit 0 cannot finish before the consumer has unit 1's result."""
    go = tmp_path / "go"
    slow, fast = (str(tmp_path / "slow"), str(go), 0), (str(tmp_path / "fast"), str(tmp_path), 1)
    results = run(units.wait_for, [slow, fast], 2)
    assert next(results)[1] == 1
    go.touch()
    assert next(results)[1] == 0
    assert list(results) == []


@pytest.fixture
def releaser():  # type: ignore[no-untyped-def]
    """A process that creates ``release`` once ``count`` files are in ``folder``."""
    started = []

    def start(folder: Path, count: int, release: Path) -> None:
        code = ("import sys, time, pathlib\n"
                "folder, n, release = pathlib.Path(sys.argv[1]), int(sys.argv[2]), pathlib.Path(sys.argv[3])\n"
                "while len(list(folder.iterdir())) < n: time.sleep(0.01)\n"
                "release.touch()\n")
        started.append(python("-c", code, str(folder), str(count), str(release)))

    yield start
    for p in started:
        p.kill()
        p.wait()


def test_in_flight_never_exceeds_workers(tmp_path: Path, releaser) -> None:  # type: ignore[no-untyped-def]
    folder, release = tmp_path / "flight", tmp_path / "release"
    folder.mkdir()
    releaser(folder, 2, release)
    out = list(run(units.in_flight, [(str(folder), str(release))] * 6, 2))
    seen = [r[0] for _, r, _ in out]
    assert max(seen) == 2  # two overlapped, never three
    assert len({r[1] for _, r, _ in out}) == 2  # two worker processes, no more


def test_exception_is_the_units_failure_and_the_rest_go_on() -> None:
    out = {u: r for u, r, _ in run(units.fail, ["a", "b"], 2)}
    assert out["a"] == Failure("error", "ValueError: a", 1)
    assert str(out["b"]) == "ValueError: b"
    out = {u: r for u, r, _ in run(units.fail, ["a"], 1)}  # the same in process
    assert out["a"] == Failure("error", "ValueError: a", 1)


def test_unpicklable_result_is_a_failure() -> None:
    [(_, outcome, _)] = run(units.unpicklable_result, [1], 2)
    assert isinstance(outcome, Failure) and outcome.kind == "error"
    assert "could not be sent back" in outcome.message


@pytest.mark.parametrize("how", ["exit", "kill", "segv"])
def test_dead_worker_replaced_and_unit_retried(tmp_path: Path, how: str) -> None:
    attempts = tmp_path / "attempts"
    attempts.mkdir()
    out = {u: r for u, r, _ in run(units.crash_first_time, [(str(attempts), how, 7)], 2)}
    value, pid = out[(str(attempts), how, 7)]
    assert value == 7
    tried = {int(p.name) for p in attempts.iterdir()}
    assert len(tried) == 2 and pid in tried  # a second worker process did it


@pytest.mark.parametrize("how, signal_name", [("segv", "SIGSEGV"), ("kill", "SIGKILL"), ("exit", "exit status 13")])
def test_unit_that_kills_two_workers_is_recorded_failed(tmp_path: Path, how: str, signal_name: str) -> None:
    attempts = tmp_path / "attempts"
    attempts.mkdir()
    bad = (str(attempts), how)
    out = {u: r for u, r, _ in run(units.crash_always, [bad], 2)}
    assert len(list(attempts.iterdir())) == 2
    failure = out[bad]
    assert isinstance(failure, Failure) and failure.kind == "crash" and failure.attempts == 2
    assert signal_name in failure.message and "2 times" in failure.message


def test_crashes_do_not_disturb_other_units(tmp_path: Path) -> None:
    attempts = tmp_path / "attempts"
    attempts.mkdir()
    bad = (str(attempts), "segv")
    out = {u: r for u, r, _ in run(units.square_or_crash, [bad, 1, 2, 3, 4, 5], 2)}
    assert {u: out[u] for u in range(1, 6)} == {i: i * i for i in range(1, 6)}
    assert out[bad].kind == "crash"


@linux
def test_worker_killed_from_outside_is_replaced(tmp_path: Path) -> None:
    """As the OOM killer would: the unit it ran is retried elsewhere."""
    marks, go = tmp_path / "marks", tmp_path / "go"
    marks.mkdir()
    got: list = []
    consumer = threading.Thread(target=lambda: got.extend(
        run(units.wait_for, [(str(marks), str(go), i) for i in range(2)], 2)))
    consumer.start()
    wait_until(lambda: len(list(marks.iterdir())) == 2, STARTUP, "both units running")
    os.kill(int(next(marks.iterdir()).name), signal.SIGKILL)
    wait_until(lambda: len(list(marks.iterdir())) == 3, STARTUP, "the unit started again in a new worker")
    go.touch()
    consumer.join()
    assert sorted(r for _, r, _ in got) == [0, 1]


def test_workers_that_cannot_start_stop_the_pool(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "vanishing.py").write_text("def f(x):\n    return x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import vanishing

    (tmp_path / "vanishing.py").unlink()  # the workers cannot import it any more
    with pytest.raises(PoolError, match="worker processes exit before they start"):
        list(run(vanishing.f, range(4), 2))


def test_max_crashes_one_means_no_retry(tmp_path: Path) -> None:
    attempts = tmp_path / "attempts"
    attempts.mkdir()
    [(_, outcome, _)] = run(units.crash_first_time, [(str(attempts), "exit", 1)], 2, max_crashes=1)
    assert outcome.kind == "crash" and outcome.attempts == 1
    assert len(list(attempts.iterdir())) == 1


@linux
def test_time_out_stops_the_worker(tmp_path: Path) -> None:
    progress = tmp_path / "progress"
    progress.mkdir()
    out = {u: r for u, r, _ in run(units.block_or_square, [str(progress), 3], 2, timeout=5.0)}
    assert out[3] == 9
    failure = out[str(progress)]
    assert failure.kind == "timeout" and "after 5 s" in failure.message
    [stuck] = [int(p.name) for p in progress.iterdir()]
    assert not procs.alive(stuck)


@linux
def test_closing_early_stops_the_workers(tmp_path: Path) -> None:
    progress = tmp_path / "progress"
    progress.mkdir()
    # queue order: the blocking unit is sent to a worker before 3 is
    results = run(units.block_or_square, [str(progress), 3], 2)
    assert next(results)[1] == 9
    wait_until(lambda: any(progress.iterdir()), STARTUP, "the blocking unit started")
    workers = pool_workers()
    assert len(workers) == 1  # the blocked one: the other, idle with no unit left, exited at once
    results.close()
    assert not running(workers)


def pool_workers() -> dict[int, int | None]:
    """This process's pool workers, by the name they give themselves."""
    return {p: t for p, t in tree(os.getpid()).items() if _comm(p) == worker.NAME}


def _comm(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return ""


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="forkserver, spawn"):
        run(units.square, [1], 2, start_method="fork")
    with pytest.raises(ValueError, match="max_crashes"):
        run(units.square, [1], 2, max_crashes=0)
    with pytest.raises(PoolError, match="module-level function"):
        list(run(lambda x: x, [1, 2], 2))


def test_nothing_to_do() -> None:
    assert list(run(units.square, [], 4)) == []


# -- the driver dies ------------------------------------------------------------
@linux
@pytest.mark.parametrize("start_method, moment, pdeathsig", [
    ("forkserver", "busy", True), ("forkserver", "idle", True), ("forkserver", "busy", False),
    ("spawn", "busy", True), ("spawn", "idle", False)])
def test_driver_sigkill_leaves_no_process(tmp_path: Path, start_method: str, moment: str, pdeathsig: bool) -> None:
    progress = tmp_path / "progress"
    progress.mkdir()
    args = ["--workers", "2", "--start-method", start_method, "--moment", moment]
    with Driver(str(Path(__file__).with_name("pool_driver.py")), str(progress), *args,
                *([] if pdeathsig else ["--no-pdeathsig"])) as driver:
        if moment == "busy":
            wait_until(lambda: len(list(progress.iterdir())) == 2, STARTUP, "both workers busy")
        else:
            wait_until(lambda: (progress / "suspended").exists(), STARTUP, "driver suspended, workers idle")
        assert len(driver.snapshot()) >= 2  # the workers (+ fork server or resource tracker)
        seconds = driver.kill()
        print(f"{start_method}/{moment}/{'pdeathsig' if pdeathsig else 'lifeline'}: all gone after {seconds:.3f} s")


# -- generate on the pool ----------------------------------------------------------
def test_two_workers_give_the_same_database(reference_db: Path, tmp_path: Path) -> None:
    db = tmp_path / "two.db"
    summary = api.generate(REFERENCE_OBJECTS, "panda", db_path=db, settings=SMALL, seed=11, workers=2)
    assert summary.units == 2 * SMALL.chunks() and not summary.failed
    assert content(db) == content(reference_db)


def test_units_that_kill_their_workers_are_recorded_failed_and_retried_by_a_rerun(
        reference_db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    db = tmp_path / "crash.db"
    with monkeypatch.context() as patch:
        patch.setattr(api, "run_unit", crash_units.generate_segfaults_on_sphere)
        with caplog.at_level(logging.WARNING, logger=pool.__name__):
            summary = api.generate(REFERENCE_OBJECTS, "panda", db_path=db, settings=SMALL, seed=11, workers=2)
    assert "killed by SIGSEGV" in summary.failed["sphere"] and "2 times" in summary.failed["sphere"]
    retried = [r for r in caplog.records if "retrying it" in r.getMessage()]
    assert len(retried) == SMALL.chunks()  # each sphere unit: one retry, then recorded failed
    with sqlite3.connect(db) as conn:
        status = conn.execute("SELECT object, status, error FROM units").fetchall()
    assert {(o, s) for o, s, _ in status} == {("box", "done"), ("sphere", "failed")}
    assert all("SIGSEGV" in e for o, s, e in status if o == "sphere")
    box = [row for row in content(reference_db) if row[0] == "box"]
    assert content(db) == box  # the box's units are untouched by the crashes next to them
    again = api.generate(REFERENCE_OBJECTS, "panda", db_path=db, settings=SMALL, seed=11, workers=2)
    assert again.skipped == SMALL.chunks() and not again.failed
    assert content(db) == content(reference_db)


def test_a_worker_left_without_units_exits_before_the_run_ends(tmp_path: Path) -> None:
    """A worker with no unit left waited for the run's end, holding its last unit's memory (an object's antipodal
    pairs: ~120 MB at 1,000,000 points) while another worker ran on."""
    go = tmp_path / "go"
    slow, fast = (str(tmp_path / "slow"), str(go), 0), (str(tmp_path / "fast"), str(tmp_path), 1)
    results = run(units.wait_for, [slow, fast], 2)
    assert next(results)[1] == 1
    assert len(pool_workers()) == 1  # the slow unit's
    go.touch()
    assert [r for _, r, _ in results] == [0]


def test_a_units_preparation_lines_reach_the_driver_while_it_runs(tmp_path: Path) -> None:
    """Lines a worker's unit logged (a mesh closed, cached afterwards) came back with its result only: a run
    interrupted before (Ctrl-C, kill -9 during a long first unit) lost them, and the cache then kept the object
    from ever saying them. Two workers that note the same line: said once."""
    from planner import prepare

    heard, lines = tmp_path / "heard", []

    class Heard(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            lines.append(record.getMessage())
            heard.touch()

    logger, handler = logging.getLogger(prepare.LOGGER), Heard()
    level = logger.level
    logger.setLevel(logging.INFO)
    logger.addHandler(handler)
    try:
        out = list(run(units.note_then_wait, [("cup.obj", str(heard))] * 2, 2))
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)
    assert [r for _, r, _ in out] == [True, True]
    assert lines == ["cup.obj: capped the mesh's open boundary loops (once: cached afterwards)"]


def test_idle_workers_are_all_told_to_stop_before_any_is_waited_for() -> None:
    """At a run's end each idle worker was told to exit only once the one before had exited (up to STOP_GRACE,
    5 s, each): the run's end waited for their exits in turn."""
    from collections import deque

    events: list[tuple[str, int]] = []

    class Conn:
        def __init__(self, i: int) -> None:
            self.i = i

        def send(self, message: object) -> None:
            events.append(("told", self.i))

        def close(self) -> None:
            pass

    class Process:
        def __init__(self, i: int) -> None:
            self.i = i

        def join(self, timeout: float | None = None) -> None:
            events.append(("waited", self.i))

        def is_alive(self) -> bool:
            return False

    idle = pool._Pool.__new__(pool._Pool)
    idle.size, idle.workers = 3, [pool._Worker(Process(i), Conn(i), ready=True) for i in range(3)]  # type: ignore[arg-type]
    assert idle._fill(deque()) == []
    assert idle.workers == []
    told = [i for kind, i in events if kind == "told"]
    assert told == [0, 1, 2] and events[:3] == [("told", 0), ("told", 1), ("told", 2)], events
