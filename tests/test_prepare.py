"""The one-time preparations' lines: said once however many workers made them."""

from __future__ import annotations

import logging

import pytest

from planner import prepare


def test_two_workers_ending_one_preparation_are_said_once(caplog: pytest.LogCaptureFixture) -> None:
    """Two workers building one collision proxy both printed "done in X s", with their two times."""
    before: set[str] = set()
    what = "collision proxy (mesh decimation) of scan"
    with caplog.at_level(logging.INFO, logger=prepare.LOGGER):
        prepare.said([f"{what}: started (once: cached afterwards)", f"{what}: done in 12.3 s"], before)
        prepare.said([f"{what}: started (once: cached afterwards)", f"{what}: done in 12.9 s"], before)
        prepare.said([f"{what} 2: done in 1.0 s", "scan: mesh repaired"], before)
    assert [r.getMessage() for r in caplog.records] == [
        f"{what}: started (once: cached afterwards)", f"{what}: done in 12.3 s", f"{what} 2: done in 1.0 s",
        "scan: mesh repaired"]
