"""The writer lock: one writer per database, a refusal names the holder, a
dead holder's lock is taken over with a one-line message naming it, and no
child process (pool worker, forked or not) keeps it."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from helpers import FAST, grasp, one_line_error
from processes import STARTUP, Driver, kill_all, python, running, wait_until

from planner.db.lock import LockBusy, writer_lock
from planner.errors import DatabaseError
from planner.run import procs
from planner.run.pool import run
from tests.run import pool_units as units

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


class Holder:
    """Another process holding the lock of ``db``."""

    def __init__(self, db: Path, mode: str = "plain") -> None:
        self.ready = db.with_name("ready")
        self.proc = python(str(Path(__file__).with_name("lock_holder.py")), str(db), str(self.ready), mode,
                           stdin=subprocess.PIPE)
        wait_until(self.ready.exists, STARTUP, "the holder has the lock")
        children = self.ready.with_name("ready.children")
        self.children = {int(p.name): procs.start_ticks(int(p.name)) for p in children.iterdir()}

    def release(self) -> None:
        self.proc.stdin.close()  # type: ignore[union-attr]
        assert self.proc.wait() == 0

    def kill(self) -> None:
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait()

    def cleanup(self) -> None:
        self.proc.kill()
        self.proc.wait()
        kill_all(self.children)


@pytest.fixture
def holders():  # type: ignore[no-untyped-def]
    made: list[Holder] = []

    def make(db: Path, mode: str = "plain") -> Holder:
        made.append(Holder(db, mode))
        return made[-1]

    yield make
    for h in made:
        h.cleanup()


def test_second_writer_refused_naming_the_holder(tmp_path: Path, holders, caplog) -> None:  # type: ignore[no-untyped-def]
    db = tmp_path / "x.db"
    holder = holders(db)
    with pytest.raises(LockBusy) as refused:
        with writer_lock(db):
            pass
    message = str(refused.value)
    assert len(message.splitlines()) == 1
    assert f"another process (pid {holder.proc.pid}, `lock_holder.py" in message and str(db) in message
    holder.release()
    with caplog.at_level(logging.WARNING), writer_lock(db) as previous:
        assert previous is None  # released cleanly: nothing taken over
    assert not caplog.records


def test_generate_refused_with_one_line_while_another_process_writes(tmp_path: Path, holders) -> None:  # type: ignore[no-untyped-def]
    db = tmp_path / "g.db"
    holder = holders(db)
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), *FAST, "--quiet")
    one_line_error(code, err, 3, f"another process (pid {holder.proc.pid}, `lock_holder.py", "use another --db")
    assert not db.exists()  # refused before the database was opened
    holder.release()
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), *FAST, "--quiet")
    assert code == 0, err


def test_same_process_refused_and_keeps_its_lock(tmp_path: Path) -> None:
    db = tmp_path / "x.db"
    with writer_lock(db):
        with pytest.raises(LockBusy, match="this process is already writing"):
            with writer_lock(db):
                pass
        (tmp_path / "x.db.lock").read_text()  # opening and closing the file elsewhere ...
        probe = python("-c", f"from planner.db.lock import writer_lock\nwith writer_lock({str(db)!r}): pass",
                       stderr=subprocess.PIPE, text=True)
        _, err = probe.communicate()
        assert probe.returncode != 0 and "LockBusy" in err  # ... does not drop the lock


def test_lock_of_a_dead_writer_is_taken_over_with_a_message(tmp_path: Path, holders, caplog) -> None:  # type: ignore[no-untyped-def]
    db = tmp_path / "x.db"
    holder = holders(db)
    holder.kill()
    with caplog.at_level(logging.WARNING), writer_lock(db) as previous:
        assert previous is not None and previous.pid == holder.proc.pid
    [record] = caplog.records
    assert f"taking over the writer lock of pid {holder.proc.pid}" in record.getMessage()


@linux
@pytest.mark.parametrize("mode", ["executor-fork", "os-fork"])
def test_forked_child_does_not_keep_the_lock(tmp_path: Path, holders, mode: str) -> None:  # type: ignore[no-untyped-def]
    """Issue 13's setup: the writer forks a child that outlives it."""
    db = tmp_path / "x.db"
    holder = holders(db, mode)
    assert len(holder.children) == 1
    holder.kill()
    assert running(holder.children)  # the orphan lives on (nothing here kills it) ...
    with writer_lock(db) as previous:  # ... and yet the lock is free at once
        assert previous is not None and previous.pid == holder.proc.pid


@linux
def test_pool_workers_hold_no_descriptor_of_the_lock(tmp_path: Path) -> None:
    db, busy, go = tmp_path / "x.db", tmp_path / "busy", tmp_path / "go"
    busy.mkdir()
    lock_file = str(tmp_path / "x.db.lock")
    with writer_lock(db):
        got: list = []
        consumer = threading.Thread(target=lambda: got.extend(
            run(units.wait_for, [(str(busy), str(go), i) for i in range(2)], 2)))
        consumer.start()
        wait_until(lambda: len(list(busy.iterdir())) == 2, STARTUP, "both units running")
        for pid in (int(p.name) for p in busy.iterdir()):
            fd_dir = Path(f"/proc/{pid}/fd")
            assert lock_file not in {os.path.realpath(fd) for fd in fd_dir.iterdir()}
        go.touch()
        consumer.join()
        assert sorted(r for _, r, _ in got) == [0, 1]


@linux
def test_driver_killed_mid_pool_lock_free_at_once(tmp_path: Path) -> None:
    db, progress = tmp_path / "x.db", tmp_path / "progress"
    progress.mkdir()
    with Driver(str(Path(__file__).parents[1] / "run" / "pool_driver.py"), str(progress), "--lock", str(db)) as driver:
        wait_until(lambda: len(list(progress.iterdir())) == 2, STARTUP, "both workers busy")
        driver.proc.send_signal(signal.SIGKILL)
        driver.proc.wait()
        with writer_lock(db) as previous:  # at once, whether or not the workers are gone yet
            assert previous is not None and previous.pid == driver.proc.pid


def test_lock_file_that_cannot_be_created(tmp_path: Path) -> None:
    with pytest.raises(DatabaseError, match="cannot create the lock file .*No such file"):
        with writer_lock(tmp_path / "missing" / "x.db"):
            pass


def test_unreadable_owner_record_is_no_owner(tmp_path: Path, caplog) -> None:  # type: ignore[no-untyped-def]
    db = tmp_path / "x.db"
    (tmp_path / "x.db.lock").write_text("garbage{")
    with caplog.at_level(logging.WARNING), writer_lock(db) as previous:
        assert previous is None
    assert not caplog.records


def test_one_lock_per_file_whichever_path_names_it(tmp_path: Path) -> None:
    """The lock was named after the path given: two writers through a symlink both ran (a helper's two
    generates did the full work twice); now the file's real path names it."""
    db = tmp_path / "x.db"
    db.touch()
    (tmp_path / "link.db").symlink_to(db)
    with writer_lock(db):
        with pytest.raises(LockBusy):
            with writer_lock(tmp_path / "link.db"):
                pass


def test_a_database_with_a_second_name_is_not_written(box_db: Path, tmp_path: Path) -> None:
    """A hard link (a `cp -al` snapshot) is a second name the lock, named after the file, does not see: two
    writers ran at once and one's unit was lost. Refused, nothing changed."""
    db = tmp_path / "a.db"
    db.write_bytes(box_db.read_bytes())
    os.link(db, tmp_path / "b.db")
    before = db.read_bytes()
    code, _, err = grasp("generate", "sphere", "--hand", "panda", "--db", str(tmp_path / "b.db"), *FAST, "--quiet")
    one_line_error(code, err, 3, "the file has 2 names (hard links", "nothing was changed")
    assert db.read_bytes() == before


@pytest.mark.parametrize("since", ["1e300", "NaN"])
def test_an_owner_record_with_a_time_no_clock_gives_is_no_owner(box_db: Path, tmp_path: Path, since: str) -> None:
    """A lock file naming an owner "since" 1e300 or NaN (garbage, another tool's file) passed as an owner: `grasp best`
    of an object not stored, `validate` (its takeover's warning) died with "internal error: OverflowError" or
    "ValueError: Invalid value NaN". It is no owner: one line each, as for any unreadable record."""
    import shutil

    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    (tmp_path / "g.db.lock").write_text(f'{{"pid": 5, "start": null, "host": "elsewhere", "command": "grasp x", '
                                        f'"since": {since}}}')
    code, _, err = grasp("best", "sphere", "--hand", "panda", "--db", str(db))
    one_line_error(code, err, 2, "no grasps of 'sphere'", "run `grasp generate sphere")
    assert "internal error" not in err


def test_validate_of_an_empty_file_with_a_lock_of_another_host_leaves_it_empty(tmp_path: Path) -> None:
    """A 0-byte file whose lock file names a writer on another host (a container killed while creating it, the
    folder shared): validate took the stale lock over and made the file a database (73,728 bytes) before saying
    "no grasps"; refused in one line, the file left empty, as without the lock file."""
    db = tmp_path / "e.db"
    db.write_bytes(b"")
    (tmp_path / "e.db.lock").write_text('{"pid": 5, "start": null, "host": "elsewhere", "command": "grasp generate '
                                        'box --db e.db", "since": 1}')
    code, _, err = grasp("validate", "--db", str(db))
    one_line_error(code, err, 3, "e.db: ")
    assert db.stat().st_size == 0


def test_a_lock_file_of_another_host_is_not_said_to_be_a_writer_at_work(box_db: Path, tmp_path: Path,
                                                                        caplog) -> None:  # type: ignore[no-untyped-def]
    """A lock file naming a writer on another host (a container or machine that died, the folder shared) read as a
    writer at work: "pid 5 on elsewhere, `grasp generate ...`, since ... is writing it", whatever its age. Said as
    what it is: whose record, since when and how long ago, that this host cannot check it, and what happens if it
    ended; the writer that takes it over does not claim it ended either."""
    import shutil

    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    record = ('{"pid": 5, "start": null, "host": "elsewhere", "command": "grasp generate box sphere --hand panda", '
              '"since": %r}' % (time.time() - 3 * 86400))
    (tmp_path / "g.db.lock").write_text(record)
    code, _, err = grasp("best", "sphere", "--hand", "panda", "--db", str(db))
    one_line_error(code, err, 2, "no grasps of 'sphere'", "its lock file records pid 5 on host elsewhere",
                   "(3.0 days ago) as writing it, a process of another host", "the next writer takes its lock over")
    empty = tmp_path / "e.db"
    empty.write_bytes(b"")
    (tmp_path / "e.db.lock").write_text(record)
    code, _, err = grasp("best", "box", "--hand", "panda", "--db", str(empty))
    one_line_error(code, err, 3, "e.db: no grasp is in it yet: its lock file records pid 5 on host elsewhere",
                   "as creating it, a process of another host")
    with caplog.at_level(logging.WARNING), writer_lock(db) as previous:
        assert previous is not None and previous.host == "elsewhere"
    [warning] = caplog.records
    assert "which holds it no longer (a process of another host" in warning.getMessage()
    assert "ended without releasing it" not in warning.getMessage()
