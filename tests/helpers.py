"""Shared test builders and the one tolerance helper."""

from __future__ import annotations

import shutil
import sqlite3
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from planner.record.grasp import Grasp

#: Geometric tolerance of the simulator-based stages [m]: PyBullet's contact
#: margins are corrected to about this.
SIM_TOL = 0.0015
#: Pure floating-point comparisons.
NUM_TOL = 1e-9

#: A small sweep for command-line runs: one preshape, few rays, one placement.
FAST = ["--approaches", "6", "--rolls", "2", "--preshapes", "wide", "--workers", "1", "--reach-placements", "1"]
#: The batch every resumption test compares against: two objects, units of two rays.
REFERENCE_OBJECTS = ("box", "sphere")
REFERENCE_ARGS = ("--seed", "11", "--approaches", "8", "--rolls", "2", "--preshapes", "wide", "--chunk", "4",
                  "--reach-placements", "1", "--workers", "1", "--quiet")


def assert_close(actual: object, expected: object, tol: float = NUM_TOL) -> None:
    a, e = np.asarray(actual, float), np.asarray(expected, float)
    assert a.shape == e.shape, f"shape {a.shape} != {e.shape}"
    assert np.allclose(a, e, atol=tol, rtol=0), f"{a} != {e} (tol {tol})"


def brute_distances(triangles: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(n,) [m] the distance of each of ``points`` (n, 3) to the nearest of
    ``triangles`` (f, 3, 3), every pair tried the plain way: the foot of the
    perpendicular where it falls inside a triangle, else the nearest point
    of its three edges (trimesh's ``closest_point`` misses on slivers:
    0.1 mm seen on a capsule's)."""
    out = np.empty(len(points))
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    normal = np.cross(b - a, c - a)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    for i, p in enumerate(points):
        foot = p - np.einsum("fk,fk->f", p - a, normal)[:, None] * normal
        inside = np.ones(len(triangles), bool)
        for u, v in ((a, b), (b, c), (c, a)):
            inside &= np.einsum("fk,fk->f", np.cross(v - u, foot - u), normal) >= 0
        best = np.where(inside, np.linalg.norm(p - foot, axis=1), np.inf)
        for u, v in ((a, b), (b, c), (c, a)):
            t = np.clip(np.einsum("fk,fk->f", p - u, v - u) / np.einsum("fk,fk->f", v - u, v - u), 0.0, 1.0)
            best = np.minimum(best, np.linalg.norm(p - (u + t[:, None] * (v - u)), axis=1))
        out[i] = best.min()
    return out


def grasp(*args: str) -> tuple[int, str, str]:
    """Run the ``grasp`` command in-process: (exit code, stdout, stderr)."""
    from planner.cli import main

    result = CliRunner().invoke(main, list(args))
    return result.exit_code, result.stdout, result.stderr


def one_line_error(code: int, err: str, expected_code: int, *needles: str) -> None:
    """The error contract: that exit code, one line on stderr, no traceback."""
    assert code == expected_code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err


def content(db: Path) -> list[tuple]:
    """Everything about the grasps that must not depend on workers, backend or interruptions."""
    with sqlite3.connect(db) as conn:
        return conn.execute(
            "SELECT object, hand, preshape, candidate, pose, closed_joints, contacts, epsilon, volume, force_closure,"
            " reachability, score, rank FROM grasps ORDER BY object, hand, candidate").fetchall()


def made_up(candidate: int, epsilon: float, fc: bool = True, reach: float | None = None) -> Grasp:
    """A grasp of an object "thing" as the planner would hand it over (no simulator needed)."""
    from planner.record.contacts import HandContacts
    from planner.record.grasp import Grasp

    pose = np.eye(4)
    pose[:3, 3] = [0.01 * candidate, 0.0, 0.1]
    contacts = HandContacts(np.array([[0.0, 0.02, 0.0], [0.0, -0.02, 0.0]]),
                            np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]]), ("left", "right"))
    return Grasp(object="thing", hand="panda", preshape="wide", candidate=candidate, seed=5,
                 approach_point=np.array([0.0, 0.0, 0.04]), approach_dir=np.array([0.0, 0.0, -1.0]), roll=0.5,
                 standoff=0.01, pose=pose, open_joints={"j": 0.04}, closed_joints={"j": 0.02}, width=0.04,
                 contacts=contacts, epsilon=epsilon, volume=epsilon / 10, force_closure=fc, reachability=reach)


def hand_copy(tmp_path: Path) -> Path:
    """A copy of the Panda's hand folder to break on purpose."""
    from planner.specs.hands import hands_dir

    folder = tmp_path / "panda"
    shutil.copytree(hands_dir() / "panda", folder)
    return folder


def refused_hand_toml(tmp_path: Path, edit: Callable[[str], str], message: str) -> None:
    """The Panda's folder copied, its hand.toml's text given to ``edit``: loading it must fail with a one-line
    ConfigError matching ``message`` and naming hand.toml."""
    import pytest

    from planner.errors import ConfigError
    from planner.specs.hands import load_folder

    folder = hand_copy(tmp_path)
    toml = folder / "hand.toml"
    toml.write_text(edit(toml.read_text()))
    with pytest.raises(ConfigError, match=message) as err:
        load_folder(folder)
    assert "hand.toml" in str(err.value) and "\n" not in str(err.value)


def damaged(db: Path, out: Path) -> Path:
    """A copy of ``db`` whose grasps table and its indexes are overwritten
    with garbage (their root pages): it opens, its ``meta`` and ``objects``
    read, every read of grasps fails."""
    shutil.copy(db, out)
    with sqlite3.connect(out) as conn:
        size = conn.execute("PRAGMA page_size").fetchone()[0]
        roots = [r for (r,) in conn.execute("SELECT rootpage FROM sqlite_master WHERE tbl_name = 'grasps'")]
    conn.close()
    with out.open("r+b") as fh:
        for root in roots:
            fh.seek((root - 1) * size)
            fh.write(b"\xff" * size)
    return out


def counting_queries(m: object, method: str) -> Counter:
    """Counts every call of ``planner.sim.Sim.<method>`` (``closest``, ``min_distance``: ``(sim, a, b, distance,
    link)``) by the body asked, ``mesh`` (an object's exact mesh) or ``hulls`` (anything else), patched through the
    monkeypatch context ``m`` for as long as it lasts."""
    from planner.sim import Sim
    asked: Counter = Counter()
    query = getattr(Sim, method)

    def counted(sim: Sim, a: int, b: int, distance: float, link=None):  # type: ignore[no-untyped-def]
        asked["mesh" if b in sim.meshes else "hulls"] += 1
        return query(sim, a, b, distance, link)

    m.setattr(Sim, method, counted)  # type: ignore[attr-defined]
    return asked
