"""The command group's error contract: one line on stderr, the exit code of
the error, never a traceback; names not found list the valid ones."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from helpers import grasp, one_line_error

from planner.cli.app import RATE_MIN_COUNT, per_second, rate_text, share
from planner.errors import InputError


@pytest.mark.parametrize("args, code, message", [
    (["generate", "teapot", "--hand", "panda"], 2, "unknown object 'teapot'"),
    (["generate", "box", "--hand", "robotiq"], 2, "unknown hand 'robotiq'. Available hands:"),
    (["generate", "missing.obj", "--hand", "panda"], 2, "missing.obj: file not found"),
    (["generate", "box", "--hand", "panda", "--preshapes", "fist"], 2, "unknown preshape 'fist'"),
    (["best", "box", "--hand", "panda", "--db", "nowhere.db"], 3, "no such database"),
])
def test_bad_input_is_one_line_and_exit_code(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[str],
                                             code: int, message: str) -> None:
    monkeypatch.chdir(tmp_path)
    got, out, err = grasp(*args)
    assert got == code
    assert message in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


@pytest.mark.parametrize("args, needle", [
    (["generate", "teapot", "--hand", "panda"], "Available objects: box, bunny"),
    (["generate", "box", "--hand", "shadow"], "Available hands: allegro, barrett, panda, pr2"),
    (["generate", "box", "--hand", "panda", "--preshapes", "fist"], "Available preshapes: half, wide"),
    (["generate", "box", "--hand", "../objects"], "folder name"),
    (["best", "box", "--hand", "panda", "--object-pose", "1,2,3"], "7 finite numbers"),
    (["best", "box", "--hand", "panda", "--object-pose", "1e308,0,0,0,0,0,1"], "more than 1000 m from the origin"),
    (["best", "box", "--hand", "panda", "--object-pose", "0.5,0,0,0,0,0,1.8"], "has length 1.8, not 1"),
    (["best", "box", "--hand", "panda", "--object-pose", "0.5,0,0,0,0,0,1", "--robot-base", "0,0,0,1,0,0,1"],
     "--robot-base: quaternion"),
    (["generate", "box", "--hand", "panda", "--depths", "nan"], "--depths"),
    (["show", "box", "--hand", "panda", "--top", "101"], "a contact sheet holds at most 100 grasps"),
    (["generate", "box", "--hand", "barrett", "--sampler", "antipodal"], "the antipodal sampler needs a parallel jaw"),
    (["generate", "box", "--hand", "barrett", "--preshapes", ""], "unknown preshape ''"),
    (["generate", "box", "--hand", "panda", "--standoffs", "inf"], "--standoffs"),
    (["generate", "box", "--hand", "panda", "--unit-timeout", "-1"], "--unit-timeout"),
    (["generate", "box", "--hand", "panda", "--unit-timeout", "1e300"], "at most 604,800 (a week)"),  # was an
    # internal error (OverflowError) in the pool's wait, with more than one worker
    (["generate", "box", "--hand", "panda", "--approaches", "1000000000"], "at most 1,000,000"),
    (["generate", "box", "--hand", "panda", "--sampler", "box", "--box-delta", "-1"], "--box-delta"),
    (["generate", "box", "--hand", "barrett", "--sampler", "box", "--box-delta", "1e-5"],
     "--box-delta 1e-05 m casts"),  # was a failed unit in the database, found in the worker
    (["generate", "box", "--hand", "panda", "--reach-weight", "3"], "--reach-weight must be in [0, 1]"),
])
def test_unknown_names_list_the_valid_ones(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[str],
                                           needle: str) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, err = grasp(*args)
    one_line_error(code, err, InputError.exit_code, needle)  # bad input: refused before any database is opened
    assert not (tmp_path / "grasps.db").exists()


@pytest.mark.parametrize("args, option", [
    (["generate", "box", "--hand", "panda", "--depths", "a,b"], "--depths"),
    (["generate", "box", "--hand", "panda", "--standoffs", "0.1,q"], "--standoffs"),
    (["best", "box", "--hand", "panda", "--object-pose", "1,2,x"], "--object-pose"),
    (["best", "box", "--hand", "panda", "--object-pose", "0.5,0,0.04,0,0,0,1", "--robot-base", "1,z"], "--robot-base"),
    (["best", "box", "--hand", "panda", "--on-table", "--table-at", "1,y"], "--table-at"),
    (["view", "box", "--hand", "panda", "--object-pose", "1,x"], "--object-pose"),
])
def test_a_list_of_numbers_that_is_not_names_its_option(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                        args: list[str], option: str) -> None:
    """'Invalid value: '1,2,x' is not a comma-separated list of numbers' named no option."""
    monkeypatch.chdir(tmp_path)
    code, _, err = grasp(*args)
    one_line_error(code, err, 2, f"Invalid value for {option}: ", "is not a comma-separated list of numbers")


@pytest.mark.parametrize("args, code", [
    (["best", "box", "--hand", "panda", "--top", "99999999999999999999"], 0),
    (["show", "box", "--hand", "panda", "--rank", "99999999999999999999"], 2),
    (["export", "--format", "csv", "--out", "x", "--top", "99999999999999999999", "--quiet"], 0),
])
def test_a_count_past_sqlites_integers_is_all_not_an_internal_error(box_db: Path, tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch,
                                                                     args: list[str], code: int) -> None:
    """--top or --rank 1e20 (a typo's zeros) was an OverflowError from SQLite: exit 1, 'internal error'."""
    monkeypatch.chdir(tmp_path)
    got, _, err = grasp(*args, "--db", str(box_db))
    assert got == code and "internal error" not in err, err


def test_debug_shows_the_traceback_and_keeps_the_exit_code(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    plain, _, _ = grasp("generate", "teapot", "--hand", "panda")
    code, _, err = grasp("--debug", "generate", "teapot", "--hand", "panda")
    assert code == plain == InputError.exit_code
    assert "Traceback" in err and err.strip().splitlines()[-1].startswith("grasp: error: unknown object 'teapot'")
    code, _, err = grasp("--debug", "best", "box", "--hand", "panda", "--db", "nowhere.db")
    assert code == 3 and "Traceback" in err


@pytest.mark.parametrize("args, needle", [
    (["generate", "box", "--hand", "panda", "--scale", "0"], "scale must be a positive number, got 0"),
    (["generate", "box", "--hand", "panda", "--scale", "-1"], "scale must be a positive number, got -1"),
    (["generate", "box", "--hand", "panda", "--workers", "0"], "'--workers': 0 is not in the range x>=1"),
    (["validate", "--workers", "0"], "'--workers': 0 is not in the range x>=1"),
    (["import", "x.h5", "--workers", "0"], "'--workers': 0 is not in the range x>=1"),
    (["generate", "box", "--hand", "panda", "--seed", "x"], "Invalid value for '--seed'"),
])
def test_early_errors_come_alone(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[str],
                                 needle: str) -> None:
    """Refused before any work: one line on stderr, nothing on stdout (no progress bar), no database."""
    monkeypatch.chdir(tmp_path)
    code, out, err = grasp(*args)
    one_line_error(code, err, InputError.exit_code, needle)
    assert out == "" and not (tmp_path / "grasps.db").exists()


def test_the_api_refuses_zero_workers_too(tmp_path: Path) -> None:
    from planner import api

    with pytest.raises(InputError, match="--workers must be at least 1, got 0"):
        api.generate(["box"], "panda", db_path=tmp_path / "g.db", workers=0)
    assert not (tmp_path / "g.db").exists()


@pytest.mark.parametrize("args", [["objects"], ["hands", "panda"]])
def test_a_reader_that_goes_away_gets_no_error(args: list[str]) -> None:
    """`grasp ... | head`: once the reader has closed the pipe, the command stops
    quietly with 128 + SIGPIPE, as shell tools do (not an internal error)."""
    import subprocess
    import sys

    from planner.cli.app import EXIT_PIPE

    child = subprocess.Popen([sys.executable, "-m", "planner.cli", *args], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE)
    child.stdout.close()  # type: ignore[union-attr]
    err = child.stderr.read().decode()  # type: ignore[union-attr]
    assert child.wait() == EXIT_PIPE and err == ""


def test_sigterm_ends_a_run_as_ctrl_c_does(tmp_path: Path) -> None:
    """`timeout`, a batch scheduler or systemd stop a run with SIGTERM: it died at once (exit 143, no line, a
    validate's ranks left stale); now it ends as Ctrl-C does, with its one line, and resumes."""
    import signal
    import sqlite3
    import subprocess

    from processes import STARTUP, env, wait_until

    db = tmp_path / "g.db"
    args = [sys.executable, "-m", "planner.cli", "generate", "mug", "box", "--hand", "panda", "--db", str(db),
            "--workers", "1", "--chunk", "16", "--quiet"]
    run = subprocess.Popen(args, env=env(), stderr=subprocess.PIPE, text=True)

    def units() -> int:
        try:
            with sqlite3.connect(db) as conn:
                return int(conn.execute("SELECT COUNT(*) FROM units").fetchone()[0])
        except sqlite3.Error:
            return 0

    try:
        wait_until(lambda: units() > 0, STARTUP, "a first unit written")
        run.send_signal(signal.SIGTERM)
        _, err = run.communicate(timeout=STARTUP)
    finally:
        run.kill()
    assert run.returncode == 130, err
    assert err.strip().splitlines()[-1] == "grasp: interrupted; finished units are saved, run the same command to " \
                                           "resume", err


def test_a_sigterm_inside_a_destructor_is_sent_again(monkeypatch: pytest.MonkeyPatch) -> None:
    """Python drops an exception raised in a destructor: a SIGTERM that came while numpy's NpzFile.__del__ ran
    let the run go on to its end with exit 0 (a fresh-clone CI run). Inside one it is sent again; elsewhere it
    interrupts at once."""
    import inspect
    import signal

    from planner.cli import app

    timers: list[tuple] = []

    class Timer:
        def __init__(self, delay: float, fn: object, args: tuple) -> None:
            timers.append((delay, fn, args))

        def start(self) -> None:
            pass

    monkeypatch.setattr(app.threading, "Timer", Timer)

    def __del__() -> None:  # what a destructor's frame is named
        app._terminated(signal.SIGTERM, inspect.currentframe())

    __del__()
    assert timers == [(app.TERM_RETRY, app.os.kill, (app.os.getpid(), signal.SIGTERM))]
    with pytest.raises(KeyboardInterrupt):
        app._terminated(signal.SIGTERM, inspect.currentframe())


def test_a_grasp_home_without_the_projects_folders_is_said_in_one_line(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """GRASP_HOME names the folder holding hands/, preshapes/ and objects/; one without them was an internal
    error (FileNotFoundError: .../hands)."""
    from planner import assets
    from planner.errors import ConfigError

    monkeypatch.setenv("GRASP_HOME", str(tmp_path))
    monkeypatch.setattr(assets, "PROJECT_ROOT", tmp_path)
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(tmp_path / "g.db"), "--approaches", "4")
    one_line_error(code, err, ConfigError.exit_code, f"GRASP_HOME={tmp_path}: no hands/, preshapes/, objects/ folder")
    assert not (tmp_path / "g.db").exists()


def test_an_install_without_the_projects_folders_is_said_in_one_line(tmp_path: Path) -> None:
    """`pip install .` (not -e) copies the package alone: run outside the checkout, every command that reads a
    hand was an internal error (FileNotFoundError: ./hands) and `grasp objects` printed an error with exit 0.
    The package copied as pip installs it, run from a folder without the project's."""
    import os
    import shutil
    import subprocess

    from planner.errors import ConfigError

    shutil.copytree(Path(__file__).parents[2] / "planner", tmp_path / "site" / "planner",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = {k: v for k, v in os.environ.items() if k != "GRASP_HOME"} | {"PYTHONPATH": str(tmp_path / "site")}
    for args in (["generate", "box", "--hand", "panda", "--db", "g.db"], ["hands"], ["objects"]):
        done = subprocess.run([sys.executable, "-c", "from planner.cli import run; run()", *args], cwd=tmp_path,
                              env=env, capture_output=True, text=True, timeout=120)
        one_line_error(done.returncode, done.stderr, ConfigError.exit_code, "no hands/, preshapes/, objects/ folder "
                       f"beside the installed package or in the current folder {tmp_path}: install from a checkout "
                       "with `pip install -e .`")
    assert not (tmp_path / "g.db").exists()


#: The console script's start (pyproject's ``planner.cli:run``) with click's argument parsing held: the group's
#: parse says so on stderr and waits for the signal.
HELD_PARSE = """
import signal, sys, time, click
signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a terminal: a background job ignores SIGINT
parse = click.Command.parse_args
def held(self, ctx, args):
    if isinstance(self, click.Group):
        print("parsing", file=sys.stderr, flush=True)
        time.sleep(60)
    return parse(self, ctx, args)
click.Command.parse_args = held
sys.argv = ["grasp", *sys.argv[1:]]
from planner.cli import run
sys.exit(run())
"""


@pytest.mark.parametrize("args", [["hands"], ["--help"]])
def test_ctrl_c_while_click_parses_exits_130_in_one_line(args: list[str]) -> None:
    """Click's standalone mode answered it with a blank line, "Aborted!" and exit 1."""
    import signal
    import subprocess

    from processes import STARTUP, env

    run = subprocess.Popen([sys.executable, "-c", HELD_PARSE, *args], env=env(), stderr=subprocess.PIPE, text=True)
    try:
        assert run.stderr is not None and run.stderr.readline() == "parsing\n"
        run.send_signal(signal.SIGINT)
        _, err = run.communicate(timeout=STARTUP)
    finally:
        run.kill()
    assert (run.returncode, err) == (130, "grasp: interrupted; nothing was changed\n")


def test_a_small_exports_line_says_its_time_without_a_rate(box_db: Path, tmp_path: Path) -> None:
    """5 grasps exported in 3.9 s read "(3.9 s, 1 grasps/s)": the rate of the start-up's seconds, rounded."""
    import re

    code, out, _ = grasp("export", "--db", str(box_db), "--format", "csv", "--out", str(tmp_path / "few"),
                         "--top", "5")
    assert code == 0 and re.search(r"exported 5 grasps as csv to 1 file\(s\) in .* \(\d+\.\d s\)$", out.strip()), out
    assert rate_text(RATE_MIN_COUNT, 0.66, "grasps") == "0.7 s, 152 grasps/s"


@pytest.mark.parametrize("count, seconds, text", [(2.4, 1.0, "2.40"), (28_176, 580.7, "48.5"), (307, 0.66, "465"),
                                                  (12_345, 1.0, "12,345"), (1, 3_000.0, "0.000333"), (0, 1.0, "0"),
                                                  (9.996, 1.0, "10.0"), (999.6, 1.0, "1,000"), (0.9996, 1.0, "1.00")])
def test_a_rate_keeps_three_significant_figures(count: float, seconds: float, text: str) -> None:
    """`:.0f` made the Barrett's 2.4 candidates/s "2" in generate's bar."""
    assert per_second(count, seconds) == text


@pytest.mark.parametrize("part, whole, text", [(997, 1_000, "99.7%"), (1_999, 2_000, "99.95%"), (5, 5, "100%"),
                                               (1, 1_000, "0.1%"), (2, 3, "67%"), (0, 0, "0%"), (0, 7, "0%")])
def test_a_share_is_not_rounded_to_all_or_none(part: int, whole: int, text: str) -> None:
    """validate said "997 held (100%)" (`:.0%`): of a hand whose grasps hold 99.7-99.85%, the one figure read."""
    assert share(part, whole) == text


def _db_of_commands(text: str) -> list[str]:
    """The ``--db`` argument of each `grasp ...` command a message gives, as a shell would split it."""
    import re
    import shlex

    found = []
    for command in re.findall(r"`(grasp [^`]*)`", text):
        words = shlex.split(command)
        found += [words[i + 1] for i, w in enumerate(words) if w == "--db"]
    return found


def test_commands_a_message_gives_run_as_pasted_with_blanks_in_paths(box_db: Path, tmp_path: Path,
                                                                    shipped_models: None) -> None:
    """`grasp validate --db my dbs/g.db --object ...` (a database or an object with a blank in its name): pasted
    into a shell, the command a note or an error gave was another one."""
    import shutil

    db = tmp_path / "my dbs" / "g é.db"
    db.parent.mkdir()
    shutil.copy(box_db, db)
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(db), "--top", "1")
    assert code == 0 and _db_of_commands(out + err) == [str(db)], out + err  # p_hold's note: grasp validate ...
    code, _, err = grasp("report", "--db", str(db), "--out", str(tmp_path / "report"))
    text = (tmp_path / "report" / "report.md").read_text()
    assert code == 0 and _db_of_commands(text) == [str(db)], text  # no trials: grasp validate ...
    gone = tmp_path / "no such" / "g.db"
    code, _, err = grasp("best", "box", "--hand", "panda", "--db", str(gone))
    assert code == 3 and _db_of_commands(err) == [str(gone)], err


@pytest.mark.parametrize("second", ["SIGINT", "SIGTERM"])
def test_a_second_ctrl_c_while_an_interrupted_run_shuts_down_keeps_exit_130(second: str) -> None:
    """`grasp generate ... --workers 2`, Ctrl-C twice: the second, while the interpreter shut down after the one
    line, ended the process by SIGINT (exit -2) or with an "Exception ignored" traceback, not exit 130; a second
    SIGTERM left that traceback too. Now either ends it at once, with 130."""
    import signal


    shutting = HELD_PARSE.replace("from planner.cli import run", "import atexit\natexit.register(lambda: (print("
                                  "'shutting down', file=sys.stderr, flush=True), time.sleep(3)))\n"
                                  "from planner.cli import run")
    assert _signalled_twice(shutting, "shutting down\n", getattr(signal, second)) == (130, "")


def _signalled_twice(script: str, marker: str, second: int) -> tuple[int, str]:
    """`grasp hands` run by ``script``: SIGINT once it parses, ``second`` once it printed ``marker`` after the
    interrupted line; its exit code and the rest of its stderr."""
    import signal
    import subprocess

    from processes import STARTUP, env

    run = subprocess.Popen([sys.executable, "-c", script, "hands"], env=env(), stderr=subprocess.PIPE, text=True)
    try:
        assert run.stderr is not None and run.stderr.readline() == "parsing\n"
        run.send_signal(signal.SIGINT)
        assert run.stderr.readline() == "grasp: interrupted; nothing was changed\n"
        assert run.stderr.readline() == marker
        run.send_signal(second)
        _, err = run.communicate(timeout=STARTUP)
    finally:
        run.kill()
    return run.returncode, err


def test_a_second_ctrl_c_while_python_tears_the_modules_down_keeps_exit_130() -> None:
    """Past the exit hooks Python put back the default action of SIGINT: a second Ctrl-C while it tore the modules
    down (0.05-0.2 s after the first, `grasp generate ... --workers 2`) ended the run by SIGINT, exit -2."""
    import signal


    late = HELD_PARSE.replace("from planner.cli import run", "import os\nclass Late:\n"
                              "    def __del__(self, write=os.write, sleep=time.sleep):\n"
                              "        write(2, b'tearing down\\n')\n        sleep(3)\n"
                              "late = Late()  # a global of __main__: deleted as the modules are torn down\n"
                              "from planner.cli import run")
    assert _signalled_twice(late, "tearing down\n", signal.SIGINT) == (130, "")
