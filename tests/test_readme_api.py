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


def test_the_cli_reference_names_every_option_of_every_command() -> None:
    """The README's CLI reference table has a row for every subcommand, and its rows name every option that
    subcommand's --help lists (the table is written by hand: `--up` was missing from `generate`'s row)."""
    import click

    from planner.cli import main

    rows = [line for line in README.read_text(encoding="utf-8").splitlines() if line.startswith("| `grasp ")]
    missing = []

    def walk(command: click.Command, path: list[str]) -> None:
        if isinstance(command, click.Group):
            for name, sub in command.commands.items():
                walk(sub, [*path, name])
            return
        mine = " ".join(row for row in rows if row.split("`")[1].split()[:len(path) + 1] == ["grasp", *path])
        if not mine:
            missing.append(f"grasp {' '.join(path)}: no row")
        options = [o for p in command.params if isinstance(p, click.Option) for o in p.opts if o.startswith("--")]
        missing.extend(f"grasp {' '.join(path)} {o}" for o in options if o != "--help" and o not in mine)

    walk(main, [])
    assert not missing, missing
