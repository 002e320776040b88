"""``python -m planner.cli``: the ``grasp`` command."""

from planner.cli import run

run()
