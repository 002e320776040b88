"""``grasp validate``: shake-test and robust-epsilon stored grasps (each
object's best, a seeded uniform sample, or all), in the crash-safe worker
pool (:mod:`planner.run.pool`), with one writer. A task whose worker dies
twice (a simulator segfault) or that fails is reported with its error; the
other tasks are written. The trial's ``engine``: PyBullet's shake trial
(:mod:`planner.validation.shake`, stored in ``validation``) or the MuJoCo
trial (:mod:`planner.validation.mujoco_trial`, another engine and protocol,
stored in ``mujoco``); each keeps its own verdicts."""

from __future__ import annotations

import json
import logging
import zlib
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import closing
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from planner import prepare
from planner.db.failures import no_grasps
from planner.db.hand_files import check_hand_files
from planner.db.ranking import RankingRule, first_of
from planner.db.store import Database, ObjectRow, Validated, open_for_writing
from planner.errors import InputError, PlannerError
from planner.plan.closing import Grasper
from planner.record.grasp import Grasp, RobustEpsilon, Trial
from planner.run import pool
from planner.run.progress import Report
from planner.sim import Sim
from planner.specs.hands import load_hand
from planner.specs.inputs import check_seed
from planner.threads import one_blas_thread
from planner.validation import kept_objects
from planner.validation.mujoco_settings import DEFAULT_ENGINE, DIVERGED, ENGINES, MujocoSettings
from planner.validation.robust import NoiseSettings, robust_epsilon
from planner.validation.shake import ShakeSettings, recorded, trials

log = logging.getLogger(__name__)

#: Grasps per worker task: enough to amortise a task's set-up and write (the
#: object rebuilt and BLAS limited, ~5 ms, until both were kept per process),
#: few enough to spread over the workers. A PyBullet trial (40-90 ms) or
#: robust samples make a grasp long: BATCH; a MuJoCo trial alone (~8 ms) is
#: short: MUJOCO_BATCH (measured, 4,086 trials of 4 random objects, one
#: worker: 6% less CPU than 8 a task; the same results, trials being
#: independent of their order and company).
BATCH = 8
MUJOCO_BATCH = 32
#: ``--top K`` tries at most this many times K grasps of an (object, hand) in one run: where every grasp
#: drops (a hand that cannot hold the object), the rounds would otherwise try them all.
TOP_TRIES = 5


@dataclass(frozen=True)
class Task:
    """Grasps of one object and hand for one worker, and how to test them."""

    row: ObjectRow  # the stored object: mesh source, scale, mass, friction
    hand: str
    grasps: tuple[Grasp, ...]
    seed: int
    trial: ShakeSettings | MujocoSettings  # the engine's settings: PyBullet's or MuJoCo's
    noise: NoiseSettings | None

    @property
    def engine(self) -> str:
        return "mujoco" if isinstance(self.trial, MujocoSettings) else "pybullet"

    @property
    def object(self) -> str:
        return self.row.name


@dataclass
class TaskResult:
    task: Task
    trials: list[Trial] = field(default_factory=list)
    robust: list[RobustEpsilon | None] = field(default_factory=list)
    error: str | None = None


def run_task(task: Task) -> TaskResult:
    out = TaskResult(task)
    try:
        with one_blas_thread():
            _run_task(task, out)
    except PlannerError as exc:
        out.error = str(exc)
    except Exception as exc:  # keep the other tasks going
        out.error = f"{type(exc).__name__}: {exc}"
    return out


def _run_task(task: Task, out: TaskResult) -> None:
    hand = load_hand(task.hand)
    obj = kept_objects.stored(task.row)  # the worker's own, built by its first task of the object
    if task.engine == "mujoco":
        from planner.validation import mujoco_trial  # loads MuJoCo: only where asked for

        out.trials = mujoco_trial.trials(hand, obj, task.grasps, task.trial)
    else:
        out.trials = trials(hand, obj, task.grasps, task.trial)
    if task.noise is None:
        out.robust += [None] * len(task.grasps)
        return
    with Sim() as sim:  # one world and grasper for the object's grasps (a new one per grasp cost ~0.1 s on a scan)
        grasper = Grasper.for_object(sim, hand, obj)
        for g in task.grasps:
            end = [1] if g.squeezed_from_turn is not None else []  # a squeeze's end: its own noise, not its parent's
            rng = np.random.default_rng([task.seed, zlib.crc32(task.object.encode()), g.candidate, g.seed, *end])
            out.robust.append(robust_epsilon(hand, obj, g, rng, task.noise, grasper))


@dataclass(frozen=True)
class Selection:
    """Which grasps of each object and hand: the ``top`` best (default; the grasps force closure as planned, or
    once squeezed where that squeeze's end is not stored beside them, rank first, :data:`planner.db.ranking.FIRST`,
    so they are such where the object has ``top`` of them), a seeded uniform ``sample`` of that many, or ``every``
    one; ``closure_only``: of those that rank first only (:func:`planner.db.ranking.first_of`)."""

    top: int = 10
    sample: int | None = None
    every: bool = False
    closure_only: bool = False

    def pick(self, db: Database, obj: str, hand: str, seed: int) -> list[Grasp]:
        if not self.every and self.sample is None:
            return self._first([g for g in db.best(obj, hand, self.top) if g.score])
        grasps = sorted(self._first([g for batch in db.grasp_batches(obj, hand) for g in batch]), key=_identity)
        if self.every or self.sample is None or self.sample >= len(grasps):
            return grasps
        rng = np.random.default_rng([seed, zlib.crc32(obj.encode()), zlib.crc32(hand.encode())])
        return [grasps[i] for i in sorted(rng.choice(len(grasps), size=self.sample, replace=False))]


    def _first(self, grasps: list[Grasp]) -> list[Grasp]:
        """``grasps``, or with ``closure_only`` those of them that rank first."""
        return [g for g, first in zip(grasps, first_of(grasps)) if first] if self.closure_only else grasps


def _identity(g: Grasp) -> tuple[int, int, bool, int]:
    """A grasp's place in its sweep, for a sample that does not depend on the order units were stored in (ids
    follow the order workers finished): its unit's seed, its candidate number, whether it is a squeeze's end
    (beside its parent) (the id only between equals)."""
    return g.seed, g.candidate, g.squeezed_from_turn is not None, g.id or 0


def _already(db: Database, obj: str, hand: str, seed: int, trial_settings: ShakeSettings | MujocoSettings,
             noise: NoiseSettings | None) -> set[int]:
    """Ids of the pair's grasps this run would give the results they hold:
    a verdict of its engine with its seed and settings (as :func:`write`
    records them), and its robust epsilon if it asks for one. The trials are
    deterministic, so a run killed half way, or run again, does not try
    them again."""
    spec = load_hand(hand)
    if isinstance(trial_settings, MujocoSettings):
        from planner.validation import mujoco_trial

        done = db.validated_ids(obj, hand, "mujoco", seed, mujoco_trial.recorded(trial_settings, spec))
    else:
        done = db.validated_ids(obj, hand, "validation", seed, recorded(trial_settings, spec))
    if noise is not None:
        done &= db.validated_ids(obj, hand, "robust", seed, noise.to_json())
    return done


def plan(db: Database, objects: list[str] | None, hands: list[str] | None, selection: Selection, seed: int,
         trial_settings: ShakeSettings | MujocoSettings, noise: NoiseSettings | None,
         kept: list[Grasp] | None = None) -> list[Task]:
    """The tasks of a run; the selected grasps it would not change (:func:`_already`) go to ``kept``."""
    kept = [] if kept is None else kept
    stored = {pair: db.object_row(pair[0]) for pair in db.pairs()}
    pairs = {pair: row for pair, row in stored.items() if row is not None}
    known = sorted({obj for obj, _ in pairs})
    if not known:
        raise InputError(no_grasps(db.path, db.object_names()))
    for name in objects or []:
        if name not in known:
            raise InputError(f"no grasps of object '{name}' in {db.path}; objects: {', '.join(known) or '(none)'}")
    with_grasps = sorted({hand for _, hand in pairs})
    for name in hands or []:
        if name not in with_grasps:
            raise InputError(f"no grasps of hand '{name}' in {db.path}; hands: {', '.join(with_grasps)}")
    tasks = []
    for (obj, hand), row in pairs.items():
        if (objects and obj not in objects) or (hands and hand not in hands):
            continue
        picked = selection.pick(db, obj, hand, seed)
        done = _already(db, obj, hand, seed, trial_settings, noise)
        grasps = [g for g in picked if g.id not in done]
        kept.extend(g for g in picked if g.id in done)
        size = MUJOCO_BATCH if isinstance(trial_settings, MujocoSettings) and noise is None else BATCH
        for i in range(0, len(grasps), size):
            tasks.append(Task(row, hand, tuple(grasps[i:i + size]), seed, trial_settings, noise))
    return tasks


def execute(tasks: list[Task], workers: int) -> Iterator[TaskResult]:
    """Run ``tasks`` in the crash-safe pool (in this process if ``workers``
    <= 1), yielding each result as it finishes; a task whose worker died
    twice comes back with its error. The objects this process kept are dropped at the end
    (:mod:`~planner.validation.kept_objects`)."""
    try:
        with closing(pool.execute(run_task, tasks, workers)) as outcomes:
            for task, outcome, _ in outcomes:
                yield outcome if isinstance(outcome, TaskResult) else TaskResult(task, error=str(outcome))
    finally:
        kept_objects.forget()


def decompose(row: ObjectRow, report: Report) -> bool:
    """Make sure the stored object's convex parts are ready (cached) for
    its trials; ``report(0, 1)`` just before CoACD runs. True if it ran."""
    from planner.geometry.decompose import convex_parts, ready_parts, refuse_known_timeout
    from planner.validation.parts import PRIMITIVES

    with one_blas_thread():
        obj = kept_objects.stored(row)
        if obj.spec.kind in PRIMITIVES or ready_parts(obj.mesh, obj.mesh_hash) is not None:
            return False
        refuse_known_timeout(obj.mesh_hash)  # not announced as started when it ran out of this time limit before
        report(0, 1)
        convex_parts(obj.mesh, obj.mesh_hash)
    return True


def prepare_objects(rows: list[ObjectRow], workers: int) -> None:
    """Decompose the objects of the trials that have no cached convex parts
    yet, in the pool (each object once, not once per task), announcing each
    decomposition as it starts and ends (:mod:`planner.prepare`). A failure is
    left to the trials, which report it per task."""
    begun: set[int] = set()

    def started(index: int, done: int, total: int) -> None:
        if index not in begun:
            begun.add(index)
            prepare.started(prepare.DECOMPOSITION, rows[index].name)

    position = {row.name: i for i, row in enumerate(rows)}
    with closing(pool.execute(decompose, rows, workers, progress=started)) as outcomes:
        for row, ran, seconds in outcomes:
            if ran is True:
                prepare.ended(prepare.DECOMPOSITION, row.name, seconds)
            elif position[row.name] in begun:
                log.warning("convex decomposition of %s failed: %s", row.name, ran)


def write(db: Database, result: TaskResult, rule: RankingRule, rescore: bool = True) -> None:
    task = result.task
    noise = task.noise.to_json() if task.noise is not None else ""
    if task.engine == "mujoco":
        from planner.validation import mujoco_trial

        settings = mujoco_trial.recorded(task.trial, load_hand(task.hand))  # type: ignore[arg-type]
        # a diverged trial has no verdict: not stored, the grasp stays untried (label and rank neutral)
        rows = [Validated(g.id, None, r, task.seed, "", noise, None if t.reason == DIVERGED else t,
                          settings) for g, t, r in zip(task.grasps, result.trials, result.robust)]
    else:
        settings = recorded(task.trial, load_hand(task.hand))  # type: ignore[arg-type]
        rows = [Validated(g.id, t, r, task.seed, settings, noise)  # type: ignore[arg-type]
                for g, t, r in zip(task.grasps, result.trials, result.robust)]
    db.write_validation(task.object, task.hand, rows, rule, rescore)


def _round(db: Database, tasks: list[Task], rule: RankingRule, workers: int, summary: ValidationSummary,
           progress: Callable[[int, int], None] | None) -> None:
    """Run ``tasks``, store their results and re-rank each (object, hand) once, with its last task's
    results (or on the way out after Ctrl-C or an error): re-ranking after every task cost time quadratic
    in a pair's grasps."""
    if progress:
        progress(0, len(tasks))
    left = Counter((t.object, t.hand) for t in tasks)
    try:
        for done, result in enumerate(execute(tasks, workers), start=1):
            pair = (result.task.object, result.task.hand)
            left[pair] -= 1
            if result.error:
                summary.failed_tasks[f"{pair[0]}/{pair[1]}"] = result.error
            else:
                write(db, result, rule, rescore=left[pair] == 0)
                diverged = sum(t.reason == DIVERGED for t in result.trials)
                summary.grasps += len(result.trials) - diverged
                summary.diverged += diverged
                summary.successes += sum(t.success for t in result.trials)
            if progress:
                progress(done, len(tasks))
    finally:  # pairs whose last task failed or never came back (the database marks them)
        _rerank_unranked(db, rule)


def _untried(tasks: list[Task], tried: set[int], counts: Counter, most: int, capped: set[str]) -> list[Task]:
    """``tasks`` without the grasps of ``tried``, and without those past ``most`` tried of a pair
    (``counts``: tried so far, by (object, hand); such a pair goes into ``capped``); tasks left empty dropped."""
    out = []
    for task in tasks:
        grasps = tuple(g for g in task.grasps if g.id not in tried)
        pair = (task.object, task.hand)
        room = max(most - counts[pair], 0)
        if len(grasps) > room:
            capped.add(f"{task.object}/{task.hand}")
            grasps = grasps[:room]
        counts[pair] += len(grasps)
        if grasps:
            out.append(replace(task, grasps=grasps))
    return out


def _rerank_unranked(db: Database, rule: RankingRule) -> None:
    """Re-rank the (object, hand) pairs the database marks as holding verdicts not yet ranked."""
    for pair in db.unranked():
        db.rescore(*pair, rule)


@dataclass
class ValidationSummary:
    """``grasps`` given a verdict (stored), ``successes`` among them, ``diverged``: trials whose state
    diverged (MuJoCo's; no verdict, not stored), ``failed_tasks``: object/hand -> error; ``kept``: selected
    grasps that already held this run's results (not tried again), ``kept_successes`` among them."""

    grasps: int = 0
    successes: int = 0
    diverged: int = 0
    failed_tasks: dict[str, str] = field(default_factory=dict)
    kept: int = 0
    kept_successes: int = 0
    rounds: int = 0
    capped: list[str] = field(default_factory=list)  # object/hand whose K best are not all tried: TOP_TRIES
    cap: int = 0  # the most grasps of a pair --top K tries in one run (TOP_TRIES x K)

    def to_json(self) -> dict:
        return {"grasps": self.grasps, "successes": self.successes, "diverged": self.diverged,
                "failed": self.failed_tasks, "kept": self.kept, "kept_successes": self.kept_successes,
                "rounds": self.rounds, "capped": self.capped, "cap": self.cap}


def validate(db_path: Path, *, objects: list[str] | None = None, hands: list[str] | None = None, top: int = 10,
             sample: int | None = None, every: bool = False, robust_samples: int = 10, seed: int = 0,
             workers: int = 1, settings: ShakeSettings | MujocoSettings | None = None, closure_only: bool = False,
             progress: Callable[[int, int], None] | None = None, engine: str | None = None) -> ValidationSummary:
    """Shake-test (and robust-epsilon) each object's ``top`` best grasps, or
    a uniform ``sample`` of its grasps drawn with ``seed``, or ``every``
    grasp (``closure_only``: only grasps force closure as planned or once
    squeezed, those that rank first), in ``engine`` (see :data:`ENGINES`; None:
    the engine of ``settings`` if given, else :data:`DEFAULT_ENGINE`; its
    verdicts are stored apart from the other's); store the results and re-rank."""
    if engine is None:  # the settings' engine, else the default
        engine = DEFAULT_ENGINE if settings is None else \
            "mujoco" if isinstance(settings, MujocoSettings) else "pybullet"
    if engine not in ENGINES:
        raise InputError(f"unknown engine '{engine}'; use {' or '.join(ENGINES)}")
    if settings is not None and isinstance(settings, MujocoSettings) != (engine == "mujoco"):
        raise InputError(f"the trial settings given are not {engine}'s")
    check_seed(seed)
    if top < 1:
        raise InputError(f"--top must be at least 1, got {top}")
    if sample is not None and sample < 1:
        raise InputError(f"--sample must be at least 1, got {sample}")
    if sample is not None and every:
        raise InputError("--sample and --all exclude each other: pick one")
    trial_settings = settings or (MujocoSettings() if engine == "mujoco" else ShakeSettings())
    noise = NoiseSettings(samples=robust_samples) if robust_samples > 0 else None
    summary = ValidationSummary()
    with open_for_writing(Path(db_path), create=False) as db:
        rule = db.rule()
        _rerank_unranked(db, rule)  # verdicts of a run killed before it re-ranked them
        kept: list[Grasp] = []
        selection = Selection(top, sample, every, closure_only)
        tasks = plan(db, objects, hands, selection, seed, trial_settings, noise, kept)
        check_hand_files(db, {t.hand for t in tasks} | {g.hand for g in kept})
        tried: set[int] = set()
        counts = Counter((t.object, t.hand) for t in tasks for _ in t.grasps)
        capped: set[str] = set()
        while tasks:
            prepare_objects(list({t.row.name: t.row for t in tasks}.values()), workers)
            _round(db, tasks, rule, workers, summary, progress)
            summary.rounds += 1
            tried.update(g.id for t in tasks for g in t.grasps if g.id is not None)
            if every or sample is not None:
                break
            # verdicts re-rank: grasps that dropped leave the top K and others move up; they are tried
            # next, until the top K all carry this run's verdicts (a grasp tried once in this run, even
            # one whose trial diverged or failed, is not tried again: the trials are deterministic)
            tasks = _untried(plan(db, objects, hands, selection, seed, trial_settings, noise, kept), tried, counts,
                             TOP_TRIES * top, capped)
        summary.capped, summary.cap = sorted(capped), (0 if every or sample is not None else TOP_TRIES * top)
        # kept: what a round selected with a verdict from before this run, each once (a later round's plan
        # also finds the verdicts this run stored: those were tried, not kept)
        before = list({g.id: g for g in kept if g.id not in tried}.values())
        summary.kept = len(before)
        verdicts = [g.mujoco if engine == "mujoco" else g.validation for g in before]
        summary.kept_successes = sum(bool(t.success) for t in verdicts if t is not None)
        db.set_meta("mujoco_settings" if engine == "mujoco" else "validation_settings", json.dumps(
            {"trial": json.loads(trial_settings.to_json()), "noise": json.loads(noise.to_json()) if noise else None,
             "seed": seed}))
    return summary
