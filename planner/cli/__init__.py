"""The ``grasp`` command: parse, call :mod:`planner.api`, print.

Errors become one line on stderr and an exit code (2 bad input, 3 database,
4 simulator, 1 anything else); ``grasp --debug ...`` shows the traceback.
Commands, one module per group of them: ``generate``; ``best``, ``show``
(query); ``view`` (the browser viewer); ``validate``, ``report``; ``calibrate``; ``export``, ``import``
(data); ``hands``, ``objects``, ``db check`` (info).
"""

from planner.cli.app import main
from planner.cli.calibrate import calibrate
from planner.cli.data import export, import_files
from planner.cli.generate import generate
from planner.cli.info import db, hands, objects
from planner.cli.query import best, show
from planner.cli.validate import report, validate
from planner.cli.view import view

for _command in (generate, best, show, view, validate, report, calibrate, export, import_files, hands, objects, db):
    main.add_command(_command)

__all__ = ["main"]
