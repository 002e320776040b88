"""Stand-ins for the unit functions of generate, validate and import that
kill their worker the way a simulator segfault does, for some units; the
tests put them in place of the real function with monkeypatch, and the pool
sends them to its workers by name (so they live in an importable module)."""

from __future__ import annotations

import ctypes

from planner.datasets.importer import Rescored, RescoreUnit, rescore_poses
from planner.plan.unit import UnitResult, UnitSpec, run_unit
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
