"""Progress by candidates: what a running unit reports, how the pool carries
it, and the figures ``generate`` gives its progress callback."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest
import trimesh

from planner import api
from planner.geometry.solid import load_object
from planner.plan.sweep import SweepSettings, candidate_count
from planner.plan.unit import BUDGET, UnitSpec, run_unit
from planner.run import pool
from planner.run.progress import Tally, Throttled
from planner.specs.hands import load_hand
from planner.specs.preshapes import sweep_preshapes
from tests import crash_units

SMALL = SweepSettings(approaches=8, rolls=2, preshapes=("wide",), chunk=4, reach_placements=1).resolved("antipodal")


def planned(settings: SweepSettings, hand: str, chunk: int = 0) -> int | None:
    shapes = sweep_preshapes(load_hand(hand), list(settings.preshapes) if settings.preshapes else None,
                             settings.table_plane is not None)  # the unit's own: no table preshapes off a table
    return candidate_count(settings, shapes, chunk)


def check_reports(calls: list[tuple[int, int]], total: int) -> None:
    """Counts from 0, never down, all of one total, ending at it."""
    assert calls[0] == (0, total) and calls[-1] == (total, total), calls
    done = [d for d, _ in calls]
    assert done == sorted(done) and {t for _, t in calls} == {total}


# -- the pieces -----------------------------------------------------------------
def test_throttled_passes_the_first_and_the_last_call() -> None:
    seen: list[tuple[int, int]] = []
    report = Throttled(lambda d, t: seen.append((d, t)), interval=float("inf"))
    for i in range(10):
        report(i, 10)
    report(10, 10)
    assert seen == [(0, 10), (10, 10)]
    every: list[tuple[int, int]] = []
    report = Throttled(lambda d, t: every.append((d, t)), interval=0.0)
    for i in range(4):
        report(i, 3)
    assert every == [(0, 3), (1, 3), (2, 3), (3, 3)]


def test_tally_counts_a_retried_unit_once_and_a_finished_one_whole() -> None:
    tally = Tally([10, 10, None])
    assert tally.total == 30 and tally.done == 0  # the unknown unit counts as the mean of the known
    tally.report(0, 7, 10)
    tally.report(0, 2, 10)  # the retry after a crash counts again from zero
    assert tally.done == 7
    tally.report(0, 9, 10)
    assert tally.done == 9
    tally.report(2, 0, 40)  # its own count replaces the estimate
    assert tally.total == 60
    tally.finish(1)  # over (done, failed or out of retries): its whole total
    tally.finish(0)
    tally.report(2, 40, 40)
    tally.finish(2)
    assert tally.done == tally.total == 60
    assert Tally([None]).total is None and Tally([]).total == 0
    failed = Tally([None, None])
    failed.finish(0)  # failed before it said anything
    assert failed.done == 0 and failed.total == 0


@pytest.mark.parametrize("sampler,table", [("antipodal", False), ("surface", False), ("surface", True)])
def test_candidate_count_is_the_units_own(sampler: str, table: bool) -> None:
    """On a table the first unit also tries the rays from above."""
    hand = "panda" if sampler == "antipodal" else "barrett"
    settings = SweepSettings(approaches=6, rolls=2, chunk=4, fan_count=1 if sampler == "surface" else 0,
                             reach_placements=0, settle=False).resolved(sampler)
    if table:
        settings = settings.on(api.table_supports(load_object("box"), 1)[0])
        assert settings.above_rays(0) > 0 and settings.above_rays(1) == 0
    for chunk in range(settings.chunks()):
        calls: list[tuple[int, int]] = []
        result = run_unit(UnitSpec("box", hand, settings, 0, chunk=chunk), lambda d, t, c=calls: c.append((d, t)))
        assert result.error is None
        assert calls[-1][1] == planned(settings, hand, chunk) == result.candidates + result.rejected[BUDGET]


# -- a unit, in process and through the pool -----------------------------------
def test_a_unit_reports_increasing_counts_ending_at_its_total() -> None:
    calls: list[tuple[int, int]] = []
    result = run_unit(UnitSpec("box", "panda", SMALL, 0), lambda d, t: calls.append((d, t)))
    total = planned(SMALL, "panda")
    assert total and result.candidates + result.rejected[BUDGET] == total
    check_reports(calls, total)
    assert len(calls) == total + 1  # unthrottled: every candidate


def test_a_budget_stop_reports_the_whole_total() -> None:
    settings = SweepSettings(approaches=8, rolls=2, preshapes=("wide",), chunk=0, reach_placements=0,
                             fc_budget=1).resolved("antipodal")
    calls: list[tuple[int, int]] = []
    result = run_unit(UnitSpec("box", "panda", settings, 0), lambda d, t: calls.append((d, t)))
    assert result.rejected[BUDGET] > 0, "the budget should stop this unit early"
    check_reports(calls, result.candidates + result.rejected[BUDGET])


@pytest.mark.parametrize("workers", [1, 2])
def test_the_pool_carries_each_units_reports(workers: int) -> None:
    units = [UnitSpec("box", "panda", SMALL, 0, chunk=c) for c in range(SMALL.chunks())]
    calls: dict[int, list[tuple[int, int]]] = {}
    plain = {(r.spec.chunk, len(r.grasps)) for _, r, _ in pool.run(run_unit, units, workers)}
    out = list(pool.run(run_unit, units, workers, progress=lambda i, d, t: calls.setdefault(i, []).append((d, t))))
    assert {(r.spec.chunk, len(r.grasps)) for _, r, _ in out} == plain  # progress changes no result
    assert sorted(calls) == list(range(len(units)))
    for i, unit in enumerate(units):
        check_reports(calls[i], planned(SMALL, "panda", unit.chunk))  # type: ignore[arg-type]


# -- generate's callback --------------------------------------------------------
def check_progress(seen: list[api.GenerateProgress], units: int) -> None:
    done = [p.candidates_done for p in seen]
    assert done == sorted(done), "the candidate count went down"
    assert all(p.candidates_total is not None and p.candidates_done <= p.candidates_total for p in seen)
    last = seen[-1]
    assert last.units_done == last.units_total == units
    assert last.candidates_done == last.candidates_total == sum(
        p.result.candidates + p.result.rejected[BUDGET] for p in seen if p.result is not None)
    assert [p.units_done for p in seen if p.result is not None] == list(range(1, units + 1))


def test_generate_counts_candidates_of_running_units(tmp_path: Path) -> None:
    seen: list[api.GenerateProgress] = []
    api.generate(["box"], "panda", db_path=tmp_path / "p.db", settings=SMALL, workers=1, progress=seen.append)
    check_progress(seen, SMALL.chunks())
    assert seen[0].candidates_done == 0 and seen[0].candidates_total == seen[-1].candidates_total  # planned exactly
    # counts between units: the bar moves while a unit runs
    assert any(p.result is None and 0 < p.candidates_done < seen[-1].candidates_total for p in seen)


def test_a_retried_crash_is_not_counted_twice(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                              caplog: pytest.LogCaptureFixture) -> None:
    mesh = tmp_path / "cube.obj"
    trimesh.creation.box((0.05, 0.05, 0.05)).export(mesh)
    seen: list[api.GenerateProgress] = []
    monkeypatch.setattr(api, "run_unit", crash_units.generate_crashes_once_after_its_candidates)
    with caplog.at_level(logging.WARNING, logger=pool.__name__):
        summary = api.generate([str(mesh)], "panda", db_path=tmp_path / "p.db", settings=SMALL, workers=2,
                               progress=seen.append)
    assert not summary.failed
    assert len([r for r in caplog.records if "retrying it" in r.getMessage()]) == SMALL.chunks()
    check_progress(seen, SMALL.chunks())
