"""The sweep: a unit's seed and candidate numbering depend only on the unit."""

from __future__ import annotations

import json
import re
import sqlite3
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from planner import api
from planner.errors import InputError
from planner.plan.sampling import Approaches
from planner.plan.sweep import ALGORITHM_VERSION, MAX_RAYS, MAX_REACH_PLACEMENTS, SweepSettings, candidates, unit_rng
from planner.specs.hands import load_hand
from planner.specs.preshapes import load_preshapes
from planner.validation.shake import ShakeSettings

RAYS = 7


@pytest.fixture(scope="module")
def shapes():  # type: ignore[no-untyped-def]
    return load_preshapes(load_hand("panda"))


def rays(n: int = RAYS) -> Approaches:
    points = np.arange(3.0 * n).reshape(n, 3)
    normals = np.tile([0.0, 0.0, 1.0], (n, 1))
    return Approaches(points, normals, -normals)


def test_unit_rng_depends_on_seed_object_hand_and_stream_only() -> None:
    draw = lambda *key: unit_rng(*key).random(4)  # noqa: E731
    assert np.array_equal(draw(3, "box", "panda"), draw(3, "box", "panda"))
    base = draw(3, "box", "panda")
    for other in ((4, "box", "panda"), (3, "mug", "panda"), (3, "box", "barrett"), (3, "box", "panda", 1)):
        assert not np.array_equal(draw(*other), base), other
    assert np.array_equal(draw(3, "box", "panda", 2, 17), draw(3, "box", "panda", 2, 17))


def test_candidates_are_numbered_in_a_fixed_order_over_the_object(shapes) -> None:  # type: ignore[no-untyped-def]
    settings = SweepSettings(rolls=3, standoffs=(0.0, 0.01), sampler="surface")
    every = candidates(rays(), shapes, settings)
    assert len(every) == RAYS * len(shapes) * 3 * 2
    assert [c.index for c in every] == list(range(len(every)))
    # ray-major, then preshape, roll, standoff
    first = every[:2 * 3 * len(shapes)]
    assert {c.ray for c in first} == {0}
    assert [(c.preshape.name, c.roll, c.standoff) for c in every[:2]] == [(shapes[0].name, 0.0, 0.0),
                                                                          (shapes[0].name, 0.0, 0.01)]


def test_chunks_partition_the_candidates_with_the_whole_object_numbers(shapes) -> None:  # type: ignore[no-untyped-def]
    settings = SweepSettings(approaches=RAYS, rolls=2, chunk=3, sampler="surface")
    every = candidates(rays(), shapes, settings)
    assert settings.chunks() == 3
    parts = [candidates(rays(), shapes, settings, rays=settings.ray_range(k, RAYS)) for k in range(settings.chunks())]
    joined = [c for part in parts for c in part]
    assert [(c.index, c.ray, c.preshape.name, c.roll, c.standoff) for c in joined] == \
        [(c.index, c.ray, c.preshape.name, c.roll, c.standoff) for c in every]
    assert [c.ray for c in parts[2]] and min(c.ray for c in parts[2]) == 6


def test_preshape_standoffs_unless_the_settings_override_them(shapes) -> None:  # type: ignore[no-untyped-def]
    own = candidates(rays(1), shapes[:1], SweepSettings(rolls=1))
    assert [c.standoff for c in own] == list(shapes[0].standoffs)
    assert [c.standoff for c in candidates(rays(1), shapes[:1], SweepSettings(rolls=1, standoffs=(0.03,)))] == [0.03]


def test_rolls_cover_one_period_of_the_hand_symmetry() -> None:
    settings = SweepSettings(rolls=4, sampler="surface")
    assert np.allclose(settings.roll_angles(1), np.arange(4) * np.pi / 2)
    assert np.allclose(settings.roll_angles(2), np.arange(4) * np.pi / 4)


def test_a_preshapes_roll_symmetry_spreads_its_rolls_over_its_period(shapes) -> None:  # type: ignore[no-untyped-def]
    """A pinch along one axis repeats after a half turn: its rolls spread over
    [0, pi), the other preshapes' over the hand's period; as many candidates."""
    pinch = replace(shapes[0], name="axis", roll_symmetry=2)
    settings = SweepSettings(rolls=2, sampler="surface")
    every = candidates(rays(2), (shapes[1], pinch), settings, symmetry=1)
    assert len(every) == len(candidates(rays(2), shapes[:2], settings, symmetry=1))
    assert [c.index for c in every] == list(range(len(every)))
    rolls = {name: sorted({c.roll for c in every if c.preshape.name == name}) for name in (shapes[1].name, "axis")}
    assert np.allclose(rolls[shapes[1].name], [0.0, np.pi]) and np.allclose(rolls["axis"], [0.0, np.pi / 2])
    halved = candidates(rays(1), (pinch,), settings, symmetry=2)  # and the hand's own symmetry on top
    assert np.allclose(sorted({c.roll for c in halved}), [0.0, np.pi / 4])


def test_settings_digest_names_the_algorithm_and_every_setting() -> None:
    data = json.loads(SweepSettings().to_json())
    assert data["algorithm"] == ALGORITHM_VERSION
    assert SweepSettings().digest == SweepSettings().digest
    assert SweepSettings(rolls=5).digest != SweepSettings().digest
    assert SweepSettings(reach_placements=0).digest != SweepSettings().digest
    assert SweepSettings(fc_budget=0).digest != SweepSettings().digest


def test_the_settles_trial_is_in_the_digest_of_a_sweep_that_settles_only() -> None:
    """The trial decides the stored settled epsilons: other trial settings,
    another digest; a sweep that does not settle does not name a trial."""
    settles = SweepSettings().resolved("surface", hand_settle=True)
    other = SweepSettings(trial=ShakeSettings(gear_erp=0.5)).resolved("surface", hand_settle=True)
    assert settles.trial == ShakeSettings(batch=1) and other.trial == ShakeSettings(gear_erp=0.5, batch=1)
    assert other.digest != settles.digest
    assert json.loads(settles.to_json())["trial"]["gear_erp"] == ShakeSettings().gear_erp
    assert settles.resolved("surface", hand_settle=True).digest == settles.digest  # resolving twice changes nothing
    still = SweepSettings(trial=ShakeSettings(gear_erp=0.5)).resolved("antipodal")
    assert still.trial is None and "trial" not in json.loads(still.to_json())
    assert still.digest == SweepSettings().resolved("antipodal").digest


def test_a_run_with_another_settle_trial_is_not_taken_as_done_nor_stored_beside(tmp_path: Path) -> None:
    """Finished units of other trial settings are not taken as done; they
    were stored as units of their own, the same candidates' grasps twice:
    refused, or replaced with ``replace``; the same settings again skip."""
    db = tmp_path / "g.db"
    small = SweepSettings(approaches=2, rolls=1, preshapes=("pinch",), reach_placements=0)
    other = replace(small, trial=ShakeSettings(gear_erp=0.5))
    first = api.generate(["box"], "barrett", db_path=db, settings=small)
    with pytest.raises(InputError, match=r"other settings \(trial .*gear_erp.*--replace"):
        api.generate(["box"], "barrett", db_path=db, settings=other)
    replaced = api.generate(["box"], "barrett", db_path=db, settings=other, replace=True)
    again = api.generate(["box"], "barrett", db_path=db, settings=other)
    assert first.units == replaced.units == 1 and replaced.replaced == first.grasps
    assert again.units == 0 and again.skipped == 1
    with sqlite3.connect(db) as conn:
        trials = [json.loads(s)["trial"]["gear_erp"] for (s,) in conn.execute("SELECT settings FROM units")]
    assert trials == [0.5]


def test_the_force_closure_budget_is_shared_evenly_by_an_objects_units() -> None:
    antipodal = SweepSettings().resolved("antipodal")  # 2048 points in units of 256: 8 units
    assert antipodal.chunks() == 8 and antipodal.budget_share() == 125  # 1000 / 8
    assert replace(antipodal, fc_budget=1001).budget_share() == 126  # rounded up: the units reach the budget
    assert replace(antipodal, fc_budget=0).budget_share() is None
    assert SweepSettings(sampler="box", fc_budget=300).resolved("box").budget_share() == 300  # one unit


@pytest.mark.parametrize("bad", [dict(approaches=0), dict(rolls=0), dict(cone_edges=2), dict(fan_count=-1),
                                 dict(chunk=-1), dict(standoffs=(-0.01,)), dict(sampler="grid"),
                                 dict(fc_budget=-1)])
def test_bad_settings_are_refused(bad: dict) -> None:
    with pytest.raises(InputError):
        SweepSettings(**bad)


@pytest.mark.parametrize("bad, message", [
    (dict(approaches=10**9), "--approaches 1000000000 is 1,000,000,000 rays per object: at most 1,000,000"),
    (dict(approaches=48, fan_count=10**5), "--approaches 48 x (1 + --fan 100000) is 4,800,048 rays per object"),
    (dict(reach_placements=10**9), "--reach-placements must be at most 1,000"),
])
def test_counts_past_what_a_sweep_holds_are_refused_naming_the_option_and_the_limit(bad: dict, message: str) -> None:
    """10**9 approaches (or a fan's rays, or placements) were taken and ran out of memory in the workers."""
    with pytest.raises(InputError, match=re.escape(message)):
        SweepSettings(**bad)
    SweepSettings(approaches=MAX_RAYS // 2, fan_count=1, reach_placements=MAX_REACH_PLACEMENTS)  # the limits pass


@pytest.mark.parametrize("settings, message", [
    (SweepSettings(rolls=10**9), "would hold 512,000,000,000 candidates (256 points (--approaches, or --chunk of them)"
                                 " x --rolls 1000000000 x 2 --depths): at most 1,000,000"),
    (SweepSettings(approaches=10**6, chunk=0), "would hold 16,000,000 candidates (1,000,000 points"),
    (SweepSettings(sampler="surface", rolls=10**5), "would hold 12,800,000 candidates (32 rays (--approaches, or "
                                                    "--chunk of them) x --rolls 100000 x 4 standoffs over the"),
])
def test_a_unit_of_work_past_its_candidates_is_refused_before_any_work(settings: SweepSettings, message: str) -> None:
    """--rolls 10**9 ran out of memory in the worker (its roll angles, then its list of candidates)."""
    with pytest.raises(InputError, match=re.escape(message)):
        api.plan_units(["box"], "panda", settings, 0)
    assert api.plan_units(["box"], "panda", SweepSettings(approaches=10**6 // 16, chunk=0), 0)  # 1,000,000 pass


def test_a_box_sampler_unit_past_its_candidates_is_refused_before_any_work() -> None:
    """Its rays depend on the mesh, so it was not counted: --box-delta 0.002 --rolls 32 lists 1,582,720 Barrett
    candidates on the box (a finer grid or more rolls: the worker's memory). One object: its mesh is loaded."""
    settings = SweepSettings(sampler="box", box_delta=0.002, rolls=32)
    with pytest.raises(InputError, match=re.escape("would hold 1,582,720 candidates (4,946 rays (the --box-delta "
                                                   "grid's that meet it) x --rolls 32 x 10 standoffs over the ")):
        api.plan_units(["box"], "barrett", settings, 0)
    assert api.plan_units(["box"], "barrett", replace(settings, rolls=20), 0)  # 989,200 pass


def test_a_box_sampler_unit_is_counted_by_the_rays_that_meet_the_object() -> None:
    """Its bound counted every ray of the grid, 1.8-2.8 times those that meet the object (the only ones with
    candidates): --box-delta 0.002 --rolls 16 on the box, 791,360 Barrett candidates, was refused as "up to
    1,450,560"; the mug's at --rolls 8, 912,480, as 1,791,200."""
    for name, rolls in (("box", 16), ("mug", 8)):
        assert api.plan_units([name], "barrett", SweepSettings(sampler="box", box_delta=0.002, rolls=rolls), 0)


def test_a_box_sampler_units_fan_is_counted() -> None:
    """Each ray's --fan tilted ones were left out of its count: --box-delta 0.002 --rolls 8 --fan 3 on the box
    passed as 725,280 candidates (grid rays), and listed 1,582,720."""
    settings = SweepSettings(sampler="box", box_delta=0.002, rolls=8, fan_count=3)
    with pytest.raises(InputError, match=re.escape("would hold 1,582,720 candidates (19,784 rays (the --box-delta "
                                                   "grid's that meet it, with --fan 3 tilted ones each) x --rolls 8")):
        api.plan_units(["box"], "barrett", settings, 0)
