"""pybullet_data's own object URDFs as objects (issue 24, item 1): each through ``grasp generate FILE --hand panda
--approaches 32`` into a fresh database, in a child process, wall-clocked.

    python bench/urdf_objects.py [--out bench/urdf_objects.json] [FILE ...]

Per file: loaded or refused (the error's line), the mass and friction stored beside what the URDF states (its
``<inertial>`` masses summed, its ``<lateral_friction>``; a value it does not state is the default), the grasps
and force-closure grasps stored, the wall time of the command; and where the planner puts the object against where
PyBullet does: the centre of the prepared mesh's bounding box against the centre of the axis-aligned box PyBullet
gives the URDF's collision shapes loaded at the origin, and the extents of both (PyBullet's collision margin widens
its box on every side alike: 4 mm a side for a mesh, 1 mm for a turned box, none for an axis-aligned box or a
sphere; a mesh is its convex hull there, whose box is the mesh's).
Files are relative to ``pybullet_data`` (located at run time, never copied).
"""

from __future__ import annotations

import argparse
import json
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: Files that look like objects: meshes, boxes, spheres, several collision elements, a fixed joint to a dummy link
#: (xarm's), mass 0 (PyBullet's fixed bodies), a shape the planner does not make (a .cdf).
FILES = ("duck_vhacd.urdf", "cube_small.urdf", "sphere_small.urdf", "lego/lego.urdf", "random_urdfs/000/000.urdf",
         "teddy_vhacd.urdf", "soccerball.urdf", "jenga/jenga.urdf", "tray/traybox.urdf", "domino/domino.urdf",
         "block.urdf", "objects/mug.urdf", "xarm/link6.urdf", "toys/concave_box.urdf", "sphere8cube.urdf")
COMMAND = ("--hand", "panda", "--approaches", "32")


def pybullet_box(urdf: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """The centre and the extents of the box PyBullet gives the URDF's collision shapes at the origin [m]; None
    without any."""
    import pybullet as pb

    client = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(urdf), useFixedBase=True, physicsClientId=client)
        boxes = [pb.getAABB(body, link, physicsClientId=client) for link in range(-1, pb.getNumJoints(body, client))
                 if pb.getCollisionShapeData(body, link, physicsClientId=client)]
    except pb.error:
        return None
    finally:
        pb.disconnect(client)
    if not boxes:
        return None
    lo, hi = np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)
    return (lo + hi) / 2, hi - lo


def stated(urdf: Path) -> dict[str, float]:
    from planner.specs.urdf_objects import read_urdf_object

    try:
        return read_urdf_object(urdf).stated()
    except Exception as exc:  # noqa: BLE001 - a refused file states what the row says
        return {"error": str(exc)}  # type: ignore[dict-item]


def relative(source: str, root: Path) -> str:
    """A stored ``source`` relative to ``root`` (pybullet_data's folder: the rows read the same on every machine),
    as stored where it lies outside."""
    path = Path(source)
    return path.relative_to(root).as_posix() if path.is_relative_to(root) else source


def one(root: Path, name: str, extra: tuple[str, ...]) -> dict:
    """``name``'s row (a file of ``root``, pybullet_data), planned with ``extra`` arguments."""
    urdf = root / name
    with tempfile.TemporaryDirectory() as folder:
        db = Path(folder) / "g.db"
        started = time.perf_counter()
        run = subprocess.run([sys.executable, "-m", "planner.cli", "generate", str(urdf), *COMMAND, *extra, "--db",
                              str(db), "--json"], capture_output=True, text=True)
        seconds = time.perf_counter() - started
        row: dict = {"file": name, "extra": list(extra), "code": run.returncode, "seconds": round(seconds, 1),
                     "urdf": stated(urdf)}
        if run.returncode:
            row["error"] = run.stderr.strip().splitlines()[-1]
            return row
        summary = json.loads(run.stdout)
        row.update(grasps=summary["grasps"], force_closure=summary["force_closure"])
        with sqlite3.connect(db) as conn:
            row["stored"] = dict(zip(("mass", "friction", "scale", "source"), conn.execute(
                "SELECT mass, friction, scale, source FROM objects").fetchone()))
        row["stored"]["source"] = relative(row["stored"]["source"], root)
        from planner.db.objects import stored_object
        from planner.db.store import open_db

        with open_db(db, create=False, readonly=True) as store:
            mesh = stored_object(store.object_row(store.object_names()[0])).mesh
        row["extents_mm"] = (np.asarray(mesh.extents) * 1000).round(1).tolist()
        theirs = pybullet_box(urdf)
        if theirs is not None:
            gap = np.linalg.norm(np.asarray(mesh.bounds).mean(axis=0) - theirs[0])
            row.update(centre_gap_mm=round(float(gap) * 1000, 2),
                       pybullet_extents_mm=(theirs[1] * 1000).round(1).tolist())
        return row


def main() -> None:
    import pybullet_data

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="*", default=FILES)
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "urdf_objects.json")
    args = parser.parse_args()
    root = Path(pybullet_data.getDataPath())
    rows = []
    for name in args.files:
        rows.append(one(root, name, ()))
        if rows[-1]["code"] and "--mass" in rows[-1].get("error", ""):  # PyBullet's fixed body: as a user would
            print(json.dumps(rows[-1]), flush=True)
            rows.append(one(root, name, ("--mass", "0.5")))
        print(json.dumps(rows[-1]), flush=True)
    args.out.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
