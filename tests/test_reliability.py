"""A killed run resumes to the database of an uninterrupted one, for the
process pool and for Ray; readers see one committed state while a writer
commits; runs on different databases do not disturb each other; a write that
fails (full disk, read-only database) keeps everything committed before it
and says so in one line.

Every moment is driven by observed progress (rows in the database), never by
wall time.
"""

from __future__ import annotations

import resource
import sqlite3
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from helpers import content, grasp, one_line_error
from processes import STARTUP, Driver, env, wait_until

from planner import api
from planner.db import store
from planner.db.ranking import RankingRule
from planner.geometry.solid import load_object
from planner.record.grasp import Grasp

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")

#: A batch of 8 units (one object, eight rays, one ray per unit): the first
#: kill comes with most of the work to do, the last with some still left.
OBJECTS = ("box",)
#: Rays (not the Panda's antipodal default): 8 one-ray units whose grasps
#: fill the full-disk test's file size limit part-way through the batch.
ARGS = ("--hand", "panda", "--sampler", "surface", "--seed", "11", "--approaches", "8", "--rolls", "2", "--preshapes",
        "wide", "--chunk", "1", "--reach-placements", "1", "--quiet")
UNITS = 8
#: Units committed when the driver is killed, one kill after another on the
#: same database (Ray: two, as each run starts a Ray instance).
MOMENTS = {"pool": (1, 3, 5), "ray": (1, 5)}


def command(db: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "planner.cli", "generate", *OBJECTS, "--db", str(db), *ARGS, *extra]


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The batch in one uninterrupted run, in this process, serially."""
    db = tmp_path_factory.mktemp("reliability") / "reference.db"
    code, _, err = grasp("generate", *OBJECTS, "--db", str(db), *ARGS, "--workers", "1")
    assert code == 0, err
    return db


def done_units(db: Path) -> int:
    """Finished units committed so far (0 while the database is being created)."""
    try:
        with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5) as conn:
            return conn.execute("SELECT COUNT(*) FROM units WHERE status = 'done'").fetchone()[0]
    except sqlite3.Error:
        return 0


def by_unit(db: Path) -> dict[tuple[str, int], list[tuple]]:
    """Each finished unit's grasps (all of :func:`helpers.content` but the
    rank, which depends on the other units)."""
    with sqlite3.connect(db) as conn:
        rows = conn.execute(
            "SELECT u.object, u.chunk, g.preshape, g.candidate, g.pose, g.closed_joints, g.contacts, g.epsilon,"
            " g.volume, g.force_closure, g.reachability, g.score FROM grasps g JOIN units u ON u.id = g.unit_id"
            " WHERE u.status = 'done' ORDER BY u.object, g.candidate").fetchall()
    out: dict[tuple[str, int], list[tuple]] = {}
    for row in rows:
        out.setdefault((row[0], row[1]), []).append(row[2:])
    return out


def assert_whole_units_of(db: Path, reference: Path) -> int:
    """``db`` holds only finished units, each exactly as in ``reference``,
    and passes the integrity check; returns how many."""
    assert api.check_db(db) == []
    got, want = by_unit(db), by_unit(reference)
    for key, rows in got.items():
        assert rows == want[key], f"unit {key} differs from the uninterrupted run"
    return done_units(db)


# -- kill -9, then the same command ---------------------------------------------------
@linux
@pytest.mark.slow  # four runs of the batch, 30-40 s on a loaded 2-core machine (Ray: three instances, ~1 min)
@pytest.mark.parametrize("backend", ["pool", pytest.param("ray", marks=pytest.mark.ray)])
def test_kill_9_at_several_moments_then_the_same_command_resumes(reference: Path, tmp_path: Path,
                                                                 backend: str) -> None:
    if backend == "ray":
        pytest.importorskip("ray")
    extra = ("--workers", "2", *(("--ray",) if backend == "ray" else ()))
    db = tmp_path / "killed.db"
    killed: list[int] = []
    logs: list[Path] = []
    for moment in MOMENTS[backend]:
        logs.append(tmp_path / f"stderr.{moment}")
        with logs[-1].open("w") as log, Driver(*command(db, *extra)[1:], stderr=log) as driver:
            wait_until(lambda: done_units(db) >= moment or driver.proc.poll() is not None, STARTUP,  # noqa: B023
                       f"{moment} units committed")
            assert driver.proc.poll() is None, f"the run ended before the kill: {logs[-1].read_text()}"
            workers = driver.snapshot()
            assert len(workers) >= 2  # pool: fork server + workers; Ray: launcher, GCS, raylet, workers
            seconds = driver.kill()
            print(f"{backend}: killed after {moment}+ units, {len(workers)} processes gone after {seconds:.2f} s")
        killed.append(driver.proc.pid)
        assert moment <= assert_whole_units_of(db, reference) < UNITS
    final = subprocess.run(command(db, *extra), env=env(), capture_output=True, text=True)
    assert final.returncode == 0, final.stderr
    # each run after a kill took the lock over, saying so in one line that names the killed driver
    for stderr, pid in zip([log.read_text() for log in logs[1:]] + [final.stderr], killed):
        takeover = [line for line in stderr.splitlines() if "taking over the writer lock" in line]
        assert len(takeover) == 1 and f"of pid {pid}," in takeover[0], stderr
    assert assert_whole_units_of(db, reference) == UNITS
    assert content(db) == content(reference)


# -- readers while a writer commits ----------------------------------------------------
def stored_units(db: Path) -> list[tuple[store.UnitRow, list[Grasp]]]:
    """The reference's units with their grasps, to write them again."""
    with sqlite3.connect(db) as conn:
        units = conn.execute("SELECT id, object, hand, settings_hash, settings, seed, chunk, candidates FROM units"
                             " ORDER BY object, chunk").fetchall()
    with store.open_db(db, create=False, readonly=True) as handle:
        grasps = [g for name in OBJECTS for batch in handle.grasp_batches(name, "panda") for g in batch]
    return [(store.UnitRow(o, h, s, settings, seed, chunk, candidates=n), [g for g in grasps if g.unit_id == uid])
            for uid, o, h, s, settings, seed, chunk, n in units]


def writes(db: Path, units: list[tuple[store.UnitRow, list[Grasp]]], rules: list[RankingRule]) -> Iterator[int]:
    """Commit each unit, then re-score the whole database under the next
    rule (as ``generate --reach-weight`` does); yields the box's grasp count
    after each commit."""
    objects = {name: load_object(name) for name in OBJECTS}
    box = 0
    with store.open_db(db) as handle:
        for i, (unit, grasps) in enumerate(units):
            handle.write_unit(unit, objects[unit.object], grasps, handle.rule())
            box += len(grasps) if unit.object == "box" else 0
            yield box
            handle.apply_rule(rules[i % len(rules)])
            yield box


def test_best_sees_one_committed_state_while_a_writer_commits(reference: Path, tmp_path: Path) -> None:
    """A reader loops over ``best`` while units are committed and the whole
    database re-scored between them; the writer goes on only once the reader
    has seen its last commit, so every committed state is read."""
    db = tmp_path / "busy.db"
    units = stored_units(reference)
    box_states, total = set(), 0
    for unit, grasps in units:
        total += len(grasps) if unit.object == "box" else 0
        box_states.add(total)
    seen: list[int] = []  # box grasps in each answer
    handover = threading.Condition()
    failed: list[BaseException] = []
    done = threading.Event()

    def writer() -> None:
        try:
            for count in writes(db, units, [RankingRule(0.9), RankingRule(0.1), RankingRule(0.5)]):
                with handover:
                    handover.wait_for(lambda: bool(seen) and seen[-1] >= count, STARTUP)  # noqa: B023
        except BaseException as exc:
            failed.append(exc)
        finally:
            done.set()

    thread = threading.Thread(target=writer)
    thread.start()
    try:
        while not done.is_set():
            try:
                answer = api.best("box", "panda", db_path=db, top=10**6)
            except api.InputError:  # no grasps of the box committed yet
                answer = []
            except store.DatabaseError:  # the file is being created
                continue
            ranks, scores = [g.rank for g in answer], [g.score for g in answer]
            assert ranks == list(range(1, len(answer) + 1)), ranks
            assert scores == sorted(scores, reverse=True), scores
            with handover:
                seen.append(len(answer))
                handover.notify_all()
    finally:
        done.wait()
        thread.join()
    assert not failed, failed
    assert set(seen) - {0} == box_states - {0}  # every committed state was read, and nothing else


def test_batched_reads_see_the_snapshot_they_started_in(reference: Path, tmp_path: Path) -> None:
    """``best --object-pose`` reads ranks in batches: a unit committed between
    two batches must not shift the second one (a grasp skipped or repeated)."""
    db = tmp_path / "snap.db"
    units = sorted((u for u in stored_units(reference) if u[0].object == "box"), key=lambda u: len(u[1]))
    late, late_grasps = units.pop()  # the unit with the most grasps comes last
    rule = RankingRule(0.5)
    box = load_object("box")
    with store.open_db(db) as writer:
        for unit, grasps in units:
            writer.write_unit(unit, box, grasps, rule)
        before = [g.candidate for g in writer.best("box", "panda", 10**6)]
        with store.open_db(db, create=False, readonly=True) as reader, reader.snapshot():
            first = reader.best("box", "panda", 3)
            writer.write_unit(late, box, late_grasps, rule)
            rest = reader.best("box", "panda", 10**6, 3)
        assert [g.candidate for g in first + rest] == before
        assert len(writer.best("box", "panda", 10**6)) == len(before) + len(late_grasps) > len(before)


# -- two databases at once -----------------------------------------------------------
@pytest.mark.slow  # two runs of the batch side by side on two cores
def test_two_runs_on_different_databases_in_parallel_are_unaffected(reference: Path, tmp_path: Path) -> None:
    """Each with its own workers, both filling one fresh mesh cache."""
    cache = tmp_path / "cache"
    runs = [subprocess.Popen(command(tmp_path / f"{name}.db", "--workers", workers), stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, text=True, env={**env(), "GRASP_CACHE": str(cache)})
            for name, workers in (("a", "1"), ("b", "2"))]
    errors = [run.communicate()[1] for run in runs]
    assert [run.returncode for run in runs] == [0, 0], errors
    assert content(tmp_path / "a.db") == content(reference)
    assert content(tmp_path / "b.db") == content(reference)


# -- writes that fail ----------------------------------------------------------------
#: [bytes] the largest file the writer may write in the full-disk test: room
#: for a few of the 8 units in the write-ahead log, not for all of them.
FILE_SIZE_LIMIT = 300_000


def limit_file_size() -> None:
    """In the child: a disk that fills up, without root or a mount. Python
    ignores SIGXFSZ, so a write past the limit fails with EFBIG."""
    resource.setrlimit(resource.RLIMIT_FSIZE, (FILE_SIZE_LIMIT, FILE_SIZE_LIMIT))


@linux
def test_full_disk_keeps_what_was_committed_and_says_so_in_one_line(reference: Path, tmp_path: Path) -> None:
    db = tmp_path / "full.db"
    run = subprocess.run(command(db, "--workers", "1"), env=env(), preexec_fn=limit_file_size, capture_output=True,
                         text=True)
    kept = assert_whole_units_of(db, reference)
    assert 0 < kept < UNITS
    one_line_error(run.returncode, run.stderr, 3, "the disk is full or the file may not grow", "disk I/O error",
                   f"everything committed before is kept ({kept} finished units)", "run the same command again")
    again = subprocess.run(command(db, "--workers", "1"), env=env(), capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    assert content(db) == content(reference)


def test_read_only_database_during_a_write_keeps_what_was_committed(reference: Path, tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """The file turns read-only after two units (SQLite's ``query_only``
    refuses writes with the error a read-only file gives)."""
    db = tmp_path / "ro.db"
    write_unit = store.Database.write_unit
    written: list[int] = []

    def turning_read_only(self: store.Database, *args, **kwargs) -> int:  # type: ignore[no-untyped-def]
        if len(written) == 2:
            self._conn.execute("PRAGMA query_only = ON")
        written.append(write_unit(self, *args, **kwargs))
        return written[-1]

    monkeypatch.setattr(store.Database, "write_unit", turning_read_only)
    code, _, err = grasp("generate", *OBJECTS, "--db", str(db), *ARGS, "--workers", "1")
    one_line_error(code, err, 3, "the database is read-only", "attempt to write a readonly database",
                   "everything committed before is kept (2 finished units)", "make it writable")
    monkeypatch.undo()
    assert assert_whole_units_of(db, reference) == 2
