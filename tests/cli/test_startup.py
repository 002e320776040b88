"""Fast start (issue 25 item 8) as a property, not a timing: starting the
command, and ``grasp best`` on a database, import no heavy library. The
times are bench/startup.py's."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

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
