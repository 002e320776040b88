"""Ray backend of :func:`planner.run.pool.execute`: a private local instance
that dies with its driver, or a cluster this process attaches to, and a
runner with the pool's contract.

``ray.init()`` in the driver (measured with Ray 2.60, bench/RESULTS.md
"Reliability"): when the driver is SIGKILLed, GCS and raylet die at once
(Ray arms PR_SET_PDEATHSIG on them), task workers within 2-3 s, but the
dashboard and runtime-env agents linger about 60 s (they report the
raylet's death to the dead GCS with a 60 s time-out). :func:`local_ray`
instead starts the instance in a launcher process
(:mod:`planner.run.ray_launcher`) that takes all of it down when the driver
ends, however it ends, within a fraction of a second. A driver attached to
a cluster it did not start needs nothing of the kind: the cluster stays up
and kills the driver's running tasks when the driver dies.
"""

from __future__ import annotations

import json
import logging
import os
import re
import secrets
import subprocess
import sys
import tempfile
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

from planner.errors import InputError, PlannerError
from planner.run import worker
from planner.run.failure import MAX_CRASHES, Failure

U = TypeVar("U")
R = TypeVar("R")

#: [s] for the launcher to take the instance down after the driver is done.
STOP_WAIT = 30.0


def _ray() -> Any:
    try:
        import ray
    except ImportError:
        raise InputError("--ray needs Ray: pip install -e '.[ray]'") from None
    return ray


def on_ray(fn: Callable[[U], R], units: Iterable[U], workers: int, target: str, *, timeout: float | None = None
           ) -> Iterator[tuple[U, R | Failure, float]]:
    """:func:`run_ray` on a private local instance with ``workers`` CPUs
    (``target == "local"``), on the cluster at address ``target``, or on the
    Ray this process is already connected to (API users)."""
    ray = _ray()
    if ray.is_initialized():
        yield from run_ray(fn, units, _cluster_cpus(ray, workers), timeout=timeout)
    elif target == "local":
        with local_ray(workers):
            yield from run_ray(fn, units, max(1, workers), timeout=timeout)
    else:
        _attach(ray, target)
        try:
            yield from run_ray(fn, units, _cluster_cpus(ray, workers), timeout=timeout)
        finally:
            ray.shutdown()


def _attach(ray: Any, target: str) -> None:
    """Connect to the cluster at ``target``; Ray's refusals (a ``ValueError``
    for a ray:// address without Ray Client or an address it cannot parse, a
    ``ConnectionError`` for no cluster there) as input errors that say what
    to do. Ray's own wording names its ``--address`` flag and ``RAY_ADDRESS``,
    not ours."""
    local = "or give --ray without an address for a private local Ray instance with --workers CPUs"
    _reachable(target, local)
    try:
        ray.init(address=target, log_to_driver=False, logging_level=logging.WARNING)
    except ValueError as exc:
        if "ray[client]" in str(exc):
            raise InputError(f"--ray {target}: a ray:// address needs Ray Client: pip install 'ray[client]' "
                             f"(or pip install -e '.[ray]'), {local}") from None
        raise InputError(f"--ray {target}: {_sentence(exc)}; give ray://HOST:10001, HOST:6379 or auto, "
                         f"{local}") from None
    except ConnectionError as exc:
        raise InputError(f"--ray {target}: could not connect to a Ray cluster ({_sentence(exc)}); start one "
                         f"('ray start --head') and give its address, {local}") from None


#: [s] how long an address's port may take to answer before --ray gives up on it.
PROBE_TIMEOUT = 5.0


def _reachable(target: str, local: str) -> None:
    """Refuse a ``HOST:PORT`` or ``ray://HOST:PORT`` address nothing answers
    at (a TCP connection within ``PROBE_TIMEOUT``): ``ray.init`` would wait
    in its own reconnect loop for minutes. Other forms (``auto``) are left
    to Ray."""
    import socket

    found = re.fullmatch(r"(?:ray://)?\[?([^\[\]/]+?)\]?:(\d+)/?", target.strip())
    if found is None:
        return
    host, port = found.group(1), int(found.group(2))
    try:
        with socket.create_connection((host, port), timeout=PROBE_TIMEOUT):
            pass
    except OSError as exc:
        reason = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or type(exc).__name__).lower()
        raise InputError(f"--ray {target}: nothing answers at {host}:{port} ({reason}); start a cluster there "
                         f"('ray start --head') and give its address, {local}") from None


def _sentence(exc: Exception) -> str:
    """The first sentence of ``exc``'s message, on one line."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text.split(". ")[0].rstrip(".")


def _cluster_cpus(ray: Any, default: int) -> int:
    return max(1, int(ray.cluster_resources().get("CPU", default)))


@contextmanager
def local_ray(num_cpus: int) -> Iterator[dict]:
    """Start a private local Ray instance with ``num_cpus`` CPUs and connect
    this process to it; yields ``{"address", "pid"}`` (GCS address, launcher
    pid). On exit, or when this process dies, every process of the instance
    is killed."""
    ray = _ray()
    package_root = str(Path(__file__).resolve().parents[2])
    # Ray >= 2.5x turns token authentication on for new local instances and
    # keeps the token in ~/.ray; a token of our own, given to the launcher and
    # to this driver only, keeps instances of concurrent runs apart.
    auth = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32)}
    env = {**os.environ, **auth,
           "PYTHONPATH": os.pathsep.join(filter(None, [package_root, os.environ.get("PYTHONPATH")]))}
    with tempfile.TemporaryFile() as errors:
        launcher = subprocess.Popen([sys.executable, "-m", "planner.run.ray_launcher", str(num_cpus)], env=env,
                                    stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=errors)
        try:
            line = launcher.stdout.readline()  # type: ignore[union-attr]
            launcher.stdout.close()  # type: ignore[union-attr]
            if not line:
                launcher.wait()
                errors.seek(0)
                tail = errors.read().decode(errors="replace").strip().splitlines()[-1:] or ["no output"]
                raise PlannerError(f"could not start a local Ray instance: {tail[0]}")
            info = json.loads(line)
            saved = {k: os.environ.get(k) for k in auth}
            os.environ.update(auth)
            _reload_ray_config(ray)
            try:
                ray.init(address=info["address"], log_to_driver=False, logging_level=logging.WARNING)
                yield info
            finally:
                ray.shutdown()
                for k, v in saved.items():
                    if v is None:
                        os.environ.pop(k, None)
                    else:
                        os.environ[k] = v
                _reload_ray_config(ray)
        finally:
            launcher.stdin.close()  # type: ignore[union-attr]  # EOF: the launcher takes the instance down
            try:
                launcher.wait(STOP_WAIT)
            except subprocess.TimeoutExpired:
                launcher.kill()
                launcher.wait()


def _reload_ray_config(ray: Any) -> None:
    """Ray reads RAY_AUTH_MODE into its C++ config when imported; refresh it
    as ``ray.init`` itself does when it turns token auth on."""
    try:
        ray._raylet.Config.initialize("")
    except AttributeError:  # older Ray: no token auth, nothing cached
        pass


def run_ray(fn: Callable[[U], R], units: Iterable[U], in_flight: int, *, timeout: float | None = None,
            max_crashes: int = MAX_CRASHES) -> Iterator[tuple[U, R | Failure, float]]:
    """:func:`planner.run.pool.run` on the connected Ray cluster: at most
    ``in_flight`` tasks at once (so a task starts about when it is sent,
    which the time-out counts from); a task whose worker dies is retried by
    Ray, ``max_crashes`` attempts in all."""
    ray = _ray()
    from ray.exceptions import GetTimeoutError, RayTaskError, TaskCancelledError

    remote = ray.remote(max_retries=max_crashes - 1, retry_exceptions=False)(fn)
    todo: deque = deque(units)
    flight: dict[Any, tuple[Any, float]] = {}
    while todo or flight:
        while todo and len(flight) < max(1, in_flight):
            unit = todo.popleft()
            flight[remote.remote(unit)] = (unit, time.perf_counter())
        wait = None if timeout is None else max(0.0, min(s for _, s in flight.values()) + timeout
                                                - time.perf_counter())
        done, _ = ray.wait(list(flight), num_returns=1, timeout=wait)
        for ref in done:
            unit, start = flight.pop(ref)
            outcome: Any
            try:
                outcome = ray.get(ref)
            except RayTaskError as exc:  # fn raised
                outcome = Failure("error", worker.describe(exc.cause) if exc.cause else str(exc), 1)
            except (TaskCancelledError, GetTimeoutError) as exc:
                outcome = Failure("error", worker.describe(exc), 1)
            except ray.exceptions.RayError as exc:  # the worker (or its node) died every time
                outcome = Failure("crash", f"Ray worker died while running this unit, {max_crashes} times; "
                                           f"recorded as failed ({type(exc).__name__})", max_crashes)
            yield unit, outcome, time.perf_counter() - start
        if timeout is not None:
            now = time.perf_counter()
            for ref, (unit, start) in list(flight.items()):
                if now - start >= timeout:
                    ray.cancel(ref, force=True)
                    del flight[ref]
                    yield unit, Failure("timeout", f"time-out: unit not finished after {timeout:g} s", 1), now - start
