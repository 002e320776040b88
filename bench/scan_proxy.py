"""Scanned meshes as published, and what the collision proxy costs and changes (issue 24, item 2).

    python bench/scan_proxy.py [--before REV] [--faces 2000 100000] [--noise MM] [--approaches 256] [--poses 200]
                               [--json FILE]

Meshes (made in code, ``tests/scanlike.py``): one capsule, 4.4 cm across and 11.4 cm long, meshed with
near-uniform triangles at each ``--faces`` count and written as an OBJ with texture coordinates whose
vertices are split at the UV seam and the poles (as textured scans are published); with ``--noise MM`` the
largest is a rough scan (each position moved along the normal by seeded noise of that deviation, the smaller
ones stay on the shape); also the largest one with small holes, and two bodies in one file. Each is loaded with
the planner's loader (what it repairs is printed).

Cost: one unit of the Panda's default sweep (antipodal, ``--approaches`` points x 8 rolls x 2 depths, no
reachability) per mesh, before (``--before``, default main's :data:`BEFORE`; ``none`` skips it) and after (this
tree), each side in its own child process, CPU time (the stage timers switched to CPU time); the object's
check and its collision proxy are made before the clock starts (printed apart: a one-time cost per mesh,
cached on disk).

Same grasps: the closed grasps of the smallest mesh's unit (a seeded sample of ``--poses``), closed again
from the same poses and open fingers on the largest mesh (through its proxy, as the sweep does) and on the
largest mesh's exact surface (no proxy); closed widths and contact points compared pairwise.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _trees import ROOT, cpu_clocks, unpack, uptime

sys.path.insert(0, str(ROOT / "tests"))

#: main at the start of issue 24's session: the "before" side by default.
BEFORE = "6ab5ae8"
FINGERS = ("panda_finger_joint1", "panda_finger_joint2")


# -- child: one tree, one mesh ----------------------------------------------------------------------------------
def child(path: str, approaches: int, out: str) -> None:
    import planner
    from planner.geometry.solid import load_object
    from planner.plan.sweep import SweepSettings
    from planner.plan.unit import UnitSpec, run_unit

    switched = cpu_clocks()
    t0 = time.process_time()
    obj = load_object(path)
    proxy_faces = None
    try:  # this tree's proxy, made (and cached) outside the clock
        from planner.geometry.proxy import collision_proxy

        proxy = collision_proxy(obj.mesh, obj.mesh_hash)
        proxy_faces = len(proxy.mesh.faces)
        deviation = proxy.deviation
    except ImportError:
        deviation = None
    prep = time.process_time() - t0
    t1 = time.process_time()
    r = run_unit(UnitSpec(path, "panda", SweepSettings(approaches=approaches, chunk=0, reach_placements=0), 0))
    cpu = time.process_time() - t1
    Path(out).write_text(json.dumps({
        "planner": str(Path(planner.__file__).resolve().parent.parent), "clocks": switched, "error": r.error,
        "faces": len(obj.mesh.faces), "proxy_faces": proxy_faces, "deviation": deviation, "prepare_cpu": prep,
        "candidates": r.candidates, "grasps": len(r.grasps), "fc": r.force_closure, "cpu": cpu,
        "timing": r.timing, "rejected": dict(r.rejected)}))


def _side(tree: Path, cache: Path, path: Path, approaches: int, out: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tree), *filter(None, [os.environ.get("PYTHONPATH")])]),
               GRASP_CACHE=str(cache), GRASP_HOME=str(tree))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", str(path), "--approaches", str(approaches),
           "--json-out", str(out)]
    done = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True)
    if done.returncode or not out.exists():
        raise SystemExit(f"{tree}: child failed (exit {done.returncode}):\n{done.stderr[-3000:]}")
    data = json.loads(out.read_text())
    if Path(data["planner"]).resolve() != tree.resolve():
        raise SystemExit(f"the child imported planner from {data['planner']}, not {tree}")
    return data


# -- the meshes ---------------------------------------------------------------------------------------------------
def write_meshes(folder: Path, faces: list[int], noise: float = 0.0) -> dict[str, Path]:
    """The capsules (``noise`` [m] on the largest), the holed one and two bodies."""
    import scanlike
    import trimesh

    out = {}
    for n in faces:
        out[f"capsule_{n}"] = folder / f"capsule_{n}.obj"
        out[f"capsule_{n}"].write_text(scanlike.uv_obj(n, noise=noise if n == max(faces) else 0.0))
    big = scanlike.capsule(max(faces))
    holed = scanlike.with_holes(big, 5, np.random.default_rng(0))
    out["holes"] = folder / "capsule_holes.obj"
    holed.export(out["holes"])
    two = scanlike.bodies(scanlike.capsule(max(faces) // 2), trimesh.creation.icosphere(4, 0.02))
    out["two_bodies"] = folder / "two_bodies.obj"
    two.export(out["two_bodies"])
    return out


def loading(paths: dict[str, Path]) -> None:
    """Each mesh through the loader: faces and vertices in the file, after the check, and what it did."""
    import trimesh

    from planner.errors import MeshError
    from planner.geometry.mesh import load_mesh_file

    print("\n## Loading (planner.geometry.mesh.load_mesh_file)")
    print(f"{'mesh':22s} {'file v':>8s} {'file f':>8s} {'loaded v':>9s} {'loaded f':>9s} {'bodies':>6s} "
          f"{'volume cm3':>10s} {'CPU s':>6s}  result")
    for name, path in paths.items():
        raw = trimesh.load(str(path), force="mesh", process=False)
        t = time.process_time()
        try:
            mesh = load_mesh_file(path)
            result = "watertight" if mesh.is_watertight else "not watertight"
            row = (len(mesh.vertices), len(mesh.faces), len(mesh.split(only_watertight=False)), mesh.volume * 1e6)
        except MeshError as exc:
            result, row = f"refused: {exc}", (0, 0, 0, 0.0)
        cpu = time.process_time() - t
        print(f"{name:22s} {len(raw.vertices):8d} {len(raw.faces):8d} {row[0]:9d} {row[1]:9d} {row[2]:6d} "
              f"{row[3]:10.3f} {cpu:6.2f}  {result}")


# -- same poses on two surfaces ----------------------------------------------------------------------------------
def same_poses(small: Path, large: Path, poses: int) -> dict:
    from planner.geometry.solid import load_object
    from planner.plan.closing import Closed, Grasper
    from planner.plan.sweep import SweepSettings
    from planner.plan.unit import UnitSpec, run_unit
    from planner.sim import Sim
    from planner.specs.hands import load_hand
    from planner.specs.preshapes import load_preshapes

    hand = load_hand("panda")
    shapes = {s.name: s for s in load_preshapes(hand)}
    unit = run_unit(UnitSpec(str(small), "panda", SweepSettings(approaches=64, chunk=0, reach_placements=0), 1))
    rng = np.random.default_rng(0)
    grasps = [unit.grasps[i] for i in sorted(rng.choice(len(unit.grasps), min(poses, len(unit.grasps)), False))]
    obj = load_object(str(large))
    closed: dict[str, list] = {"proxy": [], "exact": []}
    for kind in closed:
        with Sim() as sim:
            g = Grasper.for_object(sim, hand, obj) if kind == "proxy" else Grasper.for_mesh(sim, hand, obj.mesh)
            for grasp in grasps:
                closed[kind].append(g.close_from(np.asarray(grasp.pose), shapes[grasp.preshape],
                                                hand.full_configuration(grasp.open_joints)))
    small = load_object(str(small))
    rows = []
    for grasp, p, e in zip(grasps, closed["proxy"], closed["exact"]):
        rows.append({"small": _summary(hand, small, grasp.closed_joints, grasp.contacts),
                     "proxy": _summary(hand, obj, p.closed_joints, p.contacts) if isinstance(p, Closed) else p.reason,
                     "exact": _summary(hand, obj, e.closed_joints, e.contacts) if isinstance(e, Closed) else e.reason})
    return {"poses": len(grasps), "rows": rows}


def _summary(hand, obj, joints: dict, contacts) -> dict:  # type: ignore[no-untyped-def]
    """Closed width [m], the centroid of each link's contacts [m], epsilon and force closure."""
    from planner.plan.contacts import grasp_quality

    links = np.array(contacts.links)
    q = grasp_quality(contacts, hand, obj, 8, False)
    return {"width": sum(joints[j] for j in FINGERS), "epsilon": q.epsilon, "fc": bool(q.force_closure),
            "centres": {link: np.asarray(contacts.points)[links == link].mean(axis=0).tolist() for link in set(links)}}


def _centre_gap(a: dict, b: dict) -> float:
    """[m] largest distance between the centroids of one link's contacts in ``a`` and in ``b``."""
    if set(a["centres"]) != set(b["centres"]):
        return np.inf
    return max(float(np.linalg.norm(np.subtract(a["centres"][k], b["centres"][k]))) for k in a["centres"])


def compare(rows: list[dict], a: str, b: str) -> dict:
    """Closed widths, contact centroids per link [mm] and epsilon of the poses both closed (median, 95th
    percentile, largest), and how often both agree on force closure."""
    both = [r for r in rows if isinstance(r[a], dict) and isinstance(r[b], dict)]

    def spread(x: np.ndarray) -> list[float]:
        return [float(np.median(x)), float(np.percentile(x, 95)), float(x.max())]

    return {"pairs": len(both), "only_one_closed": len(rows) - len(both),
            "width_mm": spread(np.array([abs(r[a]["width"] - r[b]["width"]) for r in both]) * 1e3),
            "centre_mm": spread(np.array([_centre_gap(r[a], r[b]) for r in both]) * 1e3),
            "epsilon": spread(np.array([abs(r[a]["epsilon"] - r[b]["epsilon"]) for r in both])),
            "same_fc": float(np.mean([r[a]["fc"] == r[b]["fc"] for r in both]))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--faces", type=int, nargs="+", default=[2000, 100000])
    parser.add_argument("--noise", type=float, default=0.0, help="[mm] a rough scan: noise on the largest mesh")
    parser.add_argument("--approaches", type=int, default=256)
    parser.add_argument("--poses", type=int, default=200)
    parser.add_argument("--before", default=BEFORE)
    parser.add_argument("--json", help="write the figures here")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--json-out", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.approaches, args.json_out)
        return
    sys.path.insert(0, str(ROOT))
    print(f"# scan_proxy: faces {args.faces}, noise {args.noise} mm, {args.approaches} approaches, "
          f"before {args.before}; {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    print(f"# {time.strftime('%Y-%m-%d %H:%M')} start: {uptime()}")
    figures: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        paths = write_meshes(folder, sorted(args.faces), args.noise * 1e-3)
        loading(paths)
        cache = Path(os.environ.get("GRASP_CACHE", tmp)) / "scan_proxy"
        sides = {"after": ROOT}
        if args.before.lower() != "none":
            sides = {"before": unpack(args.before, folder), **sides}
        print(f"\n## One default-size unit of the Panda's sweep per mesh ({args.approaches} points), CPU time")
        print(f"{'side':7s} {'mesh':16s} {'faces':>7s} {'proxy':>6s} {'dev mm':>7s} {'prep s':>7s} {'cand':>6s} "
              f"{'grasps':>6s} {'FC':>5s} {'CPU s':>7s} {'ms/cand':>8s}  stages ms/cand")
        for side, tree in sides.items():
            for n in sorted(args.faces):
                name = f"capsule_{n}"
                d = _side(tree, cache / side, paths[name], args.approaches, folder / f"{side}_{n}.json")
                figures.setdefault(side, {})[name] = d
                stages = " ".join(f"{k} {1000 * v / max(d['candidates'], 1):.2f}" for k, v in d["timing"].items() if v)
                dev = "-" if d["deviation"] is None else f"{d['deviation'] * 1e3:.3f}"
                print(f"{side:7s} {name:16s} {d['faces']:7d} {d['proxy_faces'] or '-':>6} {dev:>7s} "
                      f"{d['prepare_cpu']:7.2f} {d['candidates']:6d} {d['grasps']:6d} {d['fc']:5d} {d['cpu']:7.2f} "
                      f"{1000 * d['cpu'] / max(d['candidates'], 1):8.2f}  {stages}")
            per = [1000 * figures[side][f"capsule_{n}"]["cpu"] / max(figures[side][f"capsule_{n}"]["candidates"], 1)
                   for n in sorted(args.faces)]
            print(f"{side:7s} cost per candidate, largest / smallest mesh: {per[-1] / per[0]:.2f}x (target <= 1.5x)")
        print(f"\n## Same poses: {args.poses} closed grasps of capsule_{min(args.faces)} closed again on "
              f"capsule_{max(args.faces)} (median / 95th percentile / largest)")
        same = same_poses(paths[f"capsule_{min(args.faces)}"], paths[f"capsule_{max(args.faces)}"], args.poses)
        for a, b in (("proxy", "exact"), ("small", "proxy"), ("small", "exact")):
            c = compare(same["rows"], a, b)
            figures.setdefault("same_poses", {})[f"{a}_vs_{b}"] = c
            print(f"{a:5s} vs {b:5s}: {c['pairs']} pairs (only one closed: {c['only_one_closed']}); width mm "
                  f"{' / '.join(f'{x:.3f}' for x in c['width_mm'])}; link contact centroids mm "
                  f"{' / '.join(f'{x:.2f}' for x in c['centre_mm'])}; |d epsilon| "
                  f"{' / '.join(f'{x:.4f}' for x in c['epsilon'])}; same force closure {c['same_fc']:.1%}")
    print(f"# end: {uptime()}")
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=1))


if __name__ == "__main__":
    main()
