"""Running units of work: in this process, a local process pool, or Ray.

Every backend yields ``(UnitResult, seconds)`` back to the caller -- the one
database writer -- as units finish. A unit's result depends only on the unit,
never on the backend or the worker count.

Local pool: at most ``workers`` units are in flight. If a worker process
dies (e.g. a segfault inside the simulator) the pool is rebuilt and the units
that were in flight are retried; a unit in flight during two crashes is
reported as failed, so one bad object cannot stop a batch.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool

from planner.errors import InputError
from planner.plan.unit import UnitResult, UnitSpec, run_unit

log = logging.getLogger(__name__)

MAX_CRASHES = 2


def execute(units: list[UnitSpec], workers: int = 1, ray_address: str | None = None,
            use_ray: bool = False) -> Iterator[tuple[UnitResult, float]]:
    if use_ray:
        yield from _ray(units, ray_address, workers)
    elif workers <= 1 or len(units) <= 1:
        for unit in units:
            t = time.perf_counter()
            yield run_unit(unit), time.perf_counter() - t
    else:
        yield from _pool(units, workers)


def _pool(units: list[UnitSpec], workers: int) -> Iterator[tuple[UnitResult, float]]:
    pending = list(reversed(units))
    crashes: dict[int, int] = {}
    while pending:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            flight: dict[Future, tuple[int, UnitSpec, float]] = {}
            broken = False
            while (pending or flight) and not broken:
                while pending and len(flight) < workers:
                    unit = pending.pop()
                    flight[pool.submit(run_unit, unit)] = (id(unit), unit, time.perf_counter())
                done, _ = wait(flight, return_when=FIRST_COMPLETED)
                for fut in done:
                    key, unit, start = flight.pop(fut)
                    try:
                        yield fut.result(), time.perf_counter() - start
                    except BrokenProcessPool:
                        broken = True
                        flight[fut] = (key, unit, start)
            if broken:
                for key, unit, start in flight.values():
                    crashes[key] = crashes.get(key, 0) + 1
                    if crashes[key] >= MAX_CRASHES:
                        failed = UnitResult(unit, error="worker process crashed (simulator segfault or killed)")
                        yield failed, time.perf_counter() - start
                    else:
                        pending.append(unit)
                log.warning("a worker process died; restarting the pool (%d units left)", len(pending))


def _ray(units: list[UnitSpec], address: str | None, workers: int) -> Iterator[tuple[UnitResult, float]]:
    try:
        import ray
    except ImportError:
        raise InputError("--ray needs Ray: pip install -e '.[ray]'") from None
    started_here = not ray.is_initialized()
    if started_here:
        kwargs = {"address": address} if address else {"num_cpus": workers, "include_dashboard": False}
        ray.init(log_to_driver=False, **kwargs)
    try:
        remote = ray.remote(max_retries=MAX_CRASHES - 1)(run_unit)
        refs = {remote.remote(unit): (unit, time.perf_counter()) for unit in units}
        while refs:
            done, _ = ray.wait(list(refs), num_returns=1)
            for ref in done:
                unit, start = refs.pop(ref)
                try:
                    result = ray.get(ref)
                except Exception as exc:  # a worker died twice: record, keep going
                    result = UnitResult(unit, error=f"Ray worker failed: {type(exc).__name__}: {exc}")
                yield result, time.perf_counter() - start
    finally:
        if started_here:
            ray.shutdown()
