"""The one crash-safe worker pool of ``generate``, ``validate`` and ``import``.

``execute(fn, units, workers)`` yields ``(unit, result or Failure, seconds)``
to the caller -- the one database writer -- as units finish. A unit's result
depends only on the unit, never on the backend or the worker count.

- ``workers <= 1``: ``fn`` runs in this process, in order (no isolation, no
  hard time-out).
- Local pool (:func:`run`): at most ``workers`` units in flight, one per
  worker process, each worker with its own pipe, so the driver knows exactly
  which unit a dead worker was running. A worker that dies (a segfault in the
  simulator, the OOM killer) is replaced and its unit retried; a unit that
  kills ``max_crashes`` workers is a ``Failure`` of kind ``"crash"``. An
  exception in ``fn`` is a ``Failure`` of kind ``"error"`` (not retried: it
  would raise again); a unit over ``timeout`` seconds has its worker killed
  and is a ``Failure`` of kind ``"timeout"``.
- Ray (``ray="local"`` or a cluster address): :mod:`planner.run.ray_local`,
  the same contract.

Progress inside units (:mod:`planner.run.progress`): with ``progress``, ``fn``
is called as ``fn(unit, report)``; the unit's throttled ``report(done,
total)`` calls reach ``progress(index, done, total)`` in the driver, ``index``
the unit's position in ``units``: directly in process, as a message on the
worker's pipe in the local pool (the driver calls ``progress`` while it waits
for results). A retried unit reports again from zero. On Ray units report
nothing: ``progress`` is not called. The lines a unit logs to
:mod:`planner.prepare` (a mesh closed, cached afterwards) reach the driver's
logger as the worker logs them, each once a run: a run stopped before the
unit's end has said them (on Ray they come with the result,
:func:`planner.prepare.kept`).

Workers die with the driver, even by SIGKILL (see :mod:`planner.run.worker`),
and never hold the database's writer lock: they start by ``forkserver``
(default) or ``spawn``, never ``fork``, so they get no descriptor of the
driver's but the two pipes they are given. The fork server is a fresh
interpreter that imports :data:`PRELOAD` once; every worker, and every
replacement after a crash, is forked from it with the planner already
imported (bench/pool.py measures both methods).

``fn`` and units must be picklable (``fn`` a module-level function); the
iterator must be consumed in one thread. A forkserver worker sees the
environment of the moment the fork server started (its first pool in this
process), not the driver's current one.
"""

from __future__ import annotations

import atexit
import logging
import multiprocessing
import pickle
import signal
import threading
import time
import weakref
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from typing import Any, TypeVar

from planner import prepare
from planner.errors import PlannerError
from planner.run import worker
from planner.run.failure import MAX_CRASHES, Failure
from planner.run.progress import Throttled

#: progress(index, done, total) in the driver: unit ``index`` (its position in
#: the units given) has finished ``done`` of its ``total`` steps.
OnProgress = Callable[[int, int, int], None]

log = logging.getLogger(__name__)

U = TypeVar("U")
R = TypeVar("R")

#: Workers in a row that die before they are ready before the pool gives up.
START_FAILURES = 3
#: [s] an idle worker gets to exit after "stop" before it is killed.
STOP_GRACE = 5.0
START_METHODS = ("forkserver", "spawn")
START_METHOD = "forkserver"
#: Modules the fork server imports once, before it forks any worker: the
#: heavy imports of every unit function (numpy, scipy, PyBullet, trimesh).
PRELOAD = ("planner.plan.unit",)
#: Imported first by a fork server started from the main thread: the kernel
#: kills the server, and so its workers, when the driver dies.
SERVER_GUARD = "planner.run.server_guard"
#: Arm PR_SET_PDEATHSIG in workers and the fork server (tests turn it off to
#: check the lifeline alone).
USE_PDEATHSIG = True


class PoolError(PlannerError):
    """The pool itself cannot run: its worker processes cannot start."""


def execute(fn: Callable[..., R], units: Iterable[U], workers: int, *, timeout: float | None = None,
            ray: str | None = None, progress: OnProgress | None = None) -> Iterator[tuple[U, R | Failure, float]]:
    """Run ``fn`` on every unit: in this process (``workers <= 1``), in a
    local pool of ``workers`` processes, or on Ray (``ray``: ``"local"`` for
    a private instance with ``workers`` CPUs, else a cluster address).
    ``progress``: see the module's docstring (not on Ray)."""
    if ray is None:
        return run(fn, units, workers, timeout=timeout, progress=progress)
    from planner.run import ray_local  # Ray is an optional extra

    return ray_local.on_ray(fn, units, workers, ray, timeout=timeout)


def run(fn: Callable[..., R], units: Iterable[U], workers: int, *, timeout: float | None = None,
        max_crashes: int = MAX_CRASHES, start_method: str = START_METHOD, progress: OnProgress | None = None
        ) -> Iterator[tuple[U, R | Failure, float]]:
    """The local pool: yield ``(unit, result or Failure, seconds)`` in the
    order units finish; ``seconds`` is the run time of the last attempt.
    Closing the iterator early stops the workers."""
    if start_method not in START_METHODS:
        raise ValueError(f"start_method must be one of {', '.join(START_METHODS)}, not {start_method!r} "
                         "(fork would hand the driver's file descriptors and locks to the workers)")
    if max_crashes < 1:
        raise ValueError(f"max_crashes must be at least 1, got {max_crashes}")
    if timeout is not None and timeout <= 0:
        raise ValueError(f"timeout must be positive, got {timeout}")
    todo = list(units)
    if workers <= 1:
        return _in_process(fn, todo, progress)
    return _pooled(fn, todo, min(workers, len(todo)), timeout, max_crashes, start_method, progress)


def _in_process(fn: Callable[..., R], units: list[U], progress: OnProgress | None
                ) -> Iterator[tuple[U, R | Failure, float]]:
    for index, unit in enumerate(units):
        start = time.perf_counter()
        try:
            outcome: R | Failure = fn(unit) if progress is None else fn(unit, Throttled(
                lambda done, total, i=index: progress(i, done, total)))
        except Exception as exc:
            outcome = Failure("error", worker.describe(exc), 1)
        yield unit, outcome, time.perf_counter() - start


def _pooled(fn: Callable[..., R], units: list[U], size: int, timeout: float | None, max_crashes: int,
            start_method: str, progress: OnProgress | None) -> Iterator[tuple[U, R | Failure, float]]:
    if not units:
        return
    pool = _Pool(fn, size, timeout, max_crashes, _context(start_method, fn), progress)
    try:
        yield from pool.results(units)
    finally:
        pool.close()


def _context(start_method: str, fn: Callable) -> Any:
    ctx = multiprocessing.get_context(start_method)
    if start_method == "forkserver":
        # Only read when the server starts (the first pool of this process).
        guard = [SERVER_GUARD] if USE_PDEATHSIG and threading.current_thread() is threading.main_thread() else []
        ctx.set_forkserver_preload([*guard, *PRELOAD, getattr(fn, "__module__", None) or PRELOAD[0]])
    return ctx


@dataclass
class _Job:
    index: int
    unit: Any
    attempts: int = 0
    started: float = 0.0  # perf_counter() when sent to a worker


@dataclass
class _Worker:
    process: Any  # a multiprocessing Process of the pool's context
    conn: Connection
    ready: bool = False
    job: _Job | None = None


class _Pool:
    def __init__(self, fn: Callable, size: int, timeout: float | None, max_crashes: int, ctx: Any,
                 progress: OnProgress | None = None) -> None:
        self.fn, self.size, self.timeout, self.max_crashes, self.ctx = fn, size, timeout, max_crashes, ctx
        self.progress = progress
        self.lifeline_r, self.lifeline_w = ctx.Pipe(duplex=False)
        self.workers: list[_Worker] = []
        self.start_failures = 0
        self.notes: set[str] = set()  # the lines said: two workers may prepare an object the first time
        _live.add(self)

    # -- the loop ---------------------------------------------------------------
    def results(self, units: list) -> Iterator[tuple[Any, Any, float]]:
        todo = deque(_Job(i, u) for i, u in enumerate(units))
        while todo or self._busy():
            done = self._fill(todo)
            ready = wait([w.conn for w in self.workers] + [w.process.sentinel for w in self.workers],
                         self._wait_time())
            for w in list(self.workers):
                if w.conn in ready or w.process.sentinel in ready:
                    done += self._service(w, todo)
            done += self._expire()
            done += self._fill(todo)  # workers go on while the consumer takes the results
            yield from done

    def _busy(self) -> int:
        return sum(w.job is not None for w in self.workers)

    def _fill(self, todo: deque) -> list[tuple[Any, Any, float]]:
        """Start workers for pending units, give each idle one a unit, stop those left idle: a worker waiting for
        the run's end held its last unit's memory to it (the antipodal pairs of an object: ~120 MB at 1,000,000
        points). A unit sent back to the queue (its worker died) starts a worker again."""
        while len(self.workers) < min(self.size, len(todo) + self._busy()):
            self._start()
        if not todo:
            self._stop([w for w in self.workers if w.ready and w.job is None])
        done = []
        for w in self.workers:
            if not todo:
                break
            if w.ready and w.job is None:
                job = todo.popleft()
                try:
                    w.conn.send((job.index, job.unit))
                except OSError:  # died while idle: not the unit's fault
                    todo.appendleft(job)
                    continue  # its sentinel is ready; _service retires it
                except Exception as exc:  # the unit does not pickle
                    done.append((job.unit, Failure("error", f"unit could not be sent to a worker: "
                                                            f"{worker.describe(exc)}", 0), 0.0))
                    continue
                job.attempts += 1
                job.started = time.perf_counter()
                w.job = job
        return done

    def _wait_time(self) -> float | None:
        if self.timeout is None or not self._busy():
            return None
        first = min(w.job.started for w in self.workers if w.job)
        return max(0.0, first + self.timeout - time.perf_counter())

    def _service(self, w: _Worker, todo: deque) -> list[tuple[Any, Any, float]]:
        """Take ``w``'s message, or deal with its death. Only the worker holds
        the other end of its pipe, so once it is dead the pipe reads what it
        sent before dying, then EOF."""
        try:
            message = w.conn.recv()
        except (EOFError, OSError):
            return self._died(w, todo)
        if message[0] == "ready":
            w.ready, self.start_failures = True, 0
            return []
        if message[0] == "note":
            prepare.said([message[1]], self.notes)
            return []
        if message[0] == "progress":
            _, index, done, total = message
            if self.progress is not None and w.job is not None and w.job.index == index:
                self.progress(index, done, total)
            return []
        kind, _, payload, seconds = message
        job, w.job = w.job, None
        assert job is not None, "a worker answers only the unit it was sent"
        return [(job.unit, payload if kind == "ok" else Failure("error", payload, job.attempts), seconds)]

    def _died(self, w: _Worker, todo: deque) -> list[tuple[Any, Any, float]]:
        self._retire(w)
        how = _exit_reason(w.process.exitcode)
        if not w.ready:
            self.start_failures += 1
            if self.start_failures >= START_FAILURES:
                raise PoolError(f"worker processes exit before they start ({how}); see the error output above")
        job = w.job
        if job is None:
            log.warning("an idle worker process died (%s); starting another", how)
            return []
        if job.attempts < self.max_crashes:
            log.warning("a worker process died (%s) running unit %d; retrying it", how, job.index)
            todo.appendleft(job)
            return []
        log.warning("unit %d killed %d worker processes (%s); recorded as failed", job.index, job.attempts, how)
        message = (f"worker process died ({how}) while running this unit, {job.attempts} times; "
                   "recorded as failed")
        return [(job.unit, Failure("crash", message, job.attempts), time.perf_counter() - job.started)]

    def _expire(self) -> list[tuple[Any, Any, float]]:
        if self.timeout is None:
            return []
        now, done = time.perf_counter(), []
        for w in list(self.workers):
            if w.job and now - w.job.started >= self.timeout:
                job = w.job
                w.process.kill()
                self._retire(w)
                log.warning("unit %d not finished after %g s; its worker was stopped", job.index, self.timeout)
                done.append((job.unit, Failure("timeout", f"time-out: unit not finished after {self.timeout:g} s",
                                               job.attempts), now - job.started))
        return done

    # -- workers ----------------------------------------------------------------
    def _start(self) -> None:
        here, there = self.ctx.Pipe()
        process = self.ctx.Process(target=worker.main, name="grasp-worker",
                                   args=(self.fn, there, self.lifeline_r, self._pdeathsig(),
                                         self.progress is not None))
        try:
            process.start()
        except (pickle.PicklingError, AttributeError, TypeError) as exc:
            raise PoolError(f"cannot send {getattr(self.fn, '__name__', self.fn)!r} to a worker process "
                            f"(it must be a module-level function): {exc}") from None
        finally:
            there.close()  # else the driver's copy hides the worker's death from recv()
        self.workers.append(_Worker(process, here))

    def _pdeathsig(self) -> bool:
        """PR_SET_PDEATHSIG fires when the *thread* that started the worker
        ends. spawn: the driver thread calling ``start``; a thread other than
        the main one may end before the pool does, so there only the
        lifeline ties workers to the driver. forkserver: the server, which
        outlives the driver as long as any of its children does (each holds
        the write end of the server's "alive" pipe), so on a driver's death
        the lifeline does the work; the signal still covers the server's."""
        if not USE_PDEATHSIG:
            return False
        return self.ctx.get_start_method() == "forkserver" or threading.current_thread() is threading.main_thread()

    def _stop(self, idle: list[_Worker]) -> None:
        """Tell every worker of ``idle`` to exit, then retire them (each killed if it has not exited within
        :data:`STOP_GRACE` of the telling): told one at a time, each after the one before had exited, a run's end
        waited for their exits in turn (up to ``STOP_GRACE`` each)."""
        for w in idle:
            try:
                w.conn.send(None)
            except OSError:  # already dead
                pass
        deadline = time.monotonic() + STOP_GRACE
        for w in idle:
            w.process.join(max(0.0, deadline - time.monotonic()))
            if w.process.is_alive():
                w.process.kill()
            self._retire(w)

    def _retire(self, w: _Worker) -> None:
        w.process.join()
        w.conn.close()
        self.workers.remove(w)

    def close(self) -> None:
        """Stop idle workers, kill busy ones (their units are abandoned)."""
        for w in self.workers:
            try:
                if w.ready and w.job is None:
                    w.conn.send(None)
                else:
                    w.process.kill()
            except OSError:
                pass
        deadline = time.monotonic() + STOP_GRACE
        for w in self.workers:
            w.process.join(max(0.0, deadline - time.monotonic()))
            if w.process.is_alive():
                w.process.kill()
                w.process.join()
            w.conn.close()
        self.workers.clear()
        self.lifeline_w.close()
        self.lifeline_r.close()
        _live.discard(self)


def _exit_reason(code: int | None) -> str:
    if code is not None and code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


# Pools left open at interpreter exit (an iterator never finished nor closed)
# are closed before multiprocessing's own exit handler, registered earlier,
# would wait for their workers forever.
_live: weakref.WeakSet[_Pool] = weakref.WeakSet()


@atexit.register
def _close_live_pools() -> None:
    for pool in list(_live):
        pool.close()
