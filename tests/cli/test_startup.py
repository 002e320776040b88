"""Fast start (issue 25 item 8) as a property, not a timing: starting the
command, and ``grasp best`` on a database, import no heavy library. The
times are bench/startup.py's."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

#: Libraries that cost a start-up of 0.1-2 s each and that only some commands need.
HEAVY = ("trimesh", "pybullet", "h5py", "pyarrow", "matplotlib", "scipy", "yourdfpy", "rich", "coacd",
         "planner.datasets.exporter", "planner.datasets.importer", "planner.plan.unit", "planner.sim")

PROBE = """
import json, sys
sys.argv = ["grasp", *json.loads(sys.argv[1])]
try:
    from planner.cli import main
    main()
except SystemExit:
    pass
finally:
    print(json.dumps(sorted(m for m in json.loads('{heavy}') if m in sys.modules)),
          file=sys.stderr)
"""


def heavy_imports(*args: str) -> list[str]:
    """The HEAVY modules loaded by ``grasp ARGS`` in a fresh interpreter."""
    code = PROBE.replace("{heavy}", json.dumps(HEAVY))
    done = subprocess.run([sys.executable, "-c", code, json.dumps(list(args))], capture_output=True, text=True,
                          timeout=120)
    return json.loads(done.stderr.strip().splitlines()[-1])


def test_importing_the_command_imports_no_heavy_library() -> None:
    done = subprocess.run([sys.executable, "-c", "import json, sys, planner.cli; "
                           f"print(json.dumps([m for m in {list(HEAVY)!r} if m in sys.modules]))"],
                          capture_output=True, text=True, timeout=120, check=True)
    assert json.loads(done.stdout) == []


def test_help_and_best_import_no_heavy_library(box_db: Path) -> None:
    assert heavy_imports("--help") == []
    assert heavy_imports("generate", "--help") == []
    assert heavy_imports("best", "box", "--hand", "panda", "--db", str(box_db)) == []
    assert heavy_imports("best", "box", "--hand", "panda", "--db", str(box_db), "--json") == []


def test_lazy_names_of_the_api_load_on_first_use() -> None:
    done = subprocess.run([sys.executable, "-c", "import sys; from planner import api; "
                           "before = 'planner.datasets.exporter' in sys.modules; "
                           "print(before, 'acronym' in api.EXPORT_FORMATS, callable(api.export))"],
                          capture_output=True, text=True, timeout=120, check=True)
    assert done.stdout.split() == ["False", "True", "True"]


#: Ctrl-C while the command's modules load (click is the first of them): a finder that raises it on that import.
INTERRUPTED_IMPORT = """
import runpy, sys
class Interrupt:
    def find_spec(self, name, path=None, target=None):
        if name == "click":
            raise KeyboardInterrupt
sys.meta_path.insert(0, Interrupt())
sys.argv = ["grasp", "hands"]
"""


@pytest.mark.parametrize("start", ["console script", "python -m planner.cli"])
def test_ctrl_c_while_the_command_loads_exits_130_in_one_line(start: str) -> None:
    """The console script imported every command module before any handler: a Ctrl-C in those ~0.25 s printed
    a traceback (and exited -2, 1)."""
    if start == "console script":  # as pip's script does it: from MODULE import FUNCTION; sys.exit(FUNCTION())
        entry = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())["project"]["scripts"]
        module, function = entry["grasp"].split(":")
        code = f"from {module} import {function}\nsys.exit({function}())"
    else:
        code = "runpy.run_module('planner.cli', run_name='__main__', alter_sys=True)"
    done = subprocess.run([sys.executable, "-c", INTERRUPTED_IMPORT + code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 130 and done.stderr == "grasp: interrupted; nothing was changed\n", done.stderr


#: SIGTERM (``timeout``, a scheduler) while click reads the arguments: sent as the group starts parsing them.
TERMINATED_PARSING = """
import os, signal, sys
import click
parse = click.Group.parse_args
def terminated(self, ctx, args):
    os.kill(os.getpid(), signal.SIGTERM)
    return parse(self, ctx, args)
click.Group.parse_args = terminated
sys.argv = ["grasp", "hands"]
from planner.cli import run
run()
"""


def test_sigterm_while_click_reads_the_arguments_exits_130_in_one_line() -> None:
    """SIGTERM's handler was set by the group's callback, after the arguments were read: a SIGTERM before it
    killed the process without a word (exit -15), where a Ctrl-C there printed one line and exited 130."""
    done = subprocess.run([sys.executable, "-c", TERMINATED_PARSING], capture_output=True, text=True, timeout=120)
    assert done.returncode == 130 and done.stderr == "grasp: interrupted; nothing was changed\n", done


def test_a_sigterm_in_a_destructor_while_the_command_starts_is_sent_again(monkeypatch: pytest.MonkeyPatch) -> None:
    """The handler set before the commands load raised KeyboardInterrupt inside a destructor too, where Python
    drops it ("Exception ignored in ... __del__"): that SIGTERM was lost and the command ran to its end."""
    import inspect
    import os
    import signal
    import threading

    import planner.cli as cli

    timers: list[tuple] = []

    class Timer:
        def __init__(self, delay: float, fn: object, args: tuple) -> None:
            timers.append((fn, args))

        def start(self) -> None:
            pass

    def command() -> None:
        handler = signal.getsignal(signal.SIGTERM)

        def __del__() -> None:  # what a destructor's frame is named
            handler(signal.SIGTERM, inspect.currentframe())  # type: ignore[operator]

        __del__()
        sys.exit(0)

    monkeypatch.setattr(threading, "Timer", Timer)
    monkeypatch.setattr(cli, "_main", lambda: command)
    before = signal.getsignal(signal.SIGTERM)
    try:
        with pytest.raises(SystemExit) as ended:
            cli.run()
    finally:
        signal.signal(signal.SIGTERM, before)
    assert ended.value.code == 0 and timers == [(os.kill, (os.getpid(), signal.SIGTERM))]
