"""The README's Python API block runs as written, in a fresh folder, and prints what it says."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

README = Path(__file__).parents[1] / "README.md"


def api_block() -> str:
    text = README.read_text(encoding="utf-8")
    section = text[text.index("## The Python API"):]
    return section[section.index("```python\n") + len("```python\n"):].split("```", 1)[0]


def test_the_readme_api_script_runs(tmp_path: Path) -> None:
    script = tmp_path / "job.py"
    script.write_text(api_block())
    run = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    lines = run.stdout.splitlines()
    assert lines[0].endswith("force closure") and int(lines[0].split()[0]) > 0
    assert "of 3 held" in run.stdout and "grasps in ['out/box__panda.h5']" in run.stdout
    assert (tmp_path / "grasps.db").is_file() and (tmp_path / "out" / "box__panda.h5").is_file()
