"""Robust epsilon: deterministic for a seed, the quantile below the mean."""

from __future__ import annotations

import shutil
import zlib
from pathlib import Path

import numpy as np
import pytest

from planner.db.objects import stored_object
from planner.db.store import open_db
from planner.plan.closing import Grasper
from planner.specs.hands import load_hand
from planner.validation.robust import NoiseSettings, epsilon_samples, robust_epsilon, summarise
from planner.validation.run import validate


def test_robust_epsilon_is_deterministic(setup, firm) -> None:  # type: ignore[no-untyped-def]
    hand, _, obj = setup
    noise = NoiseSettings(samples=4)
    values_a = epsilon_samples(hand, obj, firm, np.random.default_rng(3), noise)
    values_b = epsilon_samples(hand, obj, firm, np.random.default_rng(3), noise)
    a, b = summarise(values_a, noise.quantile), summarise(values_b, noise.quantile)
    assert a.mean == b.mean and np.array_equal(values_a, values_b) and a.samples == len(values_a) == 4
    assert 0.0 <= a.quantile <= a.mean
    assert robust_epsilon(hand, obj, firm, np.random.default_rng(3), noise) == a


def test_summary_of_known_samples() -> None:
    r = summarise(np.array([0.0, 0.1, 0.2, 0.3, 0.4]), 0.25)
    assert (r.mean, r.quantile, r.samples) == (0.2, 0.1, 5)


def test_validate_builds_one_grasper_per_object_and_each_grasps_epsilons_are_a_fresh_ones(
        box_db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`grasp validate --robust N` built a grasper (its world; on a mesh of over 5,000 faces its proxy, normals and
    distance trees, ~0.1 s) per grasp: now one per object and worker, and the epsilons are those a fresh grasper
    per grasp gives, sample for sample."""
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    built: list[str] = []
    real = Grasper.for_object

    def counted(sim, hand, obj, *args, **kwargs):  # type: ignore[no-untyped-def]
        built.append(obj.name)
        return real(sim, hand, obj, *args, **kwargs)

    monkeypatch.setattr(Grasper, "for_object", counted)
    validate(db, top=3, robust_samples=3, engine="mujoco", workers=1)
    assert built == ["box"]
    monkeypatch.undo()
    hand, noise = load_hand("panda"), NoiseSettings(samples=3)
    with open_db(db) as handle:
        obj = stored_object(handle.object_row("box"))
        tried = [g for g in handle.best("box", "panda", 3) if g.robust is not None]
    assert len(tried) == 3
    for g in tried:
        rng = np.random.default_rng([0, zlib.crc32(b"box"), g.candidate, g.seed])  # as validate seeds each grasp
        own = summarise(epsilon_samples(hand, obj, g, rng, noise), noise.quantile)
        assert (g.robust.mean, g.robust.quantile) == (own.mean, own.quantile)  # type: ignore[union-attr]
