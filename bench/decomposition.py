"""The convex decomposition a shake trial collides (CoACD, planner.geometry.decompose): its CPU per object and
how far its parts reach outside the object, for the shipped settings and others, with a previous run side by side.

    python bench/decomposition.py [--dev DIR] [--objects Category_id ...] [--mesh FILE ...] [--set key=value ...]
                          [--timeout 900] [--save FILE] [--previous FILE]

Objects: the meshes of the dev set's tuning objects (bench/acronym_split.toml; each at its first file's scale, as
``grasp import`` prepares it) unless ``--objects`` (dev objects) or ``--mesh`` (mesh files or built-in objects, as
``grasp generate`` reads them) say otherwise. Each decomposition runs in its own
child process (no cache: ``planner.geometry.decompose._run_coacd``), its CPU read with ``time.process_time`` around
CoACD alone (all the child's threads: CoACD runs some of its work on a second one, so CPU, not wall, is the figure;
imports and loading the mesh not counted); a decomposition longer than
``--timeout`` seconds of wall is stopped and reported as such. The parts are written to the planner's cache of
decompositions, as a trial's first run would (so trials of these objects with these settings find them).

Fidelity: 400 points sampled on each part's surface (seeded), their distance outside the object's mesh
(``trimesh.proximity.signed_distance``; 0 inside): the 95th percentile and the largest, in mm. Parts fatter than the
object make the trial's fingers meet the object early (and the open hand start inside it).

``--set key=value`` (repeatable, several in one run: ``--set mcts_iterations=50 --set mcts_nodes=10``) changes
``CoacdSettings`` from the shipped ones; ``--save`` writes the rows as JSON, ``--previous`` prints a saved run beside
this one (same objects).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import tomllib

ROOT = Path(__file__).resolve().parents[1]
DEV = ROOT.parent / "shared" / "labelled" / "acronym_dev"


def _object_mesh(source: str, dev: Path):  # type: ignore[no-untyped-def]
    """(name, prepared object) of a dev object (``Category_id``: its first grasp file) or, as ``grasp generate``
    reads it, a mesh file or built-in object (``mesh:`` before it, as ``--mesh`` passes it)."""
    if source.startswith("mesh:"):
        source = source[len("mesh:"):]
        from planner.geometry.solid import load_object

        return Path(source).stem, load_object(source)
    from planner.datasets import importer
    from planner.geometry.solid import prepare

    path = sorted((dev / "grasps").glob(f"{source}_*.h5"))[0]
    _hand, spec, _poses = importer.read_for_rescoring(path)
    return source, prepare(spec)


def _child(source: str, dev: str, settings: dict, out) -> None:  # type: ignore[no-untyped-def]
    import trimesh

    from planner.geometry import decompose

    name, obj = _object_mesh(source, Path(dev))
    mesh, chosen = obj.mesh, decompose.CoacdSettings(**settings)
    start, cpu = time.perf_counter(), time.process_time()
    parts = decompose._run_coacd(mesh, chosen)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    decompose._write(decompose._cache_path(obj.mesh_hash, chosen), parts)  # as a trial would cache them
    points = np.vstack([trimesh.Trimesh(v, f).sample(400, seed=0) for v, f in zip(parts.vertices, parts.faces)])
    outside = np.clip(-trimesh.proximity.signed_distance(mesh, points), 0.0, None)
    out.put({"object": name, "faces": len(mesh.faces), "parts": len(parts), "wall": wall, "cpu": cpu,
             "out_p95_mm": 1000 * float(np.percentile(outside, 95)), "out_max_mm": 1000 * float(outside.max())})


def measure(source: str, dev: Path, settings: dict, timeout: float) -> dict:
    """One decomposition in a child process: its row (``cpu``: CoACD's CPU seconds)."""
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=_child, args=(source, str(dev), settings, queue))
    proc.start()
    try:
        row = queue.get(timeout=timeout)
    except Exception:  # the queue's Empty: too long (or the child died)
        proc.kill()
        row = {"object": Path(source.removeprefix("mesh:")).stem if source.startswith("mesh:") else source,
               "timeout": True}
    proc.join()
    return row


def parse_settings(pairs: list[str]) -> dict:
    """The shipped ``CoacdSettings`` with ``pairs`` (``key=value``) changed, as a dict."""
    from _settings import parse

    from planner.geometry.decompose import DEFAULT_SETTINGS

    return asdict(replace(DEFAULT_SETTINGS, **parse(pairs, type(DEFAULT_SETTINGS), "decomposition")))


def summary(rows: list[dict]) -> str:
    done = [r for r in rows if not r.get("timeout")]
    if not done:
        return "no decomposition finished"
    cpu = np.array([r["cpu"] for r in done])
    p95 = np.array([r["out_p95_mm"] for r in done])
    return (f"{len(done)} objects ({len(rows) - len(done)} timed out): CPU {cpu.sum():.0f} s in all, median "
            f"{np.median(cpu):.1f} s, largest {cpu.max():.0f} s; parts' 95th-percentile reach outside the object "
            f"{p95.mean():.2f} mm on average, {p95.max():.2f} mm at worst")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dev", type=Path, default=DEV)
    parser.add_argument("--objects", nargs="*", help="dev objects (Category_id); default: the tuning objects")
    parser.add_argument("--mesh", nargs="*", default=[], help="mesh files or built-in objects (not dev objects)")
    parser.add_argument("--set", dest="changes", action="append", default=[], help="CoacdSettings key=value")
    parser.add_argument("--timeout", type=float, default=900.0, help="wall seconds per decomposition")
    parser.add_argument("--save", type=Path)
    parser.add_argument("--previous", type=Path)
    args = parser.parse_args()
    settings = parse_settings(args.changes)
    if args.mesh:
        sources = [f"mesh:{m}" for m in args.mesh]
    else:
        split = tomllib.loads((ROOT / "bench" / "acronym_split.toml").read_text())
        sources = args.objects or split["tuning"]
    previous = {r["object"]: r for r in json.loads(args.previous.read_text())["rows"]} if args.previous else {}
    print(f"CoACD settings: {settings}")
    rows = []
    for source in sources:
        row = measure(source, args.dev, settings, args.timeout)
        rows.append(row)
        before = previous.get(row["object"])
        then = "" if not before else "   (previous: timed out)" if before.get("timeout") else \
            f"   (previous: {before['cpu']:.1f} s, {before['out_p95_mm']:.2f} mm)"
        now = "timed out" if row.get("timeout") else \
            f"{row['parts']:3d} parts, CPU {row['cpu']:6.1f} s, outside p95 {row['out_p95_mm']:5.2f} mm, " \
            f"max {row['out_max_mm']:5.2f} mm"
        print(f"{row['object'][:40]:40s} {now}{then}", flush=True)
    print("this run:", summary(rows))
    if previous:
        print("previous:", summary([previous[r["object"]] for r in rows if r["object"] in previous]))
    if args.save:
        date = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
        args.save.write_text(json.dumps({"settings": settings, "date": date, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
