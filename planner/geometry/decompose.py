"""Convex decomposition: the CoACD adapter, with an on-disk cache.

A moving (dynamic) object in a trial (PyBullet's or MuJoCo's) collides as a
set of convex parts. The parts are cached by the mesh's content hash and the
CoACD settings, as an ``.npz`` of plain arrays (no pickle), so each object is
decomposed once per machine whatever the number of runs and workers (CoACD
takes 0.2-153 s of CPU per object here, median 11 s on the dev set's meshes).

Meshes whose connected bodies are each convex already (primitives, the
VHACD-made duck, teddy and random objects of pybullet_data) skip CoACD: their
bodies are the parts.

CoACD has no time limit of its own, so it runs in a child process that is
stopped after ``GRASP_COACD_TIME_LIMIT`` seconds of its own CPU
(:data:`TIME_LIMIT` unless set; ``0``: none; where POSIX resource limits are
missing, Windows, seconds of wall clock): a mesh it cannot finish fails with
a one-line reason instead of holding a batch's worker for hours, and the
failure is recorded beside the cache, so the object's other trials fail at
once rather than each running CoACD again (a larger limit tries again). CPU,
not wall clock: whether a mesh finishes must not depend on what else the
machine runs (a loaded host once failed a bowl that takes 153 s of CPU). A
child that has not finished after :data:`WALL_FACTOR` times that (and its
start) of wall clock is stopped too (a starved or stuck child), and that is not recorded.
"""

from __future__ import annotations

import io
import json
import logging
import math
import os
import signal
import subprocess
import sys
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import trimesh

from planner import assets
from planner.errors import MeshError

log = logging.getLogger(__name__)

#: A body is convex when its volume is within this fraction of its hull's.
CONVEX_TOL = 0.02
#: [s] CoACD's time limit per mesh unless ``GRASP_COACD_TIME_LIMIT`` says otherwise (with these settings the
#: slowest of the dev set's 30 tuning meshes, a bowl, took 153 s of CPU; their median 10.8 s).
TIME_LIMIT = 900.0
TIME_LIMIT_ENV = "GRASP_COACD_TIME_LIMIT"
#: The child is stopped after this many times (its CPU limit + :data:`STARTUP`) of wall clock (not recorded:
#: the load's doing).
WALL_FACTOR = 10.0
#: [s] of CPU the child takes to start (its imports, ~1 s here), which its limit does not count.
STARTUP = 5.0


@dataclass(frozen=True)
class CoacdSettings:
    """CoACD's settings (its own names; see ``coacd.run_coacd``).

    ``threshold``: the concavity each part may keep; ``max_convex_hull``: at
    most this many parts (CoACD merges the finest cut back to it, which on a
    thin-walled bowl or mug is what sets how far the parts bulge past the
    surface); ``mcts_*``: the tree search that chooses each cut, most of
    CoACD's time. Chosen on the ACRONYM dev set's 30 tuning objects
    (``bench/decomposition.py``, bench/RESULTS.md, 2026-12-05): against
    CoACD's own search (150 iterations, 20 nodes, depth 3) and 24 parts,
    these cost 573 s of CPU instead of 1,601 (the slowest object 153 s
    instead of 401), the parts reach 2.05 mm outside the surface at the 95th
    percentile on average instead of 2.76 (5.7 mm at worst instead of 10.0),
    and the MuJoCo trial of 4,600 poses gave the same verdict on 99.6% of
    them, agreeing with FleX as often (0.789 against 0.791) at the same CPU
    per trial.
    """

    threshold: float = 0.04  # concavity threshold (CoACD's default is 0.05)
    max_convex_hull: int = 48
    resolution: int = 2000
    seed: int = 0
    mcts_iterations: int = 50
    mcts_nodes: int = 10
    mcts_max_depth: int = 2
    preprocess_resolution: int = 50


#: The settings :func:`convex_parts` decomposes with unless told.
DEFAULT_SETTINGS = CoacdSettings()


@dataclass(frozen=True)
class Parts:
    """Convex parts of one object, object frame [m]."""

    vertices: tuple[np.ndarray, ...]  # each (k_i, 3)
    faces: tuple[np.ndarray, ...]  # each (f_i, 3)
    method: str  # "bodies" (already convex) or "coacd"

    def __len__(self) -> int:
        return len(self.vertices)


def convex_parts(mesh: trimesh.Trimesh, mesh_hash: str, settings: CoacdSettings | None = None,
                 limit: float | None = None) -> Parts:
    """The object's convex parts: its bodies if each is convex, else CoACD's
    (cached), run within ``limit`` seconds of CPU (None: :func:`time_limit`;
    0: no limit). A mesh CoACD did not finish within a limit at least this large
    before is refused at once (:class:`~planner.errors.MeshError`)."""
    settings = settings or DEFAULT_SETTINGS
    parts = ready_parts(mesh, mesh_hash, settings)
    if parts is None:
        limit = time_limit() if limit is None else limit
        path = _cache_path(mesh_hash, settings)
        refuse_known_timeout(mesh_hash, settings, limit)
        parts = _run_limited(mesh, settings, limit, path) if limit else _run_coacd(mesh, settings)
        _write(path, parts)
    return parts


def time_limit() -> float:
    """[s] CoACD's time limit: ``$GRASP_COACD_TIME_LIMIT`` (0: none), else :data:`TIME_LIMIT`."""
    text = os.environ.get(TIME_LIMIT_ENV, "").strip()
    if not text:
        return TIME_LIMIT
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value >= 0 or value == float("inf"):
        raise MeshError(f"{TIME_LIMIT_ENV}={text!r}: give seconds (0 for no limit)")
    return value


def ready_parts(mesh: trimesh.Trimesh, mesh_hash: str, settings: CoacdSettings | None = None) -> Parts | None:
    """The parts without running CoACD (the bodies when each is convex, else
    the cached decomposition), None when :func:`convex_parts` would run it."""
    bodies = mesh.split(only_watertight=False) if len(mesh.faces) else []
    if bodies and all(_is_convex(b) for b in bodies):
        hulls = [b.convex_hull for b in bodies]
        return Parts(tuple(h.vertices for h in hulls), tuple(h.faces for h in hulls), "bodies")
    path = _cache_path(mesh_hash, settings or DEFAULT_SETTINGS)
    if path.is_file():
        try:
            return _read(path)
        except (OSError, ValueError, KeyError):
            path.unlink(missing_ok=True)
    return None


def _cache_path(mesh_hash: str, settings: CoacdSettings) -> Path:
    key = assets.sha256_bytes(json.dumps([mesh_hash, settings.__dict__], sort_keys=True).encode())[:24]
    return assets.cache_dir("coacd") / f"{key}.npz"


def _is_convex(body: trimesh.Trimesh) -> bool:
    try:
        hull = body.convex_hull.volume
    except Exception:  # qhull on a degenerate body
        return False
    return hull > 0 and abs(abs(body.volume) - hull) <= CONVEX_TOL * hull


def _run_coacd(mesh: trimesh.Trimesh, settings: CoacdSettings) -> Parts:
    import coacd

    coacd.set_log_level("error")
    log.info("running CoACD (%d faces); cached afterwards", len(mesh.faces))
    try:
        result = coacd.run_coacd(coacd.Mesh(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, int)),
                                 **asdict(settings))
    except Exception as exc:
        raise MeshError(f"CoACD failed on this mesh: {exc}") from exc
    if not result:
        raise MeshError("CoACD returned no convex parts")
    return Parts(tuple(np.asarray(v, float) for v, _ in result), tuple(np.asarray(f, int) for _, f in result),
                 "coacd")


def _timeout_path(path: Path) -> Path:
    return path.with_suffix(".timeout.json")


def refuse_known_timeout(mesh_hash: str, settings: CoacdSettings | None = None, limit: float | None = None) -> None:
    """Raise the recorded reason (:class:`~planner.errors.MeshError`) if CoACD ran out of a limit >= ``limit``
    (None: :func:`time_limit`; 0: none) on this mesh with these settings before."""
    limit = time_limit() if limit is None else limit
    try:
        known = json.loads(_timeout_path(_cache_path(mesh_hash, settings or DEFAULT_SETTINGS)).read_text())
        tried, reason, clock = float(known["limit"]), str(known["reason"]), known.get("clock", "wall")
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return
    if clock != _CLOCK:  # recorded under the other clock (before the limit counted CPU): tried again
        return
    if limit and tried >= limit:
        raise MeshError(f"{reason} (recorded earlier; set {TIME_LIMIT_ENV} above {tried:g} to try again)")


def _run_limited(mesh: trimesh.Trimesh, settings: CoacdSettings, limit: float, path: Path) -> Parts:
    """:func:`_run_coacd` in a child process (``python -m planner.geometry.decompose``) stopped after ``limit``
    seconds of its CPU (:func:`_limit_cpu`); a timeout is recorded beside ``path`` (the cache file the parts would
    have gone to). Where the child cannot limit its CPU, the wall clock's ``limit`` stops it (recorded too)."""
    cpu = _CLOCK == "cpu" and _limit_cpu(None) is not None
    with tempfile.TemporaryDirectory(prefix="grasp-coacd-") as folder:
        given, made = Path(folder) / "mesh.npz", Path(folder) / "parts.npz"
        np.savez(given, vertices=np.asarray(mesh.vertices, float), faces=np.asarray(mesh.faces, np.int64),
                 settings=np.array(json.dumps(asdict(settings))))
        log.info("running CoACD (%d faces, at most %g s of CPU); cached afterwards", len(mesh.faces), limit)
        wall = (limit + STARTUP) * WALL_FACTOR if cpu else limit
        reason = (f"CoACD did not finish the convex decomposition of this mesh ({len(mesh.faces)} faces) within "
                  f"{limit:g} s" + (" of CPU" if cpu else ""))
        try:
            done = subprocess.run([sys.executable, "-m", __name__, str(given), str(made), repr(limit)],
                                  capture_output=True, text=True, timeout=wall)
        except subprocess.TimeoutExpired:
            if cpu:  # starved or stuck: the load's doing, not the mesh's; not recorded, the next run tries again
                raise MeshError(f"CoACD's child did not finish within {wall:g} s of wall clock ({limit:g} s of CPU "
                                f"allowed): the machine is too busy, run again") from None
            _record(path, limit, reason)
            raise MeshError(f"{reason}: simplify the mesh, or set {TIME_LIMIT_ENV} (seconds, 0: none)") from None
        if cpu and done.returncode == -_SIGXCPU:
            _record(path, limit, reason)
            raise MeshError(f"{reason}: simplify the mesh, or set {TIME_LIMIT_ENV} (seconds, 0: none)")
        if done.returncode or not made.is_file():
            last = (done.stderr.strip().splitlines() or [f"exit {done.returncode}"])[-1]
            raise MeshError(last if last.startswith(("CoACD failed", "CoACD returned")) else f"CoACD failed on this "
                            f"mesh: {last}")
        return _read(made)


_SIGXCPU = int(getattr(signal, "SIGXCPU", 24))  # absent on Windows, where the wall clock limits
#: What this machine's limits count: "cpu", or "wall" where there are no resource limits.
_CLOCK = "cpu" if hasattr(signal, "SIGXCPU") else "wall"


def _record(path: Path, limit: float, reason: str) -> None:
    """Record beside ``path`` that CoACD ran out of ``limit`` seconds (of :data:`_CLOCK`)."""
    assets.atomic_write(_timeout_path(path), json.dumps({"limit": limit, "reason": reason, "clock": _CLOCK}).encode())


def _limit_cpu(seconds: float | None) -> float | None:
    """Limit this process to ``seconds`` more of CPU (POSIX ``RLIMIT_CPU``: the kernel sends SIGXCPU, whose
    default action ends the process; no core file). Returns the limit set [s of the process's CPU], None where
    there are no resource limits (Windows). ``seconds`` None: only whether it can."""
    try:
        import resource
    except ImportError:
        return None
    if seconds is None:
        return 0.0
    used = resource.getrusage(resource.RUSAGE_SELF)
    at = math.ceil(used.ru_utime + used.ru_stime + seconds)
    hard = resource.getrlimit(resource.RLIMIT_CPU)[1]
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    top = at + 2 if hard == resource.RLIM_INFINITY else min(at + 2, hard)
    resource.setrlimit(resource.RLIMIT_CPU, (min(at, top), top))
    return float(at)


def _child(given: str, made: str, limit: str = "0") -> int:
    """The child of :func:`_run_limited`: CoACD on the mesh in ``given`` within ``limit`` seconds of CPU (0:
    none), its parts written to ``made``. It stops when its parent is gone (a worker killed by a unit's timeout
    or kill -9), not running on orphaned."""
    import threading
    import time

    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()
    if float(limit) > 0:
        _limit_cpu(float(limit))
    with np.load(given, allow_pickle=False) as data:
        mesh = trimesh.Trimesh(data["vertices"], data["faces"], process=False)
        settings = CoacdSettings(**json.loads(str(data["settings"])))
    try:
        parts = _run_coacd(mesh, settings)
    except MeshError as exc:
        print(exc, file=sys.stderr)
        return 1
    _write(Path(made), parts)
    return 0


def _write(path, parts: Parts) -> None:  # type: ignore[no-untyped-def]
    arrays = {"method": np.array(parts.method)}
    for i, (v, f) in enumerate(zip(parts.vertices, parts.faces)):
        arrays[f"v{i}"], arrays[f"f{i}"] = v, f
    buffer = io.BytesIO()
    np.savez(buffer, count=np.array(len(parts)), **arrays)
    assets.atomic_write(path, buffer.getvalue())


def _read(path) -> Parts:  # type: ignore[no-untyped-def]
    with np.load(path, allow_pickle=False) as data:
        n = int(data["count"])
        return Parts(tuple(data[f"v{i}"] for i in range(n)), tuple(data[f"f{i}"] for i in range(n)),
                     str(data["method"]))


if __name__ == "__main__":
    sys.exit(_child(*sys.argv[1:4]))
