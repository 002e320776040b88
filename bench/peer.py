"""This planner against the PyBullet peer ``pybullet_grasper`` 0.0.2 on the peer's own object, one worker each,
in one run: CPU per candidate and per force-closure grasp, with the previous run side by side.

    python bench/peer.py [--peer-poses N] [--seed 0] [--peer-python python3.11] [--scale S]
                         [--save [FILE]] [--previous FILE]

The peer needs open3d and numpy<2, so it runs in its own venv, made once under
``${GRASP_CACHE:-~/.cache/grasp-planner}/peer-venv`` (``--peer-python -m venv``, then ``pip install
pybullet_grasper==0.0.2`` with pyyaml, scikit-learn and matplotlib, which 0.0.2 imports without declaring them).
Nothing of the peer is kept in this repository; its object is read from that venv
(``share/pybullet_grasper/objects/object_0.obj``, a 5.4 x 9.1 x 15.9 cm scan in metres: no ``--scale``).

Each side runs in a child process, one after the other, with OpenMP/BLAS held to one thread; its CPU time is the
child's (``resource.getrusage(RUSAGE_CHILDREN)``, user + system: interpreter start, imports and all), and, as a
second reading, the CPU inside the child after its imports (``time.process_time``).

- the peer: a driver run by the venv's python imports ``pybullet_grasper.grasp_generator`` and builds
  ``GraspGenerator`` (V-HACD of the object, its point cloud, the collision-free gripper poses) with a YAML written
  from its ``default.yaml``: Robotiq 2F-85, ``debug`` and ``show_last`` off (headless, PyBullet DIRECT), analytical
  quality on, ``gws.scale`` off. Its ``run()`` would start ``cpu_count() - 2`` processes (none on two cores: it
  divides by zero), so the driver runs the worker body, ``ClientProcess.run()``, in its own process over all the
  poses (``--peer-poses``: the first N after the peer's shuffle, seeded). Headless, the peer never calls its
  analytical quality (``test_grasp`` does only in its GUI modes); the driver calls ``Grasp.evaluate_contact(["L1"])``
  where the GUI mode does, after the jaws stop and before the plane is lowered, with the peer's 2 s wall-clock alarm
  paused for it (the GUI mode has no alarm). The Linf hull is left out: the verdict does not need it, and its
  Minkowski sum has 8^contacts points; so the peer's figure is, if anything, cheap.
- candidates (peer): the gripper poses it simulates (``len(gripper_poses)``, one per cloud point whose pose is
  clear of the object); grasps: those it scores (score != -1: closed, lifted and turned without a time-out, as its
  ``grasper_main`` counts "grasps found").
- force closure (peer): the L1 grasp wrench space hull of the contacts at the closed grasp (8-edge cones,
  mu = object 1 x pad 0.5, torques / the object's radius, the zero wrench included, unscaled) exists and its
  epsilon ``min(-offset)`` exceeds our threshold, ``FORCE_CLOSURE_TOL`` (1e-9): the origin lies strictly inside,
  so the contact wrenches positively span R^6. A grasp that is not force closure has the zero wrench on its hull
  (epsilon ~1e-18 of round-off, or below 0); the smallest real margin seen is 1.6e-4. No hull (fewer than two
  contacts; a flat set, as two point contacts give) is not force closure. ``gws.scale`` (the peer's default)
  maps every wrench axis to [-0.5, 0.5] before the hull, which moves the origin to the middle of the wrenches'
  box; its epsilon > 0 is reported beside ("scaled eps > 0"), not used. After the clock stops the same wrenches
  are re-hulled without the peer's Qhull merging (``C-1e-4``, which moves facets by up to ~5e-4 here) as a check
  ("exact re-check", same threshold; its count and ratio are printed beside, the peer's own verdict is the
  figure). The peer's 2 s alarm per pose is wall-clock: on a crowded machine it can cost the peer grasps (the
  counts printed would drop; on 2026-12-03 they were the same at load 1.5 and 5).
- ours: ``planner.api.generate`` (``grasp generate OBJ --hand panda --workers 1``), the default sweep (antipodal
  sampler, its force-closure budget, reachability), into a fresh database, with a fresh ``GRASP_CACHE`` (cold:
  the object's checks, proxy and parts are built inside the clock, as the peer's V-HACD is), on the same mesh at
  the peer's mass (0.5 kg) and friction (0.5). Candidates, grasps and force closure as the run's summary counts
  them (``Summary.candidates``: every candidate tried, cheap refusals of unusable point pairs included).

Printed: per side, candidates, grasps, force-closure grasps, CPU s, CPU ms per candidate and per force-closure
grasp; the ratios peer / ours; the machine, the date, the load average at start and end. ``--save [FILE]``
writes the figures (default ``bench/peer.json``); the figures of ``--previous FILE`` (default
``bench/peer.json``) are shown in brackets.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _trees import ROOT, uptime

PREVIOUS = ROOT / "bench" / "peer.json"
PEER = "pybullet_grasper==0.0.2"
#: What 0.0.2 imports without declaring it (yaml, sklearn, matplotlib), and its own pin.
PEER_EXTRA = ("pyyaml", "scikit-learn", "matplotlib", "numpy<2")
OBJECT = Path("share", "pybullet_grasper", "objects", "object_0.obj")
#: The peer's object (its urdf template): mass [kg] and lateral friction; the pads' friction is 0.5.
PEER_MASS, PEER_FRICTION = 0.5, 0.5
ONE_THREAD = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}

#: Run by the peer's venv: argv = config out, object, pose limit (0: all), seed, force-closure tolerance, json out.
DRIVER = r'''
import json, multiprocessing, os, signal, sys, time
t_start = time.process_time()
import numpy as np
import open3d as o3d
import yaml
from scipy.spatial import ConvexHull
from pybullet_grasper.grasp_generator import ClientProcess, GraspGenerator
from pybullet_grasper.utils import get_data_folder

config, obj, limit, seed, tol, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), \
    float(sys.argv[5]), sys.argv[6]
with open(os.path.join(get_data_folder(), "configs", "default.yaml")) as f:
    c = yaml.safe_load(f)
c["debug"] = False
c["visualization"]["show_last"] = False
c["analytical"]["enabled"] = True
c["analytical"]["gws"]["scale"] = False
with open(config, "w") as f:
    yaml.safe_dump(c, f)
np.random.seed(seed)  # the peer's shuffle of its poses
o3d.utility.random.seed(seed)  # its point cloud
t0 = time.process_time()
g = GraspGenerator(obj, init_position=[0, 0, 0], config_name=config, ros=False)
t1 = time.process_time()
poses = g.gripper_poses[:limit] if limit else g.gripper_poses
worker = ClientProcess(g.client, 0, poses, multiprocessing.Array("d", np.repeat(-1, len(poses))),
                       multiprocessing.Array("d", np.repeat(-1, 7 * len(poses))))
client, test, lower = g.client, worker.test_grasp, g.client.lower_the_plane
hulls, now, analytic = {}, [None], [0.0]

def test_grasp(pose, pose_id):
    now[0] = pose_id
    return test(pose, pose_id)

def lower_the_plane(target):  # the closed grasp, where the peer's GUI mode evaluates it
    left = signal.alarm(0)
    a = time.process_time()
    client.grasper.hulls = {}
    client.grasper.evaluate_contact(["L1"])
    h = client.grasper.hulls.get("L1")
    hulls[now[0]] = None if h is None else (float(np.min(-h.equations[:, -1])), h.points.copy())
    analytic[0] += time.process_time() - a
    if left:
        signal.alarm(left)
    return lower(target)

worker.test_grasp, client.lower_the_plane = test_grasp, lower_the_plane
worker.run()
t2 = time.process_time()
score = np.array(worker.score[:])
fc = {i for i, v in hulls.items() if v is not None and v[0] > tol}

def eps(points, options, scaled):  # after the clock: the check and the peer's default scaling
    if scaled:
        lo, hi = c["analytical"]["gws"]["scale_interval"]
        points = (points - points.min(0)) * (hi - lo) / (points.max(0) - points.min(0)) + lo
    try:
        return float(np.min(-ConvexHull(points, qhull_options=options).equations[:, -1]))
    except Exception:
        return float("nan")

merge = "n Qx C-" + c["analytical"]["gws"]["merging_radius"]
done = [v for v in hulls.values() if v is not None]
pairs = sorted((v[0], eps(v[1], None, False)) for v in done)  # the peer's epsilon, the exact one
json.dump({"poses": len(g.gripper_poses), "points": len(g.client.object.pc.points), "candidates": len(poses),
           "grasps": int(np.sum(score != -1)), "evaluated": len(hulls), "hulls": len(done), "fc": len(fc),
           "fc_held": int(sum(score[i] != -1 for i in fc)),
           "epsilons": [[float(f"{a:.3g}"), float(f"{b:.3g}")] for a, b in pairs],
           "fc_exact": sum(b > tol for _, b in pairs),
           "fc_scaled": sum(eps(v[1], merge, True) > tol for v in done),
           "import_cpu": t0 - t_start, "init_cpu": t1 - t0, "trials_cpu": t2 - t1, "analytic_cpu": analytic[0],
           "work_cpu": t2 - t0, "python": sys.version.split()[0], "numpy": np.__version__,
           "open3d": o3d.__version__}, open(out, "w"))
'''


# -- the peer's venv ------------------------------------------------------------------------------------------------
def peer_venv(python: str) -> Path:
    """The peer's venv (made once; a failure ends the run with one line); returns its folder."""
    root = Path(os.environ.get("GRASP_CACHE", Path.home() / ".cache" / "grasp-planner")) / "peer-venv"
    marker = root / "peer-ready.txt"
    want = " ".join((PEER, *PEER_EXTRA))
    if marker.is_file() and marker.read_text().strip() == want:
        return root
    if (root / "pyvenv.cfg").is_file():  # a half-made venv of ours: start over
        shutil.rmtree(root)
    steps = [[python, "-m", "venv", str(root)],
             [str(root / "bin" / "python"), "-m", "pip", "install", "-q", PEER, *PEER_EXTRA],
             [str(root / "bin" / "python"), "-c", "import pybullet_grasper.grasp_generator, open3d"]]
    print(f"# making the peer's venv {root} ({want}) ...", flush=True)
    for cmd in steps:
        try:
            done = subprocess.run(cmd, capture_output=True, text=True)
        except OSError as exc:
            raise SystemExit(f"peer venv: cannot run {cmd[0]}: {exc} (use --peer-python)") from None
        if done.returncode:
            last = [s for s in (done.stderr + done.stdout).splitlines() if not s.startswith("WARNING: Location")]
            raise SystemExit(f"peer venv: `{' '.join(cmd)}` failed (exit {done.returncode}): "
                             f"{last[-1] if last else ''}")
    marker.write_text(want + "\n")
    return root


def _child_cpu(cmd: list[str], env: dict, cwd: Path) -> tuple[subprocess.CompletedProcess, float]:
    """Run ``cmd``; its CPU seconds (user + system, its own children included)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return done, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _failed(side: str, done: subprocess.CompletedProcess) -> SystemExit:
    tail = (done.stderr or done.stdout).strip().splitlines()[-3:]
    return SystemExit(f"{side} failed (exit {done.returncode}): " + " | ".join(tail))


def fc_tolerance() -> float:
    """Our force-closure threshold on the L1 epsilon, from this checkout; the peer's verdict uses it too."""
    sys.path.insert(0, str(ROOT))
    from planner.quality.tolerances import FORCE_CLOSURE_TOL

    return FORCE_CLOSURE_TOL


def run_peer(venv: Path, args: argparse.Namespace, folder: Path) -> dict:
    driver, out = folder / "peer_driver.py", folder / "peer.json"
    driver.write_text(DRIVER)
    cmd = [str(venv / "bin" / "python"), str(driver), str(folder / "peer.yaml"), str(venv / OBJECT),
           str(args.peer_poses), str(args.seed), str(fc_tolerance()), str(out)]
    start = time.perf_counter()
    done, cpu = _child_cpu(cmd, dict(os.environ, **ONE_THREAD), folder)
    if done.returncode or not out.is_file():
        raise _failed("the peer", done)
    return dict(json.loads(out.read_text()), cpu=cpu, wall=time.perf_counter() - start)


# -- ours -----------------------------------------------------------------------------------------------------------
def child(obj: str, hand: str, db: str, scale: float | None, seed: int, out: str) -> None:
    t_start = time.process_time()
    import trimesh

    import planner
    from planner import api
    from planner.specs.hands import load_hand

    t0 = time.process_time()
    summary = api.generate([obj], hand, db_path=Path(db), seed=seed, workers=1, scale=scale,
                           mass=PEER_MASS, friction=PEER_FRICTION)
    work = time.process_time() - t0
    spec = load_hand(hand)
    settings = api.SweepSettings().resolved(spec.sampler, spec.settle)
    extents = trimesh.load(obj, force="mesh").extents * (scale or 1.0)
    Path(out).write_text(json.dumps({
        "planner": str(Path(planner.__file__).resolve().parent.parent), "failed": summary.failed,
        "candidates": summary.candidates, "grasps": summary.grasps, "fc": summary.force_closure,
        "rejected": dict(summary.rejected), "units": summary.units, "import_cpu": t0 - t_start, "work_cpu": work,
        "extents_m": [round(float(e), 4) for e in extents],
        "settings": {k: getattr(settings, k) for k in (
            "sampler", "approaches", "rolls", "depths", "chunk", "fc_budget", "reach_placements", "settle")},
        "python": platform.python_version()}))


def run_ours(obj: Path, args: argparse.Namespace, folder: Path) -> dict:
    out = folder / "ours.json"
    cache = folder / "grasp-cache"  # cold: nothing of an earlier run
    env = dict(os.environ, **ONE_THREAD, GRASP_CACHE=str(cache), GRASP_HOME=str(ROOT),
               PYTHONPATH=os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", str(obj), "--hand", args.hand,
           "--db", str(folder / "ours.sqlite"), "--seed", str(args.seed), "--json-out", str(out),
           *(["--scale", str(args.scale)] if args.scale else [])]
    start = time.perf_counter()
    done, cpu = _child_cpu(cmd, env, ROOT)
    if done.returncode or not out.is_file():
        raise _failed("ours", done)
    data = json.loads(out.read_text())
    if Path(data["planner"]).resolve() != ROOT.resolve():
        raise SystemExit(f"the child imported planner from {data['planner']}, not {ROOT}")
    if data["failed"]:
        raise SystemExit(f"ours: units failed: {data['failed']}")
    return dict(data, cpu=cpu, wall=time.perf_counter() - start)


# -- figures --------------------------------------------------------------------------------------------------------
def rates(side: dict) -> dict:
    """CPU ms per candidate and per force-closure grasp, whole child and after imports."""
    out = {}
    for key, cpu in (("", side["cpu"]), (" (work)", side["work_cpu"])):
        out["ms/candidate" + key] = 1000 * cpu / side["candidates"] if side["candidates"] else float("nan")
        out["ms/FC" + key] = 1000 * cpu / side["fc"] if side["fc"] else float("nan")
    return out


def figures(peer: dict, ours: dict) -> dict:
    sides = {"peer": dict(peer, **rates(peer)), "ours": dict(ours, **rates(ours))}
    ratios = {k: sides["peer"][k] / sides["ours"][k] for k in rates(peer)}
    return {"sides": sides, "ratios": ratios}


def _cell(value: object, before: object) -> str:
    def text(v: object) -> str:
        return "-" if v is None else f"{v:d}" if isinstance(v, int) else f"{v:.4g}" if isinstance(v, float) else str(v)
    return text(value) + ("" if before is None else f" [{text(before)}]")


def _print(now: dict, previous: dict | None) -> None:
    before = previous or {}
    rows = (("candidates", "candidates"), ("grasps", "grasps"), ("force-closure", "fc"), ("CPU s", "cpu"),
            ("ms / candidate", "ms/candidate"), ("ms / FC grasp", "ms/FC"), ("CPU s after imports", "work_cpu"),
            ("  ms / candidate", "ms/candidate (work)"), ("  ms / FC grasp", "ms/FC (work)"), ("wall s", "wall"))
    print(f"\n{'':22s} {'peer':>22s} {'ours':>22s} {'peer / ours':>22s}   (previous run in brackets)")
    for label, key in rows:
        cells = [_cell(now["sides"][s].get(key), before.get("sides", {}).get(s, {}).get(key)) for s in ("peer", "ours")]
        ratio = _cell(now["ratios"].get(key), before.get("ratios", {}).get(key)) if key in now["ratios"] else ""
        print(f"{label:22s} {cells[0]:>22s} {cells[1]:>22s} {ratio:>22s}")
    p, o = now["sides"]["peer"], now["sides"]["ours"]
    exact = 1000 * p["cpu"] / p["fc_exact"] if p["fc_exact"] else float("nan")
    print(f"\npeer: {p['poses']} poses from {p['points']} cloud points, {p['candidates']} simulated; "
          f"{p['evaluated']} closed grasps evaluated, {p['hulls']} L1 hulls, FC {p['fc']} (of them held: "
          f"{p['fc_held']}); exact re-check FC {p['fc_exact']} ({exact:.4g} ms each, {exact / o['ms/FC']:.3g}x ours); "
          f"the peer's default scaled eps > 0: {p['fc_scaled']}; "
          f"CPU: imports {p['import_cpu']:.1f} s, init (V-HACD, cloud, poses) {p['init_cpu']:.1f} s, trials "
          f"{p['trials_cpu']:.1f} s (analytic {p['analytic_cpu']:.2f} s)")
    print(f"ours: {o['units']} units, rejected {o['rejected']}; imports {o['import_cpu']:.1f} s; "
          f"settings {o['settings']}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hand", default="panda", help="our hand (the peer's is its Robotiq 2F-85)")
    parser.add_argument("--peer-poses", type=int, default=0, help="the peer's first N poses only (0: all)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scale", type=float, help="our --scale for the mesh (it is in metres: none)")
    parser.add_argument("--peer-python", default="python3.11", help="the interpreter of the peer's venv")
    parser.add_argument("--previous", type=Path, default=PREVIOUS)
    parser.add_argument("--save", type=Path, nargs="?", const=PREVIOUS, help="write this run (default: %(const)s)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--db", help=argparse.SUPPRESS)
    parser.add_argument("--json-out", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.hand, args.db, args.scale, args.seed, args.json_out)
        return
    venv = peer_venv(args.peer_python)
    cpu = next((s.split(":", 1)[1].strip() for s in Path("/proc/cpuinfo").read_text().splitlines()
                if s.startswith("model name")), platform.processor()) if Path("/proc/cpuinfo").is_file() else "?"
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    date = time.strftime("%Y-%m-%d %H:%M")
    print(f"# peer: {PEER} (Robotiq 2F-85) against ours ({args.hand}) at {commit}, one worker each; "
          f"{os.cpu_count()} cores ({cpu}), Python {platform.python_version()}")
    start = uptime()
    print(f"# {date} start: {start}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        peer = run_peer(venv, args, folder)
        print(f"#   peer: {peer['candidates']} candidates, {peer['fc']} FC, {peer['cpu']:.1f} CPU s "
              f"(Python {peer['python']}, numpy {peer['numpy']}, open3d {peer['open3d']})", flush=True)
        ours = run_ours(venv / OBJECT, args, folder)
        print(f"#   ours: {ours['candidates']} candidates, {ours['fc']} FC, {ours['cpu']:.1f} CPU s; object "
              f"extents {ours['extents_m']} m", flush=True)
    end = uptime()
    print(f"# end: {end}")
    now = dict(figures(peer, ours), date=date, commit=commit, peer=PEER, hand=args.hand, seed=args.seed,
               peer_poses=args.peer_poses, machine={"nproc": os.cpu_count(), "cpu": cpu,
                                                    "python": platform.python_version()},
               load={"start": start, "end": end})
    previous = json.loads(args.previous.read_text()) if args.previous.is_file() else None
    if previous:
        print(f"# previous run: {previous.get('date')} ({previous.get('commit')})")
    _print(now, previous)
    if args.save:
        args.save.write_text(json.dumps(now, indent=1) + "\n")
        print(f"# written to {args.save}")


if __name__ == "__main__":
    main()
