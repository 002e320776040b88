"""Running validation over a database: results stored, grasps re-ranked."""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from planner.db.ranking import RankingRule, rule_measures
from planner.db.rows import Validated
from planner.db.store import open_db
from planner.errors import InputError
from planner.record.grasp import Trial
from planner.validation import run
from planner.validation.run import BATCH, validate
from planner.validation.shake import REASONS
from tests import crash_units


def test_validate_stores_trials_and_reranks(validated_db: Path) -> None:
    with sqlite3.connect(validated_db) as conn:
        rows = conn.execute("SELECT g.score, g.epsilon, g.reachability, v.success, r.samples FROM grasps g "
                            "JOIN validation v ON v.grasp_id = g.id JOIN robust r ON r.grasp_id = g.id").fetchall()
        ranks = conn.execute("SELECT object, rank, score FROM grasps ORDER BY object, rank").fetchall()
    assert len(rows) == 6
    with open_db(validated_db, create=False, readonly=True) as db:
        validated = db.validated()
    analytic = RankingRule().analytic(rule_measures(validated))  # the default rule: reach 0.5, success 1
    assert len(validated) == 6 and all(g.measures is not None for g in validated)
    for g, a in zip(validated, analytic):
        assert g.robust is not None and g.robust.samples == 2
        reach = 1.0 if g.reachability is None else g.reachability  # not computed (outside --reach-top): neutral
        assert g.score == pytest.approx(a * (0.5 + 0.5 * reach) * float(g.validation.success))
    assert all(score == 0 for score, _, _, ok, _ in rows if not ok)  # a failed trial zeroes the score
    for obj in ("box", "sphere"):
        scores = [s for o, _, s in ranks if o == obj]
        assert scores == sorted(scores, reverse=True)


def test_unknown_object_and_bad_top_are_refused_before_work(validated_db: Path, tmp_path: Path) -> None:
    copy = tmp_path / "v.db"
    shutil.copy(validated_db, copy)
    with pytest.raises(InputError, match="no grasps of object 'teapot'.*objects: box, sphere"):
        validate(copy, objects=["teapot"])
    with pytest.raises(InputError, match="--top must be at least 1"):
        validate(copy, top=0)


def trial_rows(db: Path, table: str = "mujoco") -> list[tuple]:
    """Each trial of ``table`` (``mujoco``: the default engine's; ``validation``: PyBullet's)."""
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT g.object, g.candidate, v.success, v.fingers_in_contact, v.closing_linear,"
                            " v.closing_angular, v.shaking_linear, v.shaking_angular, v.reason FROM " + table + " v"
                            " JOIN grasps g ON g.id = v.grasp_id ORDER BY g.object, g.candidate").fetchall()


def test_every_grasp_validated_the_same_with_one_or_two_workers(validated_db: Path, tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(run, "MUJOCO_BATCH", BATCH)  # several tasks of this small database: both workers busy
    one, two = tmp_path / "one.db", tmp_path / "two.db"
    for path, workers in ((one, 1), (two, 2)):
        shutil.copy(validated_db, path)
        summary = validate(path, every=True, robust_samples=0, workers=workers)
        assert not summary.failed_tasks and summary.grasps > 2 * BATCH
    with sqlite3.connect(one) as conn:
        stored = conn.execute("SELECT COUNT(*) FROM grasps").fetchone()[0]
    rows = trial_rows(one)
    assert len(rows) == stored and {r[-1] for r in rows} <= set(REASONS)
    assert any(r[-1] == "held" for r in rows)
    assert rows == trial_rows(two)  # bit for bit: one world per trial, whatever process runs it


def test_tasks_hold_more_mujoco_trials_than_pybullet_or_robust_ones(validated_db: Path) -> None:
    """A MuJoCo trial alone is short (~8 ms): MUJOCO_BATCH a task; a PyBullet trial or robust samples: BATCH."""
    from planner.validation.mujoco_settings import MujocoSettings
    from planner.validation.robust import NoiseSettings
    from planner.validation.settings import ShakeSettings

    everything = run.Selection(every=True)
    with open_db(validated_db, create=False, readonly=True) as db:
        counts = [len(db.best(o, h, 10_000)) for o, h in db.pairs()]
        # seed 99: no stored result was made with it, so every grasp is planned (none kept)
        sizes = {name: sorted(len(t.grasps) for t in run.plan(db, None, None, everything, 99, trial, noise))
                 for name, trial, noise in (("mujoco", MujocoSettings(), None), ("pybullet", ShakeSettings(), None),
                                            ("robust", MujocoSettings(), NoiseSettings(samples=2)))}

    def chunks(k: int) -> list[int]:
        return sorted(min(k, c - i) for c in counts for i in range(0, c, k))

    assert max(counts) > run.BATCH  # the sizes differ on this database
    assert sizes["mujoco"] == chunks(run.MUJOCO_BATCH)
    assert sizes["pybullet"] == sizes["robust"] == chunks(run.BATCH)


def test_a_seeded_sample_is_uniform_and_replayable(validated_db: Path, tmp_path: Path) -> None:
    picked = []
    for name, seed in (("a", 7), ("b", 7), ("c", 8)):
        path = tmp_path / f"{name}.db"
        shutil.copy(validated_db, path)
        assert validate(path, sample=3, seed=seed, robust_samples=0).grasps == 6  # 3 of each object's grasps
        picked.append([r[:2] for r in trial_rows(path)])
    assert picked[0] == picked[1] != picked[2]
    with pytest.raises(InputError, match="--sample and --all exclude each other"):
        validate(tmp_path / "a.db", sample=3, every=True)
    with pytest.raises(InputError, match="--sample must be at least 1"):
        validate(tmp_path / "a.db", sample=0)
def test_a_sample_does_not_depend_on_the_order_units_were_stored(validated_db: Path, tmp_path: Path) -> None:
    """Grasp ids follow the order units finished (workers race): the same sweep stored in another order is
    sampled alike (by each grasp's seed and candidate number, not its id)."""
    reordered = tmp_path / "r.db"
    shutil.copy(validated_db, reordered)
    with sqlite3.connect(reordered) as conn:  # the ids turned end to end (no foreign key checks: raw SQL)
        top = conn.execute("SELECT max(id) FROM grasps").fetchone()[0]
        for table in ("grasps", "validation", "robust", "mujoco"):
            key = "id" if table == "grasps" else "grasp_id"
            conn.execute(f"UPDATE {table} SET {key} = {key} + {2 * top}")
            conn.execute(f"UPDATE {table} SET {key} = {3 * top + 1} - {key}")
    picked = []
    for path in (validated_db, reordered):
        with open_db(path, create=False, readonly=True) as db:
            picked.append([(g.seed, g.candidate) for o, h in db.pairs()
                           for g in run.Selection(sample=3).pick(db, o, h, 7)])
    assert picked[0] == picked[1] and len(picked[0]) == 6


def test_a_diverged_trial_is_counted_and_not_stored(validated_db: Path, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """A MuJoCo trial whose state diverged has no verdict: the grasp stays untried (label and rank neutral)."""
    import mujoco

    from planner.sim.mujoco_world import World

    db = tmp_path / "d.db"
    shutil.copy(validated_db, db)
    stepped = World.step

    def box_diverges(world: World, n: int = 1) -> None:  # every trial of the box: a non-finite state
        stepped(world, n)
        if mujoco.mjtGeom.mjGEOM_BOX in world.model.geom_type[sorted(world.object_geoms)]:
            world.data.qvel[:] = np.nan

    monkeypatch.setattr(World, "step", box_diverges)
    summary = validate(db, top=3, robust_samples=0, workers=1, engine="mujoco")
    assert summary.diverged == 3 and summary.grasps == 3 and not summary.failed_tasks
    assert [r[0] for r in trial_rows(db)] == ["sphere"] * 3


def test_a_task_that_kills_its_workers_is_reported_and_the_others_written(reference_db: Path, tmp_path: Path,
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """One PyBullet segfault costs its task (retried once, in a new worker),
    not the validation."""
    db = tmp_path / "v.db"
    shutil.copy(reference_db, db)
    monkeypatch.setattr(run, "run_task", crash_units.validate_segfaults_on_box)
    summary = validate(db, top=2, robust_samples=0, workers=2)
    assert list(summary.failed_tasks) == ["box/panda"]
    assert "killed by SIGSEGV" in summary.failed_tasks["box/panda"] and "2 times" in summary.failed_tasks["box/panda"]
    with sqlite3.connect(db) as conn:
        trials = dict(conn.execute("SELECT g.object, COUNT(*) FROM mujoco v JOIN grasps g ON g.id = v.grasp_id"
                                   " GROUP BY g.object").fetchall())
    assert trials == {"sphere": summary.grasps} and summary.grasps > 0


def _ranks(db: Path) -> list[tuple]:
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT id, score, rank FROM grasps ORDER BY id").fetchall()


def _reranked(db: Path) -> list[tuple]:
    """The ranks a fresh re-rank of every pair gives from what is stored."""
    with open_db(db, create=False) as store:
        rule = store.rule()
        for obj, hand in store.pairs():
            store.rescore(obj, hand, rule)
    return _ranks(db)


def _slipped(task: run.Task) -> run.TaskResult:
    """Every grasp's trial slipped (its score drops to 0), at no cost."""
    return run.TaskResult(task, [Trial(False, 1, 0.0, 0.0, 0.03, 0.0, "slipped") for _ in task.grasps],
                          [None] * len(task.grasps))


@pytest.mark.parametrize("stop", ["error", "interrupt"])
def test_each_pair_is_reranked_with_every_stored_verdict_however_its_tasks_end(
        reference_db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, stop: str) -> None:
    """Ranks are rebuilt once per (object, hand), not after every task: with
    its last task, also when that task fails, or on the way out of Ctrl-C."""
    db = tmp_path / "r.db"
    shutil.copy(reference_db, db)
    before = _ranks(db)
    seen: list[str] = []

    def fake(task: run.Task) -> run.TaskResult:
        seen.append(task.object)
        if task.object == "box" and seen.count("box") == 3:  # box's last task (top 6, 2 a task)
            if stop == "interrupt":
                raise KeyboardInterrupt
            return run.TaskResult(task, error="boom")
        return _slipped(task)

    monkeypatch.setattr(run, "MUJOCO_BATCH", 2)
    monkeypatch.setattr(run, "run_task", fake)
    if stop == "interrupt":
        with pytest.raises(KeyboardInterrupt):
            validate(db, top=6, robust_samples=0, workers=1)
    else:
        summary = validate(db, top=6, robust_samples=0, workers=1)
        assert list(summary.failed_tasks) == ["box/panda"]  # box: one of its tasks; its grasps are not tried again
        with open_db(db, create=False, readonly=True) as store:
            stored_trials = len(store.validated())
        assert summary.grasps == stored_trials and summary.rounds > 1  # every slipped grasp left the top 6
    stored = _ranks(db)
    assert stored != before  # the slipped verdicts moved scores
    assert stored == _reranked(db)


def test_top_k_ends_with_the_top_k_tried(reference_db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Verdicts re-rank: a grasp that slipped leaves the top K and an untried one moves up. One `validate
    --top K` used to stop there (the top K not all tried: "run it again until it tries nothing"); it now
    tries those too, round after round, until the top K all carry a verdict, and tries no grasp twice."""
    db = tmp_path / "t.db"
    shutil.copy(reference_db, db)
    tried: list[int] = []

    def half_hold(task: run.Task) -> run.TaskResult:  # odd candidates slip (score 0), even ones hold
        tried.extend(g.id for g in task.grasps)
        return run.TaskResult(task, [Trial(g.candidate % 2 == 0, 2, 0.0, 0.0, 0.0 if g.candidate % 2 == 0 else 0.03,
                                           0.0, "held" if g.candidate % 2 == 0 else "slipped") for g in task.grasps],
                              [None] * len(task.grasps))

    monkeypatch.setattr(run, "run_task", half_hold)
    summary = validate(db, top=3, robust_samples=0, workers=1)
    with open_db(db, create=False, readonly=True) as store:
        pairs = store.pairs()
        for obj, hand in pairs:
            best = store.best(obj, hand, 3)
            assert len(best) == 3 and all(g.mujoco is not None and g.mujoco.success for g in best), (obj, hand)
        stored = sum(len(batch) for pair in pairs for batch in store.grasp_batches(*pair))
    assert len(tried) == len(set(tried)) == summary.grasps < stored  # each tried once; not every grasp
    again = validate(db, top=3, robust_samples=0, workers=1)
    assert (again.grasps, again.kept) == (0, 3 * len(pairs))


def test_top_k_counts_as_kept_the_verdicts_from_before_that_any_round_finds(
        reference_db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A grasp that moves up into the top K in a later round with a verdict of an earlier run (here a
    --sample's) is kept, not tried: the line's 'N already tried ..., kept' counted the first round's only."""
    db = tmp_path / "t.db"
    shutil.copy(reference_db, db)
    tried: list[int] = []

    def half_hold(task: run.Task) -> run.TaskResult:  # odd candidates slip, even ones hold
        tried.extend(g.id for g in task.grasps)
        return run.TaskResult(task, [Trial(g.candidate % 2 == 0, 2, 0.0, 0.0, 0.0 if g.candidate % 2 == 0 else 0.03,
                                           0.0, "held" if g.candidate % 2 == 0 else "slipped") for g in task.grasps],
                              [None] * len(task.grasps))

    monkeypatch.setattr(run, "run_task", half_hold)
    validate(db, sample=6, robust_samples=0, workers=1)
    with open_db(db, create=False, readonly=True) as store:
        before = {g.id: bool(g.mujoco and g.mujoco.success) for g in store.validated()}
    tried.clear()
    summary = validate(db, top=3, robust_samples=0, workers=1)
    with open_db(db, create=False, readonly=True) as store:
        final = {g.id for pair in store.pairs() for g in store.best(*pair, 3)}
    assert final <= set(tried) | set(before) and not set(tried) & set(before)
    from_before = final & set(before)
    assert len(from_before) > 0 and summary.grasps == len(tried)
    assert len(from_before) <= summary.kept <= len(before)  # was: the first round's 2 of these 3
    assert summary.kept_successes <= sum(before.values())


def test_top_k_tries_at_most_a_few_times_k_of_a_pair(reference_db: Path, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Where every grasp drops (a hand that cannot hold the object), the rounds of --top 1 tried every stored
    grasp (24 of 24 in 16 rounds); now at most TOP_TRIES x K of a pair, and the summary names the pair."""
    db = tmp_path / "c.db"
    shutil.copy(reference_db, db)
    tried: list[tuple[str, int]] = []

    def drops(task: run.Task) -> run.TaskResult:
        tried.extend((task.object, g.id) for g in task.grasps)
        return _slipped(task)

    monkeypatch.setattr(run, "run_task", drops)
    summary = validate(db, top=1, robust_samples=0, workers=1)
    per_pair = {obj: sum(o == obj for o, _ in tried) for obj in ("box", "sphere")}
    assert per_pair == {"box": run.TOP_TRIES, "sphere": run.TOP_TRIES}, per_pair
    assert summary.capped == ["box/panda", "sphere/panda"] and summary.cap == run.TOP_TRIES
    assert summary.to_json()["capped"] == ["box/panda", "sphere/panda"]


def test_verdicts_left_unranked_by_a_killed_run_are_ranked_by_the_next(reference_db: Path, tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """A run killed (kill -9) between a batch's verdicts and its object's re-rank leaves the pair marked
    in the database; the next ``grasp validate``, of any selection, re-ranks it first."""
    db = tmp_path / "k.db"
    shutil.copy(reference_db, db)
    before = _ranks(db)
    with open_db(db, create=False) as store:
        best = store.best("box", "panda", 2)
        store.write_validation("box", "panda", [Validated(g.id, None, None, 0, "", "", Trial(
            False, 1, 0.0, 0.0, 0.03, 0.0, "slipped"), "{}") for g in best], store.rule(), rescore=False)
        assert store.unranked() == [("box", "panda")]
    assert _ranks(db) == before  # what a kill just after that write leaves
    monkeypatch.setattr(run, "run_task", _slipped)
    validate(db, objects=["sphere"], top=1, robust_samples=0, workers=1)
    with open_db(db, create=False, readonly=True) as store:
        assert store.unranked() == []
    box = {i: (score, rank) for i, score, rank in _ranks(db)}
    assert all(box[g.id][0] == 0 for g in best)  # the slipped verdicts now count
    assert _ranks(db) == _reranked(db)


def _verdicts(db: Path, table: str) -> dict[int, tuple]:
    with sqlite3.connect(db) as conn:
        return {r[0]: r[1:] for r in conn.execute(f"SELECT grasp_id, success, closing_linear, shaking_linear, seed, "
                                                   f"settings FROM {table}")}


def test_a_run_cut_short_tries_only_what_it_had_not(box_db: Path, tmp_path: Path) -> None:
    """The trials are deterministic: a run killed half way (half its
    verdicts stored), or run again, keeps what is stored and tries the rest;
    the verdicts are those of one uninterrupted run. Another seed, or robust
    samples the stored rows lack, try again."""
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    first = validate(db, every=True, closure_only=True, robust_samples=0, workers=1)
    assert first.grasps > 4 and first.kept == 0
    whole = _verdicts(db, "mujoco")
    with sqlite3.connect(db) as conn:  # as if killed after half the tasks
        gone = [i for i, in conn.execute("SELECT grasp_id FROM mujoco ORDER BY grasp_id")][::2]
        conn.executemany("DELETE FROM mujoco WHERE grasp_id = ?", [(i,) for i in gone])
    again = validate(db, every=True, closure_only=True, robust_samples=0, workers=1)
    assert (again.grasps, again.kept) == (len(gone), first.grasps - len(gone))
    assert again.successes + again.kept_successes == first.successes
    assert _verdicts(db, "mujoco") == whole
    assert validate(db, every=True, closure_only=True, robust_samples=0, workers=1).grasps == 0  # nothing left
    assert validate(db, every=True, closure_only=True, robust_samples=0, workers=1, seed=1).kept == 0
    assert validate(db, every=True, closure_only=True, robust_samples=1, workers=1, seed=1).kept == 0  # no robust rows


def test_an_empty_database_or_an_unknown_hand_is_an_error(box_db: Path, tmp_path: Path) -> None:
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    with pytest.raises(InputError, match="no grasps of hand 'barrett'.*hands: panda"):
        validate(db, hands=["barrett"], robust_samples=0)
    with sqlite3.connect(db) as conn:
        conn.execute("DELETE FROM grasps")
    with pytest.raises(InputError, match=r"no grasps in .*: the sweeps of its objects \(box\) kept none; `grasp best"):
        validate(db, robust_samples=0)


def test_top_with_force_closure_takes_only_the_grasps_that_rank_first() -> None:
    """Grasps force closure as planned or once squeezed rank first (planner.db.ranking.FIRST), so --top takes
    others only where an object has fewer than K of them; --force-closure leaves those out, and keeps a grasp
    force closure only once squeezed, with --top, --sample and --all alike."""
    from dataclasses import replace
    from types import SimpleNamespace

    from planner.record.measures import Measures
    from tests.helpers import made_up

    squeeze = Measures(3.0, 4.0, 0.01, 0.01, 1.0, ())
    ranked = [replace(made_up(0, 0.1), score=0.9), replace(made_up(1, 0.0, fc=False), score=0.85,
                                                           measures=replace(squeeze, squeezed_force_closure=True)),
              replace(made_up(2, 0.0, fc=False), score=0.8, measures=replace(squeeze, squeezed_force_closure=False)),
              replace(made_up(3, 0.0, fc=False), score=0.0)]
    db = SimpleNamespace(best=lambda obj, hand, top: ranked[:top], grasp_batches=lambda obj, hand: [ranked])
    assert run.Selection(top=4).pick(db, "o", "h", 0) == ranked[:3]  # type: ignore[arg-type]
    for selection in (run.Selection(top=4, closure_only=True), run.Selection(every=True, closure_only=True),
                      run.Selection(sample=2, closure_only=True)):
        assert selection.pick(db, "o", "h", 0) == ranked[:2]  # type: ignore[arg-type]


@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
def test_verdicts_of_a_hand_before_it_replaced_link_inertia_are_tried_again(
        box_db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, engine: str) -> None:
    """A stored verdict records what it was made with (its trial's settings, the hand's motors): a hand whose
    trials now give some links other moments of inertia (hand.toml [dynamics.link_inertia]) runs another
    trial, so the verdicts made before are not kept as this trial's."""
    from dataclasses import replace

    from planner.specs.hands import load_hand
    from planner.validation.mujoco_settings import MujocoSettings
    from planner.validation.settings import ShakeSettings

    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    first = validate(db, top=2, robust_samples=0, workers=1, engine=engine)
    assert first.grasps == 2
    settings = MujocoSettings() if engine == "mujoco" else ShakeSettings()
    kept: list = []
    with open_db(db, create=False, readonly=True) as handle:
        assert run.plan(handle, None, None, run.Selection(top=2), 0, settings, None, kept) == [] and len(kept) == 2
        panda = load_hand("panda")
        lighter = replace(panda, link_inertia={"panda_leftfinger": (2e-5, 3e-5, 4e-5)})
        monkeypatch.setattr(run, "load_hand", lambda name: lighter)
        kept = []
        tasks = run.plan(handle, None, None, run.Selection(top=2), 0, settings, None, kept)
    assert kept == [] and sum(len(t.grasps) for t in tasks) == 2
    from planner.validation import mujoco_trial, shake

    recorded = mujoco_trial.recorded if engine == "mujoco" else shake.recorded
    assert "link_inertia" not in recorded(settings, panda)  # a hand that replaces none records as before
