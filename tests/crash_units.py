"""Stand-ins for the unit functions of generate, validate and import that
kill their worker the way a simulator segfault does, for some units; the
tests put them in place of the real function with monkeypatch, and the pool
sends them to its workers by name (so they live in an importable module)."""

from __future__ import annotations

import ctypes
from pathlib import Path

from planner.datasets.importer import Rescored, RescoreUnit, rescore_poses
from planner.plan.unit import Report, UnitResult, UnitSpec, run_unit
from planner.validation.run import Task, TaskResult, run_task


def segfault() -> None:
    ctypes.string_at(0)  # read address 0: SIGSEGV


def generate_segfaults_on_sphere(unit: UnitSpec) -> UnitResult:
    if unit.object_name == "sphere":
        segfault()
    return run_unit(unit)


def validate_segfaults_on_box(task: Task) -> TaskResult:
    if task.object == "box":
        segfault()
    return run_task(task)


def rescore_segfaults_on_first_file(unit: RescoreUnit) -> Rescored:
    if unit.file == 0 and unit.first == 0:
        segfault()
    return rescore_poses(unit)


def generate_crashes_once_after_its_candidates(unit: UnitSpec, report: Report) -> UnitResult:
    """Run the unit with its progress reports, then kill the worker the first
    time (a marker file next to the unit's mesh file, one per chunk, says it
    did): the retry reports the same candidates again."""
    result = run_unit(unit, report)
    mesh = Path(unit.object_name)
    marker = mesh.with_name(f"{mesh.stem}.{unit.chunk}.crashed")
    if not marker.exists():
        marker.touch()
        segfault()
    return result
