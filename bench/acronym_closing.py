"""Closing at given poses against ACRONYM: of the poses where ACRONYM's own
open gripper is free of the object, how many does the planner close to
contacts (issue 26, item 1)?

    python bench/acronym_closing.py [--poses 200 | --all] [--seed 0] [--objects TEXT ...]
                                    [--render DIR] [--per-outcome 3] [--labels PATH]

Reads the dev set (``../shared/labelled/acronym_dev`` beside the main
checkout, or ``--labels``) at run time, the files of the ``tuning`` objects
of ``bench/acronym_split.toml`` only (``held_out`` objects are never
opened). Per file, a uniform sample of ``--poses`` poses (a numpy Generator
seeded with ``--seed`` and the file's row in the sorted list; ``--all``: every
pose). Per pose:

1. ACRONYM's open gripper mesh (``franka_gripper_collision_mesh.stl``,
   ACRONYM's hand frame) placed at the file's transform is collided with the
   scaled object mesh (python-fcl, triangle against triangle, plus "is an
   object vertex inside the closed gripper mesh"): poses where it collides
   are counted apart and left out (the README says there are none);
2. the planner closes its widest Panda preshape at the pose as
   ``grasp import --rescore`` does (``Grasper.close_at``, the importer's
   back-off limit), on the object the importer builds (``prepare`` of the
   mesh at the file's scale);
3. an independent geometric check, with no closing code: each Panda finger's
   swept volume (the convex hull of its collision hull at its open place,
   after the planner's back-off if any, and at its final place; a
   translation, so the hull is exact), eroded by ``DEPTH`` (1 mm, closing's
   own overlap allowance), must meet no triangle and hold no vertex of the
   mesh: the finger went no deeper than that into the object on its way.
   A finger that touches is swept to where it ended, else it passed through
   something before its contact (``passed_through``); one that does not is
   swept to its closing limit (fully shut), else it closed past the object
   or stopped short of it (``finger_missed`` on a ``Closed`` grasp,
   ``no_contact_missed`` on a ``no_contact`` rejection).

Outcomes: ``contacts`` (both fingers at first contact), ``one_finger`` (one
at first contact, the other truly on air), ``on_air`` (``no_contact`` or only
the palm touching, both fingers truly on air) are faithful; every other
rejection reason of closing, and the three failures above, are not. Printed:
per file and in all, the count of every outcome, and the faithful fraction
of the free poses (target >= 98%). ``--render DIR`` draws up to
``--per-outcome`` seeded examples of each outcome to ``DIR/<outcome>.png``:
per row the planner's hand where closing left it (two views looking along
the fingers' sides at the tool centre point) and ACRONYM's open gripper at
the pose (one view), the object orange.

Runs against whatever ``planner`` is first on ``PYTHONPATH`` (it only uses
calls that the branch's first commit has too, so the same script measures
"before": ``git archive REV | tar -x -C DIR`` and ``PYTHONPATH=DIR``).
"""

from __future__ import annotations

import argparse
import platform
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import trimesh
from scipy.spatial import ConvexHull, HalfspaceIntersection

from planner.datasets import acronym
from planner.datasets.importer import MAX_BACK_OFF
from planner.geometry.solid import PreparedObject, prepare
from planner.plan.closing import Closed, Grasper
from planner.sim import Sim
from planner.sim import fcl as overlap
from planner.specs.hands import HandSpec, load_hand
from planner.specs.objects import resolve_spec
from planner.specs.preshapes import sweep_preshapes
from planner.specs.toml import read_toml
from planner.specs.urdf import load_model

BENCH = Path(__file__).resolve().parent
SPLIT = BENCH / "acronym_split.toml"
LABELS = Path("/work/shared/labelled/acronym_dev")
GRIPPER_MESH = "franka_gripper_collision_mesh.stl"
FINGERS = ("panda_leftfinger", "panda_rightfinger")
#: A finger's sweep may reach this far [m] into the object and still count as
#: free: closing itself accepts overlaps of max_penetration (1 mm), and a
#: finger sliding past a face at a grazing angle dips into it (closing counts
#: a pair closing in slower than CLOSING_SPEED_MIN as sliding past).
DEPTH = 0.001
FAITHFUL = ("contacts", "one_finger", "on_air")
#: Rendering: picture size, and the camera's distance from the tool centre point [m].
VIEW = (360, 300)
CAMERA_DISTANCE = 0.16
OBJECT_RGBA = (0.85, 0.55, 0.25, 1.0)
HAND_RGBA = (0.55, 0.6, 0.7, 1.0)
ACRONYM_RGBA = (0.3, 0.7, 0.35, 1.0)


@dataclass(frozen=True)
class Example:
    """One pose to draw: the file, the pose's row, where the planner's hand
    ended ((4, 4) pose and finger joints) and the ACRONYM transform (4, 4)."""

    file: Path
    row: int
    outcome: str
    pose: np.ndarray
    joints: dict[str, float]
    transform: np.ndarray
    note: str


def tuning_files(labels: Path, only: list[str]) -> list[Path]:
    """The dev set's grasp files of the tuning objects (never a held-out one)."""
    split = read_toml(SPLIT)
    tuning, held = set(split["tuning"]), set(split["held_out"])
    out = []
    for path in sorted((labels / "grasps").glob("*.h5")):
        obj = path.name.rsplit("_", 1)[0]
        if obj in held or obj not in tuning:
            continue
        if only and not any(text in path.name for text in only):
            continue
        out.append(path)
    return out


def load_target(labels: Path, path: Path) -> tuple[PreparedObject, np.ndarray]:
    """The object the importer builds for ``path`` and the file's (N, 4, 4) ACRONYM transforms."""
    with h5py.File(path, "r") as f:
        mesh = f["object/file"][()].decode()
        scale = float(f["object/scale"][()])
        transforms = np.asarray(f["grasps/transforms"][()], float)
    return prepare(resolve_spec(str(labels / mesh), scale=scale)), transforms


class FingerSweeps:
    """The Panda fingers' convex collision hulls, placed by a probe hand in
    its own simulator (nothing shared with the grasper)."""

    def __init__(self, hand: HandSpec) -> None:
        self.sim = Sim()
        self.body = self.sim.load_urdf(hand.urdf, visual=False)
        model = load_model(hand.urdf)
        self.hulls: dict[str, np.ndarray] = {}
        for link in FINGERS:
            points = []
            for collision in model.link_map[link].collisions:
                name = collision.geometry.mesh.filename.replace("file://", "")
                path = Path(name) if Path(name).is_absolute() else hand.urdf.parent / name
                scale = collision.geometry.mesh.scale
                vertices = trimesh.load(path, force="mesh").convex_hull.vertices * (1.0 if scale is None else scale)
                origin = np.eye(4) if collision.origin is None else np.asarray(collision.origin, float)
                points.append(vertices @ origin[:3, :3].T + origin[:3, 3])
            self.hulls[link] = np.vstack(points)

    def placed(self, pose: np.ndarray, joints: dict[str, float]) -> dict[str, np.ndarray]:
        """(k, 3) hull vertices of each finger, object frame, with the hand at ``pose`` and ``joints``."""
        self.sim.set_pose(self.body, pose)
        self.sim.set_joints(self.body, joints)
        out = {}
        for link, vertices in self.hulls.items():
            frame = self.sim.link_pose(self.body, link)
            out[link] = vertices @ frame[:3, :3].T + frame[:3, 3]
        return out


def sweep_meets(start: np.ndarray, end: np.ndarray, mesh_bvh: object, vertices: np.ndarray) -> bool:
    """Does a finger sweeping from ``start`` to ``end`` ((k, 3) hull vertices
    each, one translation apart) reach more than ``DEPTH`` into the object?
    The swept volume is the convex hull of both; eroded by ``DEPTH`` (every
    face plane moved in), it must have no triangle crossing it and no mesh
    vertex inside."""
    points = np.vstack([start, end])
    planes = ConvexHull(points).equations.copy()
    planes[:, 3] += DEPTH
    eroded = HalfspaceIntersection(planes, points.mean(0)).intersections
    core = trimesh.Trimesh(eroded, ConvexHull(eroded).simplices, process=False)
    if overlap.collides(overlap.object_bvh(core.vertices, core.faces), mesh_bvh):
        return True
    lo, hi = eroded.min(0), eroded.max(0)
    near = vertices[np.all((vertices >= lo) & (vertices <= hi), axis=1)]
    return bool(len(near)) and bool(np.any(np.all(near @ planes[:, :3].T + planes[:, 3] <= 0, 1)))


def acronym_free(gripper: trimesh.Trimesh, transform: np.ndarray, mesh_bvh: object, vertices: np.ndarray) -> bool:
    """Is ACRONYM's open gripper mesh at ``transform`` free of the object?"""
    if overlap.collides(overlap.object_bvh(gripper.vertices, gripper.faces, transform), mesh_bvh):
        return False
    local = (vertices - transform[:3, 3]) @ transform[:3, :3]
    lo, hi = gripper.bounds
    near = local[np.all((local >= lo) & (local <= hi), axis=1)]
    return not (len(near) and np.any(gripper.contains(near)))


def judge(grasper: Grasper, sweeps: FingerSweeps, hand: HandSpec, given: np.ndarray, result: object,
          mesh_bvh: object, vertices: np.ndarray) -> tuple[str, np.ndarray, dict[str, float], str]:
    """(outcome, the hand's final pose, its final finger joints, a note)."""
    names = [j.name for j in hand.joints]
    final = grasper.sim.link_pose(grasper.body, hand.root_link)
    joints = dict(zip(names, grasper.sim.joint_values(grasper.body, names)))
    if not isinstance(result, Closed) and result.reason != "no_contact":  # type: ignore[attr-defined]
        return result.reason, final, joints, ""  # type: ignore[attr-defined]
    approach = given[:3, :3] @ hand.approach
    backed = float((given[:3, 3] - final[:3, 3]) @ approach)
    start = given.copy()
    start[:3, 3] -= approach * backed
    opened = sweeps.placed(start, hand.widest(sweep_preshapes(hand)).joints)
    closed = sweeps.placed(final, joints)
    # the Panda's fingers close towards their joints' lower limits (fully shut)
    shut = sweeps.placed(start, {j.name: j.lower for j in hand.joints})
    touching = set() if not isinstance(result, Closed) else {n for n in result.contacts.links if n in FINGERS}
    width = joints[names[0]] + joints[names[1]]
    note = f"width {1000 * width:.1f} mm, back-off {1000 * backed:.1f} mm"
    for link in FINGERS:
        if link in touching:
            if sweep_meets(opened[link], closed[link], mesh_bvh, vertices):
                return "passed_through", final, joints, f"{link}; {note}"
        elif sweep_meets(opened[link], shut[link], mesh_bvh, vertices):
            missed = "finger_missed" if isinstance(result, Closed) else "no_contact_missed"
            return missed, final, joints, f"{link}; {note}"
    return {2: "contacts", 1: "one_finger", 0: "on_air"}[len(touching)], final, joints, note


def run_file(path: Path, labels: Path, hand: HandSpec, gripper: trimesh.Trimesh, sweeps: FingerSweeps,
             rows: np.ndarray, keep: dict[str, list[Example]], seen: Counter, per_outcome: int,
             rng: np.random.Generator) -> Counter:
    """Outcome counts of ``rows`` of ``path``; ``keep`` holds a uniform sample
    (reservoir, over every file so far: ``seen`` counts them) of each outcome."""
    obj, transforms = load_target(labels, path)
    poses = acronym.read_poses(path, hand)
    mesh_bvh = overlap.object_bvh(obj.mesh.vertices, obj.mesh.faces)
    vertices = np.asarray(obj.mesh.vertices, float)
    shape = hand.widest(sweep_preshapes(hand))
    counts: Counter = Counter()
    with Sim() as sim:
        grasper = Grasper.for_mesh(sim, hand, obj.mesh)
        for row in rows:
            if not acronym_free(gripper, transforms[row], mesh_bvh, vertices):
                counts["acronym_collides"] += 1
                continue
            result = grasper.close_at(poses[row], shape, MAX_BACK_OFF)
            outcome, final, joints, note = judge(grasper, sweeps, hand, poses[row], result, mesh_bvh, vertices)
            counts[outcome] += 1
            seen[outcome] += 1
            chosen = keep.setdefault(outcome, [])
            example = Example(path, int(row), outcome, final, joints, transforms[row], note)
            if len(chosen) < per_outcome:
                chosen.append(example)
            elif rng.random() < per_outcome / seen[outcome]:
                chosen[int(rng.integers(per_outcome))] = example
    return counts


def render(examples: list[Example], labels: Path, hand: HandSpec, gripper: trimesh.Trimesh, out: Path) -> None:
    from planner.present.render import save_sheet

    panels = []
    for ex in examples:
        obj, _ = load_target(labels, ex.file)
        with Sim() as sim:
            sim.add_visual_mesh(obj.mesh.vertices, obj.mesh.faces, OBJECT_RGBA)
            body = sim.load_urdf(hand.urdf)
            sim.set_pose(body, ex.pose)
            sim.set_joints(body, ex.joints)
            sim.set_color(body, HAND_RGBA)
            tcp = ex.pose[:3, :3] @ hand.widest(sweep_preshapes(hand)).tcp + ex.pose[:3, 3]
            side, fingers, approach = ex.pose[:3, 0], ex.pose[:3, 1], ex.pose[:3, 2]
            up = -approach
            views = []
            for eye in (side, 0.8 * side + 0.45 * fingers - 0.4 * approach):
                eye = eye / np.linalg.norm(eye)
                views.append(sim.render(tcp + CAMERA_DISTANCE * eye, tcp, up, VIEW))
            sim.remove_body(body.uid)
            sim.add_visual_mesh(gripper.vertices, gripper.faces, ACRONYM_RGBA, ex.transform)
            views.append(sim.render(tcp + CAMERA_DISTANCE * side, tcp, up, VIEW))
        panels.append((views, f"{ex.outcome}: {ex.file.stem[:28]} row {ex.row}; {ex.note}"))
    save_sheet(panels, out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=200, help="poses sampled per file (default 200)")
    parser.add_argument("--all", action="store_true", help="every pose of every file")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--objects", nargs="*", default=[], help="only files whose name contains one of these")
    parser.add_argument("--render", type=Path, default=None, help="draw examples of each outcome into this folder")
    parser.add_argument("--per-outcome", type=int, default=3)
    parser.add_argument("--labels", type=Path, default=LABELS)
    args = parser.parse_args()
    hand = load_hand("panda")
    gripper = trimesh.load(args.labels / GRIPPER_MESH, force="mesh")
    sweeps = FingerSweeps(hand)
    files = tuning_files(args.labels, args.objects)
    when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    sample = "every pose" if args.all else f"{args.poses} poses each"
    print(f"{platform.node()} {platform.processor() or platform.machine()}, {when}; {len(files)} tuning files, "
          f"{sample}, seed {args.seed}")
    total: Counter = Counter()
    keep: dict[str, list[Example]] = {}
    seen: Counter = Counter()
    start = time.perf_counter()
    for index, path in enumerate(files):
        rng = np.random.default_rng([args.seed, index])
        with h5py.File(path, "r") as f:
            n = len(f["grasps/transforms"])
        rows = np.arange(n) if args.all else np.sort(rng.choice(n, min(args.poses, n), replace=False))
        counts = run_file(path, args.labels, hand, gripper, sweeps, rows, keep, seen, args.per_outcome, rng)
        total += counts
        print(f"  {path.stem[:44]:44s} " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())), flush=True)
    free = sum(v for k, v in total.items() if k != "acronym_collides")
    faithful = sum(total[k] for k in FAITHFUL)
    print(f"in all ({time.perf_counter() - start:.0f} s): " + ", ".join(f"{k} {v}" for k, v in sorted(total.items())))
    print(f"ACRONYM-free poses {free} of {sum(total.values())}; faithful (contacts, one finger or on air, "
          f"checked by the finger sweeps) {faithful} = {100 * faithful / max(free, 1):.2f}%")
    if args.render is not None:
        for outcome, examples in sorted(keep.items()):
            render(examples, args.labels, hand, gripper, args.render / f"{outcome}.png")
        print(f"pictures in {args.render}: " + ", ".join(f"{k}.png" for k in sorted(keep)))
    sweeps.sim.close()


if __name__ == "__main__":
    main()
