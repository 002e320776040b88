"""The ``grasp`` command group: one-line errors with exit codes, and the
option helpers the commands share."""

from __future__ import annotations

import logging
import math
import os
import signal
import sqlite3
import sys
import threading
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import click

from planner import api
from planner.cli import EXIT_INTERRUPTED, TERM_RETRY  # noqa: F401 - TERM_RETRY re-exported
from planner.cli import terminated as _terminated
from planner.errors import DatabaseError, InputError, PlannerError

#: Exit codes besides the errors' own (``PlannerError.exit_code``: 2 bad
#: input, 3 database, 4 simulator).
EXIT_OTHER = 1  # anything else: an internal error, or nothing found
EXIT_PIPE = 141  # the reader of the output went away (`grasp best | head`): 128 + SIGPIPE, as shell tools exit


def echo_json(value: Any) -> None:
    """Print ``value`` as strict JSON (indented): a float that is not finite (a NaN of a measure not taken)
    becomes null, which every JSON reader accepts (Python's ``NaN`` token is not JSON)."""
    import json

    def strict(v: Any) -> Any:
        if isinstance(v, float):
            return v if math.isfinite(v) else None
        if isinstance(v, dict):
            return {k: strict(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [strict(x) for x in v]
        return v

    click.echo(json.dumps(strict(value), indent=2, allow_nan=False))


#: What an interrupted subcommand leaves, said in the one line (others write nothing).
INTERRUPTED = {
    "generate": "finished units are saved, run the same command to resume",
    "import": "the files imported so far are saved, run the same command to resume",
    "validate": "the verdicts stored so far are kept and ranked, run the same command to go on",
    "export": "no file under its final name is partial, unfinished ones were removed; run the export again",
    "calibrate": "nothing was stored",
}


def _interrupted(subcommand: str | None) -> None:
    click.echo(f"grasp: interrupted; {INTERRUPTED.get(subcommand or '', 'nothing was changed')}", err=True)


class Group(click.Group):
    """Maps every error to a one-line message and an exit code."""

    def main(self, args: Sequence[str] | None = None, prog_name: str | None = None,  # type: ignore[override]
             complete_var: str | None = None, standalone_mode: bool = True, **extra: Any) -> Any:
        """Click's standalone mode answers a Ctrl-C outside :meth:`invoke` (while it parses the group's options,
        prints --help, or closes the context) with "Aborted!" and exit 1: here it is run without it, and every
        interruption ends as one during a command does (one line, exit 130)."""
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, False, **extra)
        try:
            code = super().main(args, prog_name, complete_var, False, **extra)  # an Exit's code, or None
        except (KeyboardInterrupt, click.exceptions.Abort):  # Abort: click's non-standalone KeyboardInterrupt
            _interrupted(None)
            code = EXIT_INTERRUPTED
        except click.ClickException as exc:  # the group's own bad option: as standalone mode shows it
            exc.show()
            code = exc.exit_code
        except BrokenPipeError:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            code = EXIT_PIPE
        sys.exit(code or 0)

    def make_context(self, info_name: str | None, args: list[str], parent: click.Context | None = None,
                     **extra: Any) -> click.Context:
        try:
            return super().make_context(info_name, args, parent, **extra)
        except KeyboardInterrupt:  # not past click's handler, which writes a blank line first
            raise click.exceptions.Abort from None

    def invoke(self, ctx: click.Context) -> None:
        debug = "--debug" in sys.argv[1:] or (ctx.params or {}).get("debug", False)
        try:
            super().invoke(ctx)  # its value (None) would read as an exit code in main
        except click.UsageError as exc:  # a subcommand's bad option value: one line too, with where to look
            where = exc.ctx.command_path if exc.ctx is not None else ctx.command_path
            click.echo(f"grasp: error: {exc.format_message()} (see `{where} --help`)", err=True)
            ctx.exit(exc.exit_code)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException):
            raise
        except PlannerError as exc:
            _traceback(debug)
            click.echo(f"grasp: error: {exc}", err=True)
            ctx.exit(exc.exit_code)
        except sqlite3.Error as exc:
            _traceback(debug)
            click.echo(f"grasp: error: database: {exc}", err=True)
            ctx.exit(DatabaseError.exit_code)
        except BrokenPipeError:  # nothing to say: whoever would read it has gone; stdout must not flush again
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            ctx.exit(EXIT_PIPE)
        except KeyboardInterrupt:  # Ctrl-C, or SIGTERM (``main``)
            _interrupted(ctx.invoked_subcommand)
            ctx.exit(EXIT_INTERRUPTED)
        except Exception as exc:
            _traceback(debug)
            click.echo(f"grasp: internal error: {type(exc).__name__}: {exc} (rerun with --debug for details)",
                       err=True)
            ctx.exit(EXIT_OTHER)
        return None


def _traceback(debug: bool) -> None:
    """``--debug``: the traceback on stderr before the one line; the exit code stays the error's."""
    if debug:
        traceback.print_exc()


@click.group(cls=Group)
@click.option("--debug", is_flag=True, help="Show tracebacks and debug logging.")
@click.version_option(package_name="grasp-planner")
def main(debug: bool) -> None:
    """Knowledge-based grasp planner: build, query and export grasp databases."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _terminated)
    logging.basicConfig(level=logging.DEBUG if debug else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")


class _Stderr(logging.Handler):
    """A record as a bare line on the stderr of the moment."""

    def emit(self, record: logging.LogRecord) -> None:
        click.echo(self.format(record), err=True)


def show_preparation(enabled: bool = True) -> None:
    """Show the library's one-time preparation lines (:mod:`planner.prepare`:
    a convex decomposition starting and ending) on stderr, or hide them."""
    from planner import prepare

    logger = logging.getLogger(prepare.LOGGER)
    logger.propagate = False  # not twice under --debug
    if not any(isinstance(h, _Stderr) for h in logger.handlers):
        logger.addHandler(_Stderr())
    logger.setLevel(logging.INFO if enabled else logging.WARNING)


#: ``--db`` of every command that reads or writes a database.
db_option = click.option("--db", "db_path", type=click.Path(path_type=Path), default=api.DEFAULT_DB,
                         show_default=True)


class LazyHelp(click.Option):
    """An option whose help text is written when shown: the names a heavy
    module declares (the export formats) cost nothing until ``--help``."""

    def __init__(self, *args: Any, help_text: Callable[[], str], **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._help_text = help_text

    def get_help_record(self, ctx: click.Context) -> tuple[str, str] | None:
        self.help = self._help_text()
        return super().get_help_record(ctx)
def diverse_options(command):  # type: ignore[no-untyped-def]
    """``--diverse`` with its two distances, for every command that lists top grasps."""
    command = click.option("--min-rotation", type=float, default=30.0, show_default=True,
                           help="With --diverse: ... or orientations this many degrees apart.")(command)
    command = click.option("--min-translation", type=float, default=0.02, show_default=True,
                           help="With --diverse: tool centre points this many metres apart ...")(command)
    return click.option("--diverse", is_flag=True, help="Only grasps at least --min-translation metres or "
                        "--min-rotation degrees from every better one listed.")(command)


def unused(names: Sequence[str], why: str) -> None:
    """Refuse the options ``names`` (parameter names) where given on the command line: this call would not read
    them (``why``: "used with --on-table only", say). An option left at its default says nothing and passes."""
    ctx = click.get_current_context()
    given = [p for p in ctx.command.params if p.name in names and
             ctx.get_parameter_source(p.name) is click.core.ParameterSource.COMMANDLINE]
    if given:
        flags = " and ".join(p.secondary_opts[0] if p.secondary_opts and ctx.params.get(p.name) is False
                             else p.opts[0] for p in given)  # --no-plan as given, not --plan
        raise click.UsageError(f"{flags} {'do' if len(given) > 1 else 'does'} nothing here: {why}")


def spacing(diverse: bool, min_translation: float, min_rotation: float):  # type: ignore[no-untyped-def]
    """The :class:`~planner.db.diverse.Spacing` the options ask for, or None."""
    if not diverse:
        unused(["min_translation", "min_rotation"], "used with --diverse only")
        return None
    from planner.db.diverse import Spacing

    if not (min_translation >= 0 and min_rotation >= 0):
        raise click.BadParameter("--min-translation and --min-rotation must be >= 0")
    return Spacing(min_translation, math.radians(min_rotation))


def floats(text: str | None, option: str | None = None) -> tuple[float, ...] | None:
    """A comma-separated list of numbers (None stays None); ``option`` names the option in the error."""
    if text is None:
        return None
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise click.BadParameter(f"'{text}' is not a comma-separated list of numbers", param_hint=option) from None


#: Fewer items than this in a run: its rate is said not (the start-up's seconds, not the work's: 5 grasps exported
#: in 3.9 s read "1 grasps/s").
RATE_MIN_COUNT = 100


def per_second(count: float, seconds: float) -> str:
    """``count / seconds`` to three significant figures, never in exponent form (``462``, ``12.8``, ``0.641``;
    ``:.0f`` made 2.4 candidates/s "2"); rounded before its decimals are counted (9.996 read "10.00")."""
    rate = count / max(seconds, 1e-9)
    rate = float(f"{rate:.3g}") if rate < 1_000 else rate  # a large one keeps its whole units (12,345)
    return f"{rate:,.{max(0, 2 - math.floor(math.log10(rate)))}f}" if rate > 0 else "0"


def rate_text(count: int, seconds: float, unit: str) -> str:
    """The time a run took [s], with its rate where ``count`` is :data:`RATE_MIN_COUNT` or more."""
    return f"{seconds:.1f} s" + (f", {per_second(count, seconds)} {unit}/s" if count >= RATE_MIN_COUNT else "")


def share(part: int, whole: int) -> str:
    """``part`` of ``whole`` as a percentage with the fewest decimals that do not round a part to 0% or 100%
    (997 held of 1,000 read "100%")."""
    x = part / max(whole, 1)
    for digits in range(12):
        text = f"{x:.{digits}%}"
        shown = float(text[:-1])
        if (shown >= 100) == (part >= whole > 0) and (shown == 0) == (part == 0):
            break
    return text


def report_failures(failed: dict[str, str]) -> None:
    """One ``grasp: error:`` line per failed object or task; exit 2 (bad input) if any."""
    for name, error in failed.items():
        click.echo(f"grasp: error: {name}: {error}", err=True)
    if failed:
        sys.exit(InputError.exit_code)


def missing_folder(path: Path) -> Path | None:
    """The outermost folder above the file ``path`` that does not exist yet, which writing it makes (as ``export``
    makes its ``--out``): said after the write, so a mistyped folder is seen; None where its folder exists."""
    missing = None
    for folder in Path(path).absolute().parents:
        if folder.exists():
            return missing
        missing = folder
    return missing


def made(folder: Path | None) -> str:
    """The words :func:`missing_folder`'s folder, made by a write, is said with ("" where none was made)."""
    return "" if folder is None or not folder.is_dir() else f" (made the folder {folder})"
